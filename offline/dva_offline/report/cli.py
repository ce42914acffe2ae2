"""``dva report``: a recorded run as a rerun recording (.rrd with blueprint), PNGs and markdown.

Any bag of the project (``run_flight``, ``dva train sweep``, the batch path), given as its
directory or its .mcap file. The markdown lists scenario (read from the signals), controller,
divergence airspeed, leading-edge RMS, c2 range and message counts, and links the PNGs and .rrd.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import shutil
from pathlib import Path

__all__ = ["register"]


def register(subparsers) -> None:
    """Add the ``report`` command."""
    p = subparsers.add_parser("report", help="per-run report of a recorded bag: .rrd (rerun, "
                              "with blueprint), PNG plots, markdown", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", metavar="RUN", help="bag directory or .mcap file")
    p.add_argument("--out", metavar="DIR",
                   help="directory to write into (default <RUN>_report next to the bag)")
    p.add_argument("--no-rrd", action="store_true", help="skip the rerun recording")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--allow-truncated", action="store_true",
                   help="read a bag that was not closed, is cut or damaged: every chunk whose CRC "
                        "holds (warns); "
                        "`dva bag recover` makes a complete copy instead")
    p.set_defaults(func=_report)


def _report(args) -> int:
    from aero_dva.atomic_io import output_lock
    from dva_offline.report.files import write_report

    run = Path(args.run)
    if not run.exists():
        raise FileNotFoundError(f"RUN: no bag directory or .mcap file {run}")
    base = run if run.is_dir() else run.with_suffix("")
    out = Path(args.out) if args.out else base.with_name(base.name + "_report")
    with contextlib.ExitStack() as held:
        if not args.out:  # (a given --out is held by cli_tools.outputs_held)
            held.enter_context(output_lock(out, "report directory"))
        created = not out.exists()
        try:
            files = write_report(run, out, rrd=not args.no_rrd,
                                 allow_truncated=args.allow_truncated)
        except BaseException:
            if created:  # a failed report leaves no directory that looks like one
                shutil.rmtree(out, ignore_errors=True)
            raise
    if args.json:
        print(json.dumps(json.loads(files.json.read_text())))
        return 0
    s = files.report.summary
    print(f"controller          {files.report.controller}")
    print("divergence          " + (f"{s.divergence_airspeed:.2f} m/s = "
                                    f"{s.divergence_ratio:.3f} U_cr"
                                    if s.divergence_airspeed == s.divergence_airspeed
                                    else "none within the flight"))
    print(f"report              {files.markdown}")
    for caption, path in files.pngs.items():
        print(f"{caption:<20}{path}")
    if files.rrd:
        print(f"rerun recording     {files.rrd}")
    return 0
