"""The bag layer: rosbag2-layout MCAP bags. Topic names and types (channels), message schemas
and the typestore read from the .msg files (schemas), the per-message writer and the reader
(writer, reader; serialization by rosbags), the scan and recovery of damaged bags
(mcap_scan, recovery), the batch CDR encoder and chunk framing of the fast recordings
(batch_cdr, chunk_framing, batch_recorder, runtime_recording, sweep_recording_io), flight logs
read back (flight_log_io, flight_summary).
May import: ``aero_dva.flight``, ``aero_dva.wing`` and the package root; never ``control``.
"""

__all__ = ["typestore"]


def typestore():
    """A ``rosbags`` typestore that reads the project's bags: ROS 2 Jazzy's types and the
    project's message types, parsed from the ``.msg`` files (``dva_msgs/msg/DamperCommand``,
    ...). Give it where rosbags' examples give ``get_typestore(Stores.ROS2_JAZZY)``::

        from rosbags.rosbag2 import Reader
        from aero_dva.bag import typestore

        store = typestore()
        with Reader("runs/main_<time>") as reader:
            for connection, stamp, raw in reader.messages():
                msg = store.deserialize_cdr(raw, connection.msgtype)

    The store is shared (cached): register no other types in it.
    """
    from aero_dva.bag.schemas import typestore as project_typestore  # rosbags loads on demand

    return project_typestore()
