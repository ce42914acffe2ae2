"""Write a ROS 2 bag in MCAP the way rosbag2 does it, one message at a time, without rclpy.

A bag is a directory ``<dir>/`` holding ``<dir name>_0.mcap`` and ``metadata.yaml``, as
``ros2 bag record -s mcap`` leaves it:

- the MCAP file (written with ``mcap.writer.Writer``) has profile ``ros2``; each message type
  has a ``ros2msg`` schema named ``pkg/msg/Type`` whose text is
  :func:`~aero_dva.bag.schemas.message_definition`; messages are ``cdr`` (serialized by
  ``rosbags``' typestore when given as dicts or rosbags messages); each channel carries
  ``offered_qos_profiles`` metadata; on close a ``rosbag2`` metadata record holds the
  serialized bag metadata;
- ``metadata.yaml`` is rosbag2 metadata version 8 (storage ``mcap``, per-topic counts,
  starting time, duration, file list).

Crash behaviour, chosen deliberately: the MCAP file is written under its final name from the
start, not under a temporary name. MCAP is append-only, so the chunks written before a crash
stay readable (``dva bag recover``); a temporary name would hide exactly the data a crash
investigation needs. Completeness is signalled instead by ``metadata.yaml``, which is written
atomically only when the writer closes, and by the MCAP footer. A directory without
``metadata.yaml`` is therefore an unfinished recording, and the reader says so.
:meth:`BagWriter.flush` bounds what a crash can lose to the messages since the last flush.
"""
from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from aero_dva.atomic_io import atomic_output
from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES
from aero_dva.bag.schemas import Nodetype, message_definition, normalize_type_name, typestore

__all__ = [
    "COMPRESSIONS",
    "METADATA_VERSION",
    "BagSummary",
    "BagWriter",
    "TopicInfo",
    "bag_metadata",
    "create_bag_directory",
    "open_new_bag_file",
    "message_from_dict",
    "qos_profile_yaml",
    "INTERRUPTED_KEY",
    "interruption_reason",
    "mark_interrupted",
    "write_metadata_yaml",
]

#: rosbag2 metadata version written (8: ros_distro present, QoS profiles as a YAML string).
METADATA_VERSION = 8
#: Chunk compressions of the MCAP files.
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}

_HISTORY = {"system_default": 0, "keep_last": 1, "keep_all": 2}
_RELIABILITY = {"system_default": 0, "reliable": 1, "best_effort": 2}
_DURABILITY = {"system_default": 0, "transient_local": 1, "volatile": 2}
_INFINITE = {"sec": 9223372036, "nsec": 854775807}  # RMW_DURATION_INFINITE


def qos_profile_yaml(
    reliability: str = "reliable",
    durability: str = "volatile",
    history: str = "keep_last",
    depth: int = 10,
) -> str:
    """An ``offered_qos_profiles`` YAML string for one publisher, rosbag2 metadata v8 style.

    Parameters
    ----------
    reliability : {"reliable", "best_effort", "system_default"}
    durability : {"volatile", "transient_local", "system_default"}
    history : {"keep_last", "keep_all", "system_default"}
    depth : int
        History depth (>= 0).

    Returns
    -------
    str
        A one-element YAML list with the rmw enum values as integers and infinite deadline,
        lifespan and liveliness lease (what rclcpp reports for default publishers).
    """
    for name, value, table in (
        ("reliability", reliability, _RELIABILITY),
        ("durability", durability, _DURABILITY),
        ("history", history, _HISTORY),
    ):
        if value not in table:
            raise ValueError(f"{name} must be one of {sorted(table)}, got {value!r}")
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 0:
        raise ValueError(f"depth must be an integer >= 0, got {depth!r}")
    profile = {
        "history": _HISTORY[history],
        "depth": depth,
        "reliability": _RELIABILITY[reliability],
        "durability": _DURABILITY[durability],
        "deadline": dict(_INFINITE),
        "lifespan": dict(_INFINITE),
        "liveliness": 1,  # automatic
        "liveliness_lease_duration": dict(_INFINITE),
        "avoid_ros_namespace_conventions": False,
    }
    return yaml.safe_dump([profile], sort_keys=False).strip()


