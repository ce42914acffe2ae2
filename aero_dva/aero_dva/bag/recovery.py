"""What a bag holds and whether it is whole; a complete copy of a damaged or unclosed bag.

:func:`bag_info` reads a bag directory or MCAP file: its files, topics, message counts and
times, whether it was closed (``metadata.yaml`` present, every file ending in its footer
and summary) and, unless asked not to, whether every chunk passes its CRC: each file is
surveyed (:mod:`aero_dva.bag.chunk_survey`) and every damaged byte range is reported with
what it held. :func:`recover_bag` writes a new, complete rosbag2-layout bag (indexed MCAP +
``metadata.yaml``) with every message of every chunk whose CRC holds, in log-time order, with
its original schemas, QoS metadata, times and sequence numbers; the new bag appears under its
name only when it is complete (written beside it, then renamed).
"""
from __future__ import annotations

import dataclasses
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from aero_dva.bag.chunk_survey import DamagedRange, FileSurvey, survey_file
from aero_dva.bag.mcap_scan import Damage, FileScan
from aero_dva.bag.reader import BagReadError, bag_files, bag_interruption, file_summary
from aero_dva.bag.writer import COMPRESSIONS, BagWriter, TopicInfo, qos_profile_yaml
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
        Counts of the messages that read (checked: in chunks whose CRC holds); unchecked,
        a closed bag's counts from its summaries.
    message_count : int
    start_ns, end_ns : int
        First and last log time [ns] (0 for no messages).
    damage : Damage or None
        Where the first unreadable byte is, if any.
    problems : tuple of str
        Why the bag does not count as closed.
    verified : bool
        Every chunk of every file was read and its CRC checked.
    damaged : tuple of DamagedRange
        Every unreadable byte range with what it held (checked bags only).
    promised : int or None
        Messages the bag's index promises (summaries whose CRC holds, else metadata.yaml).
    lost : int or None
        Messages that do not read (None: not known).
    interrupted : str or None
        Why the recording stopped before its end, as its writer marked it (metadata.yaml);
        None for a recording that ran to its end.
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
    verified: bool = False
    damaged: tuple[DamagedRange, ...] = ()
    promised: int | None = None
    lost: int | None = None
    interrupted: str | None = None

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
                "problems": list(self.problems), "verified": self.verified,
                "damaged": [d.to_dict() for d in self.damaged], "promised": self.promised,
                "lost": self.lost, "interrupted": self.interrupted}


def bag_info(path, *, verify: bool = True) -> BagInfo:
    """Describe a bag directory or MCAP file (see the module docstring).

    ``verify=False`` reads a closed bag's summaries only (no chunk is decompressed); a file
    without a summary is then scanned up to its first damage.

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
    interrupted = bag_interruption(path) if path.is_dir() else None
    if verify:
        return dataclasses.replace(_checked_info(path, files, problems),
                                   interrupted=interrupted)
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
                   end_ns=end or 0, damage=damage, problems=tuple(problems),
                   interrupted=interrupted)


def _checked_info(path: Path, files: list[Path], problems: list[str]) -> BagInfo:
    """:func:`bag_info` with every chunk's CRC checked (a survey of each file)."""
    counts: dict[str, list] = {}  # topic -> [type, count]
    start = end = None
    surveys = [survey_file(file) for file in files]
    for survey in surveys:
        if survey.cut:
            problems.append(f"{survey.path.name} has no footer and summary")
        per_channel = {}
        for chunk in survey.chunks:
            for channel_id, n in chunk.counts.items():
                per_channel[channel_id] = per_channel.get(channel_id, 0) + n
            if chunk.messages:
                start = chunk.start_ns if start is None else min(start, chunk.start_ns)
                end = chunk.end_ns if end is None else max(end, chunk.end_ns)
        for message in survey.salvaged:
            per_channel[message.channel_id] = per_channel.get(message.channel_id, 0) + 1
            start = message.log_time if start is None else min(start, message.log_time)
            end = message.log_time if end is None else max(end, message.log_time)
        for channel in survey.channels.values():  # topics without messages included
            schema = survey.schemas.get(channel.schema_id)
            entry = counts.setdefault(channel.topic, [schema.name if schema else "", 0])
            entry[1] += per_channel.get(channel.id, 0)  # unknown channels: lost (survey)
    damaged = tuple(d for s in surveys for d in s.damaged)
    if damaged:
        problems.append(f"damaged: {len(damaged)} byte range(s) do not read")
    topics = tuple(TopicInfo(name, type_name, n) for name, (type_name, n) in counts.items())
    kept = sum(t.message_count for t in topics)
    promised, lost = _promise(path, surveys, kept)
    first = damaged[0] if damaged else None
    return BagInfo(path=path, files=tuple(files), closed=not problems, topics=topics,
                   message_count=kept, start_ns=start or 0, end_ns=end or 0,
                   damage=None if first is None else Damage(first.file, first.start,
                                                            first.reason),
                   problems=tuple(problems), verified=True, damaged=damaged,
                   promised=promised, lost=lost)


