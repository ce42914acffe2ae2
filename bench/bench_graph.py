"""Benchmark: the whole node graph flying the 30 s ramp, against the bare flight runtime.

Run (after ./test.sh or ./run.sh has set everything up)::

    source scripts/env.sh && python bench/bench_graph.py

Measures, in one run:
- baseline: the flight runtime alone (FlightRuntime stepping blocks, no ROS, no publishing);
- the graph: simulator, airspeed_controller and mcap_recorder as separate processes over DDS
  (run_flight with --real-time-factor 0, i.e. as fast as the graph goes), once with the nodes on
  rclpy's default executor and once on the events executor they use (dva_ros_common.node_tools);
- the spectrum-based graph: simulator, spectrum, rbf_controller and mcap_recorder (events
  executor), with a 100-neuron network (``--network FILE``, default: trained here on a mini
  training plan), against the target of 20x real time on 2 cores;
and prints real-time factors, their ratios, the CPU seconds the node processes used (robust to
other load on the machine, unlike wall time), message rates (from the recorded bag), and the
sim-time latency from a flight-condition sample to the damper command derived from it taking
effect (measured by the simulator).
"""
from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from aero_dva.bag.reader import bag_topics
from aero_dva.control.airspeed_schedule import fit_airspeed_schedule
from aero_dva.control.dva_design import best_damping_curve
from aero_dva.control.schedule_io import save_schedule
from aero_dva.flight.damper import DAMPER_RANGE
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing
from aero_dva_sim.run_flight import main as run_flight
from dva_ros_common.node_tools import ENV_VAR


def baseline_runtime() -> tuple[float, float]:
    """(sim seconds, wall seconds) of the ramp flight through FlightRuntime alone."""
    runtime = FlightRuntime(load_runtime_config({}))
    start = time.perf_counter()
    while not runtime.done:
        if runtime.step().diverged:
            break
    return runtime.time, time.perf_counter() - start


def schedule_file(directory: Path) -> Path:
    config = load_wing()
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    tuned = [s for s in best_damping_curve(model, np.linspace(95.0, 125.0, 13), 1.2)
             if s.min_damping_ratio > 0]
    fit = fit_airspeed_schedule([s.airspeed for s in tuned], [s.damping for s in tuned],
                                DAMPER_RANGE)
    return save_schedule(fit.schedule, directory / "schedule.json")


def network_file(directory: Path) -> Path:
    """A 100-neuron network like `dva train rbf`'s, trained on a mini plan held in memory
    (17 airspeeds x 2 densities x 4 c2, exact labels), so the benchmark needs no bag."""
    from aero_dva.control.rbf_io import save_rbf_network
    from aero_dva.control.rbf_network import spectrum_input_names, train_rbf_ols
    from aero_dva.control.spectrum import scaled_spectrum
    from aero_dva.wing.wing_io import default_wing_path
    from dva_offline.training.plan import PlanSettings, make_training_plan, ratio_grid
    from dva_offline.training.recording import simulate_dwells

    config = load_wing(default_wing_path())
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    u_cr = FlightRuntime(load_runtime_config({})).critical_airspeed
    plan = make_training_plan(model, u_cr, 1.2, PlanSettings(
        ratios=ratio_grid(0.8, 1.12, 0.02), factors=(1.0, 1.1), n_damping=4))
    inputs = [np.append(scaled_spectrum(acc[:2], 1000.0).magnitudes.ravel(), c2)
              for batch in simulate_dwells(model, plan)
              for acc, c2 in zip(batch.accelerations,
                                 plan.damping[batch.first_dwell:][:batch.n_dwells])]
    names, units = spectrum_input_names()
    labels = plan.optimal_damping.ravel()[plan.condition]
    result = train_rbf_ols(np.array(inputs), labels, 1.0, tolerance=1e-6, max_neurons=100,
                           input_names=names, input_units=units)
    return save_rbf_network(result.network, directory / "network.npz")


