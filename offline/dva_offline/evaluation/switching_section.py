"""The ``switching`` controller of ``dva evaluate``: the per-sample switching c2 law against
the best constant c2, on paired seeds, in the constant-density cases.

The law runs every 1 ms sample in the damper's own controller, so its flights are the
in-process switched flights of :mod:`dva_offline.switching.study` (`dva switching evaluate`):
the bounded and practical boundaries on the ramp 0.8 -> 1.4 U_cr in 45 s, the leading-edge
RMS, switching rate and damper power at 1.1 U_cr, each difference paired by seed with its 95 %
interval. The gains are the package's file (or ``--gains``), with the damper lag and sensor
noise they were designed for. Seeds: the evaluation's seeds plus
:data:`~dva_offline.switching.cli.EVALUATION_SEEDS`, apart from the design's.
"""
from __future__ import annotations

__all__ = ["LAW", "SWITCHING_CASES", "switching_section"]

LAW = "switching"  # the per-sample law of the controller table this section flies

SWITCHING_CASES = ("rho0", "x0.9", "x1.1")
DESIGN_NOISE = 0.05  # sensor noise / output RMS at U_cr, as `dva switching design` uses


def switching_section(cases, seeds, gains_path: str | None = None) -> dict:
    """Rows of :func:`dva_offline.switching.study.evaluate_setting`, one per case."""
    from aero_dva.control.switching_design import measured_rms
    from aero_dva.data_files import data_file
    from dva_offline.switching.cli import EVALUATION_SEEDS, _gains_for_wing, _reference
    from dva_offline.switching.study import (
        FORCE_STD,
        SAMPLE_RATE,
        Setting,
        evaluate_setting,
    )

    unknown = [c for c in cases if c not in SWITCHING_CASES]
    if unknown:
        raise ValueError(f"--controllers switching flies the constant-density cases "
                         f"{','.join(SWITCHING_CASES)} only, not {','.join(unknown)} "
                         "(choose them with --cases)")

    class _Args:  # what _gains_for_wing reads
        gains = gains_path or str(data_file("switching_gains.json"))
        wing = None
        aero = None

    gains, cfg, model = _gains_for_wing(_Args)
    u_cr, c2, u_fix = _reference(cfg, model)
    sensor_rms = measured_rms(model, u_cr, cfg.air_density, c2, SAMPLE_RATE, FORCE_STD)
    flown = [EVALUATION_SEEDS + s for s in seeds]
    rows = [evaluate_setting(model, gains, Setting(case, gains.time_constant, DESIGN_NOISE,
                                                   case=case), flown, u_cr, c2, sensor_rms)
            for case in cases]
    return {"gains": _Args.gains, "fixed_c2": c2, "fixed_flutter_ratio": u_fix / u_cr,
            "critical_airspeed_no_dva": u_cr, "time_constant": gains.time_constant,
            "sensor_noise": DESIGN_NOISE, "seeds": flown, "rows": rows}


def markdown(section: dict) -> str:
    """The section as a table (the evaluation's markdown output)."""
    def num(v, fmt=".4f", scale=1.0):
        return "n/a" if v is None else format(v * scale, fmt)

    def iv(stat, scale=1.0, fmt="+.4f"):
        return (f"{num(stat['mean'], fmt, scale)} [{num(stat['low'], fmt, scale)}, "
                f"{num(stat['high'], fmt, scale)}]")

    lines = [
        f"## switching law vs best constant c2 ({section['fixed_c2']:.1f} N s/m), "
        f"{len(section['seeds'])} paired seeds, {section['time_constant'] * 1e3:g} ms lag",
        "",
        "| case | practical: fixed / switching [U_cr] | difference | bounded difference | "
        "RMS at 1.1 U_cr | switches/s | damper power fixed / switching [W] |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in section["rows"]:
        p, b, r = row["practical"], row["bounded"], row["rms_at_1.1"]
        power = row["damper_power_w"]
        lines.append(
            f"| {row['setting']['case']} | {num(p['fixed'])} / {num(p['switching'])} | "
            f"{iv(p['difference'])} | {iv(b['difference'])} | "
            f"{iv(r['change'], 100, '+.1f')} % | "
            f"{num(row['switches_per_second']['mean'], '.0f')} | "
            f"{num(power['fixed'], '.1f')} / {num(power['switching'], '.1f')} |")
    return "\n".join(lines)