def topic_name(topic: str) -> str:
    """A fully qualified topic name (rosbag2 stores them so): a leading "/" is added."""
    if not isinstance(topic, str) or not topic.strip("/"):
        raise ValueError(f"topic must be a non-empty string, got {topic!r}")
    return topic if topic.startswith("/") else "/" + topic


@dataclass(frozen=True)
class TopicInfo:
    """A topic in a bag: fully qualified ``name``, ``type_name`` (``pkg/msg/Type``) and
    ``message_count``."""

    name: str
    type_name: str
    message_count: int


@dataclass(frozen=True)
class BagSummary:
    """What a closed writer wrote.

    Attributes
    ----------
    directory, mcap_path : pathlib.Path
        The bag directory and its (first) MCAP file.
    topics : tuple of TopicInfo
        Topics in registration order.
    message_count : int
    starting_time_ns, duration_ns : int
        Smallest log time [ns] (0 if no messages), largest minus smallest [ns].
    """

    directory: Path
    mcap_path: Path
    topics: tuple[TopicInfo, ...]
    message_count: int
    starting_time_ns: int
    duration_ns: int


def create_bag_directory(directory) -> tuple[Path, Path]:
    """Create a new bag directory; return it and its MCAP file's path (``<name>_0.mcap``).

    Raises FileExistsError if it exists and is not empty: a bag is never overwritten.
    """
    directory = Path(directory)
    if directory.exists() and (not directory.is_dir() or any(directory.iterdir())):
        raise FileExistsError(f"bag directory {str(directory)!r} exists and is not empty")
    directory.mkdir(parents=True, exist_ok=True)
    return directory, directory / f"{directory.name}_0.mcap"


def open_new_bag_file(path: Path):
    """Open the MCAP file ``path`` for writing, only if it does not exist yet: of two writers
    started into one empty bag directory, the second is refused here, never mixed in."""
    try:
        return open(path, "xb")  # noqa: SIM115 - the writer closes it
    except FileExistsError:
        raise FileExistsError(f"bag file {str(path)!r} exists: another writer has this bag "
                              "directory (a bag is never overwritten)") from None


def bag_metadata(mcap_name: str, topics: Sequence[tuple[str, str, str, int]],
                 t_min: int | None, t_max: int | None, ros_distro: str,
                 files: Sequence[tuple[str, int, int, int]] | None = None) -> dict:
    """rosbag2 ``metadata.yaml`` content (version :data:`METADATA_VERSION`) of a bag.

    ``topics`` holds (name, type, offered QoS YAML, message count) per topic; ``t_min`` and
    ``t_max`` are the first and last log times [ns] (None for an empty bag). A one-file bag
    is the file ``mcap_name``; a split bag lists its ``files`` in order, each as (name,
    starting time [ns], duration [ns], message count).
    """
    start = t_min or 0
    duration = 0 if t_min is None else t_max - t_min
    count = sum(n for *_, n in topics)
    if files is None:
        files = [(mcap_name, start, duration, count)]
    return {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": name,
                    "type": type_name,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": qos,
                    "type_description_hash": "",
                },
                "message_count": n,
            }
            for name, type_name, qos, n in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [name for name, *_ in files],
        "files": [
            {
                "path": name,
                "starting_time": {"nanoseconds_since_epoch": file_start},
                "duration": {"nanoseconds": file_duration},
                "message_count": file_count,
            }
            for name, file_start, file_duration, file_count in files
        ],
        "custom_data": {},
        "ros_distro": ros_distro,
    }


#: Key of ``custom_data`` in a bag's metadata.yaml marking a recording stopped before its end
#: (its value says why); readers and ``dva bag info`` report it, ``dva train rbf`` refuses it.
INTERRUPTED_KEY = "dva_interrupted"


def interruption_reason(exc_type, exc) -> str:
    """Why a recording stopped early, from the exception that stopped it."""
    if exc_type is not None and issubclass(exc_type, KeyboardInterrupt):
        return "interrupted (SIGINT or SIGTERM) before its end"
    return f"stopped before its end by an error ({getattr(exc_type, '__name__', exc_type)}: {exc})"


