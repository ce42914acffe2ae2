"""What the bag player reads: split bags in order, recorded QoS, a cut bag up to its damage."""
from __future__ import annotations

import shutil

import pytest
import yaml

pytest.importorskip("aero_dva_sim", reason="needs the built workspace (source scripts/env.sh)")

from aero_dva.bag.writer import BagWriter, bag_metadata, qos_profile_yaml  # noqa: E402
from aero_dva_sim.bag_source import BagSource, RecordedQos  # noqa: E402

LATCHED = qos_profile_yaml("best_effort", "transient_local", depth=7)


def _part(path, start: int, n: int) -> None:
    with BagWriter(path) as writer:
        writer.add_topic("/a", "std_msgs/msg/String", LATCHED)
        writer.add_topic("/b", "std_msgs/msg/String")
        for i in range(start, start + n):
            writer.write("/a" if i % 2 else "/b", {"data": f"m{i}"}, 1000 + i)
            if i % 50 == 49:
                writer.flush()  # a chunk of 50, as the recorder flushes every second


def test_a_split_bag_plays_file_after_file_with_its_recorded_qos(tmp_path):
    bag = tmp_path / "split"
    bag.mkdir()
    for index, start in enumerate((0, 10)):
        _part(tmp_path / f"part{index}", start, 10)
        shutil.move(next((tmp_path / f"part{index}").glob("*.mcap")), bag / f"split_{index}.mcap")
    meta = bag_metadata("split_0.mcap", [("/a", "std_msgs/msg/String", LATCHED, 10),
                                         ("/b", "std_msgs/msg/String", qos_profile_yaml(), 10)],
                        1000, 1019, "jazzy",
                        files=[("split_0.mcap", 1000, 9, 10), ("split_1.mcap", 1010, 9, 10)])
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": meta}))
    source = BagSource(bag)
    assert source.damage is None and source.start_ns == 1000
    assert {n: t.message_count for n, t in source.topics.items()} == {"/a": 10, "/b": 10}
    assert source.topics["/a"].qos == RecordedQos("best_effort", "transient_local", 7, True)
    assert source.topics["/b"].qos.reliability == "reliable"
    times = [t for t, _, _ in source.messages(["/a", "/b"])]
    assert times == list(range(1000, 1020))


def test_a_cut_bag_plays_up_to_its_damage(tmp_path):
    _part(tmp_path / "whole", 0, 400)
    cut = tmp_path / "cut"
    shutil.copytree(tmp_path / "whole", cut)
    (cut / "metadata.yaml").unlink()
    mcap = next(cut.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])  # footer, summary and half the chunks gone
    source = BagSource(cut)
    assert source.damage and "metadata.yaml" in source.damage
    assert source.topics["/a"].qos == RecordedQos()  # no metadata: the defaults
    got = [t for t, _, _ in source.messages(["/a", "/b"])]
    assert 0 < len(got) < 400 and got == list(range(1000, 1000 + len(got)))


def test_qos_text_that_is_not_a_profile_list_gives_the_defaults():
    assert RecordedQos.from_yaml("") == RecordedQos.from_yaml("[: bad") == RecordedQos()
    assert RecordedQos.from_yaml("- history: 0\n  depth: 0\n  reliability: 2\n").reliability \
        == "best_effort"


def _flip_in_chunk(bag, k: int) -> int:
    """Flip one bit in the middle of the k-th chunk (file order) of a closed bag; its
    message count."""
    from mcap.reader import make_reader

    mcap = next(bag.glob("*.mcap"))
    with open(mcap, "rb") as stream:
        summary = make_reader(stream).get_summary()
    index = sorted(summary.chunk_indexes, key=lambda i: i.chunk_start_offset)[k]
    data = bytearray(mcap.read_bytes())
    data[index.chunk_start_offset + index.chunk_length // 2] ^= 0x04
    mcap.write_bytes(bytes(data))
    return sum(int.from_bytes(data[at + 11:at + 15], "little") // 16
               for at in index.message_index_offsets.values())


def test_a_closed_bag_with_a_failing_chunk_plays_every_other_chunk(tmp_path):
    _part(tmp_path / "whole", 0, 400)  # 8 chunks of 50
    flipped = tmp_path / "flipped"
    shutil.copytree(tmp_path / "whole", flipped)
    lost = _flip_in_chunk(flipped, 2)
    source = BagSource(flipped)
    assert source.damage is None and source.indexed  # the summary is intact
    got = [t for t, _, _ in source.messages(["/a", "/b"])]
    assert lost == 50 and len(got) == 400 - lost and source.complete
    assert got == [t for t in range(1000, 1400) if not 1100 <= t < 1150]
    assert source.damage and "CRC" in source.read_problems[0]
    assert source.promised(["/a", "/b"]) == 400
