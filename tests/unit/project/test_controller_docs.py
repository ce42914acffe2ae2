"""docs/control.md lists the controllers of the table, each as its entry says."""
from __future__ import annotations

from pathlib import Path

from aero_dva.control import controllers as table

DOC = Path(__file__).resolve().parents[3] / "docs" / "control.md"


def _rows() -> dict[str, list[str]]:
    text = DOC.read_text()
    section = text[text.index("## The controllers"):text.index("## Adding a control law")]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| `"):
            rows[cells[0].strip("`")] = cells
    return rows


def test_the_docs_list_every_controller_of_the_table_as_its_entry_says():
    rows = _rows()
    entries = table.controllers(builtin_only=True)
    assert list(rows) == [e.name for e in entries]
    for entry in entries:
        _, label, runs, reads, source, node, lag = rows[entry.name]
        assert (label, runs, reads, source.strip("`")) == \
            (entry.label, entry.runs, ", ".join(entry.inputs), entry.source)
        assert float(lag) == entry.command_lag
        if entry.runs != table.REFERENCE:
            assert node.strip("`") == entry.node


def test_the_docs_entry_point_is_the_example_packages():
    text = DOC.read_text()
    block = text[text.index("```toml\n") + 8:]
    block = block[:block.index("```")]
    example = (DOC.parents[1] / "tests" / "data" / "external_law" / "pyproject.toml").read_text()
    assert block.strip() and block in example
