"""Bags built to exhaust a reader's memory, and the readers run on them in a capped process.

- :func:`bomb_bag`: a closed, indexed bag whose one zstd chunk expands to ``expanded`` bytes
  (2.5 GiB in 80 KB: RLE blocks of 128 KiB of zeros), declaring ``declared`` bytes in its
  header, with or without the content size in the zstd frame;
- :func:`lz4_bomb_bag`: the same with an lz4 chunk (lz4 expands at most about 255x);
- :func:`overlap_bag`: ``chunks`` valid chunks of ``chunk_bytes`` each, all spanning the same
  log times, so a reader merging them by log time would hold them all at once;
- :func:`listed_bag`: a valid bag whose ``metadata.yaml`` lists its file ``times`` times.

:data:`READERS` are the project's bag readers as short Python programs (the ``dva`` bag
commands, the reader, the flight-log readers, the bag player's source); :func:`run_capped`
runs them in a child process under ``resource.setrlimit(RLIMIT_AS, cap)`` and returns each
one's outcome, last stderr line and peak resident memory (VmHWM, reset before each).
"""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from mcap.data_stream import RecordBuilder
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Schema,
    Statistics,
)

MAGIC = b"\x89MCAP0\r\n"
TOPIC = "/wing/acceleration"
GiB = 2**30


def zstd_zeros(n: int, content_size: bool = True, prefix: bytes = b"") -> bytes:
    """A zstd frame of ``prefix`` then ``n`` zero bytes: a raw block, then RLE blocks of
    128 KiB (4 bytes each); the frame states its content size when ``content_size``."""
    out = bytearray(struct.pack("<I", 0xFD2FB528))
    out += bytes([0xC0, 7 << 3]) + struct.pack("<Q", n + len(prefix)) if content_size \
        else bytes([0x00, 7 << 3])
    if prefix:
        out += struct.pack("<I", len(prefix) << 3)[:3] + prefix
    left = n
    while left > 0:
        size = min(1 << 17, left)
        left -= size
        out += struct.pack("<I", (size << 3) | 2 | (left == 0))[:3] + b"\0"
    return bytes(out)


def _record(record) -> bytes:
    builder = RecordBuilder()
    record.write(builder)
    return bytes(builder.end())


def valid_bag(path: Path, blocks: int = 20) -> Path:
    """A small closed flight bag (the batch recorder's, zstd chunks)."""
    from aero_dva.bag.batch_recorder import BatchRecorder

    n = 50 * blocks
    rng = np.random.default_rng(0)
    with BatchRecorder(path, 1000.0, compression="zstd", damper_state=False) as recorder:
        recorder.write_samples(0, rng.standard_normal((3, n)), rng.standard_normal((4, n)),
                               rng.standard_normal(n), block_size=50,
                               airspeed=np.full(blocks, 90.0), density=np.full(blocks, 1.2))
    return path


def _schema_and_channel(bag: Path):
    from mcap.reader import SeekingReader

    mcap = next(bag.glob("*.mcap"))
    with open(mcap, "rb") as stream:
        summary = SeekingReader(stream).get_summary()
        channel = next(c for c in summary.channels.values() if c.topic == TOPIC)
        first = next(SeekingReader(stream).iter_messages(topics=[TOPIC]))[2]
    return mcap, summary.schemas[channel.schema_id], channel, first


def _write_mcap(path: Path, schema: Schema, channel: Channel, chunks: list[Chunk],
                indexes: list[bytes]) -> None:
    """An indexed MCAP file of ``chunks`` (each followed by its message index bytes)."""
    out = bytearray(MAGIC)
    out += _record(Header(profile="ros2", library="resource_bombs"))
    chunk_index = []
    for chunk, index in zip(chunks, indexes, strict=True):
        start = len(out)
        out += _record(chunk)
        length = len(out) - start
        index_at = len(out)
        out += index
        chunk_index.append(ChunkIndex(
            chunk_length=length, chunk_start_offset=start, compression=chunk.compression,
            compressed_size=len(chunk.data), message_end_time=chunk.message_end_time,
            message_index_length=len(index), message_index_offsets={channel.id: index_at}
            if index else {}, message_start_time=chunk.message_start_time,
            uncompressed_size=chunk.uncompressed_size))
    out += _record(DataEnd(data_section_crc=0))
    summary_start = len(out)
    out += _record(schema) + _record(channel)
    for index in chunk_index:
        out += _record(index)
    out += _record(Statistics(message_count=0, schema_count=1, channel_count=1,
                              attachment_count=0, metadata_count=0, chunk_count=len(chunks),
                              message_start_time=0, message_end_time=0,
                              channel_message_counts={}))
    out += _record(Footer(summary_start=summary_start, summary_offset_start=0,
                          summary_crc=0))
    out += MAGIC
    path.write_bytes(bytes(out))