def mark_interrupted(directory, reason: str) -> bool:
    """Mark the closed bag ``directory`` as a recording stopped before its end: its
    metadata.yaml's ``custom_data`` gets :data:`INTERRUPTED_KEY` = ``reason`` (rewritten
    atomically). False if it has no metadata.yaml (an unclosed bag says so itself)."""
    from aero_dva.text_input import loggable

    meta = Path(directory) / "metadata.yaml"
    if not meta.is_file():
        return False
    info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    custom = info.get("custom_data") or {}
    custom[INTERRUPTED_KEY] = loggable(reason, 300)
    info["custom_data"] = custom
    write_metadata_yaml(Path(directory), info)
    return True


def write_metadata_yaml(directory: Path, metadata: dict) -> None:
    """Write ``<directory>/metadata.yaml`` atomically and durably (it marks the bag complete)."""
    with atomic_output(Path(directory) / "metadata.yaml", fsync=True) as stream:
        yaml.safe_dump({"rosbag2_bagfile_information": metadata}, stream, sort_keys=False)


def summary_of(directory: Path, mcap_path: Path, metadata: dict) -> BagSummary:
    """The :class:`BagSummary` of a bag's metadata (as :func:`bag_metadata` makes it)."""
    return BagSummary(
        directory=directory, mcap_path=mcap_path,
        topics=tuple(TopicInfo(t["topic_metadata"]["name"], t["topic_metadata"]["type"],
                               t["message_count"])
                     for t in metadata["topics_with_message_count"]),
        message_count=metadata["message_count"],
        starting_time_ns=metadata["starting_time"]["nanoseconds_since_epoch"],
        duration_ns=metadata["duration"]["nanoseconds"])


def default_ros_distro(ros_distro: str | None = None) -> str:
    return ros_distro or os.environ.get("ROS_DISTRO") or "jazzy"


# --------------------------------------------------------------------------------------------
# Messages given as dicts
# --------------------------------------------------------------------------------------------

_NUMPY = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8,
          "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
          "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64,
          "float32": np.float32, "float64": np.float64}


def message_from_dict(type_name: str, values, store=None):
    """A ``rosbags`` message of ``type_name`` from a dict of field values (nested dicts for
    nested messages, numpy arrays or lists for sequences); fields left out take ROS's
    defaults (0, "", empty, nested defaults). A rosbags message is returned as it is.

    Raises
    ------
    ValueError
        A field the type does not have, or a value of the wrong kind.
    """
    store = store or typestore()
    full = normalize_type_name(type_name)
    if not isinstance(values, Mapping):
        return values
    fields = store.fielddefs[full][1]
    unknown = set(values) - {name for name, _ in fields}
    if unknown:
        raise ValueError(f"{full} has no fields {sorted(unknown)}")
    out = {name: _field_value(store, desc, values.get(name), f"{full}.{name}")
           for name, desc in fields}
    return store.types[full](**out)


def _field_value(store, desc, value, where: str):
    kind, args = desc
    if kind == Nodetype.BASE:
        name = args[0]
        if name == "string":
            return "" if value is None else _string(value, where)
        if value is None:
            value = 0
        if isinstance(value, (str, bytes)) and name not in ("byte", "char"):
            raise ValueError(f"{where} must be a number, got {value!r}")
        if name in ("byte", "char") and isinstance(value, (bytes, bytearray)):
            value = value[0]
        return bool(value) if name == "bool" else (
            float(value) if name.startswith("float") else int(value))
    if kind == Nodetype.NAME:
        return message_from_dict(args, {} if value is None else value, store)
    (item_kind, item), bound = args
    length = bound if kind == Nodetype.ARRAY else 0  # the default's length
    if item_kind == Nodetype.BASE and item[0] in _NUMPY:
        array = np.asarray(np.zeros(length) if value is None else value, dtype=_NUMPY[item[0]])
        if array.ndim != 1:
            raise ValueError(f"{where} must be one-dimensional, got shape {array.shape}")
        return array
    items = [None] * length if value is None else value
    return [_field_value(store, (item_kind, item), v, f"{where}[{i}]")
            for i, v in enumerate(items)]


def _string(value, where: str) -> str:
    if not isinstance(value, str):
        raise ValueError(f"{where} must be a string, got {type(value).__name__}")
    return value