def fly_graph(root: Path, name: str, controller: list[str], executor: str) -> dict | None:
    """One ramp flight through the graph with the nodes on ``executor``; None if it failed."""
    bag = root / name
    os.environ[ENV_VAR] = executor  # the node processes inherit it
    cpu_before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    code = run_flight([*controller, "--real-time-factor", "0", "--output", str(bag)])
    total = time.perf_counter() - started
    cpu_after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if code != 0:
        print(f"run_flight ({executor}) failed")
        return None
    from aero_dva.bag.flight_log_io import load_flight_log

    final = load_flight_log(bag).diagnostics[-1]["values"]
    cpu = (cpu_after.ru_utime - cpu_before.ru_utime) + (cpu_after.ru_stime - cpu_before.ru_stime)
    return {"bag": bag, "sim": float(final["sim_time_s"]), "wall": float(final["wall_time_s"]),
            "total": total, "cpu": cpu, "final": final}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--keep", help="directory to keep the bags in (default: temporary)")
    parser.add_argument("--network", help="RBF network (.npz) of the spectrum-based graph "
                        "(default: trained here on a mini plan)")
    parser.add_argument("--schedule-only", action="store_true",
                        help="fly only the schedule graphs (the work of this benchmark before "
                             "the spectrum graph was added: bench/compare_revisions.py)")
    args = parser.parse_args()
    sim_s, wall_s = baseline_runtime()
    print(f"baseline runtime alone: {sim_s:.2f} s sim in {wall_s:.3f} s wall = "
          f"{sim_s / wall_s:.1f}x real time")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep or tmp)
        schedule = ["--controller", "schedule", "--schedule", str(schedule_file(root))]
        runs = {kind: fly_graph(root, f"bench_graph_{kind}", schedule, kind)
                for kind in ("single_threaded", "events")}
        rbf = None
        if not args.schedule_only:
            network = Path(args.network) if args.network else network_file(root)
            rbf = fly_graph(root, "bench_graph_rbf", ["--controller", "rbf", "--network",
                                                      str(network)], "events")
        if None in runs.values() or (rbf is None and not args.schedule_only):
            return 1
        for kind, run in runs.items():
            print(f"graph, {kind + ' executor':<24}: {run['sim']:.2f} s sim in "
                  f"{run['wall']:.3f} s wall = {run['sim'] / run['wall']:.1f}x real time, "
                  f"ratio to the runtime alone {(run['sim'] / run['wall']) / (sim_s / wall_s):.3f}"
                  f"; CPU of all nodes incl. start-up {run['cpu']:.1f} s "
                  f"(run_flight total {run['total']:.1f} s wall)")
        old, new = runs["single_threaded"], runs["events"]
        print(f"events / single_threaded: real-time factor x{old['wall'] / new['wall']:.2f}, "
              f"node CPU x{new['cpu'] / old['cpu']:.2f}")
        for topic, info in sorted(bag_topics(new["bag"]).items()):
            print(f"  {topic:<24} {info.message_count:6d} messages, "
                  f"{info.message_count / new['wall']:8.0f} /s wall (events executor)")
        final = new["final"]
        print("sample -> command in effect, sim time (the simulator's own measurement): median "
              f"{float(final['command_latency_median_s']) * 1e3:.0f} ms, 95 % "
              f"{float(final['command_latency_p95_s']) * 1e3:.0f} ms, max "
              f"{float(final['command_latency_max_s']) * 1e3:.0f} ms over "
              f"{final['commands_accepted']} commands")
        if rbf is None:
            return 0
        factor = rbf["sim"] / rbf["wall"]
        print(f"graph, spectrum + rbf_controller (events): {rbf['sim']:.2f} s sim in "
              f"{rbf['wall']:.3f} s wall = {factor:.1f}x real time, ratio to the runtime alone "
              f"{factor / (sim_s / wall_s):.3f}, to the schedule graph "
              f"{factor / (new['sim'] / new['wall']):.3f}; CPU of all nodes incl. start-up "
              f"{rbf['cpu']:.1f} s; target >= 20x: {'met' if factor >= 20 else 'NOT met'}")
        for topic, info in sorted(bag_topics(rbf["bag"]).items()):
            if topic in ("/dva/spectrum", "/dva/damper_command"):
                print(f"  {topic:<24} {info.message_count:6d} messages")
        final = rbf["final"]
        print("  sample -> command in effect (rbf), sim time: median "
              f"{float(final['command_latency_median_s']) * 1e3:.0f} ms, max "
              f"{float(final['command_latency_max_s']) * 1e3:.0f} ms over "
              f"{final['commands_accepted']} commands")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