def _message_record(channel: Channel, message: Message, sequence: int, log_time: int) -> bytes:
    return _record(Message(channel_id=channel.id, sequence=sequence, log_time=log_time,
                           publish_time=log_time, data=message.data))


def bomb_bag(path: Path, expanded: int = int(2.5 * GiB), declared: int | None = None,
             content_size: bool = True) -> Path:
    """A closed bag whose one zstd chunk (a real message, then zeros) expands to ``expanded``
    bytes; its header declares ``declared`` (default: the true size)."""
    valid_bag(path)
    mcap, schema, channel, first = _schema_and_channel(path)
    head = _message_record(channel, first, 0, first.log_time)
    data = zstd_zeros(expanded, content_size, prefix=head)
    size = len(head) + expanded if declared is None else declared
    chunk = Chunk(compression="zstd", data=data, message_start_time=first.log_time,
                  message_end_time=first.log_time, uncompressed_crc=1, uncompressed_size=size)
    index = _record(MessageIndex(channel_id=channel.id, records=[(first.log_time, 0)]))
    _write_mcap(mcap, schema, channel, [chunk], [index])
    return path


def lz4_bomb_bag(path: Path, expanded: int = GiB) -> Path:
    """The same with an lz4 chunk of zeros (about 4 MB for 1 GiB)."""
    import lz4.frame

    valid_bag(path)
    mcap, schema, channel, first = _schema_and_channel(path)
    compressor = lz4.frame.LZ4FrameCompressor()
    zeros = bytes(1 << 20)
    parts = [compressor.begin()]
    parts += [compressor.compress(zeros) for _ in range(expanded >> 20)]
    parts.append(compressor.flush())
    chunk = Chunk(compression="lz4", data=b"".join(parts), message_start_time=first.log_time,
                  message_end_time=first.log_time, uncompressed_crc=1,
                  uncompressed_size=expanded)
    _write_mcap(mcap, schema, channel, [chunk], [b""])
    return path


def overlap_bag(path: Path, chunks: int = 200, chunk_bytes: int = 2**20) -> Path:
    """``chunks`` valid chunks (true CRCs and sizes) of ``chunk_bytes`` of real messages,
    every one spanning the same log times."""
    import zstandard

    valid_bag(path)
    mcap, schema, channel, first = _schema_and_channel(path)
    per_chunk = max(1, chunk_bytes // len(_message_record(channel, first, 0, 0)))
    built, indexes = [], []
    times = first.log_time + np.arange(per_chunk, dtype=np.int64) * 1000
    for k in range(chunks):
        records, entries = bytearray(), []
        for j, t in enumerate(times.tolist()):
            entries.append((t, len(records)))
            records += _message_record(channel, first, k * per_chunk + j, t)
        raw = bytes(records)
        built.append(Chunk(compression="zstd", data=zstandard.ZstdCompressor().compress(raw),
                           message_start_time=int(times[0]), message_end_time=int(times[-1]),
                           uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw)))
        indexes.append(_record(MessageIndex(channel_id=channel.id, records=entries)))
    _write_mcap(mcap, schema, channel, built, indexes)
    return path


