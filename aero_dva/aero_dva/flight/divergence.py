"""Where a ramp flight diverged: the divergence airspeed read off a simulated or logged flight.

:func:`ramp_airspeed` is the study's flight (0.8 -> 1.2 U_cr in 30 s) and
:func:`divergence_airspeed` reads off where a flight diverged
(:func:`divergence_airspeed_sliding`: the same with windows sliding by a hop, for finer
steps of U_div). The definition:

    *A flight has diverged at airspeed* ``U_d`` *when the RMS of the leading-edge displacement
    over consecutive windows (1 s by default) exceeds* ``factor`` *(10) times its median over the
    first* ``baseline_fraction`` *(10 %) of the flight, and stays above it for every later
    window;* ``U_d`` *is the airspeed at the end of the first such window.* A flight that never
    does gives NaN. This is insensitive to single random bursts (they do not stay above) and to
    the excitation level (the threshold is relative), and it lags the eigenvalue critical
    airspeed by the time the growing mode needs to grow tenfold, as the study's simulated
    divergence airspeeds do (Zhang (2006) sections 6.2.4, 6.3.3). Pure numerics.
"""

from __future__ import annotations

import math

import numpy as np

from aero_dva.wing.checks import positive, real_array

__all__ = ["divergence_airspeed", "divergence_airspeed_sliding", "ramp_airspeed"]


def ramp_airspeed(critical_airspeed: float, start: float = 0.8, stop: float = 1.2,
                  duration: float = 30.0, sample_rate: float = 1000.0) -> np.ndarray:
    """Linear airspeed ramp [m/s] from ``start`` to ``stop`` times ``critical_airspeed``.

    The study's flight (Zhang (2006) sections 6.1.3, 6.2.4, 6.3.3, 7.1.2): 0.8 -> 1.2 U_cr in 30 s.
    Returns shape (round(duration * sample_rate),).
    """
    u_cr = positive(critical_airspeed, "critical_airspeed")
    n = int(round(positive(duration, "duration") * positive(sample_rate, "sample_rate")))
    return u_cr * (start + (stop - start) * np.arange(n) / n)


def divergence_airspeed(airspeed, response, sample_rate: float = 1000.0, window: float = 1.0,
                        factor: float = 10.0, baseline_fraction: float = 0.1):
    """Airspeed at which a ramp flight diverged (definition in the module docstring).

    Parameters
    ----------
    airspeed : array_like, shape (N,) or (F, N)
        [m/s]
    response : array_like, shape (N,) or (F, N)
        The leading-edge displacement [m] (any response works; the test is relative).
    sample_rate : float
        [Hz]
    window : float
        [s] RMS window.
    factor : float
        Threshold relative to the baseline RMS, > 1.
    baseline_fraction : float
        Leading fraction of the flight used for the baseline, in (0, 1).

    Returns
    -------
    float or ndarray (F,)
        [m/s], NaN where the flight did not diverge.
    """
    x = real_array(response, "response", allow_inf=True)
    x = np.where(np.isfinite(x), x, np.finfo(float).max ** 0.25)
    single = x.ndim == 1
    x = np.atleast_2d(x)
    speed = np.broadcast_to(real_array(airspeed, "airspeed"), x.shape)
    if positive(factor, "factor") <= 1:
        raise ValueError("factor must be > 1")
    if not 0 < baseline_fraction < 1:
        raise ValueError("baseline_fraction must be in (0, 1)")
    w = int(round(positive(window, "window") * positive(sample_rate, "sample_rate")))
    nw = x.shape[1] // w
    if w < 1 or nw < 3:
        raise ValueError("the flight must span at least three windows")
    rms = np.sqrt(np.mean(x[:, : nw * w].reshape(x.shape[0], nw, w) ** 2, axis=2))
    nb = max(1, int(baseline_fraction * nw))
    base = np.median(rms[:, :nb], axis=1)
    above = rms > factor * base[:, None]
    # "stays above": all windows from i onward are above.
    stays = np.flip(np.logical_and.accumulate(np.flip(above, axis=1), axis=1), axis=1)
    out = np.full(x.shape[0], np.nan)
    for i in range(x.shape[0]):
        idx = np.flatnonzero(stays[i])
        if idx.size:
            out[i] = speed[i, (idx[0] + 1) * w - 1]
    return float(out[0]) if single else out


def divergence_airspeed_sliding(airspeed, response, sample_rate: float, window: float = 1.0,
                                hop: float = 0.05, factor: float = 10.0,
                                baseline_fraction: float = 0.1) -> float:
    """:func:`divergence_airspeed` with windows sliding by ``hop``.

    Same definition (RMS of the response over ``window`` seconds above ``factor`` times the
    median RMS of the non-overlapping windows of the first ``baseline_fraction`` of the flight,
    and above for every later window; U at the end of the first such window), but the windows
    start every ``hop`` seconds instead of every ``window``: on the study's ramp (0.4 U_cr in
    30 s) 1 s windows quantise U_div / U_cr to steps of 0.013, coarser than the differences
    between controllers. With ``hop == window`` the result equals the original exactly.

    Parameters
    ----------
    airspeed, response : (n,) [m/s] and the leading-edge displacement [m] (NaN-free)
    sample_rate : float [Hz]

    Returns
    -------
    float
        [m/s], NaN if the flight never diverged.
    """
    u = np.asarray(airspeed, dtype=float)
    x = np.asarray(response, dtype=float)
    if u.shape != x.shape or u.ndim != 1:
        raise ValueError(f"airspeed and response must be 1-D of one length, got {u.shape} "
                         f"and {x.shape}")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(x))):
        raise ValueError("airspeed and response must be finite (cut missing samples first)")
    w = int(round(window * sample_rate))
    h = int(round(hop * sample_rate))
    if w < 1 or h < 1 or h > w:
        raise ValueError(f"need 0 < hop <= window at {sample_rate} Hz, got window {window}, "
                         f"hop {hop}")
    if not 0 < baseline_fraction < 1 or factor <= 1:
        raise ValueError("need 0 < baseline_fraction < 1 and factor > 1")
    nw = x.size // w
    if nw < 3:
        raise ValueError("the flight must span at least three windows")
    blocks = np.sqrt(np.mean(x[:nw * w].reshape(nw, w) ** 2, axis=1))
    base = np.median(blocks[:max(1, int(baseline_fraction * nw))])
    # Sliding windows over the same span as the original's windows (the first nw * w samples).
    power = np.concatenate(([0.0], np.cumsum(x[:nw * w] ** 2)))
    starts = np.arange(0, nw * w - w + 1, h)
    rms = np.sqrt((power[starts + w] - power[starts]) / w)
    above = rms > factor * base
    stays = np.flip(np.logical_and.accumulate(np.flip(above)))
    idx = np.flatnonzero(stays)
    return float(u[starts[idx[0]] + w - 1]) if idx.size else math.nan
