"""Every option of every ``dva`` subcommand acts, or is refused in one line that says why.

The walk comes from the argparse tree, so a new option fails :func:`test_the_table_covers_
every_option` until it has a row in :data:`TABLE`: ``ALL`` (it acts in every mode of its
command) or the modes it has no use for, each with a command line of that mode and the words
of its refusal. Every refusal is run: exit code 2, nothing on stdout, one line on stderr naming
the option. Every option is read by its command's code (``args.<dest>``).
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from dva_offline import cli

ALL = "acts in every mode"

# Command lines of the modes below (without the option under test). Paths need not exist:
# a refusal comes before any file is read, except where {csv} (a real FRF table) or {flight} (a
# flight log with c2 held per block) is given.
IDENTIFY = ["f.csv", "--mass", "1", "--static-stiffness", "1e4"]
MAXWELL = ["--absorber", "maxwell", "--k1", "1e5", "--k2", "1e5", "--c2", "600"]
PASSIVE = ["--absorber", "passive", "--k1", "1e5", "--c1", "300"]
REPLAY = ["BAG", "--out", "{new}"]
FRF_READ = ("--quantity", "--format", "--area", "--thickness", "--geometry-factor",
            "--fmin-hz", "--fmax-hz", "--min-coherence")
PLAN = ("--ratios", "--factors", "--n-damping", "--min-decay", "--max-offset", "--window",
        "--seed")
GRAPH_ONLY = ("--mu", "--timeout", "--retries", "--real-time-factor", "--reports", "--no-rrd")
PAIRED_ONLY = ("--cases", "--rms-range", "--no-boundaries", "--one-flight", "--gains", "--ramp-to")


def _wing_absorber(command: str) -> dict:
    """The absorber options of ``dva wing modal|flutter|simulate``."""
    none = (["--absorber", "none"], "sets an absorber, but --absorber none")
    rows = {
        "--absorber": ALL,
        "--m1": ("with an absorber", [none]),
        "--k1": ("with an absorber", [none]),
        "--position": ("with an absorber", [none]),
        "--c1": ("with a passive absorber", [
            ([], "does not apply to the wing file's maxwell absorber"),
            (MAXWELL, "does not apply to --absorber maxwell")]),
        "--k2": ("with a Maxwell absorber", [(PASSIVE, "does not apply to --absorber passive")]),
        "--c2": ("with a Maxwell absorber, without --tune", [
            (PASSIVE, "does not apply to --absorber passive"),
            (["--tune"], "and --tune: --tune chooses c2 itself")]),
        "--tune": ("with an absorber", [(["--absorber", "none"], "--tune needs an absorber")]),
        "--c-max": ("with --tune", [([], "bounds the tuned damper: it needs --tune")]),
        "--aero": ALL,
        "--pitch-damping": ("with quasi-steady aerodynamics", [
            (["--aero", "wagner"], "applies to --aero quasi-steady only")]),
        "--density": ALL, "--wing": ALL, "--json": ALL,
    }
    if command != "simulate":
        rows["--section"] = ALL
    return rows


TABLE: dict[str, dict] = {
    "info": {"--json": ALL},
    "wing modal": {**_wing_absorber("modal"), "--u-max": ALL, "--points": ALL, "--plot": ALL},
    "wing flutter": {**_wing_absorber("flutter"), "--range": ALL},
    "wing design": {"--wing": ALL, "--density": ALL, "--json": ALL, "--plot": ALL},
    "wing simulate": {**_wing_absorber("simulate"), "--start": ALL, "--stop": ALL,
                      "--duration": ALL, "--sample-rate": ALL, "--force-std": ALL,
                      "--flights": ALL, "--seed": ALL, "--plot": ALL},
    "isolator modal": {o: ALL for o in ("--mass", "--k", "--c", "--maxwell", "--json")},
    "isolator identify": {
        "file": ALL, "--quantity": ALL, "--fmin-hz": ALL, "--fmax-hz": ALL,
        "--min-coherence": ALL, "--mass": ALL, "--static-stiffness": ALL, "--elements": ALL,
        "--natural-frequency-rad-s": ALL, "--damping-ratio": ALL, "--objective": ALL,
        "--weighting": ALL, "--plot": ALL, "--json": ALL,
        "--format": ("with a file whose suffix does not say UFF 58", [
            (["f.uff", "--mass", "1", "--static-stiffness", "1e4"], "is read as UFF 58")]),
        **{o: ("with --quantity modulus", [(IDENTIFY, "apply only to --quantity modulus")])
           for o in ("--area", "--thickness", "--geometry-factor")},
        "--max-elements": ("with --elements auto", [(IDENTIFY, "largest order of --elements "
                                                               "auto")]),
        "--modal-estimate": ("unless both w_n and zeta are given", [
            ([*IDENTIFY, "--natural-frequency-rad-s", "100", "--damping-ratio", "0.1"],
             "estimates w_n and zeta, but both are given")]),
    },
    "isolator estimate": {o: ALL for o in (
        "file", "--out", "--fs", "--nfft", "--window", "--estimator", "--force-column",
        "--response-column", "--fmax-hz", "--json")},
    "isolator stepped-sine": {
        "file": ALL, "--quantity": ALL, "--fmin-hz": ALL, "--fmax-hz": ALL,
        "--min-coherence": ALL, "--out": ALL, "--plot": ALL, "--json": ALL,
        "--format": ("with a file whose suffix does not say UFF 58", [
            (["f.uff"], "is read as UFF 58")]),
        **{o: ("with --quantity modulus", [(["f.csv"], "apply only to --quantity modulus")])
           for o in ("--area", "--thickness", "--geometry-factor")},
        "--mass": ("with --quantity stiffness or modulus", [
            (["f.csv"], "receptance needs no mass"),
            (["f.csv", "--quantity", "accelerance"], "accelerance needs no mass")]),
    },
    "isolator static": {
        "file": ALL, "--json": ALL,
        "--center-m": ("with --half-width-m", [(["f.csv"], "give both")]),
        "--half-width-m": ("with --center-m", [(["f.csv"], "give both")]),
    },
    "isolator plot": {
        "file": ALL, "--study": ALL, "--json": ALL,
        **{o: ("with a FRF file", [(["--study", "--plot-dir", "{dir}"],
                                    "applies to a FRF file: give FILE")])
           for o in (*FRF_READ, "--plot")},
        "--plot-dir": ("with --study", [(["f.csv", "--plot", "x.png"], "it needs --study")]),
        "--mass": ("with a FRF file and --k", [
            (["--study", "--plot-dir", "{dir}"], "applies to a FRF file"),
            (["f.csv", "--plot", "x.png"], "needs both --mass and --k")]),
        "--k": ("with a FRF file and --mass", [
            (["--study", "--plot-dir", "{dir}"], "applies to a FRF file"),
            (["f.csv", "--plot", "x.png"], "needs both --mass and --k")]),
        **{o: ("with a FRF file, --mass and --k", [
            (["--study", "--plot-dir", "{dir}"], "applies to a FRF file"),
            (["f.csv", "--plot", "x.png"], "needs --mass and --k")])
           for o in ("--c", "--maxwell")},
    },
    "discrepancy frf": {
        "file": ALL, "--quantity": ALL, "--mass": ALL, "--static-stiffness": ALL,
        "--elements": ALL, "--holdout-every": ALL, "--holdout-seed": ALL, "--max-steps": ALL,
        "--plot-dir": ALL, "--json": ALL,
        **{o: ("with a CSV table", [(["f.uff"], "a UFF 58 file carries its own")])
           for o in ("--columns", "--frequency-unit", "--value-unit", "--group-by",
                     "--covariate-tolerance", "--covariates")},
        "--max-elements": ("with --elements auto", [(["f.csv", "--elements", "2"],
                                                      "largest order of --elements auto")]),
        "--averages": ("with a coherence column", [(["{csv}"], "a coherence column")]),
        "--replicates": ("with a CSV table that has the column", [
            (["f.uff"], "a UFF 58 file carries its own"),
            (["{csv}"], "--replicates column 'x' not found")]),
    },
    "discrepancy modal": {
        "file": ALL, "--quantity": ALL, "--columns": ALL, "--frequency-unit": ALL,
        "--value-unit": ALL, "--group-by": ALL, "--covariate-tolerance": ALL,
        "--modes": ALL, "--modal-constants": ALL, "--covariates": ALL, "--holdout-every": ALL,
        "--holdout-seed": ALL,
        "--max-steps": ALL, "--plot-dir": ALL, "--json": ALL,
        "--max-modes": ("with --modes auto", [(["f.csv", "--modes", "2"],
                                                "largest order of --modes auto")]),
        "--averages": ("with a coherence column", [(["{csv}"], "a coherence column")]),
        "--replicates": ("with a table that has the column", [
            (["{csv}"], "--replicates column 'x' not found")]),
    },
    "discrepancy synth-structure": {o: ALL for o in (
        "--effect", "--seed", "--out", "--quantity", "--sigma", "--jitter", "--json")},
    "discrepancy synth": {o: ALL for o in (
        "--effect", "--seed", "--out", "--quantity", "--sigma", "--points", "--system",
        "--clean-covariate", "--json")},
    "discrepancy flight": {
        **{o: ALL for o in (
            "file", "--wing", "--namespace", "--band", "--window", "--segment-windows",
            "--settle", "--route", "--holdout-every", "--holdout-seed", "--plot-dir", "--json",
            "--allow-truncated")},
        "--damper-lag": ("with a per-sample law's flight", [
            (["{flight}"], "no per-sample law flew this log")])},
    "discrepancy synth-flight": {o: ALL for o in ("--effect", "--seed", "--dwell", "out",
                                                  "--json")},
    "control optimal-c2": {
        **{o: ALL for o in ("--wing", "--density", "--objective", "--airspeeds", "--relative",
                            "--c2-range", "--force-std", "--sample-rate", "--method", "--plot",
                            "--json", "--surface", "--check-simulation")},
        "--curves": ("with --plot", [([], "it needs --plot")]),
        **{o: ("with --check-simulation", [([], "it needs --check-simulation")])
           for o in ("--sim-duration", "--flights", "--seed")},
    },
    "control schedule": {o: ALL for o in (
        "--wing", "--density", "--objective", "--airspeeds", "--relative", "--c2-range",
        "--force-std", "--sample-rate", "--method", "--plot", "--json", "--fit-range",
        "--damping-range", "--out")},
    "train plan": {o: ALL for o in ("--wing", *PLAN, "--out", "--json")},
    "train sweep": {
        "--out": ALL, "--no-displacement": ALL, "--scenario": ALL, "--json": ALL,
        "--plan": ("without --scenario", [(["--scenario", "s.yaml"], "not a --scenario sweep")]),
        "--wing": ("without --scenario", [(["--scenario", "s.yaml"], "not a --scenario sweep")]),
        **{o: ("without --plan and --scenario", [
            (["--plan", "p.json"], "makes a plan, but --plan gives one"),
            (["--scenario", "s.yaml"], "not a --scenario sweep")])
           for o in PLAN if o not in ("--min-decay", "--window")},
        **{o: ("without --plan and --as-is", [
            (["--plan", "p.json"], "makes a plan, but --plan gives one"),
            (["--scenario", "s.yaml", "--as-is"], "which --as-is flies unchanged")])
           for o in ("--min-decay", "--window")},
        **{o: ("with --scenario, without --as-is", [
            ([], "it needs --scenario"),
            (["--scenario", "s.yaml", "--as-is"], "which --as-is flies unchanged")])
           for o in ("--c2", "--settle")},
        **{o: ("with --scenario", [([], "it needs --scenario")]) for o in ("--as-is", "--jobs")},
    },
    "train rbf": {
        **{o: ALL for o in ("bag", "--out", "--labels", "--plot", "--window", "--spreads",
                            "--validation-every", "--max-neurons", "--max-candidates",
                            "--tolerance", "--min-activation", "--allow-partial", "--json")},
        "--wing": ("with --labels exact", [(["BAG", "--out", "n.npz", "--labels",
                                             "measured-argmin"], "uses none")]),
    },
    "evaluate": {
        **{o: ALL for o in ("--out", "--seeds", "--first-seed", "--controllers", "--scenario",
                            "--json", "--workers", "--ray", "--graph")},
        **{o: ("with --graph", [([], "it needs --graph")]) for o in GRAPH_ONLY},
        **{o: ("without --graph", [(["--graph"], "is not an option of --graph")])
           for o in PAIRED_ONLY if o != "--gains"},
        "--gains": ("with --controllers ...,switching or ...,clipped_optimal", [
            ([], "switching or clipped_optimal controller, which is not flown"),
            (["--graph"], "is not an option of --graph")]),
        "--schedule": ("when the schedule is flown", [
            (["--controllers", "fixed"], "schedule controller, which is not flown"),
            (["--graph", "--controllers", "none"], "schedule controller, which is not flown")]),
        "--network": ("when the network is flown", [
            (["--controllers", "fixed,schedule"], "rbf controller, which is not flown")]),
        "--sweep-bag": ("when the network is flown and not given", [
            (["--controllers", "fixed"], "rbf controller, which is not flown"),
            (["--controllers", "rbf", "--network", "n.npz"], "but --network gives one")]),
        "--fixed-c2": ("when the fixed c2 is flown", [
            (["--graph", "--controllers", "none,schedule"],
             "fixed controller, which is not flown")]),
    },
    "report": {o: ALL for o in ("run", "--out", "--no-rrd", "--json", "--allow-truncated")},
    "replay": {
        "bag": ALL, "--controller": ALL, "--out": ALL, "--offline": ALL, "--json": ALL,
        "--network": ("with --controller rbf", [
            ([*REPLAY, "--controller", "fixed"], "is for --controller rbf, not fixed")]),
        "--schedule": ("with --controller schedule", [
            ([*REPLAY, "--controller", "fixed"], "is for --controller schedule, not fixed")]),
        "--damping": ("with --controller fixed", [
            ([*REPLAY, "--controller", "schedule", "--schedule", "s.json"],
             "is for --controller fixed, not schedule")]),
        **{o: ("on the ROS path", [([*REPLAY, "--controller", "fixed", "--offline"],
                                    "is an option of the ROS path")])
           for o in ("--rate", "--retries")},
        **{o: ("with a per-sample law's --controller", [
            ([*REPLAY, "--controller", "fixed"], "is for a per-sample law's flight")])
           for o in ("--scenario", "--wing")},
    },
    "bag info": {o: ALL for o in ("bag", "--no-verify", "--json")},
    "bag recover": {o: ALL for o in ("bag", "--out", "--compression", "--json")},
    "switching design": {o: ALL for o in (
        "--out", "--wing", "--design", "--design-airspeed", "--c-lo", "--c-hi", "--lag",
        "--efforts", "--leads", "--seeds", "--noise", "--aero")},
    "switching evaluate": {o: ALL for o in (
        "--gains", "--wing", "--seeds", "--lags", "--noises", "--mismatches", "--force-limits",
        "--yield-forces", "--blocks", "--no-wagner", "--noise", "--cases", "--json", "--aero")},
    "switching plot": {o: ALL for o in ("--gains", "--out", "--wing", "--seed", "--aero")},
    "switching mechanism": {o: ALL for o in (
        "--gains", "--effort", "--airspeed", "--seeds", "--wing", "--json")},
}

#: Values for the options whose type a plain number or word does not satisfy.
VALUES = {"--maxwell": "1e4,10", "--rms-range": "0.8:1.0", "--mu": "0.1", "--c2": "600",
          "--curves": "1.0", "--ratios": "0.9:1.0:0.05", "--factors": "1.0",
          "--columns": "frequency=f", "--format": "csv", "--jobs": "2"}


def _leaves(parser: argparse.ArgumentParser, path=()):
    """(command path, parser) of every command that runs (no subcommands of its own)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield " ".join(path), parser
        return
    for name, sub in subs[0].choices.items():
        yield from _leaves(sub, (*path, name))


