"""Every ``dva`` command that reads a file, given malformed files: exit 2, one error line that
names the file, no traceback, no output left behind; valid files at paths with spaces and
non-ASCII letters work (the matrix of bench/bench_faults.py, bench.faults.cli_matrix).

The whole matrix runs in this process (``dva_offline.cli.main``), which is fast; a few cases
run as real ``dva`` processes, and the ten-million-line files once per kind of reader.
"""
from __future__ import annotations

import pytest

from bench.faults import cli_matrix
from bench.faults.bad_inputs import WRITERS, kinds_of
from bench.faults.cli_matrix import COMMANDS, command

HUGE = "ten-million-lines"


def _key(cmd) -> str:
    return f"{cmd.name} {cmd.option}"


def _small_pairs():
    for cmd in COMMANDS:
        odd = ["odd-path"] if "valid" in WRITERS[cmd.fmt] else []
        for kind in [*kinds_of(cmd.fmt), *odd]:
            if kind != HUGE:
                yield pytest.param(_key(cmd), kind, id=f"{_key(cmd)}: {kind}")


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    """Every case but the ten-million-line ones, input files written once."""
    kinds = {kind for cmd in COMMANDS for kind in kinds_of(cmd.fmt)} - {HUGE} | {"odd-path"}
    built = cli_matrix.build_cases(tmp_path_factory.mktemp("cli_matrix"), kinds=kinds)
    return {(_key(c.command), c.kind): c for c in built}


@pytest.mark.parametrize("key,kind", list(_small_pairs()))
def test_malformed_input_is_refused_in_one_line(cases, key, kind):
    outcome = cli_matrix.run_case_in_process(cases[(key, kind)])
    assert outcome.passed, (outcome.problems(), outcome.stderr)


@pytest.mark.parametrize("key,kind", [
    ("isolator identify FILE", "binary"),
    ("isolator identify FILE", "odd-path"),  # valid, under "dir with spaces, ünïcødé ✈"
    ("wing flutter --wing", "syntax-error"),
    ("report RUN", "missing-topics"),
    ("evaluate --schedule", "nan"),  # refused before any flight
])
def test_as_a_process(cases, key, kind):
    outcome = cli_matrix.run_case(cases[(key, kind)], timeout=120.0)
    assert outcome.passed, (outcome.problems(), outcome.stderr)


@pytest.mark.slow
@pytest.mark.parametrize("name,option", [
    ("isolator identify", "FILE"),      # FRF CSV
    ("isolator estimate", "FILE"),      # time-series CSV
    ("wing flutter", "--wing"),         # YAML
    ("train sweep", "--scenario"),      # scenario YAML
    ("train rbf", "BAG"),               # bag
])
def test_ten_million_lines_refused_quickly(tmp_path, name, option):
    (case,) = cli_matrix.build_cases(tmp_path, [command(name, option)], kinds=[HUGE])
    outcome = cli_matrix.run_case(case, timeout=120.0)
    assert outcome.passed, (outcome.problems(), outcome.stderr)
    assert outcome.peak_rss_mb < 500.0  # read up to the limit, not to the end
