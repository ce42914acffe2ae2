"""The bag layer: rosbag2-layout MCAP bags. Topic names and types (channels), message schemas
and the typestore read from the .msg files (schemas), the per-message writer and the reader
(writer, reader; serialization by rosbags), the scan and recovery of damaged bags
(mcap_scan, recovery), the batch CDR encoder and chunk framing of the fast recordings
(batch_cdr, chunk_framing, batch_recorder, runtime_recording, sweep_recording_io), flight logs
read back (flight_log_io, flight_summary).
May import: ``aero_dva.flight``, ``aero_dva.wing`` and the package root; never ``control``.
"""