def _promise(path: Path, surveys: list[FileSurvey], kept: int) -> tuple[int | None, int | None]:
    """(messages the index promises, messages lost): from the summaries if every one passes
    its CRC, else from metadata.yaml, else only the damaged ranges' own counts."""
    if surveys and all(s.summary_ok and s.promised is not None for s in surveys):
        promised = sum(s.promised for s in surveys)
    else:
        promised = _metadata_count(path)
    if promised is not None:
        return promised, max(promised - kept, 0)
    losses = [s.lost for s in surveys]
    return None, None if None in losses else sum(losses)


def _metadata_count(path: Path) -> int | None:
    meta = path / "metadata.yaml" if path.is_dir() else None
    if meta is None or not meta.is_file():
        return None
    try:
        info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        count = info["message_count"]
    except (yaml.YAMLError, KeyError, TypeError, UnicodeDecodeError):
        return None
    return count if isinstance(count, int) and not isinstance(count, bool) else None


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
        The first damage (None: the source was whole, every message is kept).
    files_read, files_total : int
        Source files read and in the source (every file is read).
    topics : tuple of TopicInfo
        Topics of the new bag.
    damaged : tuple of DamagedRange
        Every unreadable byte range of the source, with what it held.
    promised : int or None
        Messages the source's index promises (None: no index that passes its CRC).
    lost : int or None
        Messages of the source not in the copy (None: not known, e.g. a cut file).
    """

    out: Path
    kept: int
    salvaged: int
    damage: Damage | None
    files_read: int
    files_total: int
    topics: tuple[TopicInfo, ...]
    damaged: tuple[DamagedRange, ...] = ()
    promised: int | None = None
    lost: int | None = None


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
    """Write ``out``: a complete bag of every message of ``path`` that reads.

    Every chunk whose CRC holds is kept, wherever the damage is (before, between or after
    damaged chunks, in any file of a split bag), and its messages are written in log-time
    order (per source file); the whole message records at the start of a chunk a cut file
    ends inside are kept too.

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
    surveys = [survey_file(file) for file in files]
    if not any(s.chunks or s.salvaged for s in surveys):
        bad = next((d for s in surveys for d in s.damaged if d.start == 0), None)
        if bad is not None:
            raise BagReadError(f"{str(bad.file)!r} holds nothing to recover: {bad.reason}")
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        kept, topics = _copy(surveys, staging / out.name, compression, chunk_size,
                             _ros_distro(path))
        if out.exists():
            out.rmdir()  # empty (checked above)
        (staging / out.name).rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    damaged = tuple(d for s in surveys for d in s.damaged)
    promised, lost = _promise(path, surveys, kept)
    first = damaged[0] if damaged else None
    return RecoveryResult(out=out, kept=kept, salvaged=sum(len(s.salvaged) for s in surveys),
                          damage=None if first is None else Damage(first.file, first.start,
                                                                   first.reason),
                          files_read=len(files), files_total=len(files), topics=topics,
                          damaged=damaged, promised=promised, lost=lost)


def _copy(surveys: list[FileSurvey], target: Path, compression: str | None, chunk_size: int,
          ros_distro: str | None):
    """Copy the messages that read of every surveyed file into a new bag at ``target``."""
    writer = None
    kept = 0
    try:
        for survey in surveys:
            topics: dict[int, str] = {}  # channel id -> registered topic, per file
            for item in survey.messages():
                if writer is None:
                    writer = _writer(target, compression, survey.compression, chunk_size,
                                     ros_distro)
                if item.channel.id not in topics:
                    topics[item.channel.id] = _add_topic(writer, item)
                message = item.message
                writer.write(topics[item.channel.id], message.data, message.log_time,
                             message.publish_time, sequence=message.sequence)
                kept += 1
        if writer is None:  # no message anywhere: an empty, complete bag
            writer = _writer(target, compression, None, chunk_size, ros_distro)
        summary = writer.close()
    except BaseException:
        if writer is not None:
            writer.close()
        raise
    return kept, summary.topics


def _writer(target: Path, compression: str | None, source: str | None, chunk_size: int,
            ros_distro: str | None) -> BagWriter:
    """The new bag's writer; compression as asked, else the source's ("" = none)."""
    if compression is None:
        compression = "none" if source == "" else source
        if compression not in COMPRESSIONS:
            compression = "zstd"
    return BagWriter(target, compression=compression, chunk_size=chunk_size,
                     ros_distro=ros_distro, library="aero_dva.bag.recovery")


def _add_topic(writer: BagWriter, item) -> str:
    channel, schema = item.channel, item.schema
    if schema is None or schema.encoding != "ros2msg" or channel.message_encoding != "cdr":
        raise BagReadError(f"topic {channel.topic!r} is not ros2msg/cdr: not a ROS 2 bag")
    return writer.add_topic(channel.topic, schema.name,
                            channel.metadata.get("offered_qos_profiles", qos_profile_yaml()),
                            schema_text=schema.data.decode("utf-8", "replace"))
