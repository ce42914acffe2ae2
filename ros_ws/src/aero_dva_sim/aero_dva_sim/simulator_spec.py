"""The simulator's parameter table and its executable's entry (``ros2 run aero_dva_sim
simulator``): ``--help`` and refused arguments are answered from the table before ROS, numpy or
the node (:mod:`aero_dva_sim.simulator_node`) are imported (docs/performance.md, the start-up
budget). Only named values are imported here.
"""
from __future__ import annotations

from aero_dva.control import controllers as table
from aero_dva.control.controllers import SAMPLE
from aero_dva.flight.flight_limits import DAMPER_RANGE, DEFAULT_STALE_TIMEOUT, MAX_DAMPING
from dva_ros_common.node_params import NodeSpec, Param, node_main

_NAN = float("nan")
_DESIGN = "the wing file's Maxwell design"

#: One gains file per per-sample law of the controller table (``switching_gains``,
#: ``clipped_optimal_gains``): the law runs in the damper path every sample while the commands
#: come from its source.
PER_SAMPLE_FILES = tuple((entry, option) for entry in table.controllers((SAMPLE,))
                         for option in entry.options if option.simulator)
PER_SAMPLE_PARAMS = tuple(
    Param(option.simulator, "", f"gains JSON of the {entry.label} ({option.help}), run in the "
          f"damper path every sample while the commands' source is \"{entry.source}\"; an "
          "invalid file or one for another wing leaves the damper on the commands' c2, and "
          "says so", default_text="none: the law cannot run")
    for entry, option in PER_SAMPLE_FILES)

