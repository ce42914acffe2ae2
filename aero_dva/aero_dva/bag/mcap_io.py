"""ROS 2 bags in MCAP, written and read the way rosbag2 does it, without rclpy.

A bag is a directory ``<dir>/`` holding ``<dir name>_0.mcap`` and ``metadata.yaml``, as
``ros2 bag record -s mcap`` leaves it:

- the MCAP file has profile ``ros2``; each message type has a ``ros2msg`` schema named
  ``pkg/msg/Type`` whose text is the type's .msg file followed by every dependency, each once,
  depth first, in rosbag2's layout (see :func:`message_definition`); messages are ``cdr``;
  each channel carries ``offered_qos_profiles`` metadata (a YAML string); on close a
  ``rosbag2`` metadata record holds the serialized bag metadata;
- ``metadata.yaml`` is rosbag2 metadata version 8 (storage ``mcap``, per-topic counts,
  starting time, duration, file list).

Crash behaviour, chosen deliberately: the MCAP file is written under its final name from the
start, not under a temporary name. MCAP is append-only, so the chunks written before a crash
stay readable (``mcap recover``, or :func:`read_messages` with ``allow_truncated=True``);
a temporary name would hide exactly the data a crash investigation needs. Completeness is
signalled instead by ``metadata.yaml``, which is written atomically (temporary file + rename)
only when the writer closes, and by the MCAP footer. A directory without ``metadata.yaml``
is therefore an unfinished recording, and the reader says so. :meth:`BagWriter.flush` bounds
what a crash can lose to the messages since the last flush.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
import warnings
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory

__all__ = [
    "METADATA_VERSION",
    "BagMessage",
    "BagReadError",
    "BagSummary",
    "BagWriter",
    "MessageDefinitionNotFound",
    "MessageTypeError",
    "TopicInfo",
    "TopicNotFoundError",
    "bag_metadata",
    "create_bag_directory",
    "bag_topics",
    "find_message_file",
    "message_definition",
    "normalize_type_name",
    "qos_profile_yaml",
    "read_messages",
]

#: rosbag2 metadata version written (8: ros_distro present, QoS profiles as a YAML string).
METADATA_VERSION = 8

_SEPARATOR = "=" * 80 + "\n"
_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string "
    "wstring".split()
)
# First token of each line of a .msg file: the field (or constant) type, as rosbag2 parses it.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_NAME = re.compile(rf"^({_NAME})/(?:(msg)/)?({_NAME})$")

# Last-resort copies of the ROS 2 Jazzy definitions, byte for byte (including a trailing blank).
_EMBEDDED = {
    "std_msgs/Header": (
        "# Standard metadata for higher-level stamped data types.\n"
        "# This is generally used to communicate timestamped data\n"
        "# in a particular coordinate frame.\n"
        "\n"
        "# Two-integer timestamp that is expressed as seconds and nanoseconds.\n"
        "builtin_interfaces/Time stamp\n"
        "\n"
        "# Transform frame with which this data is associated.\n"
        "string frame_id\n"
    ),
    "builtin_interfaces/Time": (
        "# This message communicates ROS Time defined here:\n"
        "# https://design.ros2.org/articles/clock_and_time.html\n"
        "\n"
        "# The seconds component, valid over all int32 values.\n"
        "int32 sec\n"
        "\n"
        "# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds"
        " component. \n"
        "# e.g.\n"
        "# The time -1.7 seconds is represented as {sec: -2, nanosec: 3e8}\n"
        "# The time 1.7 seconds is represented as {sec: 1, nanosec: 7e8}\n"
        "uint32 nanosec\n"
    ),
}


class MessageDefinitionNotFound(LookupError):
    """No .msg file for a message type in any search location."""


class BagReadError(ValueError):
    """A bag or MCAP file cannot be read; the message names the file and what failed."""


class TopicNotFoundError(BagReadError, KeyError):
    """A requested topic is not in the bag; the message lists the topics that are."""

    def __str__(self) -> str:  # KeyError would add quotes
        return str(self.args[0])


class MessageTypeError(BagReadError, TypeError):
    """A topic carries a different message type than expected."""


# --------------------------------------------------------------------------------------------
# Message definitions
# --------------------------------------------------------------------------------------------


def normalize_type_name(type_name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` -> ``pkg/msg/Type`` (other namespaces are refused)."""
    if not isinstance(type_name, str):
        raise TypeError(f"type_name must be a string, got {type(type_name).__name__}")
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(
            f"type_name must look like 'pkg/msg/Type' or 'pkg/Type', got {type_name!r}"
        )
    return f"{match.group(1)}/msg/{match.group(3)}"


