"""Read ROS 2 bags in MCAP (rosbag2 layout, or a lone .mcap file) without rclpy.

:func:`read_messages` yields each message's topic, type, log and publish times and its CDR
bytes or, decoded, a ``rosbags`` message (attribute access to fields; float sequences as numpy
arrays). :func:`deserialize` decodes CDR bytes of any type whose schema the bag carries. A
bag that was not closed (no ``metadata.yaml``) or whose file is cut is refused with a message
naming ``dva bag recover``; ``allow_truncated=True`` reads every chunk whose CRC holds and
warns how many messages it skipped.
"""
from __future__ import annotations

import heapq
import io
import os
import warnings
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import Chunk, Message

from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES, ChunkLimitError, MergeBudget, chunk_records
from aero_dva.bag.chunk_survey import survey_file
from aero_dva.bag.mcap_scan import FileScan
from aero_dva.bag.schemas import normalize_type_name, schema_typestore, typestore
from aero_dva.bag.writer import TopicInfo
from aero_dva.safe_files import read_yaml

__all__ = [
    "RECOVER_HINT",
    "BagMessage",
    "BagReadError",
    "MessageTypeError",
    "TopicNotFoundError",
    "bag_files",
    "bag_interruption",
    "bag_topics",
    "deserialize",
    "file_summary",
    "read_messages",
]

#: What a reader's error tells a user to do with a cut or unclosed bag.
RECOVER_HINT = ("run `dva bag recover {bag} --out NEW_BAG` to write a complete bag of the "
                "messages that still read")


class BagReadError(ValueError):
    """A bag or MCAP file cannot be read; the message names the file and what failed."""


class TopicNotFoundError(BagReadError, KeyError):
    """A requested topic is not in the bag; the message lists the topics that are."""

    def __str__(self) -> str:  # KeyError would add quotes
        return str(self.args[0])


class MessageTypeError(BagReadError, TypeError):
    """A topic carries a different message type than expected."""


@dataclass(frozen=True)
class BagMessage:
    """One message of a bag.

    Attributes
    ----------
    topic : str
        Fully qualified topic name.
    type_name : str
        ``pkg/msg/Type``.
    log_time_ns, publish_time_ns : int
        [ns] MCAP log and publish times.
    message : object
        The decoded ``rosbags`` message, or its serialized CDR bytes when read with
        ``decode=False`` (decode those with :func:`deserialize`).
    schema_text : str
        The ``ros2msg`` schema the bag stores for the type.
    """

    topic: str
    type_name: str
    log_time_ns: int
    publish_time_ns: int
    message: object
    schema_text: str = ""


def deserialize(data, type_name: str, schema_text: str | None = None):
    """Decode CDR bytes of ``type_name`` into a ``rosbags`` message.

    ``schema_text`` (a bag's ``ros2msg`` schema, :attr:`BagMessage.schema_text`) is needed
    only for a type that is neither ROS 2 Jazzy's nor one of the project's .msg files, or
    that a bag recorded with another definition.

    Raises
    ------
    BagReadError
        The bytes do not decode as that type.
    """
    full = normalize_type_name(type_name)
    store = schema_typestore(full, schema_text) if schema_text else typestore()
    try:
        return store.deserialize_cdr(data, full)
    except KeyError:
        raise BagReadError(f"{full} is unknown: pass the bag's schema text") from None
    except Exception as exc:  # the CDR reader raises assorted errors
        raise BagReadError(f"the bytes do not decode as {full} ({type(exc).__name__}: "
                           f"{exc})") from None


def _file_order(path: Path) -> tuple:
    """rosbag2 numbers split files ``<name>_<i>.mcap``: ``_10`` comes after ``_9``."""
    stem, _, index = path.stem.rpartition("_")
    return (stem, int(index), "") if index.isdigit() else (path.stem, -1, path.name)


def bag_files(path, allow_truncated: bool = False) -> list[Path]:
    """The MCAP files of a bag directory (in order) or the lone MCAP file ``path``.

    Raises
    ------
    BagReadError
        Missing path, no metadata.yaml (unless ``allow_truncated``), bad metadata, a listed
        file missing.
    """
    path = Path(path)
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
            f"(still running or crashed); MCAP files there: {[p.name for p in found]}; "
            + RECOVER_HINT.format(bag=path))
    try:
        info = read_yaml(meta, "bag metadata", BagReadError)["rosbag2_bagfile_information"]
        if info["storage_identifier"] != "mcap":
            raise BagReadError(
                f"bag {str(path)!r} uses storage {info['storage_identifier']!r}, not mcap")
        if info.get("compression_mode"):
            raise BagReadError(f"bag {str(path)!r} uses file compression, which is not supported")
        _check_metadata_numbers(info, meta)
        files = [path / Path(p).name for p in info["relative_file_paths"]]
        counts = Counter(f.name for f in files)
        name, times = max(counts.items(), key=lambda kv: kv[1], default=("", 0))
        if times > 1:
            raise BagReadError(f"bag {str(path)!r}: metadata.yaml lists {name!r} {times} "
                               "times; each file of a bag is read once")
    except BagReadError:
        raise
    except (KeyError, TypeError, AttributeError) as exc:
        raise BagReadError(f"{str(meta)!r} is not valid rosbag2 metadata ({exc!r})") from None
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise BagReadError(f"bag {str(path)!r}: files listed in metadata.yaml are missing: "
                           f"{missing}")
    return files


