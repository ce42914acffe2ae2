"""The README's and the docs' examples print what the pages say (tests/docs_examples.py).

Every fenced block is run and compared, or named in tests/docs_registry.py with the reason it
is not (a benchmark's record, a usage synopsis, a listing); the examples that need the ROS
graph run in tests/integration/test_docs_examples_ros.py, the long ones (minutes, hundreds of
MB) only with ``DVA_DOCS_LONG=1``. Every ``dva`` command line of the pages, in blocks and in
inline code, uses only options its command has, so a renamed option cannot stay documented.
"""
from __future__ import annotations

import os
import re
import shlex

import pytest

from dva_offline import cli
from tests.docs_examples import PAGES, REPO, blocks, scratch
from tests.docs_registry import EXAMPLES, NOT_RUN, RECORD_PAGES, SETUPS

pytestmark = pytest.mark.slow
COMMANDS = ("bash", "sh")


def _claimed(example) -> set:
    keys = {(example.page, example.anchor)}
    if example.commands_from:
        keys.add((example.page, example.commands_from))
    keys |= {(page, anchor) for _, page, anchor in example.files}
    return keys


def test_every_block_is_run_or_says_why():
    run = set().union(*(_claimed(e) for e in EXAMPLES))
    for page, anchor in run:  # an example names exactly one block; a reason at least one
        assert len([b for b in blocks(page) if b.first.startswith(anchor)]) == 1, anchor
    for page, anchor in NOT_RUN:
        assert any(b.first.startswith(anchor) for b in blocks(page)), anchor
    claimed = run | set(NOT_RUN)
    # A ``bash`` block holds commands without a printout: nothing to compare; its dva command
    # lines are checked by test_documented_command_lines_parse.
    unclaimed = [f"{b.page}:{b.line}: {b.first[:70]}" for page in PAGES
                 if page not in RECORD_PAGES for b in blocks(page) if b.lang not in COMMANDS
                 and not any(b.page == p and b.first.startswith(a) for p, a in claimed)]
    assert not unclaimed, "blocks neither run nor said why:\n" + "\n".join(unclaimed)


OFFLINE = [e for e in EXAMPLES if not e.ros]


@pytest.mark.parametrize("example", OFFLINE, ids=lambda e: f"{e.page}:{e.anchor[:40]}")
def test_the_example_prints_what_the_page_says(example, tmp_path):
    if example.long and not os.environ.get("DVA_DOCS_LONG"):
        pytest.skip(f"{example.long}: run with DVA_DOCS_LONG=1")
    cwd = scratch(tmp_path / "work")
    setup = SETUPS.get((example.page, example.anchor))
    if setup is not None:
        setup(cwd)
    example.check(cwd)


def _command_lines(text: str) -> list[str]:
    """``dva ...`` command lines of a page: in blocks (with ``$``, ``.venv/bin/`` or a path
    before it; backslash continuations joined) and in inline code."""
    text = re.sub(r"\\\n\s*", " ", text)
    found = re.findall(r"(?:^|\$ |/bin/|[`;&] ?)(dva (?:[a-z][\w-]* )[^`\n|;&>#]*)", text,
                       flags=re.M)
    return [c.strip() for c in found]


def _unknown_options(words: list[str]) -> list[str]:
    """The ``--options`` of ``dva WORDS`` that its (sub)command does not have."""
    import argparse

    parser = cli.build_parser()
    for word in words:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs or word not in subs[0].choices:
            break
        parser = subs[0].choices[word]
    known = {o for a in parser._actions for o in a.option_strings}
    alternatives = [["--" + p.lstrip("-") for p in w.split("=")[0].split("/")]
                    for w in words if w.startswith("--")]  # --network/--schedule: either
    return ["/".join(a) for a in alternatives if not set(a) <= known]


@pytest.mark.parametrize("page", PAGES)
def test_documented_command_lines_parse(page):
    """Each ``dva`` command line of a page, in a block or in inline code, uses only options its
    command has (a renamed or removed option cannot stay documented)."""
    bad = []
    for line in _command_lines((REPO / page).read_text()):
        try:
            words = shlex.split(line)[1:]
        except ValueError:  # an unbalanced quote of a line cut by the page's wrapping
            words = line.split()[1:]
        unknown = _unknown_options(words)
        if unknown:
            bad.append(f"{line}\n    unknown: {' '.join(unknown)}")
    assert not bad, f"{page}: options the commands do not have:\n" + "\n".join(bad)