SPEC = NodeSpec(
    name="simulator",
    package="aero_dva_sim",
    summary="Fly a scenario with the pitch-plunge wing and the tunable Maxwell DVA, block by "
            "block (exact zero-order hold), publish what sensors would see, and be the clock: "
            "the rest of the graph runs on its /clock (use_sim_time:=true). The damper applies "
            "the latest accepted dva/damper_command (range, lag, stale fallback, rejection of "
            "absurd commands); a stepped-sweep scenario applies its own c2 values.",
    params=(
        Param("scenario", "", "scenario YAML: at most 20,000,000 samples (duration x "
              "sample rate, 100..20000 Hz), at least one block",
              default_text="the package's scenario_ramp.yaml (0.8 -> 1.2 U_cr in 30 s)"),
        Param("wing", "", "wing YAML", default_text="the package's chapter-6 wing"),
        Param("absorber", "maxwell", "absorber on the wing", choices=("maxwell", "none")),
        Param("absorber_mass", _NAN, "DVA mass", "kg", 1.0e-6, 1.0e5, nan_means=_DESIGN),
        Param("absorber_stiffness", _NAN, "DVA spring k1", "N/m", 0.0, 1.0e10,
              nan_means=_DESIGN),
        Param("absorber_series_stiffness", _NAN, "spring k2 in series with the damper", "N/m",
              1.0, 1.0e10, nan_means=_DESIGN),
        Param("absorber_position", _NAN, "DVA position from the gravity centre, + toward the "
              "leading edge (on the chord)", "m", -100.0, 100.0, nan_means=_DESIGN),
        Param("damper_min", DAMPER_RANGE[0], "damper range, lower end", "N s/m", 0.0,
              MAX_DAMPING),
        Param("damper_max", DAMPER_RANGE[1], "damper range, upper end", "N s/m", 0.0,
              MAX_DAMPING),
        Param("damper_initial", _NAN, "c2 before the first command", "N s/m", 0.0, MAX_DAMPING,
              nan_means="the fallback c2"),
        Param("damper_fallback", _NAN, "c2 when commands go stale", "N s/m", 0.0, MAX_DAMPING,
              nan_means="the design's c2 clamped to the damper range"),
        Param("damper_timeout", DEFAULT_STALE_TIMEOUT, "sim time without commands before the "
              "fallback applies",
              "s", 0.0, 1.0e12),
        Param("damper_time_constant", 0.0, "first-order lag of the damper (0: ideal, the "
              "study's)", "s", 0.0, 3600.0),
        *PER_SAMPLE_PARAMS,
        Param("damper_sensor_noise", 0.0, "noise on the measurements of a per-sample law's "
              "observer, std as a fraction of each one's stationary RMS at U_cr (0: exact; "
              "run_flight gives the law's design value)", "", 0.0, 10.0),
        Param("stepping", "numpy", "how the blocks are stepped: numpy, or compiled (numba's "
              "loop and exponential: about 0.1 ms less per block, the same flight to rounding, "
              "but about 0.7 s of CPU to load before the flight starts; a wing with the Wagner "
              "lag steps in NumPy)", choices=("numpy", "compiled")),
        Param("real_time_factor", 20.0, "sim seconds per wall second (0: as fast as possible)",
              "", 0.0, 1.0e6),
        Param("wait_for_subscribers", 0, "start the flight when every data topic has this many "
              "subscribers", "", 0, 1000),
        Param("wait_for_nodes", [""], "... and these nodes are in the graph"),
        Param("wait_for_topics", [""], "... and these topics have N subscribers (TOPIC:N): "
              "matched to the simulator's publisher for its own topics (/clock included), in "
              "the graph for the others (dva/damper_command: the recorder's)"),
        Param("wait_for_command_publishers", 0, "... and this many dva/damper_command "
              "publishers have matched the simulator", "", 0, 1000),
        Param("wait_timeout", 30.0, "wall time after which the flight starts anyway (with a "
              "warning), or fails (wait_timeout_fails)", "s", 0.0, 1.0e6),
        Param("wait_timeout_fails", False, "fail the flight (exit code 3) when the graph is "
              "not complete after wait_timeout, instead of starting anyway"),
        Param("exit_on_end", True, "stop the node when the flight ends"),
        Param("max_command_lag", 0.0, "sim time the flight may run ahead of the newest accepted "
              "command's stamp (0: free running); bounds the loop's sim-time latency whatever "
              "the machine's load", "s", 0.0, 3600.0),
        Param("command_wait_timeout", 2.0, "wall time to wait for the controller before flying "
              "on (the damper's stale fallback then acts)", "s", 0.0, 3600.0),
        Param("first_input_time", 0.0, "with max_command_lag: sim time of the controller's "
              "first input (0: the first block; the spectrum window for the RBF network); the "
              "flight holds past it until the first command has arrived", "s", 0.0, 1.0e6),
        Param("controller", "", "the controller the flight is flown with (its table name): "
              "its node is the one commander expected on dva/damper_command and its sources "
              "the ones expected in the commands; commands from anyone else are counted and "
              "reported", choices=("", *table.names(), table.NONE),
              default_text="'' (any commander)"),
        Param("strict_commands", False, "refuse commands of another source than the "
              "controller's, and every command while another node publishes on "
              "dva/damper_command (the damper then falls back when stale)"),
        Param("wait_for_last_answer", False, "with max_command_lag: after the last block, wait "
              "(at most command_wait_timeout) for the command that answers its input before "
              "the end-of-flight report, which then counts it (received:dva/damper_command), "
              "so a recorder stopped after the flight can wait for it too; for a law that "
              "answers every block (a law of flight conditions)"),
        Param("first_command_timeout", 30.0, "wall time the flight holds for the first command "
              "before it fails (exit code 3): the controller never acted", "s", 0.0, 1.0e6),
    ),
    topics="""
publishes wing/acceleration, wing/displacement, wing/excitation, flight/condition,
  dva/damper_state, /clock, /diagnostics
subscribes dva/damper_command (dva_msgs/DamperCommand)
""",
)



def main(args=None) -> int:
    return node_main(SPEC, "aero_dva_sim.simulator_node:Simulator", args)