# --------------------------------------------------------------------------------------------
# Writer
# --------------------------------------------------------------------------------------------


class BagWriter:
    """Write a rosbag2-layout MCAP bag directory, message by message.

    Parameters
    ----------
    directory : path-like
        Bag directory to create; it must not exist or be empty.
    msg_dirs : sequence of path-like
        Extra .msg search directories (see :func:`~aero_dva.bag.schemas.find_message_file`).
    compression : {"zstd", "lz4", "none"}
        Chunk compression.
    chunk_size : int
        [bytes] uncompressed chunk size; a crash loses at most the unfinished chunk.
    ros_distro : str, optional
        Written to the metadata; default ``$ROS_DISTRO`` or "jazzy".
    library : str
        Writer name in the MCAP header.

    Notes
    -----
    Use as a context manager. :meth:`close` is idempotent and also runs when the ``with`` body
    raises, so messages written before an error are kept. Not thread-safe.
    """

    def __init__(self, directory, *, msg_dirs: Sequence[str | os.PathLike] = (),
                 compression: str = "zstd", chunk_size: int = 1 << 20,
                 ros_distro: str | None = None, library: str = "aero_dva.bag.writer"):
        if compression not in COMPRESSIONS:
            raise ValueError(
                f"compression must be one of {sorted(COMPRESSIONS)}, got {compression!r}")
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or \
                not 1 <= chunk_size <= MAX_CHUNK_BYTES // 2:
            raise ValueError(f"chunk_size must be an integer in [1, {MAX_CHUNK_BYTES // 2}] "
                             f"bytes (readers read chunks of at most {MAX_CHUNK_BYTES}), got "
                             f"{chunk_size!r}")
        self.directory, self.mcap_path = create_bag_directory(directory)
        self._msg_dirs = tuple(msg_dirs)
        self._ros_distro = default_ros_distro(ros_distro)
        self._stream = open_new_bag_file(self.mcap_path)
        self._closed = False
        self._summary: BagSummary | None = None
        try:
            self._writer = McapWriter(self._stream, chunk_size=chunk_size,
                                      compression=COMPRESSIONS[compression])
            self._writer.start(profile="ros2", library=library)
        except BaseException:
            self._stream.close()
            raise
        self._schemas: dict[str, int] = {}  # type name -> schema id
        self._channels: dict[str, int] = {}  # topic -> channel id
        self._topics: dict[str, tuple[str, str]] = {}  # topic -> (type, qos yaml)
        self._counts: dict[str, int] = {}
        self._t_min: int | None = None
        self._t_max: int | None = None

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()
        if exc_type is not None:  # closed, and marked as not the whole recording
            mark_interrupted(self.directory, interruption_reason(exc_type, exc))

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"bag {str(self.directory)!r} is closed")

    def add_topic(self, topic: str, type_name: str, offered_qos_profiles: str | None = None,
                  *, schema_text: str | None = None) -> str:
        """Register a topic before writing to it; returns the stored (absolute) topic name.

        Parameters
        ----------
        topic : str
            Topic name; a missing leading "/" is added (rosbag2 stores absolute names).
        type_name : str
            ``pkg/msg/Type`` or ``pkg/Type``; its .msg definition must be findable unless
            ``schema_text`` is given.
        offered_qos_profiles : str, optional
            YAML string as rosbag2 records it; default :func:`qos_profile_yaml` ().
        schema_text : str, optional
            The ``ros2msg`` schema to store (a bag being copied keeps its own); the first
            topic of a type sets it.
        """
        self._check_open()
        name = topic_name(topic)
        full_type = normalize_type_name(type_name)
        qos = qos_profile_yaml() if offered_qos_profiles is None else offered_qos_profiles
        if not isinstance(qos, str):
            raise TypeError("offered_qos_profiles must be a YAML string")
        if name in self._topics:
            if self._topics[name][0] != full_type:
                raise ValueError(
                    f"topic {name!r} is already registered with type {self._topics[name][0]!r}"
                )
            return name
        if full_type not in self._schemas:
            text = schema_text if schema_text is not None else \
                message_definition(full_type, self._msg_dirs)
            self._schemas[full_type] = self._writer.register_schema(
                name=full_type, encoding="ros2msg", data=text.encode("utf-8"))
        self._channels[name] = self._writer.register_channel(
            topic=name, message_encoding="cdr", schema_id=self._schemas[full_type],
            metadata={"offered_qos_profiles": qos})
        self._topics[name] = (full_type, qos)
        self._counts[name] = 0
        return name

    def write(self, topic: str, message, log_time_ns: int, publish_time_ns: int | None = None,
              *, sequence: int | None = None) -> None:
        """Write one message.

        Parameters
        ----------
        topic : str
            A registered topic.
        message : dict, rosbags message or bytes-like
            A dict of field values (see :func:`message_from_dict`) or a ``rosbags`` message,
            serialized with the project's typestore, or an already CDR-encoded message
            (e.g. from an rclpy subscription with ``raw=True``).
        log_time_ns : int
            [ns] receive time (rosbag2's timestamp; sim time in this project).
        publish_time_ns : int, optional
            [ns] publish time; default ``log_time_ns``.
        sequence : int, optional
            MCAP sequence number; default the topic's count of messages so far.
        """
        self._check_open()
        name = topic_name(topic)
        if name not in self._channels:
            raise ValueError(
                f"topic {name!r} is not registered; registered: {sorted(self._channels)}")
        log_time = self._time(log_time_ns, "log_time_ns")
        publish_time = (
            log_time if publish_time_ns is None else self._time(publish_time_ns, "publish_time_ns")
        )
        if isinstance(message, (bytes, bytearray, memoryview)):
            data = bytes(message)
            if len(data) < 4:
                raise ValueError(f"CDR message for {name!r} is shorter than its 4-byte header")
        else:
            data = self._serialize(name, message)
        self._writer.add_message(
            channel_id=self._channels[name], log_time=log_time, publish_time=publish_time,
            data=data, sequence=self._counts[name] if sequence is None else sequence)
        self._counts[name] += 1
        self._t_min = log_time if self._t_min is None else min(self._t_min, log_time)
        self._t_max = log_time if self._t_max is None else max(self._t_max, log_time)

    def _serialize(self, topic: str, message) -> bytes:
        type_name = self._topics[topic][0]
        store = typestore()
        if type_name not in store.fielddefs:
            raise ValueError(f"cannot encode message for {topic!r}: {type_name} is not in the "
                             "project's typestore; write it as CDR bytes")
        try:
            return bytes(store.serialize_cdr(message_from_dict(type_name, message, store),
                                             type_name))
        except Exception as exc:  # the serializer raises assorted errors for bad fields
            raise ValueError(f"cannot encode message for {topic!r} as {type_name}: "
                             f"{exc}") from exc

    @staticmethod
    def _time(value, name: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            if hasattr(value, "__index__"):
                value = int(value)  # numpy integers
            else:
                raise TypeError(f"{name} must be an integer number of nanoseconds")
        if not 0 <= value < 2**64:
            raise ValueError(f"{name} must be in [0, 2**64) ns, got {value}")
        return value

    def flush(self) -> None:
        """Finish the current chunk and push it to the file (bounds what a crash loses)."""
        self._check_open()
        self._writer.flush()

    def close(self) -> BagSummary | None:
        """Finish the MCAP file and write ``metadata.yaml`` atomically. Safe to call again.

        Returns
        -------
        BagSummary or None
            None if an earlier close failed.
        """
        if self._closed:
            return self._summary
        self._closed = True
        topics = [(name, type_name, qos, self._counts[name])
                  for name, (type_name, qos) in self._topics.items()]
        metadata = bag_metadata(self.mcap_path.name, topics, self._t_min, self._t_max,
                                self._ros_distro)
        try:
            self._writer.add_metadata("rosbag2", {
                "serialized_metadata": yaml.safe_dump(metadata, sort_keys=False),
                "ROS_DISTRO": self._ros_distro,
            })
            self._writer.finish()
            self._stream.flush()
            os.fsync(self._stream.fileno())
        finally:
            self._stream.close()
        write_metadata_yaml(self.directory, metadata)
        self._summary = summary_of(self.directory, self.mcap_path, metadata)
        return self._summary
