"""Plausibility before a name: a candidate whose fitted parameters mean nothing physically
is listed as ``implausible: reason`` and never added (the ranges are in docs/discrepancy.md).

Checked here, for every candidate that could be added (significant by the loop's F test
and dBIC rule):

* ``sensor_delay``: a delay is identified by the *slope* of the phase it adds across the
  band; a constant phase (an instrument's phase, a complex modal constant, a phase wrap in a
  narrow band) is no delay. A constant phase offset in place of the delay (one parameter,
  like the delay; solved in closed form with every other parameter at the delay fit's
  values, then, if that is not enough, fitted with them all as the delay was) must leave a
  training residual power larger than the delay's by the F test's margin, chi^2_1 at
  1 - significance times the fit's residual variance. Otherwise the delay
  is implausible, and its standard error says what the data leave of it: the slope's own
  standard error with a phase offset fitted beside it, combined with how far the delay
  moves when the offset is there (a phase wrap: the whole delay).
* laws of a covariate effect (:class:`~.laws.LawModel`): every factor (stiffness, damping,
  modal constant, shift factor) positive and finite over the measured range.
* the domain's own ranges (``domain.implausible(spec, fit)``, e.g. the FRF domain's shift
  no larger than its sweeps' overlap can determine).

Masses, stiffnesses, dampers and foundation parameters keep the right sign by their bounds
(log-scaled, or a fixture mass above -0.9 m), so no fit can leave their range.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import stats

from dva_offline.discrepancy.fitting import (
    HoldoutSplit,
    ModelFit,
    ModelSpec,
    Observations,
    ParamSpec,
    fit_model,
)


def _offset_spec(spec: ModelSpec, values: np.ndarray, phi: float) -> ModelSpec:
    """``spec`` with a constant phase in place of its delay (the last parameter), started at
    the delay fit's other values and the phase ``phi``."""
    def predict(v):
        v = np.asarray(v, float)
        z = v.copy()
        z[-1] = 0.0
        return spec.predict(z) * np.exp(1j * v[-1])

    def rows(vs):
        vs = np.asarray(vs, float)
        z = vs.copy()
        z[:, -1] = 0.0
        return spec.batch_predict(z) * np.exp(1j * vs[:, -1, None])

    params = tuple(replace(p, initial=float(np.clip(v, p.lower, p.upper)))
                   for p, v in zip(spec.params[:-1], values[:-1]))
    phase = ParamSpec("phase", "rad", float(np.angle(np.exp(1j * phi))), -np.pi, np.pi)
    return ModelSpec(spec.name + " (a constant phase for the delay)", None, (*params, phase),
                     0, predict, batch_predict=rows if spec.batch_predict is not None else None)


def delay_check(spec: ModelSpec, fit: ModelFit, obs: Observations, split: HoldoutSplit,
                significance: float = 1e-3) -> tuple[str, ModelFit]:
    """('' or why the delay is implausible, the fit with the delay's standard error from
    the fit with a phase offset beside it when implausible)."""
    train = split.train
    values = np.array([e.value for e in fit.estimates])
    tau = values[-1]
    zero = values.copy()
    zero[-1] = 0.0
    with np.errstate(all="ignore"):
        m0 = spec.predict(zero)[train]
    y, w = obs.values[train], obs.weights[train]
    omega = 2 * np.pi * obs.axis[train]
    if not np.all(np.isfinite(m0)) or tau == 0:
        return "", fit
    a, b = w * m0, w * y
    s_offset = float(np.sum(np.abs(a) ** 2) + np.sum(np.abs(b) ** 2)
                     - 2 * np.abs(np.sum(a * np.conj(b))))
    dof = 2 * fit.n_train - fit.n_params
    if dof <= 0:
        return "", fit
    s2 = fit.rss_train / dof
    margin = float(stats.chi2.ppf(1 - significance, 1)) * s2
    if s_offset - fit.rss_train > margin:
        # the offset with every other parameter refitted too, as the delay's were
        phi = float(np.angle(np.sum(np.conj(a) * b)))
        try:
            again = fit_model(_offset_spec(spec, values, phi), obs, split)
            s_offset = min(s_offset, again.rss_train)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            pass
        if s_offset - fit.rss_train > margin:
            return "", fit
    # the delay's phase slope (its sign as the model applies it) and its standard error
    # with a constant phase beside it: psi = phi + beta omega, Gauss-Newton from the fit
    pred = w * fit.prediction[train]
    beta = min((tau, -tau), key=lambda bt: float(np.sum(np.abs(a * np.exp(1j * bt * omega)
                                                                 - pred) ** 2)))
    sign, phi = (1.0 if beta == tau else -1.0), 0.0
    for _ in range(20):
        e = a * np.exp(1j * (phi + beta * omega))
        r = e - b
        jac = np.column_stack([1j * e, 1j * omega * e])
        jr = np.vstack([jac.real, jac.imag])
        rr = np.concatenate([r.real, r.imag])
        step = np.linalg.lstsq(jr, -rr, rcond=None)[0]
        phi, beta = phi + step[0], beta + step[1]
        if np.all(np.abs(step) < [1e-10, 1e-14]):
            break
    cov = np.linalg.pinv(jr.T @ jr) * s2
    slope_tau = sign * beta  # the delay the phase's slope alone shows
    # what the data leave of it: the slope's standard error and how far the delay moves
    # when a phase offset may be beside it (a phase wrap: the whole delay)
    se = float(np.hypot(np.sqrt(max(cov[1, 1], 0.0)), tau - slope_tau))
    est = fit.estimates[-1]
    fixed = replace(fit, estimates=fit.estimates[:-1] + (replace(est, std=max(se, est.std)),))
    f = obs.axis[train]
    why = (f"a constant phase offset fits the phase this delay corrects as well as the delay "
           f"(training residual power {s_offset:.4g} against {fit.rss_train:.4g}, margin "
           f"{margin:.2g}): the data show a phase, not a delay's slope over "
           f"{f.min():.4g}-{f.max():.4g} Hz; the delay {tau * 1e3:.4g} ms turns the phase by "
           f"{np.degrees(2 * np.pi * f.max() * abs(tau)):.0f} deg at the band's top (a phase "
           f"wrap when above 180); the phase's slope alone shows {slope_tau * 1e3:.3g} ms, "
           f"so +- {se * 1e3:.2g} ms")
    return why, fixed


def check(domain, spec: ModelSpec, fit: ModelFit, obs: Observations, split: HoldoutSplit,
          significance: float = 1e-3) -> tuple[str, ModelFit]:
    """('' or why ``fit`` is implausible, the fit as reported) for a candidate that could
    be added (module docstring)."""
    if fit.law is not None:
        why = fit.law.implausible(fit)
        if why:
            return why, fit
    if spec.effect == "sensor_delay" and spec.n_added >= 1 and spec.params[-1].unit == "s":
        why, fit = delay_check(spec, fit, obs, split, significance)
        if why:
            return why, fit
    own = getattr(domain, "implausible", None)
    if own is not None:
        why = own(spec, fit)
        if why:
            return why, fit
    return "", fit
