"""Every fenced block of README.md and docs/*.md: the examples the tests run, and why the others
are not run. A new block fails ``test_every_block_is_run_or_says_why`` until it is here (a
``bash`` block, commands without a printout, needs no entry)."""
from __future__ import annotations

import shutil
from pathlib import Path

from tests.docs_examples import TIMES, Example

ROS = "the ROS graph: tests/integration/test_docs_examples_ros.py"

# -- setups: what a page's example starts from --------------------------------------------------


def damaged_bags(cwd: Path) -> None:
    """docs/bags.md: the batch recorder's 120-block test flight cut at 40 % of its file
    (``crashed/``) and a closed copy with one bit flipped at bytes 100000 and 300000
    (``flipped/``)."""
    from tests.unit.aero_dva.bag.reference_bag import write_batch_bag

    bag = write_batch_bag(cwd / "source" / "run")
    (mcap,) = bag.glob("*.mcap")
    data = bytearray(mcap.read_bytes())
    (cwd / "crashed").mkdir()
    (cwd / "crashed" / "crashed_0.mcap").write_bytes(data[:int(0.4 * len(data))])
    shutil.copytree(bag, cwd / "flipped")
    for at in (100000, 300000):
        data[at] ^= 1
    (cwd / "flipped" / mcap.name).write_bytes(data)


def a_bag(cwd: Path) -> None:
    """A closed flight bag at ``runs/main_x`` (the batch recorder's test flight)."""
    from tests.unit.aero_dva.bag.reference_bag import write_batch_bag

    write_batch_bag(cwd / "runs" / "main_x")


SETUPS = {("docs/bags.md", "$ dva report crashed"): damaged_bags,
          ("docs/bags.md", "from rosbags.rosbag2 import Reader"): a_bag,
          ("docs/bags.md", "from aero_dva.bag.reader import deserialize"): a_bag}

# -- the examples ---------------------------------------------------------------------------------

ISOLATOR_SCRIPT = ("make_examples.py", "docs/isolator.md", "import numpy as np")
EXAMPLES = [
    # README.md
    Example("README.md", "$ dva discrepancy frf", subset=True),
    Example("README.md", "$ dva discrepancy synth-flight --effect cubic_stiffness", subset=True),
    Example("README.md", "controller           schedule", ros=True),
    Example("README.md", "divergence           none within the flight", ros=True),
    Example("README.md", "$ dva replay runs/main_", ros=True),
    # docs/bags.md
    Example("docs/bags.md", "$ dva report crashed"),
    Example("docs/bags.md", "from rosbags.rosbag2 import Reader", script=True,
            replace=(("runs/main_<time>", "runs/main_x"),)),
    Example("docs/bags.md", "from aero_dva.bag.reader import deserialize", script=True),
    # docs/control.md
    Example("docs/control.md", "objective: leading_edge RMS", "dva control optimal-c2",
            masks=(TIMES,), subset=True),
    Example("docs/control.md", "c2 = -1059.7", "dva control schedule --out schedule.json"),
    # docs/discrepancy.md
    Example("docs/discrepancy.md", "dva discrepancy: error: tests/data/discrepancy/dma_tension",
            "dva discrepancy frf tests/data/discrepancy/dma_tension_raw.csv --quantity "
            "stiffness --covariates T --columns f=f,real=E_stor,imag=E_loss"),
    Example("docs/discrepancy.md", "read 1200 points",
            "dva discrepancy synth-structure --effect amplitude_dependence --seed 7 --jitter "
            "--out s7.csv > /dev/null && dva discrepancy modal s7.csv --group-by set",
            subset=True),
    Example("docs/discrepancy.md", "  amplitude_dependence (excitation_n): storage moves",
            "dva discrepancy synth --effect power_level --seed 5 --out mount.csv > /dev/null && "
            "dva discrepancy frf mount.csv --quantity receptance --covariates excitation_n",
            subset=True),
    Example("docs/discrepancy.md", "read 210 points", subset=True,
            commands_from="dva discrepancy frf tests/data/discrepancy/dma_tension_raw.csv"),
    Example("docs/discrepancy.md", "read 170 points", subset=True,
            commands_from="dva discrepancy frf tests/data/discrepancy/dma_shear_eplexor.csv"),
    Example("docs/discrepancy.md", "read 360 points", subset=True,
            commands_from="dva discrepancy frf offline/dva_offline/discrepancy/examples/"),
    Example("docs/discrepancy.md", "route segments (12 segments of constant airspeed, density",
            subset=True,
            commands_from="dva discrepancy synth-flight --effect actuator_lag --seed 7"),
    # docs/evaluation.md
    Example("docs/evaluation.md", "1.11 [-1.06,", commands_from="# growth rate [1/s]"),
    Example("docs/evaluation.md", "[1.0001", commands_from="# stationary leading-edge RMS"),
    # docs/isolator.md
    Example("docs/isolator.md", "$ REPO/.venv/bin/python make_examples.py",
            files=(ISOLATOR_SCRIPT,)),
    Example("docs/isolator.md", "$ dva isolator identify dma.csv", files=(ISOLATOR_SCRIPT,),
            prepare=("REPO/.venv/bin/python make_examples.py",
                     "dva isolator stepped-sine steps.csv --quantity accelerance --out "
                     "steps_frf.csv")),
    # docs/replay.md
    Example("docs/replay.md", "$ dva replay runs/main_", ros=True),
    # docs/training.md
    Example("docs/training.md", "$ .venv/bin/dva train rbf runs/train_final --out", masks=(TIMES,),
            prepare=("dva train sweep --out runs/train_final",), long="2-3 min, a 756 MB bag",
            replace=(("docs/figures/fig7_11_network_vs_optimum.png", "fig7_11.png"),)),
    Example("docs/training.md", "$ .venv/bin/dva train rbf runs/train_final --labels",
            masks=(TIMES,), prepare=("dva train sweep --out runs/train_final",),
            long="2-3 min, a 756 MB bag"),
]

