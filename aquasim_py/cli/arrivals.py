"""``aquasim-py arrivals SCENARIO --from X,Y,Z --to X,Y,Z``: every arrival of one link in the
scenario's environment (delay, level, angles, bounces, path), as a table or JSON."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from typing import Any

from aquasim_py.cli import common

EXAMPLES = """examples:
  aquasim-py arrivals scenarios/itmtl.toml --from 0,0,50 --to 800,300,120
  aquasim-py arrivals scenarios/itmtl.toml --from 0,0,50 --to 800,300,120 --json --max-bounces 3
  aquasim-py arrivals scenarios/geographic.toml --from -2000,7500,40 --to 600,3900,90
"""


def _point(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in metres, got {text!r}") from None
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z (m), got {text!r}")
    return vals[0], vals[1], vals[2]


def _bounces(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 0 <= v <= 20:
        raise argparse.ArgumentTypeError(f"expected 0..20 bounces, got {v}")
    return v


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py arrivals",
        description="List every eigenray (arrival) of one link in a scenario's environment, in "
        "increasing delay: delay (s), level (dB re the source level at 1 m: spreading, absorption, "
        "bottom loss), launch and arrival grazing angles (deg, positive down), surface and bottom "
        "bounces, path class. Coordinates in metres, z = depth (positive down).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scenario", metavar="SCENARIO.toml", help="scenario file (its [environment] and [channel])")
    p.add_argument("--from", dest="src", metavar="X,Y,Z", type=_point, required=True, help="source (m)")
    p.add_argument("--to", dest="dst", metavar="X,Y,Z", type=_point, required=True, help="receiver (m)")
    p.add_argument(
        "--max-bounces",
        type=_bounces,
        default=None,
        help="surface + bottom bounces per arrival (default: the scenario's [channel] max_bounces, 2 unless set)",
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    return p


def _environment(path: str) -> tuple[Any, Any]:
    from aquasim_py.scenario import load
    from aquasim_py.scenario.build import make_ssp
    from aquasim_py.scenario.ocean import depth_profile, make_environment

    sc = load(path)
    return sc, make_environment(sc, make_ssp(sc) if depth_profile(sc) else None)


def command(argv: Sequence[str]) -> int:
    # "--from -1500,0,40": a negative x is a value, not an option (argparse would say so only
    # for a plain number)
    argv = list(argv)
    for i in range(len(argv) - 1):
        if argv[i] in ("--from", "--to") and argv[i + 1].startswith("-"):
            argv[i : i + 2] = [f"{argv[i]}={argv[i + 1]}", ""]
    args = parser().parse_args([a for a in argv if a != ""])  # --help exits here
    from aquasim_py.channel.arrivals import arrivals

    sc, env = _environment(args.scenario)
    for name, pt in (("--from", args.src), ("--to", args.dst)):
        floor = float(env.depth(pt[0], pt[1]))
        if not 0.0 <= pt[2] <= floor:
            raise common.UsageError(
                f"{name} {pt[0]:g},{pt[1]:g},{pt[2]:g}: depth outside the water (0 to {floor:g} m there)"
            )
    ch = sc.channel
    if args.max_bounces is None:
        args.max_bounces = ch.max_bounces
    arr = arrivals(env, args.src, args.dst, max_bounces=args.max_bounces, frequency_khz=ch.frequency_khz)
    rows = arr.records()
    for r in rows:
        r.pop("link")
    if args.json:
        doc = {
            "scenario": str(args.scenario),
            "from": list(args.src),
            "to": list(args.dst),
            "max_bounces": args.max_bounces,
            "frequency_khz": ch.frequency_khz,
            "range_independent": bool(env.range_independent),
            "arrivals": rows,
        }
        json.dump(doc, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    if not rows:
        print(f"no arrival with at most {args.max_bounces} bounces (try --max-bounces)")
        return 0
    head = f"{'delay s':>14} {'level dB':>9} {'launch':>8} {'arrival':>8} {'surf':>4} {'bot':>4}  path"
    print(head)
    for r in rows:
        print(
            f"{r['delay_s']:14.9f} {r['level_db']:9.2f} {r['launch_angle_deg']:8.3f} {r['arrival_angle_deg']:8.3f} "
            f"{r['surface_bounces']:4d} {r['bottom_bounces']:4d}  {r['path']}"
        )
    return 0
