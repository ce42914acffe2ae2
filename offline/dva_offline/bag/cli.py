"""``dva bag info|recover``: what a recorded bag holds, and a complete copy of a damaged one.

    dva bag info BAG [--json]
    dva bag recover BAG --out NEW_BAG [--compression zstd|lz4|none] [--json]

``info`` prints the topics with their types and message counts, the duration and whether the
bag was closed (``metadata.yaml`` and every MCAP file's footer present); for a bag that was not
closed it counts what can be read and says where the damage starts. ``recover`` writes
NEW_BAG, a complete rosbag2-layout bag (``metadata.yaml`` + indexed MCAP), holding every message
before the damage of BAG (a recorder killed mid-run, a file cut by a full disk or a copy), and
says how many it kept and where the damage starts; BAG is not changed. BAG is a bag directory
or an .mcap file.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["register"]


def register(subparsers) -> None:
    """Add the ``bag`` command and its subcommands."""
    p = subparsers.add_parser("bag", help="inspect a recorded bag, recover a damaged one",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="bag_command", metavar="<subcommand>", required=True)
    info = sub.add_parser("info", help="topics, counts, duration, closed or not")
    info.add_argument("bag", metavar="BAG", help="bag directory or .mcap file")
    info.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    info.set_defaults(func=_info)
    recover = sub.add_parser("recover", help="write a complete bag of the messages before the "
                             "damage of a cut or unclosed one")
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

    info = bag_info(args.bag)
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
    print("closed     " + ("yes" if info.closed else "no: " + "; ".join(info.problems)))
    if info.damage is not None:
        print(f"damage     {info.damage}")
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


def _recover(args) -> int:
    from aero_dva.bag.recovery import recover_bag

    result = recover_bag(args.bag, Path(args.out), compression=args.compression)
    damage = "none: every message kept" if result.damage is None else str(result.damage)
    if args.json:
        print(json.dumps({
            "out": str(result.out), "kept": result.kept, "salvaged": result.salvaged,
            "damage": None if result.damage is None else {
                "file": str(result.damage.file), "offset": result.damage.offset,
                "reason": result.damage.reason},
            "files_read": result.files_read, "files_total": result.files_total,
            "topics": {t.name: t.message_count for t in result.topics}}))
        return 0
    print(f"kept       {result.kept} messages"
          + (f" ({result.salvaged} from the chunk the file ends in)" if result.salvaged else ""))
    print(f"damage     {damage}")
    if result.files_read < result.files_total:
        print(f"files      {result.files_read} of {result.files_total} read; the files after "
              "the damage are left out")
    print(f"new bag    {result.out}")
    return 0
