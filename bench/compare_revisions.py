"""Every benchmark of bench/, run on an earlier revision and on this tree, side by side.

    source scripts/env.sh && python bench/compare_revisions.py --base REV [--runs 3]
        [--only NAME ...] [--list]

Checks out REV into a temporary git worktree and runs each benchmark script as a whole process,
with the same (small) arguments, alternately on REV and on the working tree, ``--runs`` times
each. The earlier revision's packages come first on PYTHONPATH (its layout: ROS package
sources and offline/, or aero_dva/ and offline/), with this tree's virtual environment. For the
node-graph benchmark the earlier revision's ROS workspace is built with colcon into the
temporary worktree first. Prints per benchmark the median wall time and the median CPU time of
the process and its children on each revision, and their ratio (this tree / base): below 1 is
faster. CPU time is the figure to trust on a loaded machine.
A benchmark that does more work than on the base gets a second row, "(same work)", with the
arguments that do the base's work (``SAME_WORK_NOW``); the closing line's largest ratio is over
the rows of the same work. A benchmark new since the base runs on this tree only (its times are
printed, to show it runs). A benchmark that fails on either side is reported with its exit code
and last line of output.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# Benchmark -> arguments of a short run that exercises the same code as the default run.
BENCHMARKS = {
    "bench_batch_recording": ["--blocks", "4000", "--baseline-blocks", "100",
                              "--reference-blocks", "400"],
    "bench_discrepancy": ["2"],
    "bench_discrepancy_acceptance": ["--cases", "2"],
    "bench_discrepancy_flight": ["1", "100"],
    "bench_graph": [],
    "bench_isolator_fit": ["--repeats", "2"],
    "bench_isolator_identify": ["--cases", "2"],
    "bench_optimal_damping": ["--repeats", "1", "--airspeeds", "50", "--c2", "40",
                              "--duration", "2"],
    "bench_sweep_recording": ["--airspeeds", "12", "--stepped-airspeeds", "1"],
    "bench_wing_flutter": [],
    "bench_wing_sim": ["--flights", "16", "--repeats", "1"],
    # new since the layout move: listed, not compared, against a base without them
    "bench_bag_player": [],
    "bench_flight_log_read": ["--blocks", "4000"],
    "bench_discrepancy_combined": ["--cases", "1", "--only", "pairs"],
    "bench_discrepancy_laws": ["--cases", "1", "--only", "power_level,structure_clean"],
    "bench_discrepancy_real": ["--only", "pi88k"],
    "bench_faults": ["--trials", "1", "--only", "burst"],
    "bench_evaluate_workers": ["--runs", "1", "--seeds", "2", "--cases", "rho0",
                               "--controllers", "fixed,oracle"],
    "bench_flight_runtime": ["--repeats", "1"],
}
NEEDS_ROS_BUILD = {"bench_graph"}
# Benchmarks that do more since the base: arguments of this tree's run that do the base's work,
# compared on a second row. The discrepancy loop now adds effects until the residual is
# explained (the base stopped after the first); bench_graph also flies the spectrum graph.
SAME_WORK_NOW = {"bench_discrepancy": ["--max-steps", "1"],
                 "bench_discrepancy_acceptance": ["--max-steps", "1"],
                 "bench_graph": ["--schedule-only"]}


@dataclass(frozen=True)
class Run:
    wall: float
    cpu: float
    code: int
    tail: str


@contextlib.contextmanager
def base_worktree(rev: str):
    """A temporary git worktree of ``rev`` (detached), removed afterwards; its path."""
    base_dir = Path(tempfile.mkdtemp(prefix="dva-bench-base-"))
    try:
        subprocess.run(["git", "worktree", "add", "--detach", str(base_dir), rev],
                       cwd=REPO, check=True, capture_output=True)
        yield base_dir
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base_dir)], cwd=REPO,
                       capture_output=True)
        shutil.rmtree(base_dir, ignore_errors=True)


def python_path(tree: Path) -> list[str]:
    """The package roots of a checkout, whatever its layout."""
    roots = [tree / "aero_dva", tree / "offline", tree / "ros_ws/src/aero_dva_sim",
             tree / "ros_ws/src/dva_controller", tree / "ros_ws/src/dva_ros_common"]
    return [str(p) for p in roots if p.is_dir()]


def build_workspace(tree: Path) -> dict[str, str]:
    """colcon-build ``tree``'s ROS packages into ``tree/ros_ws/install``; its environment."""
    env = dict(os.environ)
    venv = Path(sys.prefix)
    env["AMENT_PREFIX_PATH"] = f"{venv}:{env.get('AMENT_PREFIX_PATH', '')}".rstrip(":")
    env["CMAKE_PREFIX_PATH"] = f"{venv}:{env.get('CMAKE_PREFIX_PATH', '')}".rstrip(":")
    subprocess.run([sys.executable, "-m", "colcon", "build", "--symlink-install",
                    "--event-handlers", "console_cohesion-", "--cmake-args",
                    f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"],
                   cwd=tree / "ros_ws", env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.STDOUT)
    setup = tree / "ros_ws/install/local_setup.bash"
    out = subprocess.run(["bash", "-c", f"source {setup} >/dev/null && env -0"],
                         capture_output=True, env=env, check=True).stdout
    return dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)


