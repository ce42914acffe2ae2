"""``dva discrepancy``: residual -> named missing effects -> augmented model -> error before/after.

``dva discrepancy frf FILE --quantity receptance|accelerance|stiffness|modulus [--mass KG]
[--static-stiffness N_PER_M] [--elements N] [--covariates COL[,COL...]] [--columns
f=COL,real=COL,imag=COL,NAME=COL] [--frequency-unit U] [--value-unit U] [--group-by COL |
--covariate-tolerance TOL] [--max-steps N] [--plot-dir DIR] [--json]`` analyses isolator or
material FRFs (an instrument's export read as written); ``dva discrepancy modal FILE --quantity
receptance|mobility|accelerance [--modes N]`` (same table flags) a vibration test of a
structure. Both print the first step's verdict, the effects the loop added in turn (``steps``)
and where it ended (``final``). ``dva discrepancy synth`` / ``synth-structure`` write test CSVs
hiding effects (the generators of the tests). ``dva discrepancy flight RUN.mcap [--wing FILE]
[--plot-dir DIR] --json`` does the same for a flight log (MCAP bag of the simulator node or the
batch recorder) against the wing + Maxwell DVA model; ``dva discrepancy synth-flight --effect E
--seed S OUT`` records a test flight that hides one plant effect. SI units inside (kg, N/m, Hz).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from dva_offline.cli_tools import CliError, not_with
from dva_offline.isolator import files as isolator_files

EXIT_OK = 0


def _progress():
    from tqdm import tqdm

    bar = tqdm(file=sys.stderr, desc="discrepancy", unit="fit", leave=False)

    def step(text: str) -> None:
        bar.set_postfix_str(text)
        bar.update(1)

    return bar, step


# the covariate name of an analyzer's coherence column (gamma^2 per point)
COHERENCE = "coherence"


def _conditions(args):
    """Sweeps of the input file in SI units, how they were grouped, and the units used."""
    from dva_offline.discrepancy import table_io

    path = Path(args.file)
    columns = None
    if args.covariates:
        columns = [c.strip() for c in args.covariates.split(",") if c.strip()]
    quantity = args.quantity
    if path.suffix.lower() in (".uff", ".unv"):
        not_with(args, "reads a CSV table; a UFF 58 file carries its own columns and units "
                       "and no covariates", "--covariates", "--group-by",
                 "--covariate-tolerance", "--columns", "--frequency-unit", "--value-unit",
                 "--replicates")
        data = isolator_files.read_uff58(path, quantity)
        grouping = table_io.Grouping("a single sweep (UFF 58)", (), 1, ())
        return [data], columns, grouping, {}
    table = table_io.read_table(path)
    isolator_files.say_large_table(path, table.n_rows)
    try:
        conditions, grouping, info = table_io.conditions_from_table(
            table, quantity, table_io.ColumnMap.parse(args.columns), args.frequency_unit,
            args.value_unit, args.group_by, args.covariate_tolerance, columns)
    except ValueError as exc:  # say which file
        raise ValueError(f"{path}: {exc}") from None
    if columns is None:
        # every covariate whose condition levels differ, except the set column itself
        skip = set(grouping.columns) if args.group_by else set()
        columns = [n for n in conditions[0].covariates if n not in skip]
    return conditions, columns, grouping, info


def _take_coherence(conditions, columns):
    """Conditions without the coherence column (``--columns coherence=COL``), the covariates
    to analyse without it, and the coherence per point (None without the column)."""
    from dataclasses import replace

    if not conditions or not all(COHERENCE in c.covariates for c in conditions):
        return conditions, columns, None
    coherence = np.concatenate([np.asarray(c.covariates[COHERENCE], float) for c in conditions])
    conditions = [replace(c, covariates={k: v for k, v in c.covariates.items()
                                         if k != COHERENCE}) for c in conditions]
    if columns is not None:
        columns = [n for n in columns if n != COHERENCE]
    return conditions, columns, coherence


def _check_averages(args, coherence) -> None:
    """``--averages`` measures the noise from the coherence column: refused without one."""
    if args.averages is not None and coherence is None:
        raise CliError(f"--averages measures the noise from a coherence column, which "
                       f"{Path(args.file).name} has not (map one with --columns coherence=COL)")


def _replicates(args, conditions, columns, notes=None):
    """Replicate sets of the sweeps (:func:`.noise_sources.sweep_replicates`: by the measured
    scatter of the covariates and a difference that is noise, or the user's ``--replicates
    COLUMN``), how they were found, and the covariates to analyse: none when every sweep is a
    replicate of one condition (their covariates differ only by their scatter), never the
    replicate column itself. ``notes`` (a list) gets the sets turned down."""
    from dva_offline.discrepancy.noise_sources import sweep_replicates

    declared, how = None, "covariate means within their measured scatter in a sweep"
    col = args.replicates
    if col is not None:
        if any(col not in c.covariates for c in conditions):
            have = sorted(conditions[0].covariates) if conditions else []
            raise ValueError(f"--replicates column {col!r} not found; have {have}")
        if any(np.ptp(c.covariates[col]) > 0 for c in conditions):
            raise ValueError(f"--replicates column {col!r} changes within a sweep; it must "
                             "name each sweep's nominal condition")
        declared = [float(c.covariates[col][0]) for c in conditions]
        how = f"declared by --replicates {col}"
    names = [n for n in (columns or []) if n != col]  # the set column is no covariate
    sets = sweep_replicates([{n: c.covariates[n] for n in names} for c in conditions],
                            [c.frequency_hz for c in conditions], declared=declared,
                            values=[c.values for c in conditions], notes=notes)
    if columns is not None and col is not None:
        columns = [n for n in columns if n != col]
    if len(conditions) > 1 and sets and len(sets[0]) == len(conditions):
        columns = []  # one condition measured again: no covariate to analyse
    return sets, how, columns


def _measured_noise(args, domain, coherence, sets=(), how="", notes=()):
    """The noise the file measures itself (replicate sweeps, else coherence with --averages)
    and what was found, for the report (:mod:`.noise_sources`; ``notes``: what the replicate
    search turned down)."""
    from dva_offline.discrepancy.noise_sources import coherence_noise, replicate_noise

    if args.averages is not None and args.averages < 1:
        raise ValueError(f"--averages must be an integer >= 1, got {args.averages}")
    notes = list(notes)
    rep = replicate_noise(domain.observations, sets=list(sets), how=how) if sets else None
    if args.replicates is not None and rep is None:  # an option that would do nothing
        raise CliError(f"--replicates {args.replicates}: no two sweeps with one value of it "
                       "share 5 frequency lines; nothing to measure the noise from")
    coh = None
    if coherence is not None:
        coh, note = coherence_noise(coherence, args.averages)
        notes += [note] if note else []
    used = rep or coh
    return used, {"replicates": None if rep is None else rep.sigma,
                  "replicate_sets": [list(map(int, st)) for st in sets],
                  "replicates_found_by": how if sets else None,
                  "coherence": None if coh is None else coh.sigma, "notes": notes}


def _run_loop(args, domain, noise=None):
    """The loop on ``domain`` with the held-out split and step limit of the loop options,
    with a progress bar (``noise``: a measured noise estimate, else second differences)."""
    from dva_offline.discrepancy import loop
    from dva_offline.discrepancy.fitting import DataError

    rng = None if args.holdout_seed is None else np.random.default_rng(args.holdout_seed)
    split = loop.holdout_split(domain.observations.groups, args.holdout_every, rng)
    bar, step = _progress()
    try:
        return loop.run(domain, rule=loop.DecisionRule(max_steps=args.max_steps), split=split,
                        progress=step, noise=noise)
    except DataError as exc:  # the data as given cannot be analysed: say which file
        raise ValueError(f"{args.file}: {exc}") from None
    finally:
        bar.close()


def _cmd_frf(args) -> int:
    from dva_offline.discrepancy.frf_domain import FrfDomain

    if args.mass is not None and not args.mass > 0:
        raise ValueError(f"--mass must be > 0 kg, got {args.mass}")
    if args.static_stiffness is not None and not args.static_stiffness > 0:
        raise ValueError(f"--static-stiffness must be > 0 N/m, got {args.static_stiffness}")
    elements = None
    max_elements = 3 if args.max_elements is None else args.max_elements
    if args.elements != "auto":
        not_with(args, "is the largest order of --elements auto", "--max-elements")
        try:
            elements = int(args.elements)
        except ValueError:
            raise ValueError(
                f"--elements must be an integer >= 0 or 'auto', got {args.elements!r}"
            ) from None
    conditions, columns, grouping, info = _conditions(args)
    conditions, columns, coherence = _take_coherence(conditions, columns)
    _check_averages(args, coherence)
    turned_down: list[str] = []  # sets whose difference is no noise
    sets, how, columns = _replicates(args, conditions, columns, turned_down)
    domain = FrfDomain(conditions, mass=args.mass, static_stiffness=args.static_stiffness,
                       elements=elements, max_elements=max_elements, covariates=columns,
                       modulus=args.quantity == "modulus")
    noise, noise_info = _measured_noise(args, domain, coherence, sets, how, turned_down)
    result = _run_loop(args, domain, noise)
    sel = domain.order_selection
    extra = {
        "file": str(args.file), "quantity": args.quantity, "n_points": int(domain.omega.size),
        "grouping": {"method": grouping.method, "columns": list(grouping.columns),
                     "n_conditions": grouping.n_conditions,
                     "dropped": [{"condition": d, "n_points": n} for d, n in grouping.dropped],
                     "covariate_values": grouping.covariate_values},
        "input": info,
        "conditions": [
            {"n_points": int(c.frequency_hz.size),
             "covariates": {n: float(np.mean(c.covariates[n]))
                            for n in domain.observations.covariates},
             "covariate_spread": {n: float(np.ptp(c.covariates[n]))
                                  for n in domain.observations.covariates}}
            for c in conditions
        ],
        "noise_estimates": noise_info,
        "mass_kg": args.mass, "static_stiffness_n_per_m": args.static_stiffness,
        "elements": "auto" if elements is None else elements,
        "order_selection": {
            "isolator_selected_order": None if sel is None else sel.selected_order,
            "refined_holdout_errors": {str(k): v for k, v in domain.order_errors.items()},
            "baseline_order": domain.baseline_order,
        },
    }
    final = result.final.fit if result.final is not None else result.baseline
    extra["shift_factors"] = domain.shift_factors(final)  # per condition, for master curves
    return _report(args, result, domain, grouping, extra, args.quantity)


def _report(args, result, domain, grouping, extra: dict, quantity: str) -> int:
    """Print the loop's result of ``dva discrepancy frf|modal`` (JSON or lines), with plots of
    ``quantity`` in --plot-dir."""
    from dva_offline.discrepancy.report import plot_result, result_to_dict

    if "noise_estimates" in extra:  # the data's own estimate beside a measured one
        extra["noise_estimates"]["second_differences"] = result.residual.noise.sigma
    payload = result_to_dict(result, extra)
    if args.plot_dir:
        paths = plot_result(result, domain.observations, args.plot_dir, quantity,
                            Path(args.file).name)
        payload["plots"] = [str(p) for p in paths]
    if args.json:
        print(json.dumps(payload))
    else:
        ignored = extra.get("input", {}).get("ignored_text_columns")
        print(f"read {domain.omega.size} points: {grouping.describe()}"
              + (f"; ignored text column(s) {', '.join(ignored)}" if ignored else ""))
        est = extra.get("noise_estimates", {})
        other = ("" if result.noise.method.startswith("1.4826") else
                 f"; second differences of the baseline's residual give "
                 f"{result.residual.noise.sigma:.4f}, not used")
        print(f"noise: {result.noise.sigma:.4f} from {result.noise.method}{other}"
              + "".join(f"; {n}" for n in est.get("notes", [])))
        print("\n".join(_summary_lines(result) + _shift_lines(extra.get("shift_factors"))))
    return EXIT_OK


def _shift_lines(shifts) -> list[str]:
    """The final model's shift factors per condition (to hold against a master curve's)."""
    if not shifts:
        return []
    vertical = shifts.get("vertical")
    head = (f"shift factors of the final model (log10 a_T{', b_T' if vertical else ''}, "
            f"{shifts['form']}, {shifts['covariate']} reference "
            f"{shifts['reference_level']:.4g}):")
    return [head] + [f"  {r['level']:10.4g}: {r['log10_aT']:8.3f}"
                     + (f"  {r['b_T']:7.4f}" if vertical else "")
                     for r in shifts["per_condition"]]


def _cmd_modal(args) -> int:
    from dva_offline.discrepancy import table_io
    from dva_offline.discrepancy.modal_domain import ModalDomain, to_receptance
    from dva_offline.isolator.frf_data import FrfData

    modes = None
    max_modes = 8 if args.max_modes is None else args.max_modes
    if args.modes != "auto":
        not_with(args, "is the largest order of --modes auto", "--max-modes")
        try:
            modes = int(args.modes)
        except ValueError:
            raise ValueError(f"--modes must be an integer >= 1 or 'auto', got {args.modes!r}"
                             ) from None
    columns = ([c.strip() for c in args.covariates.split(",") if c.strip()]
               if args.covariates else None)
    table = table_io.read_table(args.file)
    try:
        raw, grouping, info = table_io.conditions_from_table(
            table, args.quantity, table_io.ColumnMap.parse(args.columns), args.frequency_unit,
            args.value_unit, args.group_by, args.covariate_tolerance, columns,
            internal_quantity="receptance")
    except ValueError as exc:  # say which file
        raise ValueError(f"{args.file}: {exc}") from None
    conditions = [FrfData(c.frequency_hz, to_receptance(c.frequency_hz, c.values, args.quantity),
                          "receptance", c.covariates) for c in raw]
    if columns is None:
        skip = set(grouping.columns) if args.group_by else set()
        columns = [n for n in conditions[0].covariates if n not in skip]
    conditions, columns, coherence = _take_coherence(conditions, columns)
    _check_averages(args, coherence)
    turned_down: list[str] = []  # sets whose difference is no noise
    sets, how, columns = _replicates(args, conditions, columns, turned_down)
    domain = ModalDomain(conditions, modes=modes, max_modes=max_modes, covariates=columns,
                         quantity=args.quantity, constants=args.modal_constants)
    noise, noise_info = _measured_noise(args, domain, coherence, sets, how, turned_down)
    result = _run_loop(args, domain, noise)
    extra = {
        "file": str(args.file), "quantity": args.quantity, "model_quantity": "receptance",
        "n_points": int(domain.omega.size),
        "grouping": {"method": grouping.method, "columns": list(grouping.columns),
                     "n_conditions": grouping.n_conditions,
                     "dropped": [{"condition": d, "n_points": n} for d, n in grouping.dropped],
                     "covariate_values": grouping.covariate_values},
        "input": info,
        "noise_estimates": noise_info,
        "order_selection": {"refined_holdout_errors": {str(k): v for k, v in
                                                       domain.order_errors.items()},
                            "modes": domain.baseline_order,
                            "rule": domain.order_choice.reason,
                            "modal_constants": ("complex" if domain.complex_constants
                                                else "real"),
                            "modal_constants_rule": domain.constants_reason,
                            "form_holdout_errors": domain.form_errors},
    }
    return _report(args, result, domain, grouping, extra, "receptance")


def _law_case(args, options: dict):
    """A case of :mod:`.synthetic_laws` for ``synth``/``synth-structure --effect CASE``;
    the options it does not take (``options``: flag -> whether it was given) are refused."""
    from dva_offline.discrepancy import synthetic_laws

    given = [flag for flag, used in options.items() if used]
    if given:
        raise ValueError(f"--effect {args.effect} draws its own levels and system; "
                         f"{', '.join(given)} cannot be used with it")
    return synthetic_laws.generate(args.effect, np.random.default_rng(args.seed),
                                   sigma=args.sigma)


def _cmd_synth_structure(args) -> int:
    from dva_offline.cli_tools import json_safe
    from dva_offline.discrepancy import structure_synthetic, synthetic_laws, table_io

    effect = None if args.effect == "none" else args.effect
    if effect in synthetic_laws.CASES:
        case = _law_case(args, {"--quantity other than accelerance":
                                args.quantity != "accelerance", "--jitter": args.jitter})
    else:
        case = structure_synthetic.generate_structure(
            effect, np.random.default_rng(args.seed), quantity=args.quantity,
            sigma=args.sigma, jitter=args.jitter)
    table_io.write_table(args.out, case.frequency_hz, case.values, case.covariates)
    payload = {"out": str(args.out), "seed": args.seed, "quantity": case.quantity,
               "hidden_effect": case.effect, "hidden_parameters": case.parameters,
               "modes_hz": list(case.modes_hz), "noise_sigma": case.sigma,
               "effect_size": case.effect_size, "covariates": list(case.covariates),
               "n_points": int(case.frequency_hz.size)}
    if args.json:
        print(json.dumps(json_safe(payload), allow_nan=False))
    else:
        print(f"wrote {payload['n_points']} points to {args.out} (modes "
              f"{', '.join(f'{f:.4g}' for f in case.modes_hz)} Hz; hidden: {case.effect})")
    return EXIT_OK


def _cmd_synth(args) -> int:
    from dva_offline.discrepancy import synthetic, synthetic_laws, table_io

    effect = None if args.effect == "none" else args.effect
    if effect in synthetic_laws.CASES:
        case = _law_case(args, {"--quantity other than receptance":
                                args.quantity != "receptance", "--points": args.points != 300,
                                "--system": args.system is not None,
                                "--clean-covariate": args.clean_covariate is not None})
    else:
        case = synthetic.generate_case(
            effect, np.random.default_rng(args.seed), quantity=args.quantity,
            sigma=args.sigma, n_points=args.points, system=args.system,
            clean_covariate=args.clean_covariate)
    table_io.write_table(args.out, case.frequency_hz, case.values, case.covariates)
    payload = {
        "out": str(args.out), "seed": args.seed, "quantity": case.quantity,
        "hidden_effect": case.effect, "hidden_parameters": case.parameters,
        "system": case.system, "mass_kg": case.mass,
        "static_stiffness_n_per_m": case.static_stiffness, "base_elements": case.n_elements,
        "noise_sigma": case.sigma, "effect_size": case.effect_size,
        "covariates": list(case.condition_columns), "n_points": int(case.frequency_hz.size),
    }
    from dva_offline.cli_tools import json_safe

    if args.json:
        print(json.dumps(json_safe(payload), allow_nan=False))
    else:
        print(f"wrote {payload['n_points']} points to {args.out} (system {case.system}, "
              f"m = {case.mass:g} kg, k = {case.static_stiffness:.6g} N/m; hidden: "
              f"{case.effect})")
    return EXIT_OK


def _flight_summary(result, domain) -> list[str]:
    fs = domain.data.sample_rate
    a, b = domain.span
    lines = [f"route {domain.route} ({domain.route_reason})"]
    if domain.route == "whole-flight":
        lines[0] += (f": {len(domain.segments)} segments in {a / fs:.1f}-{b / fs:.1f} s, "
                     f"ending at {domain.span_reason}")
    if domain.data.per_sample:
        lag = (f"through the declared lag {1e3 * domain.declared_lag:g} ms"
               if domain.declared_lag > 0 else "with no damper lag declared")
        lines.append(f"damper: the c2 {', '.join(domain.data.law_sources)} commanded, {lag} "
                     f"({domain.lag_reason})")
    return lines + _summary_lines(result, f"; {len(domain.segments)} segments, "
                                          f"{result.split.held.sum()} held-out points")


def _trend_lines(result) -> list[str]:
    """Which parameters of the per-condition fits move beyond their errors, and the law
    each moving coordinate of a covariate effect follows (:mod:`.laws`)."""
    lines = []
    moving = [m["name"] for m in getattr(result, "moving", ()) if m["moving"]]
    if getattr(result, "moving", ()):
        lines.append(f"per-condition parameters moving beyond their errors: "
                     f"{', '.join(moving) or 'none'} (of {len(result.moving)})")
    for t in getattr(result, "trends", ()):
        if t.moving:
            lines.append(f"  {t.effect} ({t.covariate}): {t.coordinate} moves (chi2 "
                         f"{t.chi2:.3g}, {t.dof} dof, p = {t.p_value:.2g}): law {t.law}, "
                         f"{t.reason}")
    return lines


def _summary_lines(result, baseline_detail: str = "") -> list[str]:
    """The human-readable report of either domain (``--json`` prints the full object)."""
    v = result.verdict
    lines = [
        f"baseline {result.baseline.name}: held-out error {result.baseline.error:.4f} "
        f"(noise floor {result.noise.sigma:.4f}{baseline_detail})",
        f"verdict: {v.status}" + (f" -> {v.effect}" + (f" ({v.label})" if v.label else "")
                                  if v.effect else ""),
    ]
    ref = getattr(result, "reference", None)
    if ref is not None:
        lines.insert(1, f"per-condition reference (baseline fitted to each of "
                        f"{ref.n_fitted}/{ref.n_conditions} conditions): held-out error "
                        f"{ref.error:.4f}" + ("" if result.reference_used else
                                              " (no better than the baseline: not used)"))
        lines[2:2] = _trend_lines(result)
    if result.augmented is not None:
        a = result.augmented
        lines.append(f"augmented {a.name}: held-out error {a.error:.4f} "
                     f"({100 * (1 - a.error / result.baseline.error):.0f} % lower)")
        lines += [f"  {e.name} = {e.value:.6g} +- {e.std:.2g} {e.unit}" for e in a.added]
        lines += [f"  law: {a.law.describe(a)}"] if a.law is not None else []
    for i, st in enumerate(result.steps):
        label = f" ({st.label})" if st.label else ""
        lines.append(f"step {i + 1}: + {st.effect}{label}: held-out error {st.error_before:.4f} "
                     f"-> {st.error_after:.4f} (noise floor {st.noise_before:.4f}, dBIC "
                     f"{st.delta_bic:.1f}, explains {100 * st.explained_fraction:.0f} % of the "
                     "excess" + (f", {100 * st.achieved_fraction:.0f} % of what the "
                                 "per-condition fits reach" if np.isfinite(st.achieved_fraction)
                                 else "") + ")")
        lines += [f"    {e.name} = {e.value:.6g} +- {e.std:.2g} {e.unit}" for e in st.fit.added]
        lines += [f"    law: {st.fit.law.describe(st.fit)}"] if st.fit.law is not None else []
        lines += [f"    caveat: {c}" for c in st.caveats]
    if result.final is not None:
        fin = result.final
        lines.append(f"final: {fin.status}: {fin.model}: held-out error {fin.error:.4f} = "
                     f"{fin.error / fin.noise:.2f} x the noise floor {fin.noise:.4f}; "
                     f"{fin.reason}")
    lines.append(f"evidence: {v.evidence}")
    lines.append("candidates (held-out error, dBIC):")
    for c in result.candidates:
        label = f" ({c.label})" if c.label else ""
        if c.applicable:
            lines.append(f"  {c.effect}{label}: {c.fit.error:.4f}, {c.delta_bic:.1f}")
        elif c.implausible:  # fitted and significant, never added
            lines.append(f"  {c.effect}{label}: {c.fit.error:.4f}, {c.delta_bic:.1f}, "
                         f"{c.reason}")
        else:  # a failed start or fit says "failed: reason"
            lines.append(f"  {c.effect}{label}: "
                         + (c.reason if c.failed else f"not applicable: {c.reason}"))
    return lines


def _cmd_flight(args) -> int:
    from aero_dva.bag.flight_log_io import law_sources, load_flight_log
    from aero_dva.wing.wing_io import load_wing
    from dva_offline.discrepancy import loop
    from dva_offline.discrepancy.flight_domain import (
        FlightDomain,
        FlightSettings,
        arrays_from_log,
    )
    from dva_offline.discrepancy.report import plot_result, result_to_dict

    path = Path(args.file)
    if not path.exists():
        raise FileNotFoundError(f"flight log not found: {path}")
    try:
        band = tuple(float(x) for x in args.band.split(","))
    except ValueError:
        raise ValueError(f"--band must be LOW,HIGH in Hz, got {args.band!r}") from None
    if len(band) != 2:
        raise ValueError(f"--band must be LOW,HIGH in Hz, got {args.band!r}")
    settings = FlightSettings(band=band, window_s=args.window,
                              segment_windows=args.segment_windows, settle_s=args.settle,
                              route=args.route)
    sources = law_sources(path, args.namespace, args.allow_truncated)
    if args.damper_lag is not None and not sources:
        raise ValueError("--damper-lag declares a lag for a per-sample law's commands, and no "
                         "per-sample law flew this log (no dva/damper_block): leave it out")
    print(f"reading {path} ...", file=sys.stderr, flush=True)
    log = load_flight_log(path, namespace=args.namespace, allow_truncated=args.allow_truncated)
    wing = load_wing(args.wing)
    domain = FlightDomain(arrays_from_log(log, sources), wing, settings,
                          damper_lag=args.damper_lag)
    rng = None if args.holdout_seed is None else np.random.default_rng(args.holdout_seed)
    split = loop.holdout_split(domain.observations.groups, args.holdout_every, rng)
    bar, step = _progress()
    try:
        result = loop.run(domain, rule=domain.decision_rule, split=split, progress=step)
    finally:
        bar.close()
    fs = domain.data.sample_rate
    extra = {
        "file": str(path), "wing": args.wing or "reference",
        "n_points": int(domain.observations.values.size),
        "observations": {
            "quantity": "H1 estimate, aileron force -> plunge [m/s^2/N] and pitch "
                        "[rad/s^2/N] acceleration",
            "band_hz": list(settings.band), "resolution_hz": fs / domain.n_window,
            "window": f"Hann, {domain.n_window} samples, 50 % overlap",
            "channels": ["plunge", "pitch"],
        },
        "route": {"name": domain.route, "why": domain.route_reason,
                  "span_s": [domain.span[0] / fs, domain.span[1] / fs],
                  "span_ends": domain.span_reason},
        "damper": {"per_sample_laws": list(domain.data.law_sources),
                   "c2_read": ("commanded by the per-sample law (dva/damper_block "
                               "commanded_damping), reported where c2 was held"
                               if domain.data.per_sample else
                               "reported per block (dva/damper_state applied_damping)"),
                   "declared_lag_s": domain.declared_lag, "declared_lag_why": domain.lag_reason},
        "segments": [
            {"start_s": s.start / fs, "stop_s": s.stop / fs, "windows": len(s.windows),
             "airspeed_mps": float(np.mean(domain.data.airspeed[s.start:s.stop])),
             "density": float(np.mean(domain.data.density[s.start:s.stop])),
             "damper_c2": float(np.mean(domain.data.damping[s.start:s.stop])),
             "pitch_rms_rad": float(domain.seg_pitch_rms[i])}
            for i, s in enumerate(domain.segments)
        ],
    }
    payload = result_to_dict(result, extra)
    if args.plot_dir:
        from dva_offline.discrepancy.flight_domain import CHANNELS

        obs = domain.observations
        labels = {g: f"U {np.mean(obs.covariates['airspeed_mps'][obs.groups == g]):.1f} m/s, "
                     f"c2 {np.mean(obs.covariates['damper_c2'][obs.groups == g]):.0f} N s/m"
                  for g in np.unique(obs.groups)}
        units = {"plunge": "(m/s^2)/N", "pitch": "(rad/s^2)/N"}
        paths = plot_result(result, obs, args.plot_dir, "H (force -> acceleration)", path.name,
                            panels=[(f"H {c} acceleration / aileron force", units[c])
                                    for c in CHANNELS],
                            condition_labels=labels)
        payload["plots"] = [str(p) for p in paths]
    if args.json:
        print(json.dumps(payload))
    else:
        print("\n".join(_flight_summary(result, domain)))
    return EXIT_OK


def _cmd_synth_flight(args) -> int:
    from dva_offline.discrepancy import flight_synthetic

    effect = None if args.effect == "none" else args.effect
    if Path(args.out).exists():
        raise ValueError(f"output {args.out} exists; choose a new bag directory")
    if not args.dwell > 0:
        raise ValueError(f"--dwell must be > 0 s, got {args.dwell}")
    print(f"flying and recording {12 * args.dwell:g} s ...", file=sys.stderr, flush=True)
    case = flight_synthetic.generate_flight(effect, args.seed, args.out, dwell=args.dwell)
    payload = {
        "out": str(case.path), "seed": case.seed, "hidden_effect": case.effect,
        "hidden_parameters": case.parameters, "airspeed_ratios": list(case.airspeed_ratios),
        "damper_c2": list(case.damping), "accelerometer_noise": list(case.noise),
        "outcome": case.outcome, "wall_time_s": case.wall_time,
    }
    from dva_offline.cli_tools import json_safe

    if args.json:
        print(json.dumps(json_safe(payload), allow_nan=False))
    else:
        print(f"wrote {case.path} ({case.outcome}; hidden: {case.effect} "
              f"{case.parameters})")
    return EXIT_OK


def _add_table_arguments(p) -> None:
    """Flags that read an instrument's export as it is (columns, units, sweeps)."""
    p.add_argument("--columns", default=None, metavar="ROLE=COL[,...]",
                   help="file columns: frequency=COL,real=COL,imag=COL, and NAME=COL to rename "
                        "a covariate (e.g. temperature_c=T); default frequency_hz,real,imag")
    p.add_argument("--frequency-unit", default=None, choices=("Hz", "kHz", "rad/s"),
                   help="unit of the frequency column (default: the file's units row, else Hz)")
    p.add_argument("--value-unit", default=None, metavar="UNIT",
                   help="unit of the real/imag columns, e.g. MPa, N/mm, mm/N, g/N (default: "
                        "the file's units row, else SI)")
    p.add_argument("--group-by", default=None, metavar="COL",
                   help="split the rows into sweeps by this set column (e.g. the instrument's "
                        "step number)")
    p.add_argument("--covariate-tolerance", type=float, default=None, metavar="TOL",
                   help="split the rows into sweeps by covariate levels closer than TOL (a "
                        "measured temperature that drifts within a sweep)")


