"""Named values of the control laws that the controller table states: the study's spectrum band
and the window functions of the scaled spectrum (eq. 7.3), the switching supervisor's fallback
source (pure constants, no imports: a node's ``--help`` states them without loading the
numerics; :mod:`~aero_dva.control.spectrum` and
:mod:`~aero_dva.control.switching_supervisor` re-export them).
"""

#: [Hz] the study's band: 5..20 Hz in 1 Hz steps (section 7.2.1).
STUDY_BAND = tuple(float(f) for f in range(5, 21))
#: Window functions understood by :func:`aero_dva.control.spectrum.scaled_spectrum` (names as
#: in dva_msgs/ScaledSpectrum).
WINDOW_FUNCTIONS = ("rectangular", "hann")
#: ``DamperCommand.source`` of the switching supervisor's safe c2 (the switching law's table
#: entry's second source).
FALLBACK_SOURCE = "switching_fallback"