# -- blocks that are not run, and why -------------------------------------------------------------

BENCH = "a benchmark's dated record (wall and CPU times): its bench/ script reproduces it"
USAGE = "a usage synopsis (options in brackets)"
NOT_RUN = {
    ("README.md", "aero_dva/aero_dva/          the ROS-free"): "a listing of the folders",
    ("docs/control.md", "default (chapter-6) wing, U_cr"): BENCH,
    ("docs/control.md", '[project.entry-points."aero_dva.controllers"]'):
        "the entry point of tests/data/external_law/pyproject.toml (test_controller_docs holds "
        "the two to each other; test_external_law installs and flies the package)",
    ("docs/discrepancy.md", "dva discrepancy frf tests/data/discrepancy/dma_tension_raw.csv"):
        "the command of the next block",
    ("docs/discrepancy.md", "dva discrepancy frf tests/data/discrepancy/dma_shear_eplexor"):
        "the command of the next block",
    ("docs/discrepancy.md", "dva discrepancy synth --effect covariate_shift --seed 7"):
        "how the shipped example file was made (test_the_shipped_example_is_what_synth_writes)",
    ("docs/discrepancy.md", "dva discrepancy frf offline/dva_offline/discrepancy/examples/"):
        "the command of the block after next",
    ("docs/discrepancy.md", "dva discrepancy flight RUN [--wing FILE]"): USAGE,
    ("docs/discrepancy.md", "dva discrepancy synth-flight --effect actuator_lag --seed 7"):
        "the commands of the next block",
    ("docs/discrepancy.md", ".venv/bin/python bench/bench_discrepancy_acceptance.py --cases "
                            "20"): BENCH,
    ("docs/discrepancy.md", ".venv/bin/python bench/bench_discrepancy_acceptance.py --cases "
                            "40"): BENCH,
    ("docs/discrepancy.md", ".venv/bin/python bench/bench_discrepancy_combined.py"): BENCH,
    ("docs/evaluation.md", "$ source scripts/env.sh; .venv/bin/dva evaluate --graph"):
        "the command of the table below it (a graph evaluation of 20 min)",
    ("docs/isolator.md", "50 random M-V systems per row"): BENCH,
    ("docs/isolator.md", "dva isolator modal --mass 1 --k 12000 --c 40 --maxwell"): USAGE,
    ("docs/replay.md", "machine            load average"): BENCH,
    ("docs/replay.md", "$ ros2 run aero_dva_sim mcap_recorder"):
        "a session of two processes, one in the background, whose log lines carry wall times; "
        "test_round_trip_into_the_recorder_keeps_every_message_its_order_and_bytes checks the "
        "same round trip on a 4 s flight",
    ("docs/replay.md", "dva replay BAG --controller {rbf,schedule,fixed}"): USAGE,
    ("docs/replay.md", "dva replay BAG --controller {switching,clipped_optimal}"): USAGE,
    ("docs/replay.md", "plunge       max |difference| 0 of a peak 12.05"):
        "a dated record of one flight through the graph; tests/integration/"
        "test_per_sample_replay.py flies both per-sample laws and checks the same",
    ("docs/training.md", "$ python bench/bench_sweep_recording.py"): BENCH,
    ("docs/training.md", "$ /usr/bin/time .venv/bin/dva train sweep"):
        "the sweep's JSON summary, shortened, with its wall and CPU times (a dated record; its "
        "numbers reappear in the training runs below, which are run)",
    ("docs/training.md", "issue target: >= 10000 x real time"): BENCH,
    ("docs/wing.md", "sim = StreamingSimulator(wing, absorber"): "a fragment of an API "
                                                                 "description (no imports)",
    ("docs/wing.md", "dva wing modal    [--wing F | --section F]"): USAGE,
}
#: docs/performance.md and docs/reliability.md are records of measurements: their blocks are
#: bench/ commands and what they printed on a dated run.
RECORD_PAGES = {"docs/performance.md": BENCH, "docs/reliability.md": BENCH}