def _add_loop_arguments(p) -> None:
    """Flags of the loop over a table of sweeps (``frf``, ``modal``)."""
    p.add_argument("--covariates", default=None, metavar="COL[,COL...]",
                   help="covariates to analyse (temperature, excitation level); default: every "
                        "extra column whose level differs between sweeps")
    p.add_argument("--holdout-every", type=int, default=4,
                   help="hold out every Nth point of each condition (default 4)")
    p.add_argument("--holdout-seed", type=int, default=None,
                   help="hold out a seeded random 1/N of the points instead")
    p.add_argument("--max-steps", type=int, default=12,
                   help="most effects the loop adds one after another (default 12)")
    p.add_argument("--replicates", default=None, metavar="COL",
                   help="sweeps with one value of this column are replicates of one condition "
                        "(their scatter is the noise; default: sweeps whose covariates differ "
                        "by no more than their scatter within a sweep)")
    p.add_argument("--averages", type=int, default=None, metavar="N",
                   help="number of averages of the analyzer's H1 estimate: with a coherence "
                        "column (--columns coherence=COL) the noise is measured from it")
    p.add_argument("--plot-dir", default=None, help="write PNG plots into this directory")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def register(subparsers) -> None:
    """Add the ``discrepancy`` subcommand to the ``dva`` parser."""
    from dva_offline.discrepancy import synthetic, synthetic_laws

    parser = subparsers.add_parser(
        "discrepancy",
        help="find the effect a model lacks: residual -> named effect -> error before/after",
        description=__doc__,
    )
    sub = parser.add_subparsers(dest="discrepancy_command", metavar="<domain>", required=True)

    p = sub.add_parser("frf", help="isolator / viscoelastic FRF data against the Maxwell model")
    p.add_argument("file", help="CSV frequency_hz,real,imag[,covariates] (sweeps may be "
                               "stacked by covariate) or UFF 58")
    p.add_argument("--quantity", choices=("receptance", "accelerance", "stiffness", "modulus"),
                   default="receptance",
                   help="what the file holds (modulus: E' + j E'' or G' + j G'', analysed as "
                        "a stiffness per unit geometry factor)")
    _add_table_arguments(p)
    p.add_argument("--mass", type=float, default=None,
                   help="isolated mass [kg] (default: fitted; fixture_mass then not tested)")
    p.add_argument("--static-stiffness", type=float, default=None,
                   help="static stiffness [N/m] (default: fitted)")
    p.add_argument("--elements", default="auto",
                   help="Maxwell elements of the baseline, or 'auto' (isolator order "
                        "selection); a fixed order makes maxwell_element a candidate")
    p.add_argument("--max-elements", type=int, default=None,
                   help="largest order for --elements auto (default 3)")
    _add_loop_arguments(p)
    p.set_defaults(func=_cmd_frf)

    p = sub.add_parser("modal", help="vibration-test FRFs of a structure against N modes")
    p.add_argument("file", help="CSV frequency_hz,real,imag[,covariates] (sweeps stacked)")
    p.add_argument("--quantity", choices=("receptance", "mobility", "accelerance"),
                   default="accelerance", help="what the file holds (SI units)")
    _add_table_arguments(p)
    p.add_argument("--modes", default="auto",
                   help="number of modes of the baseline, or 'auto' (order rule)")
    p.add_argument("--max-modes", type=int, default=None,
                   help="largest order for --modes auto (default 8)")
    p.add_argument("--modal-constants", choices=("auto", "real", "complex"), default="auto",
                   help="modal constants of the baseline: complex (LSFD, non-proportional "
                        "damping or a constant phase of the channel), real, or auto: complex "
                        "when they beat real ones and a single delay significantly (default)")
    _add_loop_arguments(p)
    p.set_defaults(func=_cmd_modal)

    from dva_offline.discrepancy import structure_synthetic

    p = sub.add_parser("synth-structure",
                       help="write a synthetic vibration test (several modes) hiding one effect")
    p.add_argument("--effect", required=True,
                   choices=("none", *structure_synthetic.EFFECTS,
                            *(c for c in synthetic_laws.CASES if c.startswith("structure"))),
                   help="hidden effect; structure_* cases follow a law outside the library's "
                        "forms, or none at all (synthetic_laws: four levels 2-20 N, a set "
                        "column)")
    p.add_argument("--seed", type=int, required=True, help="random seed")
    p.add_argument("--out", required=True, help="output CSV")
    p.add_argument("--quantity", choices=("receptance", "mobility", "accelerance"),
                   default="accelerance")
    p.add_argument("--sigma", type=float, default=None, help="noise RMS (default 0.005-0.02)")
    p.add_argument("--jitter", action="store_true",
                   help="record the covariates with measurement jitter and a set column")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=_cmd_synth_structure)

    p = sub.add_parser("synth", help="write a synthetic FRF CSV that hides one effect")
    p.add_argument("--effect", required=True,
                   choices=("none", *synthetic.LIBRARY_EFFECTS, *synthetic.OUTSIDE_EFFECTS,
                            *(c for c in synthetic_laws.CASES if not c.startswith("structure"))),
                   help="hidden effect; power_level, temperature_kink, phase_offset follow a "
                        "law outside the library's forms, replicates has none "
                        "(synthetic_laws)")
    p.add_argument("--seed", type=int, required=True, help="random seed")
    p.add_argument("--out", required=True, help="output CSV")
    p.add_argument("--quantity", choices=("receptance", "accelerance", "stiffness"),
                   default="receptance")
    p.add_argument("--sigma", type=float, default=None,
                   help="noise RMS (default: random 0.005-0.02)")
    p.add_argument("--points", type=int, default=300, help="points per condition")
    p.add_argument("--system", choices=sorted(synthetic.BASE_SYSTEMS), default=None)
    p.add_argument("--clean-covariate", choices=("temperature_c", "excitation_n"),
                   default=None, help="stack the data set at 3 levels of this covariate, on "
                   "which the hidden effect does not depend")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=_cmd_synth)

    from dva_offline.discrepancy.flight_synthetic import LIBRARY_EFFECTS, OUTSIDE_EFFECTS

    p = sub.add_parser("flight", help="flight log (MCAP) against the wing + Maxwell DVA model")
    p.add_argument("file", help="rosbag2 directory or .mcap file of a flight (simulator node "
                               "or batch recorder)")
    p.add_argument("--wing", default=None, help="wing file (default: the chapter-6 wing)")
    p.add_argument("--namespace", default="", help="topic namespace of the flight")
    p.add_argument("--band", default="2,20", help="frequency band LOW,HIGH [Hz] (default 2,20)")
    p.add_argument("--window", type=float, default=1.0,
                   help="DFT window [s] (Hann, 50 %% overlap; default 1)")
    p.add_argument("--segment-windows", type=int, default=None,
                   help="windows per segment (default 7 on the segments route: a 4 s dwell is "
                        "one segment; 3 on the whole-flight route)")
    p.add_argument("--settle", type=float, default=1.0,
                   help="seconds of data at the log's start not analysed: the model is "
                        "simulated from rest from there (default 1)")
    p.add_argument("--route", choices=("auto", "segments", "whole-flight"), default="auto",
                   help="segments of constant airspeed, density and c2, or the whole "
                        "analysable flight sample by sample (default auto: whole-flight for a "
                        "per-sample law's flight or a log without 2 constant segments)")
    p.add_argument("--damper-lag", type=float, default=None, metavar="SECONDS",
                   help="a damper lag the model declares for a per-sample law's flight: its "
                        "commanded c2 goes through it (default none: the wing file's ideal "
                        "damper; actuator_lag fits another in its place)")
    p.add_argument("--holdout-every", type=int, default=4,
                   help="hold out every Nth point of each segment and channel (default 4)")
    p.add_argument("--holdout-seed", type=int, default=None,
                   help="hold out a seeded random 1/N of the points instead")
    p.add_argument("--plot-dir", "--plot", dest="plot_dir", default=None,
                   help="write PNG plots into this directory")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--allow-truncated", action="store_true",
                   help="read a bag that was not closed, is cut or damaged: every chunk whose CRC "
                        "holds (warns); "
                        "`dva bag recover` makes a complete copy instead")
    p.set_defaults(func=_cmd_flight)

    p = sub.add_parser("synth-flight",
                       help="record a test flight (MCAP) that hides one plant effect")
    p.add_argument("--effect", required=True,
                   choices=("none", *LIBRARY_EFFECTS, *OUTSIDE_EFFECTS))
    p.add_argument("--seed", type=int, required=True, help="random seed")
    p.add_argument("--dwell", type=float, default=4.0,
                   help="seconds per (airspeed, c2) pair; 12 of them (default 4)")
    p.add_argument("out", help="bag directory to create")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=_cmd_synth_flight)


if __name__ == "__main__":  # pragma: no cover
    from dva_offline.cli import main

    sys.exit(main(["discrepancy", *sys.argv[1:]]))
