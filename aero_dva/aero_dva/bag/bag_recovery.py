"""What a bag holds and whether it was closed; a complete copy of a damaged or unclosed bag.

:func:`bag_info` reads a bag directory or MCAP file: its files, topics, message counts and
times, and whether it was closed (``metadata.yaml`` present, every file ending in its footer
and summary). A bag that was not closed is scanned (:mod:`aero_dva.bag.mcap_scan`) and the
place of the damage is reported. :func:`recover_bag` writes a new, complete rosbag2-layout
bag (indexed MCAP + ``metadata.yaml``) with every message before the damage, with its original
schemas, QoS metadata, times and sequence numbers; the new bag appears under its name only
when it is complete (written beside it, then renamed).
"""
from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from aero_dva.bag.bag_reader import BagReadError, bag_files, file_summary
from aero_dva.bag.bag_writer import COMPRESSIONS, BagWriter, TopicInfo, qos_profile_yaml
from aero_dva.bag.mcap_scan import Damage, FileScan
from aero_dva.safe_files import read_yaml

__all__ = ["BagInfo", "RecoveryResult", "bag_info", "recover_bag"]


@dataclass(frozen=True)
class BagInfo:
    """What :func:`bag_info` found.

    Attributes
    ----------
    path : pathlib.Path
    files : tuple of pathlib.Path
        The MCAP files, in order.
    closed : bool
        ``metadata.yaml`` present (for a directory) and every file complete.
    topics : tuple of TopicInfo
        Counts of a closed bag from its summaries; of another, what the scan could read.
    message_count : int
    start_ns, end_ns : int
        First and last log time [ns] (0 for no messages).
    damage : Damage or None
        Where the first unreadable byte is, if any.
    problems : tuple of str
        Why the bag does not count as closed.
    """

    path: Path
    files: tuple[Path, ...]
    closed: bool
    topics: tuple[TopicInfo, ...]
    message_count: int
    start_ns: int
    end_ns: int
    damage: Damage | None = None
    problems: tuple[str, ...] = field(default_factory=tuple)

    @property
    def duration_ns(self) -> int:
        return self.end_ns - self.start_ns

    def to_dict(self) -> dict:
        return {"path": str(self.path), "files": [str(f) for f in self.files],
                "closed": self.closed, "message_count": self.message_count,
                "start_ns": self.start_ns, "end_ns": self.end_ns,
                "duration_s": self.duration_ns * 1e-9,
                "topics": [{"name": t.name, "type": t.type_name, "count": t.message_count}
                           for t in self.topics],
                "damage": None if self.damage is None else {
                    "file": str(self.damage.file), "offset": self.damage.offset,
                    "reason": self.damage.reason},
                "problems": list(self.problems)}


def bag_info(path) -> BagInfo:
    """Describe a bag directory or MCAP file (see the module docstring).

    Raises
    ------
    BagReadError
        No such path, no MCAP file, or metadata that is not rosbag2's.
    """
    path = Path(path)
    files = bag_files(path, allow_truncated=True)
    problems = []
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        problems.append("no metadata.yaml (the recording was not closed)")
    counts: dict[str, list] = {}  # topic -> [type, count]
    start = end = None
    damage = None
    for file in files:
        summary = file_summary(file)
        if summary is not None and summary.statistics is not None:
            stats = summary.statistics
            for channel in summary.channels.values():
                schema = summary.schemas.get(channel.schema_id)
                entry = counts.setdefault(channel.topic, [schema.name if schema else "", 0])
                entry[1] += int(stats.channel_message_counts.get(channel.id, 0))
            if stats.message_count:
                start = stats.message_start_time if start is None else min(
                    start, stats.message_start_time)
                end = stats.message_end_time if end is None else max(end,
                                                                     stats.message_end_time)
            continue
        problems.append(f"{file.name} has no footer and summary")
        scan = FileScan(file)
        for item in scan.messages():
            schema = item.schema
            entry = counts.setdefault(item.channel.topic, [schema.name if schema else "", 0])
            entry[1] += 1
            t = item.message.log_time
            start = t if start is None else min(start, t)
            end = t if end is None else max(end, t)
        if scan.damage is not None:
            damage = damage or scan.damage
            break  # what follows the damage is not read (as recover_bag)
    topics = tuple(TopicInfo(name, type_name, n) for name, (type_name, n) in counts.items())
    return BagInfo(path=path, files=tuple(files), closed=not problems, topics=topics,
                   message_count=sum(t.message_count for t in topics), start_ns=start or 0,
                   end_ns=end or 0, damage=damage, problems=tuple(problems))


