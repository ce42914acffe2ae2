"""What the ROS 2 supervisor of a per-sample c2 law decides, without ROS (pure logic).

The law runs in the damper's own controller, every sample; a node only supervises it. Each
command period the supervisor either arms the law (a ``"switching"`` command whose c2 is the
safe constant the damper holds if the law cannot run) or holds the safe constant c2 itself
(a ``"switching_fallback"`` command), and says why:

- the gains file is invalid (the law is never armed);
- a burst: a leading-edge displacement beyond the peak limit (the practical boundary of
  :mod:`aero_dva.flight.peak_limit`). The law is disarmed and stays so for ``rearm_after``
  seconds of sim time after the last sample over the limit (inf: for the rest of the flight).

Stale commands are the damper's to catch: when this node falls silent the damper's timeout
applies its fallback c2 and ends the law (:class:`~aero_dva.flight.damper.DamperModel`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.control.law_defaults import FALLBACK_SOURCE
from aero_dva.flight.damper import SWITCHING_SOURCE

__all__ = ["FALLBACK_SOURCE", "SupervisorCommand", "SwitchingSupervisor"]



@dataclass(frozen=True)
class SupervisorCommand:
    """One command: c2 [N s/m], the command's source, and why the law is not armed (None when
    it is)."""

    damping: float
    source: str
    reason: str | None


class SwitchingSupervisor:
    """Arm the law unless the gains are invalid or a burst is recent (module docstring).

    Parameters
    ----------
    safe_damping : float
        [N s/m] the constant c2 held when the law is not armed, >= 0.
    peak_limit : float
        [m] leading-edge displacement that counts as a burst, > 0.
    rearm_after : float
        [s] sim time after a burst's last sample before the law is armed again (inf: never).
    gains_problem : str or None
        Why the gains cannot be used (None: they can).
    source, fallback_source : str
        The commands' sources that arm the law and that hold the safe c2 (the per-sample
        law's, e.g. ``"clipped_optimal"`` and ``"clipped_optimal_fallback"``).
    """

    def __init__(self, safe_damping: float, peak_limit: float, rearm_after: float,
                 gains_problem: str | None = None, source: str = SWITCHING_SOURCE,
                 fallback_source: str = FALLBACK_SOURCE):
        if not (math.isfinite(safe_damping) and safe_damping >= 0.0):
            raise ValueError(f"safe_damping must be finite and >= 0 N s/m, got {safe_damping}")
        if not (math.isfinite(peak_limit) and peak_limit > 0.0):
            raise ValueError(f"peak_limit must be finite and > 0 m, got {peak_limit}")
        if not rearm_after >= 0.0:
            raise ValueError(f"rearm_after must be >= 0 s, got {rearm_after}")
        self.safe_damping = float(safe_damping)
        self.peak_limit = float(peak_limit)
        self.rearm_after = float(rearm_after)
        self.gains_problem = gains_problem
        self.source, self.fallback_source = source, fallback_source
        self.bursts = 0  # blocks with a sample over the limit
        self._burst_until = -math.inf  # [s] sim time the law stays disarmed until
        self.last_burst = ""  # the last burst's description

    def observe(self, t0: float, sample_rate: float, leading_edge) -> str | None:
        """Read one block of leading-edge samples starting at sim time ``t0``; returns the
        burst's description when this block has a sample over the limit (else None)."""
        le = np.asarray(leading_edge, dtype=float)
        over = np.flatnonzero(~(np.abs(le) <= self.peak_limit))  # NaN counts as over
        if over.size == 0:
            return None
        self.bursts += 1
        peak = float(np.nanmax(np.abs(le))) if np.any(np.isfinite(le)) else math.inf
        last = t0 + over[-1] / sample_rate
        self._burst_until = max(self._burst_until, last + self.rearm_after)
        self.last_burst = (f"|leading edge| reached {peak:.4g} m > peak_limit "
                           f"{self.peak_limit:g} m at t = {t0 + over[0] / sample_rate:.3f} s")
        return self.last_burst

    def command(self, now: float) -> SupervisorCommand:
        """The command to send at sim time ``now``."""
        if self.gains_problem is not None:
            return SupervisorCommand(self.safe_damping, self.fallback_source,
                                     self.gains_problem)
        if now <= self._burst_until:
            return SupervisorCommand(self.safe_damping, self.fallback_source,
                                     f"burst detector: |leading edge| over the peak limit of "
                                     f"{self.peak_limit:g} m within the last "
                                     f"{self.rearm_after:g} s")
        return SupervisorCommand(self.safe_damping, self.source, None)
