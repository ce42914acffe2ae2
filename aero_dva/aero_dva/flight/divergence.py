"""Where a ramp flight diverged: the one divergence airspeed every output of the project reads.

:func:`ramp_airspeed` is the study's flight (0.8 -> 1.2 U_cr in 30 s) and
:func:`divergence_airspeed` the detector of its divergence, the only one: ``run_flight``'s
summary, ``dva evaluate`` (every controller), ``dva report`` (its table and the plots' marker),
``dva switching`` and ``dva wing simulate`` all call it. The definition:

    *A flight has diverged at airspeed* ``U_d`` *when the RMS of the leading-edge displacement
    over 1 s windows, starting every 0.05 s, exceeds 10 times its median over the consecutive
    1 s windows of the first 10 % of the flight, and stays above it for every later window;*
    ``U_d`` *is the airspeed at the end of the first such window.* A flight that never does
    gives NaN.

This is insensitive to single random bursts (they do not stay above) and to the excitation
level (the threshold is relative), and it lags the eigenvalue critical airspeed by the time the
growing mode needs to grow tenfold, as the study's simulated divergence airspeeds do (Zhang
(2006) sections 6.2.4, 6.3.3). The windows slide because on the study's ramp (0.4 U_cr in
30 s) whole 1 s windows would quantise U_d / U_cr to steps of 0.013, coarser than the
differences between controllers. Where a simulator stopped a flight (the leading edge beyond
half the chord) is another thing: the end of the flight, after its divergence. Pure numerics.
"""

from __future__ import annotations

import math

import numpy as np

from aero_dva.wing.checks import positive, real_array

__all__ = ["BASELINE_FRACTION", "DETECTOR", "FACTOR", "HOP", "STOP_PREFIX", "WINDOW",
           "divergence_airspeed", "ramp_airspeed", "stop_message"]


def ramp_airspeed(critical_airspeed: float, start: float = 0.8, stop: float = 1.2,
                  duration: float = 30.0, sample_rate: float = 1000.0) -> np.ndarray:
    """Linear airspeed ramp [m/s] from ``start`` to ``stop`` times ``critical_airspeed``.

    The study's flight (Zhang (2006) sections 6.1.3, 6.2.4, 6.3.3, 7.1.2): 0.8 -> 1.2 U_cr in 30 s.
    Returns shape (round(duration * sample_rate),).
    """
    u_cr = positive(critical_airspeed, "critical_airspeed")
    n = int(round(positive(duration, "duration") * positive(sample_rate, "sample_rate")))
    return u_cr * (start + (stop - start) * np.arange(n) / n)


#: The detector's constants: 1 s windows every 0.05 s, 10x the median of the first 10 %.
WINDOW = 1.0  # [s]
HOP = 0.05  # [s]
FACTOR = 10.0
BASELINE_FRACTION = 0.1
#: The detector in words, stored with records that are kept and resumed: a record read with
#: another detector is not mixed with these.
DETECTOR = (f"RMS over {WINDOW:g} s windows every {HOP:g} s above {FACTOR:g}x the median of "
            f"the first {BASELINE_FRACTION:.0%} of the flight, for good")


def divergence_airspeed(airspeed, response, sample_rate: float = 1000.0):
    """Airspeed at which a ramp flight diverged (definition in the module docstring).

    Parameters
    ----------
    airspeed : array_like, shape (N,) or (F, N)
        [m/s]
    response : array_like, shape (N,) or (F, N)
        The leading-edge displacement [m] (any response works; the test is relative).
        Non-finite samples (a blown-up flight) count as far above any threshold.
    sample_rate : float
        [Hz]

    Returns
    -------
    float or ndarray (F,)
        [m/s], NaN where the flight did not diverge. ValueError for a flight shorter than three
        windows.
    """
    x = real_array(response, "response", allow_inf=True)
    single = x.ndim == 1
    x = np.atleast_2d(x)
    speed = np.broadcast_to(real_array(airspeed, "airspeed"), x.shape)
    rate = positive(sample_rate, "sample_rate")
    w, h = int(round(WINDOW * rate)), int(round(HOP * rate))
    if w < 1 or h < 1:
        raise ValueError(f"{rate:g} Hz is too slow for {WINDOW:g} s windows every {HOP:g} s")
    if x.shape[1] // w < 3:
        raise ValueError("the flight must span at least three windows")
    out = np.array([_diverged(speed[i], x[i], w, h) for i in range(x.shape[0])])
    return float(out[0]) if single else out


def _diverged(u, x, w: int, h: int) -> float:
    x = np.where(np.isfinite(x), x, np.finfo(float).max ** 0.25)
    nw = x.size // w
    blocks = np.sqrt(np.mean(x[:nw * w].reshape(nw, w) ** 2, axis=1))
    base = np.median(blocks[:max(1, int(BASELINE_FRACTION * nw))])
    # Sliding windows over the span of the whole windows (the first nw * w samples).
    power = np.concatenate(([0.0], np.cumsum(x[:nw * w] ** 2)))
    starts = np.arange(0, nw * w - w + 1, h)
    rms = np.sqrt((power[starts + w] - power[starts]) / w)
    above = rms > FACTOR * base
    stays = np.flip(np.logical_and.accumulate(np.flip(above)))  # above from there on
    idx = np.flatnonzero(stays)
    return float(u[starts[idx[0]] + w - 1]) if idx.size else math.nan


#: How the simulator's final status begins when it stopped a flight (:func:`stop_message`).
STOP_PREFIX = "flight stopped at U = "


def stop_message(airspeed: float, critical_airspeed: float, time: float) -> str:
    """The simulator's final status when it stops a flight whose leading edge passed its
    divergence limit (half the chord by default, outside the linear model). That airspeed is
    where the flight ended, after the divergence, and is named so: the divergence airspeed is
    :func:`divergence_airspeed`'s."""
    return (f"{STOP_PREFIX}{airspeed:.2f} m/s (U/U_cr = {airspeed / critical_airspeed:.3f}, "
            f"t = {time:.3f} s): the leading edge passed the simulator's limit after the wing "
            "diverged")