def run_once(tree: Path, name: str, args: list[str], env: dict[str, str]) -> Run:
    env = dict(env)
    env["PYTHONPATH"] = ":".join(python_path(tree) + [env.get("PYTHONPATH", "")]).rstrip(":")
    script = tree / "bench" / f"{name}.py"
    start = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen([sys.executable, str(script), *args], cwd=tree, env=env,
                                stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        out.seek(0)
        lines = out.read().decode(errors="replace").strip().splitlines()
    return Run(wall, usage.ru_utime + usage.ru_stime, os.waitstatus_to_exitcode(status),
               lines[-1] if lines else "")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", required=True, help="the earlier revision (commit, tag)")
    parser.add_argument("--runs", type=int, default=3, help="runs per side (default 3)")
    parser.add_argument("--only", nargs="*", default=None, metavar="NAME",
                        help="benchmarks to run (default: all of bench/)")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    args = parser.parse_args(argv)
    present = sorted(p.stem for p in (REPO / "bench").glob("bench_*.py"))
    missing = [name for name in (args.only or present) if name not in BENCHMARKS]
    if missing:
        print(f"compare_revisions: error: no short arguments for {', '.join(missing)}",
              file=sys.stderr)
        return 2
    names = args.only or present
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        print(f"compare_revisions: error: unknown benchmark {', '.join(unknown)}",
              file=sys.stderr)
        return 2
    if args.list:
        print("\n".join(f"{n} {' '.join(BENCHMARKS[n])}" for n in names))
        return 0
    if args.runs < 1:
        print("compare_revisions: error: --runs must be >= 1", file=sys.stderr)
        return 2
    with base_worktree(args.base) as base_dir:
        base_env = current_env = dict(os.environ)
        if NEEDS_ROS_BUILD & set(names):
            print(f"building the ROS workspace of {args.base} ...", file=sys.stderr)
            base_env = build_workspace(base_dir)
        print(f"base {args.base} vs this tree, {args.runs} run(s) each, alternating")
        print(f"{'benchmark':42s} {'wall base':>10s} {'wall now':>10s} {'ratio':>6s}"
              f" {'cpu base':>10s} {'cpu now':>10s} {'ratio':>6s}")
        worst = 0.0
        for name in names:
            if not (base_dir / "bench" / f"{name}.py").is_file():
                # nothing to compare with, but it must still run
                new = [run_once(REPO, name, BENCHMARKS[name], current_env)
                       for _ in range(args.runs)]
                bad = next((r for r in new if r.code != 0), None)
                if bad is not None:
                    print(f"{name:42s} FAILED on now (exit {bad.code}): {bad.tail[-120:]}")
                    worst = float("inf")
                else:
                    print(f"{name:42s} {'new':>10s} "
                          f"{statistics.median(r.wall for r in new):9.2f}s {'':6s} {'new':>10s} "
                          f"{statistics.median(r.cpu for r in new):9.2f}s", flush=True)
                continue
            rows = {name: BENCHMARKS[name]}
            if name in SAME_WORK_NOW:
                rows[f"{name} (same work)"] = BENCHMARKS[name] + SAME_WORK_NOW[name]
            for label, now_args in rows.items():
                runs: dict[str, list[Run]] = {"base": [], "now": []}
                for _ in range(args.runs):
                    runs["base"].append(run_once(base_dir, name, BENCHMARKS[name], base_env))
                    runs["now"].append(run_once(REPO, name, now_args, current_env))
                failed = [(side, r) for side, rs in runs.items() for r in rs if r.code != 0]
                if failed:
                    side, r = failed[0]
                    print(f"{label:42s} FAILED on {side} (exit {r.code}): {r.tail[-120:]}")
                    worst = float("inf")
                    continue
                med = {side: (statistics.median(r.wall for r in rs),
                              statistics.median(r.cpu for r in rs)) for side, rs in runs.items()}
                wall_ratio = med["now"][0] / med["base"][0]
                cpu_ratio = med["now"][1] / med["base"][1]
                if name not in SAME_WORK_NOW or label != name:
                    worst = max(worst, cpu_ratio)
                print(f"{label:42s} {med['base'][0]:9.2f}s {med['now'][0]:9.2f}s "
                      f"{wall_ratio:6.3f} {med['base'][1]:9.2f}s {med['now'][1]:9.2f}s "
                      f"{cpu_ratio:6.3f}", flush=True)
        print("largest CPU ratio (this tree / base) of the same work: "
              + (f"{worst:.3f}" if worst else "none compared"))
        return 0


if __name__ == "__main__":
    sys.exit(main())
