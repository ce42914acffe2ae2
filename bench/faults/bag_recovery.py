"""The one step that gets the messages back from a bag whose recorder was killed (SIGKILL).

:func:`recover` is the switch: with ``dva bag recover`` installed (the ``dva bag`` command
group) it writes a complete copy of the bag and the copy is read as any bag; without it, the
reader keeps what precedes the damage (``allow_truncated``). Either way the answer is the
sample indexes of the acceleration blocks that came back, and which way was used.

:func:`complete_chunk_indexes` is the independent check: it walks the MCAP records of the file
as written and lists the acceleration blocks inside every chunk that is complete on disk, so
"everything in complete chunks before the kill is kept" can be asserted.
"""
from __future__ import annotations

import importlib.util
import subprocess
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

from mcap.reader import breakup_chunk
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import StreamReader

from aero_dva.bag import channels as ch
from aero_dva.bag.reader import TopicNotFoundError, read_messages

TOPIC = ch.ACCELERATION.absolute()


@dataclass(frozen=True)
class Recovered:
    """Sample indexes of the acceleration blocks read back, and how they were read."""

    indexes: list[int]
    method: str


def has_bag_recover() -> bool:
    """Whether this tree has ``dva bag recover`` (the ``dva bag`` command group)."""
    return importlib.util.find_spec("dva_offline.bag.cli") is not None


def read_indexes(bag: Path, allow_truncated: bool = False) -> list[int]:
    """Sample indexes of the acceleration blocks of a bag, in file order."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # "ends early": expected here
        try:
            messages = read_messages(bag, [TOPIC], allow_truncated=allow_truncated,
                                     log_time_order=False)
        except TopicNotFoundError:  # killed before a chunk with a block reached the file
            return []
        return [int(m.message.first_sample_index) for m in messages]


def recover(bag: Path, work: Path) -> Recovered:
    """Read back the acceleration blocks of a killed recorder's bag (see the module doc)."""
    if not any(bag.glob("*.mcap")):
        return Recovered([], "nothing written")
    if has_bag_recover():
        copy = work / (bag.name + "_recovered")
        result = subprocess.run([sys.executable, "-m", "dva_offline.cli", "bag", "recover",
                                 str(bag), "--out", str(copy)], capture_output=True, text=True,
                                timeout=300)
        if result.returncode not in (0, 1):  # 1: written, messages lost (a killed recorder)
            if "nothing to recover" in result.stderr:  # killed before its first flush
                return Recovered([], "dva bag recover (nothing written yet)")
            raise RuntimeError(f"dva bag recover {bag} failed: {result.stderr.strip()}")
        return Recovered(read_indexes(copy), "dva bag recover")
    return Recovered(read_indexes(bag, allow_truncated=True), "reader, allow_truncated")


def complete_chunk_indexes(mcap_path: Path) -> list[int]:
    """Sample indexes of the acceleration blocks in the chunks complete in the file."""
    from mcap_ros2.decoder import DecoderFactory

    channels: dict[int, Channel] = {}
    schemas: dict[int, Schema] = {}
    indexes: list[int] = []
    decoders = DecoderFactory()
    with open(mcap_path, "rb") as stream:
        records = StreamReader(stream, skip_magic=False, emit_chunks=True).records
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except Exception:  # the first incomplete record: the end of what was written
                break
            inner = breakup_chunk(record) if isinstance(record, Chunk) else [record]
            for item in inner:
                if isinstance(item, Channel):
                    channels[item.id] = item
                elif isinstance(item, Schema):
                    schemas[item.id] = item
                elif isinstance(item, Message) and isinstance(record, Chunk):
                    channel = channels.get(item.channel_id)
                    if channel is not None and channel.topic == TOPIC:
                        decode = decoders.decoder_for("cdr", schemas[channel.schema_id])
                        indexes.append(int(decode(item.data).first_sample_index))
    return indexes