@dataclass(frozen=True)
class RecoveryResult:
    """What :func:`recover_bag` wrote.

    Attributes
    ----------
    out : pathlib.Path
        The new bag directory.
    kept : int
        Messages written to it.
    salvaged : int
        Of those, messages taken from a chunk the file ends inside.
    damage : Damage or None
        Where reading stopped (None: the source was whole, every message is kept).
    files_read, files_total : int
        Source files read (the damaged one included) and in the source.
    topics : tuple of TopicInfo
        Topics of the new bag.
    """

    out: Path
    kept: int
    salvaged: int
    damage: Damage | None
    files_read: int
    files_total: int
    topics: tuple[TopicInfo, ...]


def _ros_distro(path: Path) -> str | None:
    meta = path / "metadata.yaml" if path.is_dir() else None
    if meta is None or not meta.is_file():
        return None
    try:
        info = read_yaml(meta, "bag metadata")["rosbag2_bagfile_information"]
        return info.get("ros_distro") or None
    except (ValueError, KeyError, TypeError, AttributeError):
        return None


def recover_bag(path, out, *, compression: str | None = None,
                chunk_size: int = 1 << 20) -> RecoveryResult:
    """Write ``out``: a complete bag of every message of ``path`` before its damage.

    Parameters
    ----------
    path : path-like
        A bag directory (closed or not) or an MCAP file.
    out : path-like
        New bag directory; it must not exist or be empty.
    compression : {"zstd", "lz4", "none"}, optional
        Chunk compression of the new bag; default the source's (zstd if it has no chunk).
    chunk_size : int
        [bytes] uncompressed chunk size of the new bag.

    Raises
    ------
    BagReadError
        ``path`` is not a bag, or holds no MCAP data at all (nothing to recover).
    FileExistsError
        ``out`` exists and is not empty.
    """
    path, out = Path(path), Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"--out {str(out)!r} exists and is not empty")
    files = bag_files(path, allow_truncated=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        result = _copy(files, staging / out.name, compression, chunk_size, _ros_distro(path))
        if out.exists():
            out.rmdir()  # empty (checked above)
        (staging / out.name).rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return RecoveryResult(out=out, kept=result[0], salvaged=result[1], damage=result[2],
                          files_read=result[3], files_total=len(files), topics=result[4])


def _copy(files: list[Path], target: Path, compression: str | None, chunk_size: int,
          ros_distro: str | None):
    """Copy the messages of ``files`` up to the first damage into a new bag at ``target``."""
    writer = None
    kept = salvaged = read = 0
    damage = None
    try:
        for file in files:
            read += 1
            scan = FileScan(file)
            topics: dict[int, str] = {}  # channel id -> registered topic, per file
            for item in scan.messages():
                if writer is None:
                    writer = _writer(target, compression, scan.compression, chunk_size,
                                     ros_distro)
                if item.channel.id not in topics:
                    topics[item.channel.id] = _add_topic(writer, item)
                message = item.message
                writer.write(topics[item.channel.id], message.data, message.log_time,
                             message.publish_time, sequence=message.sequence)
                kept += 1
            salvaged += scan.salvaged
            if scan.damage is not None:
                if scan.damage.offset == 0 and kept == 0:
                    raise BagReadError(f"{str(file)!r} holds nothing to recover: "
                                       f"{scan.damage.reason}")
                damage = scan.damage
                break
        if writer is None:  # no message anywhere: an empty, complete bag
            writer = _writer(target, compression, None, chunk_size, ros_distro)
        summary = writer.close()
    except BaseException:
        if writer is not None:
            writer.close()
        raise
    return kept, salvaged, damage, read, summary.topics


def _writer(target: Path, compression: str | None, source: str | None, chunk_size: int,
            ros_distro: str | None) -> BagWriter:
    """The new bag's writer; compression as asked, else the source's ("" = none)."""
    if compression is None:
        compression = "none" if source == "" else source
        if compression not in COMPRESSIONS:
            compression = "zstd"
    return BagWriter(target, compression=compression, chunk_size=chunk_size,
                     ros_distro=ros_distro, library="aero_dva.bag.bag_recovery")


def _add_topic(writer: BagWriter, item) -> str:
    channel, schema = item.channel, item.schema
    if schema is None or schema.encoding != "ros2msg" or channel.message_encoding != "cdr":
        raise BagReadError(f"topic {channel.topic!r} is not ros2msg/cdr: not a ROS 2 bag")
    return writer.add_topic(channel.topic, schema.name,
                            channel.metadata.get("offered_qos_profiles", qos_profile_yaml()),
                            schema_text=schema.data.decode("utf-8", "replace"))
