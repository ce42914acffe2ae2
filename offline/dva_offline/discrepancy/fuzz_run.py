"""One random table through ``dva discrepancy frf|modal`` as a user would run it, classified.

Outcomes: ``verdict`` (exit 0 with a JSON verdict), ``input error`` (exit 2 with one line
naming the file: the reader refused it), ``internal`` (any other exception, with its
traceback's last line). The bench ``bench/bench_discrepancy_fuzz.py`` and the CI test use it.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import traceback
from pathlib import Path

from dva_offline.discrepancy.fuzz_tables import FuzzTable
from dva_offline.discrepancy.table_io import write_table

# which commands read which quantity (the FRF domain has no mobility)
COMMANDS = {"modulus": ("frf",), "receptance": ("frf", "modal"),
            "accelerance": ("frf", "modal"), "mobility": ("modal",)}


def commands(table: FuzzTable) -> tuple:
    """The commands that read ``table`` (an isolator table goes to ``frf`` only)."""
    if table.covariates.get("force_n") is None and table.quantity != "modulus":
        return ("frf",)
    return COMMANDS[table.quantity]


def run_table(table: FuzzTable, path: Path, command: str,
              extra: tuple = ("--max-steps", "2")) -> tuple[str, str]:
    """Write ``table`` to ``path`` and run ``dva discrepancy COMMAND`` on it: (outcome,
    detail), detail the verdict, the error line or the exception."""
    from dva_offline import cli

    write_table(path, table.frequency_hz, table.values, table.covariates)
    args = ["discrepancy", command, str(path), *table.flags, *extra, "--json"]
    out, err = io.StringIO(), io.StringIO()
    old = os.environ.pop("DVA_DEBUG", None)
    os.environ["DVA_DEBUG"] = "1"  # exceptions propagate: an input error must name the file
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = cli.main(args)
    except (ValueError, FileNotFoundError) as exc:
        if str(exc).startswith(str(path)) and "\n" not in str(exc):
            return "input error", str(exc)
        return "internal", "".join(traceback.format_exception_only(type(exc), exc)).strip()
    except Exception as exc:  # noqa: BLE001 - the fuzz reports any exception
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return "internal", f"{type(exc).__name__}: {exc} ({Path(tb.filename).name}:{tb.lineno})"
    finally:
        if old is None:
            os.environ.pop("DVA_DEBUG", None)
        else:
            os.environ["DVA_DEBUG"] = old
    if code != 0:
        return "internal", f"exit code {code}: {err.getvalue().strip()}"
    payload = json.loads(out.getvalue())
    verdict = payload["verdict"]
    return "verdict", verdict["status"] + (f" -> {verdict['effect']}"
                                           if verdict.get("effect") else "")
