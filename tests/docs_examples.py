"""The examples of README.md and docs/*.md, run as written and compared with what they print.

A fenced block of a page is a *session* when its lines start with ``$ `` (a command, continued
by a trailing backslash) followed by what it prints; other blocks hold a printout whose command
the registry names (:class:`Example`), a script, or something that is not run (a usage
synopsis, a benchmark's dated record), which tests/docs_registry.py says. Commands run with bash
in a scratch directory that links the repository's input folders, with the project's
``.venv/bin`` first on PATH (``dva`` is ``.venv/bin/dva``; a plain ``dva`` command line runs in
the test's process) and ``REPO`` the repository.

Printouts are compared line by line after ``masks`` (regular expressions of what a run may
change: wall times, paths) have replaced their matches in both texts; ``...`` in a documented
line stands for any text, and a line of only ``...`` for any lines. ``subset``: the documented
lines are some of the printed ones, in order (a page that thins a long printout says so).
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAGES = ("README.md", *sorted(str(p.relative_to(REPO)) for p in (REPO / "docs").glob("*.md")))
#: Repository folders a scratch directory links, so the pages' relative input paths resolve.
LINKED = ("aero_dva", "offline", "tests", "bench", "scripts", "ros_ws")
#: Wall and CPU times, which no two runs share.
TIMES = r"\d+(\.\d+)? s\b"
#: The file a script block is saved as.
SCRIPT = "example.py"


@dataclass(frozen=True)
class Block:
    page: str
    line: int  # of the opening fence, 1-based
    lang: str
    body: str

    @property
    def first(self) -> str:
        return self.body.splitlines()[0] if self.body else ""


def blocks(page: str) -> list[Block]:
    """The fenced blocks of ``page`` (a path relative to the repository)."""
    out, body, start, lang = [], None, 0, ""
    for i, line in enumerate((REPO / page).read_text().splitlines()):
        if line.startswith("```"):
            if body is None:
                body, start, lang = [], i + 1, line[3:].strip()
            else:
                out.append(Block(page, start, lang, "\n".join(body)))
                body = None
        elif body is not None:
            body.append(line)
    return out


def find(page: str, anchor: str) -> Block:
    """The one block of ``page`` whose first line starts with ``anchor``."""
    hits = [b for b in blocks(page) if b.first.startswith(anchor)]
    assert len(hits) == 1, f"{page}: {len(hits)} blocks start with {anchor!r}"
    return hits[0]


def session(block: Block) -> list[tuple[str, str]]:
    """(command, documented printout) of each ``$`` command of a session block."""
    steps: list[list] = []
    continued = False
    for line in block.body.splitlines():
        if line.startswith("$ ") or continued:
            text = line[2:] if line.startswith("$ ") and not continued else line.strip()
            if continued:
                steps[-1][0] += " " + text.rstrip("\\").strip()
            else:
                steps.append([text.rstrip("\\").strip(), []])
            continued = line.rstrip().endswith("\\")
        elif steps:
            steps[-1][1].append(line)
    return [(cmd, "\n".join(out).strip("\n")) for cmd, out in steps]


def _masked(text: str, masks) -> list[str]:
    lines = [line.rstrip() for line in text.strip("\n").splitlines()]
    for mask in masks:
        lines = [re.sub(mask, "<~>", line) for line in lines]
    return lines


def _matches(documented: str, printed: str) -> bool:
    if "..." not in documented:
        return documented == printed
    pattern = ".*".join(re.escape(part) for part in documented.split("..."))
    return re.fullmatch(pattern, printed) is not None


def _lines_match(want: list[str], have: list[str]) -> bool:
    """Line by line; a documented line ``...`` alone stands for any number of lines."""
    if not want:
        return not have
    if want[0].strip() == "...":
        return any(_lines_match(want[1:], have[k:]) for k in range(len(have) + 1))
    return bool(have) and _matches(want[0], have[0]) and _lines_match(want[1:], have[1:])


def differences(documented: str, printed: str, masks=(), subset: bool = False) -> str | None:
    """None when ``printed`` is what ``documented`` says, else a readable account."""
    want, have = _masked(documented, masks), _masked(printed, masks)
    if subset:
        k = 0
        for line in want:
            while k < len(have) and not _matches(line, have[k]):
                k += 1
            if k == len(have):
                return f"documented line not printed (in order): {line!r}\nprinted:\n" + \
                    "\n".join(have)
            k += 1
        return None
    if _lines_match(want, have):
        return None
    rows = [f"{'=' if i < min(len(want), len(have)) and _matches(want[i], have[i]) else '!'} "
            f"doc: {want[i] if i < len(want) else '<none>'}\n  run: "
            f"{have[i] if i < len(have) else '<none>'}"
            for i in range(max(len(want), len(have)))]
    return "\n".join(rows)


def scratch(directory: Path) -> Path:
    """A working directory whose repository folders are links to the repository's."""
    directory.mkdir(parents=True, exist_ok=True)
    for name in LINKED:
        link = directory / name
        if not link.exists():
            link.symlink_to(REPO / name)
    return directory