def _split(type_name: str) -> tuple[str, str]:
    pkg, _, name = normalize_type_name(type_name).split("/")
    return pkg, name


def _search_roots(msg_dirs: Sequence[str | os.PathLike]) -> list[Path]:
    roots = [Path(d) for d in msg_dirs]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            roots.append(Path(prefix) / "share")
    # The package's own interfaces/: a link to ros_ws/src/dva_msgs in the source tree (a wheel
    # built from it carries the .msg files themselves).
    roots.append(Path(__file__).resolve().parent / "interfaces")
    # ROS 2 wheels install share/ into the environment's prefix (no sourcing needed).
    roots.append(Path(sys.prefix) / "share")
    return roots


def find_message_file(type_name: str, msg_dirs: Sequence[str | os.PathLike] = ()) -> Path | None:
    """Locate ``<Type>.msg`` for a type.

    Search order: each directory of ``msg_dirs`` (as ``<dir>/<pkg>/msg/<Type>.msg``, or
    ``<dir>/<Type>.msg`` if ``dir`` is itself ``.../<pkg>/msg``), then
    ``$AMENT_PREFIX_PATH/<prefix>/share/<pkg>/msg/<Type>.msg``, then the package's
    ``interfaces/<pkg>/msg`` (dva_msgs, linked from ``ros_ws/src/dva_msgs``). None if none exists.
    """
    pkg, name = _split(type_name)
    explicit = [Path(d) for d in msg_dirs]
    for root in _search_roots(msg_dirs):
        candidates = [root / pkg / "msg" / f"{name}.msg"]
        if root in explicit and root.name == "msg" and root.parent.name == pkg:
            candidates.append(root / f"{name}.msg")
        for candidate in candidates:
            if candidate.is_file():
                return candidate
    return None


def _load_text(type_name: str, msg_dirs: Sequence[str | os.PathLike]) -> str:
    path = find_message_file(type_name, msg_dirs)
    if path is not None:
        # newline="" keeps the bytes as they are (rosbag2 reads the file verbatim).
        with open(path, encoding="utf-8", newline="") as stream:
            return stream.read()
    pkg, name = _split(type_name)
    if f"{pkg}/{name}" in _EMBEDDED:
        return _EMBEDDED[f"{pkg}/{name}"]
    raise MessageDefinitionNotFound(
        f"no .msg file for {type_name!r}: looked in {[str(p) for p in _search_roots(msg_dirs)]}"
        " (as <root>/<pkg>/msg/<Type>.msg); source the ROS 2 workspace or pass msg_dirs"
    )


def _dependencies(text: str, package: str) -> list[str]:
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(deps)  # rosbag2 keeps them in a std::set: byte order


