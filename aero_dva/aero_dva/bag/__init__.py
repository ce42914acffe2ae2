"""The bag layer: rosbag2-layout MCAP bags: message schemas read from the .msg files, writers and
readers, the batch CDR encoder and chunk framing of the recorded sweep, flight logs read back.
May import: ``aero_dva.flight``, ``aero_dva.wing`` and the package root; never ``control``.
"""
