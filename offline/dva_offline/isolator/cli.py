"""``dva isolator``: modal analysis, identification, FRF estimation, plots (Zhang 2006, ch. 3-5).

All values on the command line and in files are SI: kg, N/m, N s/m, Pa, m, m^2, Hz (rad/s where
named).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dva_offline.cli_tools import emit, not_with
from dva_offline.isolator import files as isolator_files
from dva_offline.isolator.element_types import classify_elements
from dva_offline.isolator.frf_data import (
    check_units,
    estimate_modal,
    geometry_factor,
    modulus_to_stiffness,
    select_points,
    to_receptance,
)
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties

#: The options that say how a FRF file is read.
FRF_INPUT_OPTIONS = ("--quantity", "--format", "--area", "--thickness", "--geometry-factor",
                     "--fmin-hz", "--fmax-hz", "--min-coherence")


def _maxwell_pair(text: str) -> tuple[float, float]:
    try:
        k_text, c_text = text.split(",")
        return float(k_text), float(c_text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--maxwell expects K,C (N/m,N s/m), got {text!r}"
        ) from None


def _model_from_args(args) -> MaxwellModel:
    pairs = args.maxwell or []
    return MaxwellModel(
        args.mass, args.k, args.c, tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)
    )


def _elements_json(model: MaxwellModel, types, k_std=None, c_std=None) -> list[dict]:
    out = []
    for i, (ki, ci, t) in enumerate(zip(model.maxwell_k, model.maxwell_c, types)):
        item = {
            "k": ki, "c": ci, "tau_s": ci / ki, "type": t.label,
            "omega_tau": t.omega_tau, "phase_deg": t.phase_deg,
        }
        if k_std is not None:
            item["k_std"] = k_std[i]
            item["c_std"] = c_std[i]
        out.append(item)
    return out


def _cmd_modal(args) -> int:
    model = _model_from_args(args)
    modal = modal_properties(model)
    types = classify_elements(model, modal.natural_frequency_rad_s)
    payload = {
        "natural_frequency_rad_s": modal.natural_frequency_rad_s,
        "natural_frequency_hz": modal.natural_frequency_rad_s / (2 * np.pi),
        "damping_ratio": modal.damping_ratio,
        "element_types": [t.label for t in types],
        "elements": _elements_json(model, types),
        "static_stiffness_n_per_m": model.static_stiffness,
        "stable": modal.is_stable,
        "eigenvalues": [[float(e.real), float(e.imag)] for e in modal.eigenvalues],
    }
    lines = [
        f"natural frequency {modal.natural_frequency_rad_s:.3f} rad/s "
        f"({payload['natural_frequency_hz']:.3f} Hz), damping ratio {modal.damping_ratio:.4f}",
        *(f"element {i + 1}: k = {e['k']:.6g} N/m, c = {e['c']:.6g} N s/m, "
          f"tau = {1e3 * e['tau_s']:.3f} ms, w_n tau = {e['omega_tau']:.3f}, Type {e['type']}"
          for i, e in enumerate(payload["elements"])),
    ]
    emit(args, payload, lines)
    return 0


def _read_frf(args):
    """Read the FRF file of ``args``; a modulus comes back as complex stiffness [N/m]."""
    path = Path(args.file)
    modulus = args.quantity == "modulus"
    if modulus:
        factor = geometry_factor(args.area, args.thickness, args.geometry_factor)
    elif args.area is not None or args.thickness is not None or args.geometry_factor is not None:
        raise ValueError("--area/--thickness/--geometry-factor apply only to --quantity modulus")
    quantity = "stiffness" if modulus else args.quantity
    if path.suffix.lower() in (".uff", ".unv") and args.format not in (None, "uff58"):
        raise ValueError(f"--format {args.format}: {path.name} is read as UFF 58 (its suffix)")
    if path.suffix.lower() in (".uff", ".unv") or args.format == "uff58":
        data = isolator_files.read_uff58(path, quantity)
    elif (args.format or args.default_format) == "stepped-sine":
        data = isolator_files.read_stepped_sine_csv(path, quantity)
    else:
        data = isolator_files.read_frf_csv(path, quantity)
    isolator_files.say_large_table(path, data.frequency_hz.size)
    try:
        data = select_points(data, args.fmin_hz, args.fmax_hz, args.min_coherence)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return modulus_to_stiffness(data, factor) if modulus else data


def _check_units(args, omega, h, mass, static_stiffness, wn) -> None:
    try:
        check_units(omega, h, mass, static_stiffness, wn)
    except ValueError as exc:
        if args.quantity != "modulus":
            raise
        raise ValueError(
            f"{exc}; for a modulus check Pa vs MPa and the geometry in m (area in m^2)"
        ) from None


def _fit_json(fit) -> dict:
    """JSON of one fit: parameters with standard errors, modal solution, FRF error, warnings."""
    model = fit.model
    return {
        "method": fit.method,
        "c": model.c,
        "c_std": fit.c_std,
        "n_elements": model.n_elements,
        "elements": _elements_json(model, fit.element_types, fit.maxwell_k_std,
                                   fit.maxwell_c_std),
        "natural_frequency_rad_s": fit.modal.natural_frequency_rad_s if fit.modal else None,
        "damping_ratio": fit.modal.damping_ratio if fit.modal else None,
        "frf_error": fit.frf_error,
        "warnings": list(fit.warnings),
    }


def _r_squared(model, omega, h) -> float:
    """1 - ||H_model - H||^2 / ||H - mean H||^2 over the receptance points."""
    resid = frf(model, omega) - h
    return float(1.0 - np.sum(np.abs(resid) ** 2) / np.sum(np.abs(h - h.mean()) ** 2))


def _rough_natural_frequency(args, omega, h):
    """Given w_n, else the zero crossing of Re(H) (only for the fast unit check), else None."""
    if args.natural_frequency_rad_s is not None:
        return args.natural_frequency_rad_s
    from dva_offline.isolator.frf_estimation import natural_frequency_zero_crossing

    try:
        return natural_frequency_zero_crossing(omega, h)
    except ValueError:
        return None


def _cmd_identify(args) -> int:
    args.quantity = args.quantity or "receptance"
    if not args.mass > 0:
        raise ValueError(f"--mass must be > 0 kg, got {args.mass}")
    if not args.static_stiffness > 0:
        raise ValueError(f"--static-stiffness must be > 0 N/m, got {args.static_stiffness}")
    if args.elements == "auto":
        n = 3 if args.max_elements is None else args.max_elements
    else:
        not_with(args, "is the largest order of --elements auto", "--max-elements")
        try:
            n = int(args.elements)
        except ValueError:
            raise ValueError(
                f"--elements must be an integer or 'auto', got {args.elements!r}"
            ) from None
    if n < 1:
        raise ValueError(f"--elements must be >= 1, got {n}")
    if args.natural_frequency_rad_s is not None and args.damping_ratio is not None:
        not_with(args, "estimates w_n and zeta, but both are given", "--modal-estimate")
    args.modal_estimate = args.modal_estimate or "fit"
    data = _read_frf(args)
    omega, h = to_receptance(data, args.mass)
    if args.modal_estimate == "half-power" and (args.natural_frequency_rad_s is None
                                                or args.damping_ratio is None):
        try:
            estimate_modal(omega, h)
        except ValueError as exc:
            raise ValueError(
                f"{args.file}: {exc}; use --modal-estimate fit or give "
                "--natural-frequency-rad-s and --damping-ratio"
            ) from None
    rough = _rough_natural_frequency(args, omega, h)
    if rough is not None:
        _check_units(args, omega, h, args.mass, args.static_stiffness, rough)
    # scipy.optimize is imported only once the input has passed its checks (fast errors).
    from dva_offline.isolator.identification import identify

    result = identify(
        omega, h, args.mass, args.static_stiffness, n, args.natural_frequency_rad_s,
        args.damping_ratio, args.modal_estimate, objective=args.objective,
        weighting=args.weighting,
    )
    mf = result.modal_fit
    _check_units(args, omega, h, args.mass, args.static_stiffness, mf.natural_frequency_rad_s)
    fit = result.fit
    model = fit.model
    wn, zeta = result.target_natural_frequency_rad_s, result.target_damping_ratio
    payload = {"file": str(args.file), "mass_kg": model.mass,
               "static_stiffness_n_per_m": model.k, **_fit_json(fit)}
    payload.update({
        "element_types": [t.label for t in fit.element_types],
        "target_natural_frequency_rad_s": wn,
        "target_damping_ratio": zeta,
        "target_sources": {"natural_frequency": result.target_sources[0],
                           "damping_ratio": result.target_sources[1]},
        "modal_estimate": {
            "method": "modal solution of the unconstrained fit",
            "natural_frequency_rad_s": mf.natural_frequency_rad_s,
            "natural_frequency_std": mf.natural_frequency_std,
            "damping_ratio": mf.damping_ratio,
            "damping_ratio_std": mf.damping_ratio_std,
        },
        "frf_error_definition": "||H_model - H||_2 / ||H||_2 over the receptance points",
        "r_squared": _r_squared(model, omega, h),
        "unconstrained_fit": _fit_json(mf.fit),
        "constraint_check": None,
        "order": {
            "requested": mf.requested_elements, "selected": model.n_elements,
            "orders": list(mf.orders), "frf_errors": list(mf.order_frf_errors),
            "f_test_p_values": list(mf.order_p_values),
            "reductions": list(result.reductions),
        },
        "warnings": list(result.warnings),
        "covariates": sorted(data.covariates),
    })
    check = result.constraint_check
    if check is not None:
        payload["constraint_check"] = {
            "f_statistic": check.f_statistic, "p_value": check.p_value, "dof": check.dof,
            "frf_error_constrained": check.frf_error_constrained,
            "frf_error_unconstrained": check.frf_error_unconstrained,
            "z_natural_frequency": check.z_natural_frequency,
            "z_damping_ratio": check.z_damping_ratio, "rejected": check.rejected,
            "constraints": list(check.named), "message": check.message,
        }
    if args.elements == "auto":
        payload["order_selection"] = {
            "orders": list(mf.orders), "frf_errors": list(mf.order_frf_errors),
            "selected_order": model.n_elements,
        }
    if args.quantity == "modulus":
        payload["geometry_factor_m"] = geometry_factor(args.area, args.thickness,
                                                       args.geometry_factor)
    if args.plot:
        from dva_offline.isolator.plots import plot_frf

        f_hz = omega / (2 * np.pi)
        n = model.n_elements
        label = "identified " + ("M-" * n + "V" if n <= 3 else f"model, {n} Maxwell elements")
        measured = "measured" if data.quantity == "receptance" else (
            f"measured ({args.quantity} converted)")
        title = (f"{Path(args.file).name}: identified with ωₙ = {wn:.1f} rad/s, "
                 f"ζ = {zeta:.4f} imposed\nrelative FRF error {fit.frf_error:.3g}")
        plot_frf(args.plot, [(measured, f_hz, h, "k."), (label, f_hz, frf(model, omega), "r-")],
                 "receptance", title)
        payload["plot"] = str(args.plot)
    src = {"fit": "unconstrained fit", "half-power": "zero crossing / half power",
           "given": "given"}
    lines = [
        f"from the data (unconstrained fit): w_n = {mf.natural_frequency_rad_s:.6g} +- "
        f"{mf.natural_frequency_std:.2g} rad/s, zeta = {mf.damping_ratio:.5g} +- "
        f"{mf.damping_ratio_std:.2g}, FRF error {mf.fit.frf_error:.4f}",
        f"target: w_n = {wn:.3f} rad/s ({src[result.target_sources[0]]}), zeta = {zeta:.4f} "
        f"({src[result.target_sources[1]]}); static stiffness {model.k:.6g} N/m",
        f"elements: {model.n_elements} of at most {mf.requested_elements}",
        *(f"order rule: {r}" for r in result.reductions),
        f"c = {model.c:.6g} +- {fit.c_std:.2g} N s/m",
        *(f"element {i + 1}: k = {e['k']:.6g} +- {e['k_std']:.2g} N/m, c = {e['c']:.6g} +- "
          f"{e['c_std']:.2g} N s/m, Type {e['type']} (w_n tau = {e['omega_tau']:.3f})"
          for i, e in enumerate(payload["elements"])),
        f"relative FRF error {fit.frf_error:.4f}, R^2 = {payload['r_squared']:.6f}",
        *([f"constraint check: F = {check.f_statistic:.3g}, p = {check.p_value:.2g}"
           + (" (rejected)" if check.rejected else " (consistent with the data)")]
          if check is not None else []),
        *(f"warning: {w}" for w in result.warnings),
    ]
    emit(args, payload, lines)
    return 0


def _cmd_estimate(args) -> int:
    from dva_offline.isolator.frf_estimation import estimate_frf

    series = isolator_files.read_time_series_csv(
        args.file, args.force_column, args.response_column, args.fs
    )
    est = estimate_frf(series.force, series.response, series.fs, args.nfft, args.window)
    h = est.h1 if args.estimator == "h1" else est.h2
    keep = (est.frequency_hz > 0) & (est.frequency_hz <= (args.fmax_hz or np.inf))
    isolator_files.write_frf_csv(
        args.out, est.frequency_hz[keep], h[keep], {"coherence": est.coherence[keep]}
    )
    payload = {
        "out": str(args.out), "fs_hz": series.fs, "nfft": args.nfft, "window": args.window,
        "estimator": args.estimator, "n_points": int(keep.sum()),
        "responses": list(series.response_names),
        "mean_coherence": float(np.nanmean(est.coherence[keep])),
    }
    emit(args, payload, [f"wrote {payload['n_points']} FRF points to {args.out} "
                          f"(mean coherence {payload['mean_coherence']:.3f})"])
    return 0


def _cmd_stepped_sine(args) -> int:
    args.quantity = args.quantity or "receptance"
    if args.quantity in ("receptance", "accelerance"):
        not_with(args, f"converts stiffness or modulus to receptance; {args.quantity} needs "
                       "no mass", "--mass")
    data = _read_frf(args)
    if args.mass is not None and not args.mass > 0:
        raise ValueError(f"--mass must be > 0 kg, got {args.mass}")
    omega, h = to_receptance(data, args.mass)
    try:
        est = estimate_modal(omega, h)
    except ValueError as exc:
        raise ValueError(f"{args.file}: {exc}") from None
    two_pi = 2 * np.pi
    f_hz = omega / two_pi
    band = (omega >= est.half_power_lower_rad_s) & (omega <= est.half_power_upper_rad_s)
    warn = []
    if band.sum() < 3:
        warn.append(
            f"only {int(band.sum())} step(s) between the half-power points: the damping ratio "
            "is coarse; use finer steps near resonance"
        )
    payload = {
        "file": str(args.file),
        "quantity": args.quantity,
        "n_steps": int(data.frequency_hz.size),
        "frequency_min_hz": float(data.frequency_hz[0]),
        "frequency_max_hz": float(data.frequency_hz[-1]),
        "natural_frequency_rad_s": est.natural_frequency_rad_s,
        "natural_frequency_hz": est.natural_frequency_rad_s / two_pi,
        "damping_ratio": est.damping_ratio,
        "half_power_lower_hz": est.half_power_lower_rad_s / two_pi,
        "half_power_upper_hz": est.half_power_upper_rad_s / two_pi,
        "peak_hz": est.peak_rad_s / two_pi,
        "method": "w_n: zero crossing of Re(receptance); zeta: half-power points of |receptance|",
        "warnings": warn,
        "covariates": sorted(data.covariates),
    }
    if args.out:
        isolator_files.write_frf_csv(args.out, data.frequency_hz, data.values, data.covariates)
        payload["out"] = str(args.out)
        payload["out_quantity"] = data.quantity
    if args.plot:
        from dva_offline.isolator.plots import plot_modal_estimate

        title = f"{Path(args.file).name}: stepped-sine modal estimate"
        if data.quantity != "receptance":
            title += f" ({args.quantity} converted to receptance)"
        plot_modal_estimate(args.plot, f_hz, h, est, title)
        payload["plot"] = str(args.plot)
    lines = [
        f"{payload['n_steps']} steps, {payload['frequency_min_hz']:g}-"
        f"{payload['frequency_max_hz']:g} Hz",
        f"natural frequency {est.natural_frequency_rad_s:.2f} rad/s "
        f"({payload['natural_frequency_hz']:.3f} Hz) from the zero crossing of Re(H)",
        f"damping ratio {est.damping_ratio:.4f} from the half-power points "
        f"{payload['half_power_lower_hz']:.3f} and {payload['half_power_upper_hz']:.3f} Hz",
        *([f"wrote {data.quantity} FRF to {args.out}"] if args.out else []),
        *(f"warning: {w}" for w in warn),
    ]
    emit(args, payload, lines)
    return 0


def _cmd_static(args) -> int:
    from dva_offline.isolator.frf_estimation import static_stiffness_from_load_deflection

    if (args.center_m is None) != (args.half_width_m is None):
        raise ValueError("--center-m and --half-width-m choose the range together: give both")
    x, f = isolator_files.read_load_deflection_csv(args.file)
    res = static_stiffness_from_load_deflection(x, f, args.center_m, args.half_width_m)
    payload = {
        "static_stiffness_n_per_m": res.stiffness_n_per_m, "offset_n": res.offset_n,
        "n_points": res.n_points, "rms_residual_n": res.rms_residual_n,
    }
    emit(args, payload, [f"static stiffness {res.stiffness_n_per_m:.6g} N/m "
                          f"from {res.n_points} points"])
    return 0


def _cmd_plot(args) -> int:
    from dva_offline.isolator.plots import parametric_study_figures, plot_frf

    written = []
    if not args.study:
        not_with(args, "is where --study writes its figures: it needs --study", "--plot-dir")
    if not args.file:
        not_with(args, "applies to a FRF file: give FILE", "--plot", *FRF_INPUT_OPTIONS,
                 "--mass", "--k", "--c", "--maxwell")
    elif (args.mass is None) != (args.k is None):
        raise ValueError("the model over the file needs both --mass and --k")
    elif args.mass is None:
        not_with(args, "is a parameter of the model, which needs --mass and --k", "--c",
                 "--maxwell")
    args.quantity = args.quantity or "receptance"
    if args.study:
        if not args.plot_dir:
            raise ValueError("--study needs --plot-dir DIR")
        written += [str(p) for p in parametric_study_figures(args.plot_dir)]
    if args.file:
        if not args.plot:
            raise ValueError("plotting a FRF file needs --plot FILE.png")
        data = _read_frf(args)
        curves = [("measured", data.frequency_hz, data.values, "k.")]
        if args.mass is not None and args.k is not None:
            args.c = 0.0 if args.c is None else args.c
            model = _model_from_args(args)
            curves.append(("model", data.frequency_hz,
                           frf(model, data.omega_rad_s, data.quantity), "r-"))
        title = Path(args.file).name
        if args.quantity == "modulus":
            title += " (modulus x A/h)"
        written.append(str(plot_frf(args.plot, curves, data.quantity, title)))
    if not written:
        raise ValueError("nothing to plot: give a FRF file with --plot, or --study --plot-dir")
    emit(args, {"plots": written}, [f"wrote {p}" for p in written])
    return 0


def register(subparsers) -> None:
    """Add the ``isolator`` subcommand to the ``dva`` parser."""
    parser = subparsers.add_parser(
        "isolator",
        help="rubber isolator models: modal analysis, identification, FRF estimation",
        description=__doc__,
    )
    sub = parser.add_subparsers(dest="isolator_command", metavar="<action>", required=True)

    def common(p):
        p.add_argument("--json", action="store_true", help="print one JSON object on stdout")

    p = sub.add_parser("modal", help="natural frequency, damping ratio and element types")
    p.add_argument("--mass", type=float, required=True, help="mass [kg]")
    p.add_argument("--k", type=float, required=True, help="primary stiffness [N/m]")
    p.add_argument("--c", type=float, required=True, help="primary damping [N s/m]")
    p.add_argument("--maxwell", type=_maxwell_pair, action="append", metavar="K,C",
                   help="Maxwell element stiffness [N/m] and damping [N s/m]; repeat")
    common(p)
    p.set_defaults(func=_cmd_modal)

    def frf_input(p, default_format="csv"):
        p.set_defaults(default_format=default_format)
        p.add_argument("--quantity",
                       choices=("receptance", "accelerance", "stiffness", "modulus"),
                       default=None,
                       help="what the file holds: receptance [m/N] (default), accelerance "
                            "[(m/s^2)/N], complex stiffness [N/m] or a material's complex "
                            "modulus E', E'' [Pa] (needs --area and --thickness, or "
                            "--geometry-factor)")
        p.add_argument("--format", choices=("csv", "stepped-sine", "uff58"),
                       default=None,
                       help="csv: frequency_hz,real,imag; stepped-sine: also amplitude/phase "
                            f"per step; uff58 (default {default_format}; .uff/.unv files are "
                            "read as UFF 58)")
        p.add_argument("--area", type=float, default=None, metavar="M2",
                       help="modulus only: loaded area A of the rubber specimen [m^2]")
        p.add_argument("--thickness", type=float, default=None, metavar="M",
                       help="modulus only: thickness h of the rubber specimen [m]")
        p.add_argument("--geometry-factor", type=float, default=None, metavar="M",
                       help="modulus only: A/h [m], so that K* = E* A/h")
        p.add_argument("--fmin-hz", type=float, default=None, help="use points >= this [Hz]")
        p.add_argument("--fmax-hz", type=float, default=None, help="use points <= this [Hz]")
        p.add_argument("--min-coherence", type=float, default=None,
                       help="use points whose 'coherence' column is >= this")

    p = sub.add_parser("identify", help="identify a general Maxwell model from a measured FRF")
    p.add_argument("file", help="FRF file: CSV frequency_hz,real,imag[,covariates] or UFF 58")
    frf_input(p)
    p.add_argument("--mass", type=float, required=True, help="isolated mass [kg]")
    p.add_argument("--static-stiffness", type=float, required=True,
                   help="static stiffness k [N/m]")
    p.add_argument("--elements", default="2",
                   help="largest number of Maxwell elements (degenerate ones are merged or "
                        "dropped by the order rule), or 'auto' (= --max-elements)")
    p.add_argument("--max-elements", type=int, default=None,
                   help="largest order for --elements auto (default 3)")
    p.add_argument("--natural-frequency-rad-s", type=float, default=None,
                   help="w_n to impose exactly [rad/s]; default: estimated (--modal-estimate)")
    p.add_argument("--damping-ratio", type=float, default=None,
                   help="zeta to impose exactly; default: estimated (--modal-estimate)")
    p.add_argument("--modal-estimate", choices=("fit", "half-power"), default=None,
                   help="how w_n and zeta are estimated when not given: modal solution of an "
                        "unconstrained fit (default, any damping) or zero crossing of Re(H) "
                        "and half-power points (light damping only)")
    p.add_argument("--objective", choices=("l2", "l1"), default="l2")
    p.add_argument("--weighting", choices=("relative", "none"), default="relative")
    p.add_argument("--plot", metavar="FILE.png", help="write measured vs model FRF")
    common(p)
    p.set_defaults(func=_cmd_identify)

    p = sub.add_parser("estimate", help="FRF (H1/H2, coherence) from a time-series CSV")
    p.add_argument("file", help="CSV with time_s, force and response columns")
    p.add_argument("--out", required=True, help="output FRF CSV")
    p.add_argument("--fs", type=float, default=None, help="sampling rate [Hz] (default: time_s)")
    p.add_argument("--nfft", type=int, default=10000, help="FFT/segment length (study: 10000)")
    p.add_argument("--window", default="boxcar", help="window (study: none = boxcar)")
    p.add_argument("--estimator", choices=("h1", "h2"), default="h1")
    p.add_argument("--force-column", default="force_n")
    p.add_argument("--response-column", action="append", default=None,
                   help="response column (repeat; default: all other columns)")
    p.add_argument("--fmax-hz", type=float, default=None, help="highest frequency written")
    common(p)
    p.set_defaults(func=_cmd_estimate)

    p = sub.add_parser(
        "stepped-sine",
        help="natural frequency and damping ratio from stepped-sine data (Table 5.2 method)",
        description="Reads one row per excitation frequency: frequency_hz plus real,imag or "
                    "force_amplitude_n,force_phase_deg,response_amplitude,response_phase_deg. "
                    "w_n is the zero crossing of Re(H), zeta comes from the half-power points "
                    "of |receptance| (study section 5.2).",
    )
    p.add_argument("file", help="stepped-sine CSV")
    frf_input(p, default_format="stepped-sine")
    p.add_argument("--mass", type=float, default=None,
                   help="isolated mass [kg]; needed for --quantity stiffness or modulus")
    p.add_argument("--out", default=None, help="write the FRF as frequency_hz,real,imag CSV")
    p.add_argument("--plot", metavar="FILE.png", help="plot |H| with the half-power points "
                                                      "and Re(H) with its zero crossing")
    common(p)
    p.set_defaults(func=_cmd_stepped_sine)

    p = sub.add_parser("static", help="static stiffness from a load-deflection CSV")
    p.add_argument("file", help="CSV deflection_m,load_n (loading and unloading)")
    p.add_argument("--center-m", type=float, default=None, help="static equilibrium x_o [m]")
    p.add_argument("--half-width-m", type=float, default=None, help="range about x_o [m]")
    common(p)
    p.set_defaults(func=_cmd_static)

    p = sub.add_parser("plot", help="FRF plot of a file (with a model) or Figs. 3.2-3.11")
    p.add_argument("file", nargs="?", help="FRF file to plot")
    frf_input(p)
    p.add_argument("--plot", metavar="FILE.png", help="output PNG for the FRF plot")
    p.add_argument("--study", action="store_true", help="write the Figs. 3.2-3.11 study")
    p.add_argument("--plot-dir", help="directory for --study figures")
    p.add_argument("--mass", type=float, default=None,
                   help="model mass [kg] (with --k: the model is drawn over the file)")
    p.add_argument("--k", type=float, default=None, help="model primary stiffness [N/m]")
    p.add_argument("--c", type=float, default=None,
                   help="model primary damping [N s/m] (default 0)")
    p.add_argument("--maxwell", type=_maxwell_pair, action="append", metavar="K,C",
                   help="model Maxwell element stiffness [N/m] and damping [N s/m]; repeat")
    common(p)
    p.set_defaults(func=_cmd_plot)


if __name__ == "__main__":  # pragma: no cover
    from dva_offline.cli import main

    sys.exit(main(["isolator", *sys.argv[1:]]))