def message_definition(type_name: str, msg_dirs: Sequence[str | os.PathLike] = ()) -> str:
    """Full ``ros2msg`` schema text of a type, as rosbag2 stores it in MCAP.

    The type's own .msg text comes first, unchanged (comments and constants included). Each
    dependency follows once, depth first, in sorted order of the names as written in the
    .msg files: ``"\\n" + "=" * 80 + "\\nMSG: pkg/Type\\n" + text``.

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type`` or ``pkg/Type``.
    msg_dirs : sequence of path-like
        Extra directories searched first (see :func:`find_message_file`).

    Raises
    ------
    MessageDefinitionNotFound
        If a definition is found nowhere (std_msgs/Header and builtin_interfaces/Time have
        embedded fallbacks).
    """
    seen: set[str] = set()

    def expand(name: str, depth: int) -> str:
        if depth > 50:
            raise ValueError(f"message definitions nest too deeply below {type_name!r}")
        text = _load_text(name, msg_dirs)
        out = text
        for dep in _dependencies(text, _split(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += "\n" + _SEPARATOR + f"MSG: {dep}\n" + expand(dep, depth + 1)
        return out

    return expand(type_name, 0)


# --------------------------------------------------------------------------------------------
# Writer
# --------------------------------------------------------------------------------------------

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


def _topic_name(topic: str) -> str:
    if not isinstance(topic, str) or not topic.strip("/"):
        raise ValueError(f"topic must be a non-empty string, got {topic!r}")
    # rosbag2 stores fully qualified names.
    return topic if topic.startswith("/") else "/" + topic


def _plain(value):
    """numpy arrays and scalars -> Python lists and scalars, for the CDR encoder."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (bytes, bytearray)):
        return value.tolist()
    return value


@dataclass(frozen=True)
class TopicInfo:
    """A topic in a bag.

    Attributes
    ----------
    name : str
        Fully qualified topic name.
    type_name : str
        ``pkg/msg/Type``.
    message_count : int
        Messages on the topic.
    """

    name: str
    type_name: str
    message_count: int


@dataclass(frozen=True)
class BagSummary:
    """What a closed :class:`BagWriter` wrote.

    Attributes
    ----------
    directory : pathlib.Path
        The bag directory.
    mcap_path : pathlib.Path
        The MCAP file.
    topics : tuple of TopicInfo
        Topics in registration order.
    message_count : int
        All messages.
    starting_time_ns : int
        Smallest log time [ns] (0 if no messages).
    duration_ns : int
        Largest minus smallest log time [ns].
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


class BagWriter:
    """Write a rosbag2-layout MCAP bag directory.

    Parameters
    ----------
    directory : path-like
        Bag directory to create; it must not exist or be empty.
    msg_dirs : sequence of path-like
        Extra .msg search directories (see :func:`find_message_file`).
    compression : {"zstd", "lz4", "none"}
        Chunk compression.
    chunk_size : int
        [bytes] uncompressed chunk size; a crash loses at most the unfinished chunk.
    ros_distro : str, optional
        Written to the metadata; default ``$ROS_DISTRO`` or "jazzy".

    Notes
    -----
    Use as a context manager. :meth:`close` is idempotent and also runs when the ``with`` body
    raises, so messages written before an error are kept. Not thread-safe.
    """

    def __init__(
        self,
        directory,
        *,
        msg_dirs: Sequence[str | os.PathLike] = (),
        compression: str = "zstd",
        chunk_size: int = 1 << 20,
        ros_distro: str | None = None,
    ):
        compressions = {
            "zstd": CompressionType.ZSTD,
            "lz4": CompressionType.LZ4,
            "none": CompressionType.NONE,
        }
        if compression not in compressions:
            raise ValueError(
                f"compression must be one of {sorted(compressions)}, got {compression!r}"
            )
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
            raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
        self.directory, self.mcap_path = create_bag_directory(directory)
        self._msg_dirs = tuple(msg_dirs)
        self._ros_distro = ros_distro or os.environ.get("ROS_DISTRO") or "jazzy"
        self._stream = open(self.mcap_path, "wb")
        self._closed = False
        self._summary: BagSummary | None = None
        try:
            self._writer = McapWriter(
                self._stream, chunk_size=chunk_size, compression=compressions[compression]
            )
            self._writer.start(profile="ros2", library="aero_dva.bag.mcap_io")
        except BaseException:
            self._stream.close()
            raise
        self._schemas: dict[str, int] = {}  # type name -> schema id
        self._encoders: dict[str, object] = {}
        self._channels: dict[str, int] = {}  # topic -> channel id
        self._topics: dict[str, tuple[str, str]] = {}  # topic -> (type, qos yaml)
        self._counts: dict[str, int] = {}
        self._t_min: int | None = None
        self._t_max: int | None = None

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"bag {str(self.directory)!r} is closed")

    def add_topic(
        self, topic: str, type_name: str, offered_qos_profiles: str | None = None
    ) -> str:
        """Register a topic before writing to it.

        Parameters
        ----------
        topic : str
            Topic name; a missing leading "/" is added (rosbag2 stores absolute names).
        type_name : str
            ``pkg/msg/Type`` or ``pkg/Type``; its .msg definition must be findable.
        offered_qos_profiles : str, optional
            YAML string as rosbag2 records it; default :func:`qos_profile_yaml` ().

        Returns
        -------
        str
            The stored topic name.
        """
        self._check_open()
        name = _topic_name(topic)
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
            text = message_definition(full_type, self._msg_dirs)
            self._schemas[full_type] = self._writer.register_schema(
                name=full_type, encoding="ros2msg", data=text.encode("utf-8")
            )
            self._encoders[full_type] = serialize_dynamic(full_type, text)[full_type]
        self._channels[name] = self._writer.register_channel(
            topic=name,
            message_encoding="cdr",
            schema_id=self._schemas[full_type],
            metadata={"offered_qos_profiles": qos},
        )
        self._topics[name] = (full_type, qos)
        self._counts[name] = 0
        return name

    def write(self, topic: str, message, log_time_ns: int, publish_time_ns: int | None = None):
        """Write one message.

        Parameters
        ----------
        topic : str
            A registered topic.
        message : dict or bytes-like
            A dict of field values (nested dicts for nested messages; numpy arrays allowed),
            encoded to CDR with the topic's schema, or an already CDR-encoded message (e.g.
            from an rclpy subscription with ``raw=True``).
        log_time_ns : int
            [ns] receive time (rosbag2's timestamp; sim time in this project).
        publish_time_ns : int, optional
            [ns] publish time; default ``log_time_ns``.
        """
        self._check_open()
        name = _topic_name(topic)
        if name not in self._channels:
            raise ValueError(
                f"topic {name!r} is not registered; registered: {sorted(self._channels)}"
            )
        log_time = self._time(log_time_ns, "log_time_ns")
        publish_time = (
            log_time if publish_time_ns is None else self._time(publish_time_ns, "publish_time_ns")
        )
        if isinstance(message, (bytes, bytearray, memoryview)):
            data = bytes(message)
            if len(data) < 4:
                raise ValueError(f"CDR message for {name!r} is shorter than its 4-byte header")
        elif isinstance(message, Mapping):
            type_name = self._topics[name][0]
            try:
                data = self._encoders[type_name](_plain(message))
            except Exception as exc:  # the encoder raises assorted errors for bad fields
                raise ValueError(
                    f"cannot encode message for {name!r} as {type_name}: {exc}"
                ) from exc
        else:
            raise TypeError(f"message must be a dict or bytes, got {type(message).__name__}")
        self._writer.add_message(
            channel_id=self._channels[name],
            log_time=log_time,
            publish_time=publish_time,
            data=data,
            sequence=self._counts[name],
        )
        self._counts[name] += 1
        self._t_min = log_time if self._t_min is None else min(self._t_min, log_time)
        self._t_max = log_time if self._t_max is None else max(self._t_max, log_time)

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

    def _metadata(self) -> dict:
        topics = [(name, type_name, qos, self._counts[name])
                  for name, (type_name, qos) in self._topics.items()]
        return bag_metadata(self.mcap_path.name, topics, self._t_min, self._t_max,
                            self._ros_distro)

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
        metadata = self._metadata()
        try:
            self._writer.add_metadata(
                "rosbag2",
                {
                    "serialized_metadata": yaml.safe_dump(metadata, sort_keys=False),
                    "ROS_DISTRO": self._ros_distro,
                },
            )
            self._writer.finish()
            self._stream.flush()
            os.fsync(self._stream.fileno())
        finally:
            self._stream.close()
        text = yaml.safe_dump({"rosbag2_bagfile_information": metadata}, sort_keys=False)
        _atomic_write_text(self.directory / "metadata.yaml", text)
        self._summary = BagSummary(
            directory=self.directory,
            mcap_path=self.mcap_path,
            topics=tuple(
                TopicInfo(name, type_name, self._counts[name])
                for name, (type_name, _) in self._topics.items()
            ),
            message_count=metadata["message_count"],
            starting_time_ns=metadata["starting_time"]["nanoseconds_since_epoch"],
            duration_ns=metadata["duration"]["nanoseconds"],
        )
        return self._summary


def _atomic_write_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a bag is meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BagMessage:
    """One decoded message.

    Attributes
    ----------
    topic : str
        Fully qualified topic name.
    type_name : str
        ``pkg/msg/Type``.
    log_time_ns, publish_time_ns : int
        [ns] MCAP log and publish times.
    message : object
        Decoded message (attribute access to fields, as mcap-ros2-support builds it), or its
        serialized CDR bytes when read with ``decode=False``.
    """

    topic: str
    type_name: str
    log_time_ns: int
    publish_time_ns: int
    message: object


def _file_order(path: Path) -> tuple:
    """rosbag2 numbers split files ``<name>_<i>.mcap``: ``_10`` comes after ``_9``."""
    stem, _, index = path.stem.rpartition("_")
    return (stem, int(index), "") if index.isdigit() else (path.stem, -1, path.name)


def _mcap_files(path: Path, allow_truncated: bool) -> list[Path]:
    if not path.exists():
        raise BagReadError(f"bag {str(path)!r} does not exist")
    if path.is_file():
        return [path]
    meta = path / "metadata.yaml"
    if not meta.is_file():
        found = sorted(path.glob("*.mcap"), key=_file_order)
        if allow_truncated and found:
            return found
        raise BagReadError(
            f"bag directory {str(path)!r} has no metadata.yaml: the recording was not closed "
            f"(still running or crashed). MCAP files there: {[p.name for p in found]}; pass "
            "allow_truncated=True (or run `mcap recover`) to read what was written"
        )
    try:
        info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        if info["storage_identifier"] != "mcap":
            raise BagReadError(
                f"bag {str(path)!r} uses storage {info['storage_identifier']!r}, not mcap"
            )
        if info.get("compression_mode"):
            raise BagReadError(f"bag {str(path)!r} uses file compression, which is not supported")
        files = [path / Path(p).name for p in info["relative_file_paths"]]
    except BagReadError:
        raise
    except (yaml.YAMLError, KeyError, TypeError) as exc:
        raise BagReadError(f"{str(meta)!r} is not valid rosbag2 metadata ({exc!r})") from None
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise BagReadError(
            f"bag {str(path)!r}: files listed in metadata.yaml are missing: {missing}"
        )
    return files


def _file_topics(path: Path, allow_truncated: bool) -> dict[str, TopicInfo]:
    """Topics of one MCAP file from its summary, or by a linear scan if allowed."""
    with open(path, "rb") as stream:
        try:
            reader = SeekingReader(stream)
            summary = reader.get_summary()
        except Exception as exc:  # corrupt data raises assorted errors
            if not allow_truncated:
                raise BagReadError(
                    f"MCAP file {str(path)!r} is truncated or corrupt: no valid footer and "
                    f"summary ({type(exc).__name__}: {exc}); pass allow_truncated=True to read "
                    "the messages before the damage"
                ) from None
            summary = None
        if summary is not None:
            counts = summary.statistics.channel_message_counts if summary.statistics else {}
            return {
                ch.topic: TopicInfo(
                    ch.topic,
                    _schema_type(summary.schemas.get(ch.schema_id)),
                    int(counts.get(ch.id, 0)),
                )
                for ch in summary.channels.values()
            }
    topics: dict[str, TopicInfo] = {}
    for schema, channel, _ in _scan(path):
        old = topics.get(channel.topic)
        topics[channel.topic] = TopicInfo(
            channel.topic, _schema_type(schema), (old.message_count if old else 0) + 1
        )
    return topics


def _schema_type(schema) -> str:
    if schema is None:
        return ""
    try:
        return normalize_type_name(schema.name)
    except ValueError:
        return schema.name


def _scan(path: Path):
    """Records of a possibly truncated file, in file order, stopping at the damage."""
    with open(path, "rb") as stream:
        reader = NonSeekingReader(stream)
        iterator = reader.iter_messages(log_time_order=False)
        while True:
            try:
                item = next(iterator)
            except StopIteration:
                return
            except Exception as exc:  # corrupt data raises assorted errors
                warnings.warn(
                    f"MCAP file {str(path)!r} ends early or is damaged ({exc}); "
                    "reading stopped there",
                    RuntimeWarning,
                    stacklevel=3,
                )
                return
            yield item


def bag_topics(path, *, allow_truncated: bool = False) -> dict[str, TopicInfo]:
    """Topics of a bag directory or MCAP file, keyed by name.

    Raises
    ------
    BagReadError
        Missing path, unfinished bag (no metadata.yaml), bad metadata, truncated or corrupt file.
    """
    path = Path(path)
    topics: dict[str, TopicInfo] = {}
    for file in _mcap_files(path, allow_truncated):
        for name, info in _file_topics(file, allow_truncated).items():
            if name in topics:
                if topics[name].type_name != info.type_name:
                    raise BagReadError(
                        f"bag {str(path)!r}: topic {name!r} has types "
                        f"{topics[name].type_name!r} and {info.type_name!r}"
                    )
                info = TopicInfo(
                    name, info.type_name, topics[name].message_count + info.message_count
                )
            topics[name] = info
    return topics


def _resolve(topic: str, available: Mapping[str, TopicInfo], path: Path) -> str:
    if topic in available:
        return topic
    if not topic.startswith("/") and "/" + topic in available:
        return "/" + topic
    raise TopicNotFoundError(
        f"topic {topic!r} is not in bag {str(path)!r}; topics there: {sorted(available)}"
    )


def read_messages(
    path,
    topics: Iterable[str] | None = None,
    *,
    expected_types: Mapping[str, str] | None = None,
    allow_truncated: bool = False,
    decode: bool = True,
    log_time_order: bool = True,
) -> Iterator[BagMessage]:
    """Decoded (or raw) messages of chosen topics, in log-time order per file.

    Parameters
    ----------
    path : path-like
        Bag directory (with metadata.yaml) or a single MCAP file.
    topics : iterable of str, optional
        Topics to read (with or without the leading "/"); default all.
    expected_types : mapping of str to str, optional
        Topic -> required type (``pkg/msg/Type`` or ``pkg/Type``); a topic named here is
        also read.
    allow_truncated : bool
        Read what precedes the damage in a truncated file (in file order, with a
        RuntimeWarning) instead of raising.
    decode : bool
        False: ``message`` is the serialized CDR bytes, for a caller with a faster decoder.
    log_time_order : bool
        False: in file order, which skips the reader's merge of chunks by log time (most of
        the reading time of a large bag); for callers that order by stamps themselves.

    Returns
    -------
    iterator of BagMessage

    Raises
    ------
    BagReadError
        Raised here, before iteration, for a missing path, unfinished bag, bad metadata, or a
        truncated/corrupt file; during iteration for damage found in the data.
    TopicNotFoundError
        A requested topic is not in the bag (the message lists those that are).
    MessageTypeError
        A topic carries another type than ``expected_types`` says.
    """
    path = Path(path)
    available = bag_topics(path, allow_truncated=allow_truncated)
    expected = dict(expected_types or {})
    if topics is None:
        selected = set(available)
    else:
        names = [*topics, *expected]
        selected = {_resolve(t, available, path) for t in names}
    for topic, type_name in expected.items():
        actual = available[_resolve(topic, available, path)].type_name
        if actual != normalize_type_name(type_name):
            raise MessageTypeError(
                f"topic {topic!r} in bag {str(path)!r} carries {actual!r}, "
                f"expected {normalize_type_name(type_name)!r}"
            )
    return _iterate(_mcap_files(path, allow_truncated), selected, allow_truncated, decode,
                    log_time_order)


def _iterate(files: list[Path], selected: set[str], allow_truncated: bool, decode: bool = True,
             log_time_order: bool = True):
    for file in files:
        decoders = DecoderFactory()  # schema ids are per file
        count = 0
        complete = True
        if allow_truncated:
            with open(file, "rb") as probe:
                try:
                    complete = SeekingReader(probe).get_summary() is not None
                except Exception:  # any damage: fall back to the linear scan
                    complete = False
        if complete:
            stream = open(file, "rb")
            reader = SeekingReader(stream, decoder_factories=[decoders])
            records = reader.iter_messages(topics=sorted(selected), log_time_order=log_time_order)
        else:
            stream = None
            records = (r for r in _scan(file) if r[1].topic in selected)
        try:
            while True:
                try:
                    schema, channel, message = next(records)
                except StopIteration:
                    break
                except Exception as exc:  # corrupt data raises assorted errors
                    raise BagReadError(
                        f"MCAP file {str(file)!r} is corrupt: reading failed after {count} "
                        f"messages ({type(exc).__name__}: {exc})"
                    ) from None
                if not decode:
                    if channel.message_encoding != "cdr":
                        raise BagReadError(
                            f"MCAP file {str(file)!r}: topic {channel.topic!r} is not cdr "
                            f"(encoding {channel.message_encoding!r})")
                    count += 1
                    yield BagMessage(channel.topic, _schema_type(schema), message.log_time,
                                     message.publish_time, message.data)
                    continue
                try:
                    decoder = decoders.decoder_for(channel.message_encoding, schema)
                except Exception as exc:  # an unparsable schema text
                    raise BagReadError(
                        f"MCAP file {str(file)!r}: the schema of {channel.topic!r} does not "
                        f"parse ({type(exc).__name__}: {exc})"
                    ) from None
                if decoder is None:
                    raise BagReadError(
                        f"MCAP file {str(file)!r}: topic {channel.topic!r} is not ros2msg/cdr "
                        f"(encoding {channel.message_encoding!r})"
                    )
                try:
                    decoded = decoder(message.data)
                except Exception as exc:  # the CDR reader raises assorted errors
                    raise BagReadError(
                        f"MCAP file {str(file)!r}: message {count} on {channel.topic!r} does "
                        f"not decode as {schema.name} ({type(exc).__name__}: {exc})"
                    ) from None
                count += 1
                yield BagMessage(
                    channel.topic,
                    _schema_type(schema),
                    message.log_time,
                    message.publish_time,
                    decoded,
                )
        finally:
            if stream is not None:
                stream.close()