#: The numbers of rosbag2's metadata (counts, times in ns, the version): whole and >= 0.
_METADATA_NUMBERS = ("version", "message_count", "nanoseconds", "nanoseconds_since_epoch")


def _check_metadata_numbers(node, meta: Path, trail: str = "") -> None:
    """Every count, time and version of rosbag2's metadata a whole number in [0, 2**63):
    BagReadError naming the field otherwise (a player would take a negative start time, a
    reader a negative message count for its promise)."""
    if isinstance(node, dict):
        for key, value in node.items():
            where = f"{trail}.{key}" if trail else str(key)
            if key in _METADATA_NUMBERS and not (
                    isinstance(value, int) and not isinstance(value, bool)
                    and 0 <= value < 2**63):
                raise BagReadError(f"{str(meta)!r}: {where} must be a whole number in "
                                   f"[0, 2**63), got {value!r}"[:300])
            _check_metadata_numbers(value, meta, where)
    elif isinstance(node, list):
        for index, value in enumerate(node):
            _check_metadata_numbers(value, meta, f"{trail}[{index}]")


def bag_interruption(path) -> str | None:
    """Why the recording in the bag directory ``path`` stopped before its end, as its writer
    marked it in metadata.yaml (:data:`aero_dva.bag.writer.INTERRUPTED_KEY`); None for a
    recording that ran to its end (or a lone MCAP file, or a bag without metadata.yaml)."""
    from aero_dva.bag.writer import INTERRUPTED_KEY

    meta = Path(path) / "metadata.yaml"
    if not meta.is_file():
        return None
    info = read_yaml(meta, "bag metadata", BagReadError)
    try:
        custom = info["rosbag2_bagfile_information"].get("custom_data") or {}
        reason = custom.get(INTERRUPTED_KEY)
    except (KeyError, TypeError, AttributeError):
        return None
    return None if reason is None else str(reason)


def file_summary(path: Path):
    """The file's MCAP summary, or None if it has none (not closed, cut or corrupt)."""
    with open(path, "rb") as stream:
        try:
            return SeekingReader(stream, record_size_limit=MAX_CHUNK_BYTES).get_summary()
        except Exception:  # noqa: BLE001 - corrupt data raises assorted errors
            return None


def _schema_type(schema) -> str:
    if schema is None:
        return ""
    try:
        return normalize_type_name(schema.name)
    except ValueError:
        return schema.name


def _file_topics(path: Path, bag: Path, allow_truncated: bool) -> dict[str, TopicInfo]:
    """Topics of one MCAP file from its summary, or by a scan if allowed."""
    summary = file_summary(path)
    if summary is not None:
        counts = summary.statistics.channel_message_counts if summary.statistics else {}
        return {ch.topic: TopicInfo(ch.topic, _schema_type(summary.schemas.get(ch.schema_id)),
                                    int(counts.get(ch.id, 0)))
                for ch in summary.channels.values()}
    if not allow_truncated:
        raise BagReadError(f"MCAP file {str(path)!r} is truncated or corrupt (no valid footer "
                           "and summary); " + RECOVER_HINT.format(bag=bag))
    topics: dict[str, TopicInfo] = {}
    for item in _scan(path):
        old = topics.get(item.channel.topic)
        topics[item.channel.topic] = TopicInfo(item.channel.topic, _schema_type(item.schema),
                                               (old.message_count if old else 0) + 1)
    return topics


def _scan(path: Path):
    """Messages of every chunk of a file whose CRC holds, in log-time order, with a
    RuntimeWarning saying what was skipped if the file is damaged or cut."""
    survey = survey_file(path)
    yield from survey.messages()
    if survey.damaged:
        lost = survey.lost
        skipped = ("an unknown number of messages (no index that passes its CRC)"
                   if lost is None else f"{lost} messages" + (
                       f" of the {survey.promised} its index promises"
                       if survey.promised is not None else ""))
        warnings.warn(f"MCAP file {str(path)!r} ends early or is damaged "
                      f"({'; '.join(str(d) for d in survey.damaged)}); skipped {skipped}",
                      RuntimeWarning, stacklevel=3)