def _options(parser) -> dict[str, argparse.Action]:
    """Each option (its first long name) or positional (its dest) -> its action."""
    out = {}
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._VersionAction)):
            continue
        names = [o for o in action.option_strings if o.startswith("--")]
        out[names[0] if names else action.dest] = action
    return out


LEAVES = dict(_leaves(cli.build_parser()))


def test_the_table_covers_every_option():
    """A row per option of every command, and no row for an option that is gone."""
    assert set(LEAVES) == set(TABLE), "commands without a row or rows without a command"
    for command, parser in LEAVES.items():
        assert set(_options(parser)) == set(TABLE[command]), command


def _refusals():
    for command, rows in TABLE.items():
        for option, row in rows.items():
            if row is ALL:
                continue
            applies, modes = row
            for i, (mode, words) in enumerate(modes):
                yield pytest.param(command, option, mode, words, id=f"{command} {option} {i}")


def _value(action: argparse.Action, option: str) -> list[str]:
    if action.nargs == 0:
        return []
    if option in VALUES:
        return [VALUES[option]]
    if action.choices:
        return [list(action.choices)[-1]]
    if action.nargs == 2:
        return ["1", "2"]
    return ["2" if action.type is int else "1.5" if action.type is float else "x"]


@pytest.fixture(scope="module")
def frf_csv(tmp_path_factory) -> Path:
    """A FRF table without a coherence column."""
    path = tmp_path_factory.mktemp("frf") / "table.csv"
    assert cli.main(["discrepancy", "synth", "--effect", "none", "--seed", "1", "--out",
                     str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def held_flight(tmp_path_factory) -> Path:
    """A 2.5 s flight log whose c2 is held per block (no per-sample law flew it)."""
    from aero_dva.bag.runtime_recording import record_runtime
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    scenario = tmp_path_factory.mktemp("flight") / "hold.yaml"
    scenario.write_text("name: hold\nduration: 2.5\nblock_size: 50\n"
                        "airspeed: {kind: constant, value: 60.0}\n")
    bag = scenario.parent / "bag"
    record_runtime(bag, FlightRuntime(load_runtime_config({"scenario": str(scenario)})))
    return bag


@pytest.mark.parametrize("command,option,mode,words", list(_refusals()))
def test_an_option_its_mode_has_no_use_for_is_refused_in_one_line(
        command, option, mode, words, tmp_path, frf_csv, capsys, request):
    fill = {"{new}": str(tmp_path / "new"), "{dir}": str(tmp_path / "figs"),
            "{csv}": str(frf_csv)}
    if "{flight}" in mode:
        fill["{flight}"] = str(request.getfixturevalue("held_flight"))
    capsys.readouterr()
    mode = [fill.get(a, a) for a in mode]
    argv = [*command.split(), *mode, option,
            *_value(_options(LEAVES[command])[option], option)]
    code = cli.main(argv)
    out, err = capsys.readouterr()
    assert code == 2, (argv, err)
    assert out == "" and len(err.strip().splitlines()) == 1, (argv, out, err)
    assert err.startswith(f"dva {command.split()[0]}: error: ") and option in err, err
    assert words in err, err
    assert not (tmp_path / "new").exists() and not (tmp_path / "figs").exists()


SOURCES = Path(cli.__file__).parent


@pytest.mark.parametrize("command", sorted(TABLE))
def test_every_option_is_read_by_its_command(command):
    """A cheap guard against an option that nothing reads: its dest appears as ``args.DEST``
    (or as the name ``"DEST"`` that code looks up with getattr) in its command family's code
    or the shared CLI tools; a controller's option (the controller table's, which the code
    reads through its entry as ``getattr(args, option.name)``) where the family reads the
    entry's options so."""
    from aero_dva.control.controllers import controllers

    table_options = {o.name for c in controllers() for o in c.options}
    parser = LEAVES[command]
    family = Path(__import__(parser.get_default("func").__module__,
                             fromlist=["_"]).__file__).parent
    files = [SOURCES / "cli_tools.py", *sorted(family.glob("*.py"))]
    text = "\n".join(f.read_text() for f in files)
    for option, action in _options(parser).items():
        dest = action.dest
        read = re.search(rf"\bargs\.{dest}\b|[\"']{dest}[\"']", text) or (
            dest in table_options and "getattr(args, option.name" in text)
        assert read, f"dva {command}: nothing reads {option} (args.{dest})"
