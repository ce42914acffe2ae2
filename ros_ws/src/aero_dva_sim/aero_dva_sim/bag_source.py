"""What the bag player reads from a bag, in one small adapter over the domain's bag reader.

Everything the player needs from a bag goes through here: the topics with their types, counts
and recorded QoS (``offered_qos_profiles`` of ``metadata.yaml``), the bag's start time, and the
messages in log-time order as raw CDR bytes. The reading itself is
:func:`aero_dva.bag.reader.read_messages` (``decode=False``) and
:func:`~aero_dva.bag.reader.bag_topics`; switching to another reader changes only this module.

A bag that cannot be read whole (no metadata.yaml, a file cut short, a chunk that fails its
CRC) is read allowing damage: every chunk whose CRC holds is played, and
:attr:`BagSource.damage` says what was skipped.
"""
from __future__ import annotations

import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import yaml

from aero_dva.bag.reader import BagReadError, bag_topics, read_messages

__all__ = ["BagReadError", "BagSource", "BagTopic", "RecordedQos"]

_RELIABILITY = {1: "reliable", 2: "best_effort"}  # rmw enums as rosbag2 stores them
_DURABILITY = {1: "transient_local", 2: "volatile"}
_HISTORY = {1: "keep_last", 2: "keep_all"}


@dataclass(frozen=True)
class RecordedQos:
    """The QoS a topic's publishers offered when recorded (what a player offers again).

    ``reliability`` is "reliable" unless a publisher was best effort; ``durability`` is
    "transient_local" only if every publisher was; ``depth`` is the largest keep-last depth
    (0 when the history was not known), as rosbag2 adapts several publishers into one.
    """

    reliability: str = "reliable"
    durability: str = "volatile"
    depth: int = 0
    known: bool = False

    @classmethod
    def from_yaml(cls, text: str | None) -> RecordedQos:
        try:
            profiles = yaml.safe_load(text) if text else None
        except yaml.YAMLError:
            profiles = None
        if not isinstance(profiles, list) or not profiles:
            return cls()
        try:
            reliability = {_RELIABILITY.get(int(p.get("reliability", 0)), "reliable")
                           for p in profiles}
            durability = {_DURABILITY.get(int(p.get("durability", 0)), "volatile")
                          for p in profiles}
            depth = max((int(p.get("depth", 0)) for p in profiles
                         if _HISTORY.get(int(p.get("history", 0))) == "keep_last"), default=0)
        except (AttributeError, TypeError, ValueError):
            return cls()
        return cls(
            reliability="best_effort" if "best_effort" in reliability else "reliable",
            durability="transient_local" if durability == {"transient_local"} else "volatile",
            depth=depth,
            known=True,
        )


@dataclass(frozen=True)
class BagTopic:
    """A topic of the bag: fully qualified name, ``pkg/msg/Type``, message count, QoS."""

    name: str
    type_name: str
    message_count: int
    qos: RecordedQos


class BagSource:
    """A bag opened for playing.

    Parameters
    ----------
    path : path-like
        Bag directory (with ``metadata.yaml``; split bags included) or one MCAP file.

    Attributes
    ----------
    topics : dict of str to BagTopic
    start_ns : int or None
        [ns] the bag's first log time (metadata.yaml), None if not recorded there.
    damage : str or None
        Why the bag could not be read whole (it then plays every chunk whose CRC holds).

    Raises
    ------
    BagReadError
        The bag does not exist or cannot be read at all.
    """

    def __init__(self, path) -> None:
        self.path = Path(path)
        self.damage: str | None = None
        try:
            found = bag_topics(self.path)
        except BagReadError as exc:
            if not self.path.exists():
                raise
            with warnings.catch_warnings(record=True) as caught:  # where the damage starts
                warnings.simplefilter("always", RuntimeWarning)
                found = bag_topics(self.path, allow_truncated=True)  # raises if nothing usable
            self.damage = "; ".join([str(exc), *(str(w.message) for w in caught)])
        metadata = self._metadata()
        qos = {}
        for entry in metadata.get("topics_with_message_count") or []:
            meta = entry.get("topic_metadata", {}) if isinstance(entry, dict) else {}
            if "name" in meta:
                qos[meta["name"]] = RecordedQos.from_yaml(meta.get("offered_qos_profiles"))
        self.topics = {
            name: BagTopic(name, info.type_name, info.message_count,
                           qos.get(name, RecordedQos()))
            for name, info in found.items()
        }
        start = (metadata.get("starting_time") or {}).get("nanoseconds_since_epoch")
        self.start_ns = int(start) if isinstance(start, int) and not self.damage else None
        self.read_problems: list[str] = []  # damage met while reading (also in damage)
        self.indexed = self.damage is None  # topic counts from an index, not from a scan
        self.complete = False

    def _metadata(self) -> dict:
        meta = self.path / "metadata.yaml"
        if not meta.is_file():
            return {}
        try:
            info = yaml.safe_load(meta.read_text(encoding="utf-8"))
            return info.get("rosbag2_bagfile_information") or {}
        except (OSError, yaml.YAMLError, AttributeError):
            return {}

    def promised(self, topics: Iterable[str]) -> int:
        """Messages of ``topics`` the bag's index promises (what reads, if it has none)."""
        return sum(self.topics[t].message_count for t in topics)

    def messages(self, topics: Iterable[str]) -> Iterator[tuple[int, str, bytes]]:
        """(log time [ns], topic, serialized CDR) of ``topics`` in log-time order (per file).

        A chunk that fails its CRC is skipped: the reading goes on with every chunk whose CRC
        holds (after the messages already given). What was skipped is appended to
        :attr:`read_problems` (and :attr:`damage` set) instead of raising;
        :attr:`complete` says whether the bag was read to its end.
        """
        topics = list(topics)
        allow = self.damage is not None
        self.complete = False
        records = self._open(topics, allow)
        given_t, given_at_t = None, 0  # the last log time given, and how many at it
        skip = None  # after switching readers: (log time, count at it) already given
        while True:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", RuntimeWarning)
                try:
                    record = next(records)
                except StopIteration:
                    record = None
                except BagReadError as exc:
                    self._note(str(exc))
                    if allow:
                        return
                    allow, skip = True, (given_t, given_at_t)
                    records = self._open(topics, allow)
                    continue
            for warning in caught:
                self._note(str(warning.message))
            if record is None:
                self.complete = True
                return
            t = record.log_time_ns
            if skip is not None and skip[0] is not None:
                if t < skip[0] or (t == skip[0] and skip[1] > 0):
                    skip = (skip[0], skip[1] - (t == skip[0]))
                    continue
                skip = None
            given_at_t = given_at_t + 1 if t == given_t else 1
            given_t = t
            yield t, record.topic, bytes(record.message)

    def _open(self, topics: list[str], allow_truncated: bool):
        with warnings.catch_warnings():  # the damage was noted when the bag was opened
            warnings.simplefilter("ignore", RuntimeWarning)
            return read_messages(self.path, topics, decode=False,
                                 allow_truncated=allow_truncated)

    def _note(self, text: str) -> None:
        self.read_problems.append(text)
        self.damage = self.damage or text
