"""dva wing: flutter, modal and time analyses of the wing, and its calibration."""
