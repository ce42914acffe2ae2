"""The small store of values kept between calls (the batch simulator's wings, the switched
flight's maps)."""
import pytest

from aero_dva.flight.kept import KeptByKey


def test_the_least_recently_used_value_goes_first_and_the_first_kept_one_wins():
    kept = KeptByKey(2)
    assert kept.get("a") is None and kept.latest() is None
    first = [1]
    assert kept.keep("a", first) is first
    assert kept.keep("a", [2]) is first  # built twice (two threads): one is shared
    kept.keep("b", [3])
    assert kept.get("a") is first  # now the most recent
    kept.keep("c", [4])  # drops "b", the least recently used
    assert kept.get("b") is None and kept.latest() == [4] and len(kept) == 2
    with pytest.raises(TypeError):
        kept.get(["unhashable"])
    kept.clear()
    assert len(kept) == 0
    with pytest.raises(ValueError, match="size must be >= 1"):
        KeptByKey(0)