def listed_bag(path: Path, times: int = 2000) -> Path:
    """A valid bag whose metadata.yaml lists its one file ``times`` times."""
    valid_bag(path)
    meta = path / "metadata.yaml"
    data = yaml.safe_load(meta.read_text())
    info = data["rosbag2_bagfile_information"]
    info["relative_file_paths"] = info["relative_file_paths"] * times
    info["files"] = info["files"] * times
    class Plain(yaml.SafeDumper):  # each copy written out, as a hostile writer would
        def ignore_aliases(self, data):
            return True

    meta.write_text(yaml.dump(data, Dumper=Plain))
    return path


@dataclass(frozen=True)
class ReaderRun:
    """One reader on one bag: ``outcome`` "read" (it returned), "refused" (an error of the
    project's, one line), "memory" (MemoryError: the cap was reached) or "crashed" (anything
    else); the last line it said on stderr; its peak resident memory [bytes] (VmHWM)."""

    reader: str
    bag: str
    outcome: str
    line: str
    peak: int


#: name -> Python statements reading the bag ``bag`` (``scratch``: an empty directory).
READERS = {
    "dva bag info": "code = main(['bag', 'info', bag])",
    "dva bag info --no-verify": "code = main(['bag', 'info', '--no-verify', bag])",
    "dva bag recover": "code = main(['bag', 'recover', bag, '--out', scratch + '/copy'])",
    "read_messages": "for m in read_messages(bag, decode=False): pass",
    "read_messages allow_truncated": "for m in read_messages(bag, decode=False, "
                                     "allow_truncated=True): pass",
    "load_flight_log": "load_flight_log(bag)",
    "indexed_messages": "for f in sorted(Path(bag).glob('*.mcap')):\n"
                        "    for m in indexed_messages(f, ['/wing/acceleration']) or []: pass",
    "bag_player source": "source = BagSource(bag)\n"
                         "for m in source.messages(list(source.topics)): pass\n"
                         "assert source.complete or source.read_problems",
}

_CHILD = """\
import io, json, resource, sys, tempfile, warnings
from contextlib import redirect_stderr
from pathlib import Path
cap, sim = int(sys.argv[1]), sys.argv[2]
if cap:
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
sys.path.insert(0, sim)
warnings.simplefilter("ignore")
from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.indexed_read import indexed_messages
from aero_dva.bag.reader import read_messages
from aero_dva_sim.bag_source import BagSource
from dva_offline.cli import main
from dva_offline.cli_failures import is_input_error
for task in sys.stdin:
    reader, bag, program = json.loads(task)
    scratch = tempfile.mkdtemp()
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # resets VmHWM: each task's own peak
    err = io.StringIO()
    code = 0
    try:
        with redirect_stderr(err):
            exec(program)
        outcome = "read" if code in (0, 1, 3) else "refused" if code == 2 else "crashed"
    except MemoryError:
        outcome = "memory"
    except Exception as exc:
        outcome = "refused" if is_input_error(exc) else "crashed"
        print(f"{type(exc).__name__}: {exc}", file=err)
    hwm = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM"))
    lines = err.getvalue().strip().splitlines()
    print(json.dumps([reader, bag, outcome, lines[-1] if lines else "", hwm * 1024]),
          flush=True)
"""


def run_capped(tasks: list[tuple[str, Path]], cap: int, timeout: float = 1800.0
               ) -> list[ReaderRun]:
    """Run each ``(reader, bag)`` of ``tasks`` (:data:`READERS`) in one child process limited
    to ``cap`` bytes of address space (0: no cap), one after the other; a child that dies is
    reported as "crashed" for the tasks it did not finish."""
    sim = Path(__file__).resolve().parents[2] / "ros_ws" / "src" / "aero_dva_sim"
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    lines = "".join(json.dumps([r, str(b), READERS[r]]) + "\n" for r, b in tasks)
    result = subprocess.run([sys.executable, "-c", _CHILD, str(cap), str(sim)], input=lines,
                            capture_output=True, text=True, env=env, timeout=timeout)
    runs = [ReaderRun(*json.loads(line)) for line in result.stdout.splitlines()
            if line.startswith("[")]
    tail = (result.stderr.strip().splitlines() or [f"exit {result.returncode}"])[-1]
    runs += [ReaderRun(r, str(b), "crashed", tail, -1) for r, b in tasks[len(runs):]]
    return runs
