"""Evaluation flights of Zhang (2006) sec. 7.1.3 / 7.2.4: the numbers, without files or processes.

The study flies the ramp 0.8 -> 1.2 U_cr in 30 s under a 1 kN white aileron force, with the air
density varying as rho0 (1 + mu sin 2 pi t) (eq. 7.2), mu = 0, 0.05, 0.1, and reads off the
airspeed at which the response starts to grow quickly: one flight per case. Here every case
(controller x mu) is flown with several excitation seeds, and the divergence airspeed ratio
U_div / U_cr (U_cr: the wing without DVA at the base density) is summarised over them.

Controllers: ``none`` (the wing without DVA) and those of the controller table that fly through
the graph (:mod:`aero_dva.control.controllers`; by default ``fixed``, the Maxwell DVA with the
best constant c2, :func:`aero_dva.control.dva_design.best_fixed_damping`; ``schedule``, eq.
7.1 from the airspeed; ``rbf``, the network from the scaled spectra).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "DEFAULT_CONTROLLERS",
    "CaseStats",
    "FlightCase",
    "KeyResult",
    "aggregate",
    "case_grid",
    "compare_rbf_with_schedule",
    "evaluation_scenario",
    "graph_controllers",
    "label",
    "markdown_table",
    "parse_controllers",
    "parse_mu_list",
    "study_ratios",
]

def graph_controllers(builtin_only: bool = False) -> tuple[str, ...]:
    """``none`` and the controllers of the table that fly through the graph (block-rate and
    per-sample laws), in the table's order."""
    from aero_dva.control.controllers import BLOCK, NONE, SAMPLE, names

    return (NONE, *names((BLOCK, SAMPLE), builtin_only))


def _default_controllers() -> tuple[str, ...]:
    from aero_dva.control.controllers import BLOCK, NONE, names

    return (NONE, *names((BLOCK,), builtin_only=True))


#: What ``--graph`` flies unless told: the wing without DVA and the project's block-rate laws.
DEFAULT_CONTROLLERS = _default_controllers()


def label(controller: str) -> str:
    """A controller's label in tables and plots (its table entry's; ``none``: no DVA)."""
    from aero_dva.control.controllers import NONE, NONE_LABEL
    from aero_dva.control.controllers import controller as entry

    return NONE_LABEL if controller == NONE else entry(controller).label


def study_ratios(controller: str) -> dict[float, float]:
    """The study's single flights (U_div / U_cr) by mu: the table entry's (fig. 7.5-7.7 for the
    schedule, fig. 7.13, 7.15, 7.16 for the RBF network); without DVA the wing flutters at U_cr
    by definition (fig. 6.4); the study flies no fixed-c2 Maxwell DVA in chapter 7."""
    from aero_dva.control.controllers import NONE
    from aero_dva.control.controllers import controller as entry

    return {0.0: 1.00} if controller == NONE else dict(entry(controller).study_ratios)


@dataclass(frozen=True)
class FlightCase:
    """One evaluation flight: who controls c2, the density variation mu, the excitation seed."""

    controller: str
    mu: float
    seed: int

    def __post_init__(self):
        if self.controller not in graph_controllers():
            raise ValueError(f"controller must be one of {graph_controllers()}, got "
                             f"{self.controller!r}")
        if not (math.isfinite(self.mu) and 0.0 <= self.mu < 1.0):
            raise ValueError(f"mu must be in [0, 1) (the density must stay positive), "
                             f"got {self.mu}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")

    @property
    def case(self) -> tuple[str, float]:
        return self.controller, self.mu

    @property
    def key(self) -> str:
        """File-name-safe identifier, e.g. ``schedule_mu0.05_seed3``."""
        return f"{self.controller}_mu{self.mu:g}_seed{self.seed}"