def bag_topics(path, *, allow_truncated: bool = False) -> dict[str, TopicInfo]:
    """Topics of a bag directory or MCAP file, keyed by name.

    Raises
    ------
    BagReadError
        Missing path, unfinished bag (no metadata.yaml), bad metadata, truncated or corrupt file.
    """
    path = Path(path)
    topics: dict[str, TopicInfo] = {}
    for file in bag_files(path, allow_truncated):
        for name, info in _file_topics(file, path, allow_truncated).items():
            if name in topics:
                if topics[name].type_name != info.type_name:
                    raise BagReadError(f"bag {str(path)!r}: topic {name!r} has types "
                                       f"{topics[name].type_name!r} and {info.type_name!r}")
                info = TopicInfo(name, info.type_name,
                                 topics[name].message_count + info.message_count)
            topics[name] = info
    return topics


def _resolve(topic: str, available: Mapping[str, TopicInfo], path: Path) -> str:
    if topic in available:
        return topic
    if not topic.startswith("/") and "/" + topic in available:
        return "/" + topic
    raise TopicNotFoundError(
        f"topic {topic!r} is not in bag {str(path)!r}; topics there: {sorted(available)}")


def read_messages(
    path,
    topics: Iterable[str] | None = None,
    *,
    expected_types: Mapping[str, str] | None = None,
    allow_truncated: bool = False,
    decode: bool = True,
    log_time_order: bool = True,
) -> Iterator[BagMessage]:
    """Messages of chosen topics, decoded or raw, in log-time order per file.

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
        Read a cut, unclosed or damaged file instead of raising: every message of every
        chunk whose CRC holds, in log-time order, with a RuntimeWarning that lists the
        damaged byte ranges and how many messages were skipped.
    decode : bool
        False: ``message`` is the serialized CDR bytes (see :func:`deserialize`).
    log_time_order : bool
        False: in file order, which skips the reader's merge of chunks by log time (most of
        the reading time of a large bag); for callers that order by stamps themselves.

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
        selected = {_resolve(t, available, path) for t in [*topics, *expected]}
    for topic, type_name in expected.items():
        actual = available[_resolve(topic, available, path)].type_name
        if actual != normalize_type_name(type_name):
            raise MessageTypeError(
                f"topic {topic!r} in bag {str(path)!r} carries {actual!r}, "
                f"expected {normalize_type_name(type_name)!r}")
    return _iterate(bag_files(path, allow_truncated), selected, decode, log_time_order, path,
                    allow_truncated)


def _records(file: Path, selected: set[str], log_time_order: bool, allow_truncated: bool):
    """(schema, channel, message) of the selected topics: indexed, or, allowing damage, of
    every chunk whose CRC holds (the chunks are checked before the first message)."""
    if allow_truncated:
        for item in _scan(file):
            if item.channel.topic in selected:
                yield item.schema, item.channel, item.message
        return
    with open(file, "rb") as stream:
        summary = SeekingReader(stream, record_size_limit=MAX_CHUNK_BYTES).get_summary()
        if summary is None or not summary.chunk_indexes:
            yield from _unchunked(file, selected, log_time_order)
            return
        yield from _indexed(stream, file, summary, selected, log_time_order)


def _indexed(stream, file: Path, summary, selected: set[str], log_time_order: bool):
    """(schema, channel, message) of the selected topics by the summary's chunk index, in
    ``mcap.reader.SeekingReader``'s order (log time, then chunk offset, then record), each
    chunk read, CRC-checked and decompressed within the readers' limits
    (:mod:`aero_dva.bag.chunk_limits`) when the merge reaches its first log time."""
    size = os.fstat(stream.fileno()).st_size
    chunks = [c for c in summary.chunk_indexes if not c.message_index_offsets or any(
        summary.channels[cid].topic in selected for cid in c.message_index_offsets
        if cid in summary.channels)]

    def messages(index):
        for at, record in enumerate(_chunk_of(stream, file, index, size)):
            if isinstance(record, Message):
                channel = summary.channels[record.channel_id]
                if channel.topic in selected:
                    schema = summary.schemas[channel.schema_id] if channel.schema_id else None
                    yield (record.log_time, index.chunk_start_offset, at), (schema, channel,
                                                                           record)

    if not log_time_order:
        for index in chunks:
            for _, item in messages(index):
                yield item
        return
    budget = MergeBudget(f"MCAP file {str(file)!r}")
    heap = [((c.message_start_time, c.chunk_start_offset, -1), None, c) for c in chunks]
    heapq.heapify(heap)
    while heap:
        _, item, index = heapq.heappop(heap)
        if item is None:  # a chunk the merge has reached: its messages join the queue
            queued = list(messages(index))
            budget.hold(m for _, (_, _, m) in queued)
            for key, entry in queued:
                heapq.heappush(heap, (key, entry, None))
            continue
        budget.release(item[2])
        yield item


def _chunk_of(stream, file: Path, index, size: int) -> list:
    """The records of the chunk ``index`` names, read within the file and the limits."""
    length, at = index.chunk_length, index.chunk_start_offset
    if length > MAX_CHUNK_BYTES + 2**16:
        raise ChunkLimitError(f"MCAP file {str(file)!r}: the chunk at byte {at} declares "
                              f"{length:,} bytes, more than the {MAX_CHUNK_BYTES:,} a chunk "
                              "may hold (the readers' ceiling)")
    if at + length > size:
        raise BagReadError(f"MCAP file {str(file)!r}: the chunk at byte {at} runs past the "
                           "end of the file")
    stream.seek(index.chunk_start_offset)
    raw = stream.read(length)
    if len(raw) != length or raw[0] != Opcode.CHUNK:
        raise BagReadError(f"MCAP file {str(file)!r}: no chunk record at byte "
                           f"{index.chunk_start_offset}")
    try:
        return chunk_records(Chunk.read(ReadDataStream(io.BytesIO(raw[9:]))))
    except ChunkLimitError as exc:
        raise ChunkLimitError(f"MCAP file {str(file)!r}: {exc}") from None


def _unchunked(file: Path, selected: set[str], log_time_order: bool):
    """A closed file without a chunk index, read record by record (bounded); its messages
    must already be in log-time order when that order is asked for (nothing to merge by)."""
    scan = FileScan(file)
    last = None
    for item in scan.messages():
        if log_time_order and last is not None and item.message.log_time < last:
            raise BagReadError(f"MCAP file {str(file)!r} has no chunk index and its messages "
                               "are not in log-time order")
        last = item.message.log_time
        if item.channel.topic in selected:
            yield item.schema, item.channel, item.message
    if scan.damage is not None:
        raise BagReadError(f"MCAP file {str(file)!r}: {scan.damage.reason}")


def _iterate(files: list[Path], selected: set[str], decode: bool, log_time_order: bool,
             bag: Path, allow_truncated: bool):
    for file in files:
        count = 0
        schemas: dict[int, tuple] = {}  # schema id -> (type, text, typestore or None), per file
        records = _records(file, selected, log_time_order, allow_truncated)
        while True:
            try:
                schema, channel, message = next(records)
            except StopIteration:
                break
            except (BagReadError, ChunkLimitError) as exc:  # each names the file
                raise BagReadError(f"{exc}; " + RECOVER_HINT.format(bag=bag)) from None
            except Exception as exc:  # noqa: BLE001 - corrupt data raises assorted errors
                raise BagReadError(
                    f"MCAP file {str(file)!r} is corrupt: reading failed after {count} "
                    f"messages ({type(exc).__name__}: {exc}); "
                    + RECOVER_HINT.format(bag=bag)
                ) from None
            known = schemas.get(schema.id) if schema is not None else None
            if known is None:
                known = schemas[schema.id] = _schema_entry(file, schema, channel, decode)
            type_name, text, store = known
            data = message.data
            if store is not None:
                try:
                    data = store.deserialize_cdr(data, type_name)
                except Exception as exc:  # noqa: BLE001 - the CDR reader raises assorted errors
                    raise BagReadError(f"MCAP file {str(file)!r}: message {count} on "
                                       f"{channel.topic!r} does not decode as {type_name} "
                                       f"({type(exc).__name__}: {exc})") from None
            count += 1
            yield BagMessage(channel.topic, type_name, message.log_time, message.publish_time,
                             data, text)


def _schema_entry(file: Path, schema, channel, decode: bool) -> tuple:
    """(type name, schema text, typestore to decode with or None) of a file's schema."""
    if channel.message_encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
        raise BagReadError(f"MCAP file {str(file)!r}: topic {channel.topic!r} is not "
                           f"ros2msg/cdr (encoding {channel.message_encoding!r})")
    type_name, text = _schema_type(schema), schema.data.decode("utf-8", "replace")
    if not decode:
        return type_name, text, None
    try:
        return type_name, text, schema_typestore(type_name, text)
    except Exception as exc:  # noqa: BLE001 - an unparsable schema text
        raise BagReadError(f"MCAP file {str(file)!r}: the schema of {channel.topic!r} does "
                           f"not parse ({type(exc).__name__}: {exc})") from None
