"""What the damper flew with, block by block: a controller's c2, the start-up c2 or the fallback.

A flight summary that names a controller must say how much of the flight that controller really
flew: a loaded machine can leave the damper on its start-up value for a whole flight (no command
ever arrived) or on the stale fallback for part of it, and the divergence and RMS figures are
then those of another damper. :class:`AppliedControl` counts the blocks by the source of the c2
they were flown with; :func:`control_problem` says when a flight must not be reported as
controlled.
"""
from __future__ import annotations

from dataclasses import dataclass

STARTUP_SOURCE = "initial"  # DamperSnapshot.source before the first accepted command
FALLBACK_SOURCE = "fallback"  # ... while commands are stale


@dataclass
class AppliedControl:
    """Blocks flown, by the source of their c2 (the damper's snapshot at the block's start)."""

    blocks: int = 0
    startup: int = 0
    fallback: int = 0

    def count(self, source: str) -> None:
        """One block flown with a c2 from ``source`` (a DamperSnapshot.source)."""
        self.blocks += 1
        if source == STARTUP_SOURCE:
            self.startup += 1
        elif source == FALLBACK_SOURCE:
            self.fallback += 1

    @property
    def controlled(self) -> int:
        return self.blocks - self.startup - self.fallback

    def values(self) -> dict:
        """The counts for the simulator's end-of-flight summary (and so for the bag)."""
        return {"blocks": self.blocks, "blocks_controlled": self.controlled,
                "blocks_startup": self.startup, "blocks_fallback": self.fallback}


def control_problem(blocks: int, controlled: int, fallback: int, max_fallback_share: float
                    ) -> str | None:
    """Why a flight must not be reported as flown by its controller, or None.

    ``blocks`` flown, ``controlled`` of them on a controller's c2, ``fallback`` on the stale
    fallback; the flight fails when no block was controlled, or when more than
    ``max_fallback_share`` (0..1) of the blocks ran on the fallback.
    """
    if blocks <= 0:
        return "no block was flown"
    if controlled <= 0:
        return (f"the controller never acted: all {blocks} blocks were flown on the start-up "
                "or fallback c2")
    share = fallback / blocks
    if share > max_fallback_share:
        return (f"{fallback} of {blocks} blocks ({share:.1%}) were flown on the fallback c2, "
                f"more than the {max_fallback_share:.1%} allowed")
    return None