def parse_mu_list(text: str) -> tuple[float, ...]:
    """``"0,0.05,0.1"`` -> (0.0, 0.05, 0.1); errors name ``--mu``."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ValueError(f"--mu expects numbers separated by commas, got {text!r}") from None
    if not values or any(not (math.isfinite(v) and 0.0 <= v < 1.0) for v in values):
        raise ValueError(f"--mu values must lie in [0, 1), got {text!r}")
    if len(set(values)) != len(values):
        raise ValueError(f"--mu lists a value twice: {text!r}")
    return values


def parse_controllers(text: str) -> tuple[str, ...]:
    """``"none,rbf"`` -> ('none', 'rbf') in the canonical order; errors name the bad one."""
    known = graph_controllers()
    names = [v.strip() for v in text.split(",") if v.strip()]
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise ValueError(f"--controllers must be a comma-separated subset of "
                         f"{','.join(known)}, got {text!r}")
    return tuple(c for c in known if c in names)


def case_grid(controllers: Sequence[str], mus: Sequence[float],
              seeds: Sequence[int]) -> list[FlightCase]:
    """Every (controller, mu, seed), seeds innermost so each case's first flight comes early."""
    if not seeds:
        raise ValueError("at least one seed is needed")
    return [FlightCase(c, float(m), int(s)) for c in controllers for m in mus for s in seeds]


def evaluation_scenario(base: Mapping, mu: float, seed: int) -> dict:
    """The base scenario mapping (scenario YAML as parsed) with density variation ``mu`` and
    excitation ``seed``; everything else (ramp, duration, force) is kept."""
    if not isinstance(base, Mapping) or "airspeed" not in base:
        raise ValueError("the base scenario must be a scenario mapping with an 'airspeed' "
                         "section")
    out = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in base.items()}
    out.setdefault("density", {})
    out["density"]["variation"] = float(mu)
    out.setdefault("excitation", {})
    out["excitation"]["seed"] = int(seed)
    out["name"] = f"{base.get('name', 'ramp')}_mu{mu:g}_seed{seed}"
    return out


# -- the best fixed c2 --------------------------------------------------------------------------

# -- aggregation --------------------------------------------------------------------------------

@dataclass(frozen=True)
class CaseStats:
    """Divergence airspeed ratios of one (controller, mu) over its flights.

    ``mean``, ``std`` (sample, ddof=1; NaN for one flight), ``min``, ``max`` are over the flights
    that diverged; a flight that reached the end of the ramp without diverging only says
    U_div > its final airspeed and is counted in ``n_not_diverged``; ``n_failed`` flights gave
    no summary (their errors are in the per-flight files).
    """

    controller: str
    mu: float
    n_flights: int
    n_diverged: int
    n_not_diverged: int
    n_failed: int
    mean: float
    std: float
    min: float
    max: float
    ratios: tuple[float, ...]
    mean_rms: float
    mean_damping: float
    study_ratio: float | None

    @property
    def standard_error(self) -> float:
        return self.std / math.sqrt(self.n_diverged) if self.n_diverged > 1 else math.nan

    def to_dict(self) -> dict:
        def clean(v):
            return None if isinstance(v, float) and not math.isfinite(v) else v

        out = {k: clean(getattr(self, k)) for k in self.__dataclass_fields__}
        out["ratios"] = [clean(r) for r in self.ratios]
        out["standard_error"] = clean(self.standard_error)
        out["label"] = _label_or_name(self.controller)
        return out


def _label_or_name(controller: str) -> str:
    try:
        return label(controller)
    except ValueError:  # a record of a controller no longer in the table
        return controller


def _study_ratio(controller: str, mu: float) -> float | None:
    try:
        ratios = study_ratios(controller)
    except ValueError:
        return None
    for m, value in ratios.items():
        if abs(m - mu) < 1e-9:
            return value
    return None


def _number(record: Mapping, key: str) -> float:
    value = record.get(key)
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        else math.nan