def environment(extra: dict | None = None) -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{REPO / '.venv' / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env.update(REPO=str(REPO), COLUMNS="200", **(extra or {}))
    env.pop("DVA_DEBUG", None)
    return env


def run(command: str, cwd: Path, timeout: float = 900.0,
        env: dict | None = None) -> tuple[str, int]:
    """(what ``command`` prints, its exit code), run with bash in ``cwd``; ``REPO`` in it is the
    repository. The printout is stdout, and after it stderr when the command failed (as a
    terminal shows its error line; progress bars on stderr are not part of a success)."""
    command = command.replace("REPO/", f"{shlex.quote(str(REPO))}/")
    if re.fullmatch(r"dva [^|;&<>$`]*", command) and env is None:
        return _in_process(shlex.split(command, comments=True)[1:], cwd)
    result = subprocess.run(["bash", "-c", command], cwd=cwd, capture_output=True, text=True,
                            timeout=timeout, env=env or environment())
    printed = result.stdout + (result.stderr if result.returncode else "")
    return printed, result.returncode


def _in_process(argv: list[str], cwd: Path) -> tuple[str, int]:
    """``dva ARGV`` in this process (the same code as ``.venv/bin/dva``, without starting an
    interpreter and importing scipy for every command)."""
    import contextlib
    import io

    from dva_offline import cli

    out, err = io.StringIO(), io.StringIO()
    here = Path.cwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = cli.main(argv)
    finally:
        os.chdir(here)
    return out.getvalue() + (err.getvalue() if code else ""), code


@dataclass(frozen=True)
class Example:
    """A documented printout and how to make it again.

    ``anchor``: the start of the block's first line. ``command``: for a block without ``$``
    lines, the command that prints it. ``masks``: regular expressions of what a run may change.
    ``subset``: the block shows some of the printed lines. ``replace``: (documented text, text
    of this run) put into the commands and the printout, e.g. a bag's time-stamped name.
    ``files``: (file name, page, anchor) of script blocks the page tells the reader to save
    first. ``commands_from``: the anchor of a block of the same page holding the commands (one
    per line; the last one's printout is the block's), or a Python script (a ``python`` block)
    whose printout the block is. ``prepare``: commands that make what earlier blocks made.
    ``script``: the block is a Python script, run with the project's interpreter; it must
    succeed. ``ros``: needs the ROS graph (tests/integration/test_docs_examples_ros.py).
    ``long``: why it runs only with ``DVA_DOCS_LONG=1``.
    """

    page: str
    anchor: str
    command: str | None = None
    masks: tuple[str, ...] = ()
    subset: bool = False
    replace: tuple[tuple[str, str], ...] = field(default_factory=tuple)
    files: tuple[tuple[str, str, str], ...] = field(default_factory=tuple)
    commands_from: str | None = None
    prepare: tuple[str, ...] = ()
    script: bool = False
    ros: bool = False
    long: str = ""

    @property
    def block(self) -> Block:
        return find(self.page, self.anchor)

    def steps(self) -> list[tuple[str, str | None]]:
        """(command, documented printout or None: not compared) in order."""
        if self.script:
            return [(f"REPO/.venv/bin/python {SCRIPT}", None)]
        if self.commands_from is not None:
            if find(self.page, self.commands_from).lang == "python":
                return [(f"REPO/.venv/bin/python {SCRIPT}", self.block.body)]
            lines = find(self.page, self.commands_from).body.replace("\\\n", " ")
            commands = [c.split("  #")[0].strip() for c in lines.splitlines() if c.strip()]
            return [(c, None) for c in commands[:-1]] + [(commands[-1], self.block.body)]
        if self.command is not None:
            return [(self.command, self.block.body)]
        return session(self.block)

    def check(self, cwd: Path, env: dict | None = None) -> None:
        """Run the example in ``cwd``; AssertionError with the differences if it drifted."""
        steps = self.steps()
        for name, page, anchor in self.files:
            (cwd / name).write_text(find(page, anchor).body + "\n")
        source = self.block if self.script else None
        if self.commands_from is not None and find(self.page, self.commands_from).lang == \
                "python":
            source = find(self.page, self.commands_from)
        if source is not None:
            body = source.body
            for old, new in self.replace:
                body = body.replace(old, new)
            (cwd / SCRIPT).write_text(body + "\n")
        for command in self.prepare:  # what an earlier block of the page made
            printed, code = run(command, cwd, env=env)
            assert code == 0, f"$ {command}\nexit {code}\n{printed}"
        problems, code = [], 0
        for command, documented in steps:
            for old, new in self.replace:
                command = command.replace(old, new)
                documented = None if documented is None else documented.replace(old, new)
            if command == "echo $?":  # the exit code of the command before
                printed = f"{code}\n"
            else:
                printed, code = run(command, cwd, env=env)
            if documented is None:
                if code:
                    problems.append(f"$ {command}\nexit {code}\n{printed}")
                continue
            diff = differences(documented, printed, self.masks, self.subset)
            if diff:
                problems.append(f"$ {command}\n{diff}")
        assert not problems, f"{self.page}:{self.block.line} drifted:\n" + "\n\n".join(problems)
