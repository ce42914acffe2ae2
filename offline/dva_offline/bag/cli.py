"""``dva bag info|recover``: what a recorded bag holds, and a complete copy of a damaged one.

    dva bag info BAG [--no-verify] [--json]
    dva bag recover BAG --out NEW_BAG [--compression zstd|lz4|none] [--json]

``info`` prints the topics with their types and message counts, the duration, whether the
bag was closed (``metadata.yaml`` and every MCAP file's footer present) and whether it is
damaged: every chunk's CRC is checked (``--no-verify``: not, the summaries are believed) and
every byte range that does not read is listed with the messages, topics and log times it held.
``recover`` writes NEW_BAG, a complete rosbag2-layout bag (``metadata.yaml`` + indexed MCAP),
holding every message of every chunk of BAG whose CRC holds, in log-time order (a recorder
killed mid-run, a file cut by a full disk or a copy, flipped bits), and lists the damaged
ranges; BAG is not changed. BAG is a bag directory or an .mcap file.

Exit codes of ``recover``: 0 the copy holds every message BAG's index promises; 1 the copy was
written but messages were lost (or may have been: a cut file has no index to tell); 2 bad
input (nothing written); 3 it failed (no space left, say); 130 interrupted.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from aero_dva import exits

__all__ = ["RECOVERED_WITH_LOSSES", "register"]

#: Exit code of ``dva bag recover`` when the copy was written but messages were (or may have
#: been) lost: completed, partial.
RECOVERED_WITH_LOSSES = exits.PARTIAL


def register(subparsers) -> None:
    """Add the ``bag`` command and its subcommands."""
    p = subparsers.add_parser("bag", help="inspect a recorded bag, recover a damaged one",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="bag_command", metavar="<subcommand>", required=True)
    info = sub.add_parser("info", help="topics, counts, duration, closed or not")
    info.add_argument("bag", metavar="BAG", help="bag directory or .mcap file")
    info.add_argument("--no-verify", action="store_true",
                      help="do not check the chunk CRCs (read the summaries only; faster)")
    info.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    info.set_defaults(func=_info)
    recover = sub.add_parser("recover", help="write a complete bag of every message of a "
                             "damaged, cut or unclosed one that passes its chunk's CRC")
    recover.add_argument("bag", metavar="BAG", help="bag directory or .mcap file")
    recover.add_argument("--out", metavar="NEW_BAG", required=True,
                         help="new bag directory (must not exist or be empty)")
    recover.add_argument("--compression", choices=("zstd", "lz4", "none"), default=None,
                         help="chunk compression of the new bag (default: as BAG)")
    recover.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    recover.set_defaults(func=_recover)


def _seconds(ns: int) -> str:
    return f"{ns * 1e-9:.3f} s"


def _info(args) -> int:
    from aero_dva.bag.recovery import bag_info

    info = bag_info(args.bag, verify=not args.no_verify)
    if info.damage is not None and info.damage.offset == 0 and info.message_count == 0:
        # Not a damaged bag but no bag at all (as `dva bag recover` says too).
        size = info.damage.file.stat().st_size if info.damage.file.is_file() else 0
        raise ValueError(f"{info.damage.file}: " + ("empty (0 bytes): nothing was recorded"
                                                     if size == 0 else info.damage.reason))
    if args.json:
        print(json.dumps(info.to_dict()))
        return 0
    print(f"bag        {info.path}")
    print(f"files      {', '.join(f.name for f in info.files)}")
    problems = [p for p in info.problems if not p.startswith("damaged:")]
    print("closed     " + ("yes" if not problems else "no: " + "; ".join(problems)))
    if info.interrupted is not None:
        print(f"interrupted the recording was {info.interrupted}: not the whole flight")
    if not info.verified:
        print("chunks     CRCs not checked (--no-verify)")
        if info.damage is not None:
            print(f"damage     {info.damage}")
    elif info.damaged:
        print(f"damaged    {len(info.damaged)} byte range(s) do not read; messages lost: "
              + _lost(info.lost, info.promised))
        for damaged in info.damaged:
            print(f"damage     {damaged}")
    else:
        print("chunks     every chunk passes its CRC")
    print(f"messages   {info.message_count}")
    print(f"start      {_seconds(info.start_ns)}")
    print(f"duration   {_seconds(info.duration_ns)}")
    width = max([len(t.name) for t in info.topics] + [5])
    print(f"{'topic':<{width}}  {'count':>9}  type")
    for topic in info.topics:
        print(f"{topic.name:<{width}}  {topic.message_count:>9}  {topic.type_name}")
    if not info.closed:
        print(f"run `dva bag recover {args.bag} --out NEW_BAG` for a complete copy")
    return 0


def _lost(lost, promised) -> str:
    if lost is None:
        return "unknown (no index that passes its CRC)"
    return f"{lost}" + ("" if promised is None else f" of {promised} the bag's index promises")


def _recover(args) -> int:
    from aero_dva.bag.recovery import recover_bag

    result = recover_bag(args.bag, Path(args.out), compression=args.compression)
    code = 0 if result.lost == 0 else RECOVERED_WITH_LOSSES
    if args.json:
        print(json.dumps({
            "out": str(result.out), "kept": result.kept, "salvaged": result.salvaged,
            "lost": result.lost, "promised": result.promised,
            "damage": None if result.damage is None else {
                "file": str(result.damage.file), "offset": result.damage.offset,
                "reason": result.damage.reason},
            "damaged": [d.to_dict() for d in result.damaged],
            "files_read": result.files_read, "files_total": result.files_total,
            "topics": {t.name: t.message_count for t in result.topics}}))
        return code
    print(f"kept       {result.kept} messages"
          + (f" ({result.salvaged} from the chunk the file ends in)" if result.salvaged else ""))
    if not result.damaged:
        print("damage     none: every message kept")
    for damaged in result.damaged:
        print(f"damage     {damaged}")
    print(f"lost       {_lost(result.lost, result.promised)}")
    print(f"new bag    {result.out}")
    return code