def aggregate(records: Iterable[Mapping],
              ratio_key: str = "divergence_ratio") -> list[CaseStats]:
    """Per (controller, mu) statistics of flight records.

    A record is a mapping with ``controller``, ``mu``, ``seed``, ``ok`` (bool) and, when ok, the
    run_flight summary keys ``leading_edge_rms``, ``mean_damping`` and the divergence ratio
    under ``ratio_key`` (None if not diverged). Cases come out in the order controller
    (:func:`graph_controllers`), then mu.
    """
    groups: dict[tuple[str, float], list[Mapping]] = {}
    for record in records:
        for key in ("controller", "mu", "ok"):
            if key not in record:
                raise ValueError(f"flight record lacks {key!r}: {dict(record)}")
        groups.setdefault((record["controller"], float(record["mu"])), []).append(record)
    stats = []
    order = graph_controllers()
    for (controller, mu) in sorted(groups, key=lambda k: (order.index(k[0])
                                                          if k[0] in order else 99, k[1])):
        flights = groups[(controller, mu)]
        ok = [r for r in flights if r["ok"]]
        ratios = np.array([_number(r, ratio_key) for r in ok])
        diverged = ratios[np.isfinite(ratios)]
        rms = np.array([_number(r, "leading_edge_rms") for r in ok])
        damping = np.array([_number(r, "mean_damping") for r in ok])

        def mean(x):
            return float(np.mean(x[np.isfinite(x)])) if np.isfinite(x).any() else math.nan

        stats.append(CaseStats(
            controller=controller, mu=mu, n_flights=len(flights),
            n_diverged=int(diverged.size), n_not_diverged=int(ratios.size - diverged.size),
            n_failed=len(flights) - len(ok),
            mean=float(diverged.mean()) if diverged.size else math.nan,
            std=float(diverged.std(ddof=1)) if diverged.size > 1 else math.nan,
            min=float(diverged.min()) if diverged.size else math.nan,
            max=float(diverged.max()) if diverged.size else math.nan,
            ratios=tuple(float(r) for r in diverged),
            mean_rms=mean(rms),
            mean_damping=math.nan if controller == "none" else mean(damping),  # no absorber
            study_ratio=_study_ratio(controller, mu)))
    return stats


def _fmt(value: float, spec: str = ".3f") -> str:
    return "-" if value is None or not math.isfinite(value) else format(value, spec)


def markdown_table(stats: Sequence[CaseStats]) -> str:
    """The evaluation table: U_div / U_cr per controller x mu next to the study's figure."""
    lines = ["| controller | mu | flights | diverged | mean | std | min | max | study (1 flight) "
             "| mean LE RMS [mm] | mean c2 [N s/m] |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in stats:
        diverged = f"{s.n_diverged}"
        if s.n_not_diverged:
            diverged += f" ({s.n_not_diverged} reached the end)"
        if s.n_failed:
            diverged += f", {s.n_failed} failed"
        lines.append(
            f"| {_label_or_name(s.controller)} | {s.mu:g} | "
            f"{s.n_flights} | {diverged} | {_fmt(s.mean)} | {_fmt(s.std)} | {_fmt(s.min)} | "
            f"{_fmt(s.max)} | {_fmt(s.study_ratio, '.2f')} | {_fmt(s.mean_rms * 1e3, '.3f')} | "
            f"{_fmt(s.mean_damping, '.0f')} |")
    return "\n".join(lines)


# -- the study's key claim -----------------------------------------------------------------------

@dataclass(frozen=True)
class KeyResult:
    """RBF network against airspeed schedule at one mu > 0.

    ``difference`` = mean U_div/U_cr of the network minus that of the schedule, ``standard_error``
    its standard error (Welch); ``verdict`` is ``"rbf better"`` / ``"schedule better"`` when the
    difference exceeds two standard errors, else ``"no significant difference"`` (or
    ``"not enough flights"``).
    """

    mu: float
    rbf_mean: float
    schedule_mean: float
    difference: float
    standard_error: float
    verdict: str

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in self.__dict__.items()}


def compare_rbf_with_schedule(stats: Sequence[CaseStats]) -> list[KeyResult]:
    """The study's key claim per mu > 0: under density variation the network beats the schedule.

    Flights that did not diverge are left out of the means (they would only raise them), so a
    case with such flights is compared conservatively; the table shows their number.
    """
    by_case = {(s.controller, s.mu): s for s in stats}
    out = []
    for (controller, mu), rbf in sorted(by_case.items(), key=lambda kv: kv[0][1]):
        if controller != "rbf" or mu <= 0 or ("schedule", mu) not in by_case:
            continue
        sch = by_case[("schedule", mu)]
        diff = rbf.mean - sch.mean
        if rbf.n_diverged < 2 or sch.n_diverged < 2:
            se, verdict = math.nan, "not enough flights"
        else:
            se = math.sqrt(rbf.std ** 2 / rbf.n_diverged + sch.std ** 2 / sch.n_diverged)
            if abs(diff) > 2 * se and diff > 0:
                verdict = "rbf better"
            elif abs(diff) > 2 * se:
                verdict = "schedule better"
            else:
                verdict = "no significant difference"
        out.append(KeyResult(mu=mu, rbf_mean=rbf.mean, schedule_mean=sch.mean, difference=diff,
                             standard_error=se, verdict=verdict))
    return out
