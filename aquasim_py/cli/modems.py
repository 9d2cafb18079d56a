"""``aquasim-py modems [NAME ...]``: the acoustic modem presets (``[channel] modem = "NAME"``) with
every figure and its source, as text or JSON."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import Any

from aquasim_py.cli import common

EXAMPLES = """examples:
  aquasim-py modems                          # every preset, its figures and their sources
  aquasim-py modems evologics_s2cr_18_34     # one
  aquasim-py modems --json
  aquasim-py scenarios/itmtl.toml --set 'channel.modem="whoi_mm2_psk"'   # run with one
"""


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py modems",
        description='List the acoustic modem presets a scenario can name with [channel] modem = "NAME": band, '
        "bit rate, source level, detection threshold, packet overhead, modulation and power by modem state, each "
        "with its source (a datasheet or paper, or the stated assumption where no figure is published). Any key a "
        "scenario's [channel] table gives overrides the preset's.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("names", nargs="*", metavar="NAME", help="presets to show (default: all)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    return p


def _doc(p: Any) -> dict[str, Any]:
    from aquasim_py.channel.modem_presets import FIELDS

    figures = {k: {"value": getattr(p, k), "unit": FIELDS[k], "source": p.sources[k]} for k in FIELDS if k in p.sources}
    if p.range_m is not None:
        figures["range_m"] = {"value": p.range_m, "unit": "m (nominal, not applied)", "source": p.sources["range_m"]}
    return {"name": p.name, "title": p.title, "figures": figures}


def _value(v: Any, unit: str) -> str:
    text = f"{v:g}" if isinstance(v, float) else str(v)
    return f"{text} {unit}".rstrip()


def command(argv: Sequence[str]) -> int:
    from aquasim_py.channel.modem_presets import PRESETS, REFERENCES

    args = parser().parse_args(list(argv))
    unknown = [n for n in args.names if n not in PRESETS]
    if unknown:
        raise common.UsageError(f"unknown modem {unknown[0]!r} (known: {', '.join(PRESETS)})")
    chosen = [PRESETS[n] for n in (args.names or PRESETS)]
    docs = [_doc(p) for p in chosen]
    texts = [f["source"] for d in docs for f in d["figures"].values()]
    cited = sorted(k for k in REFERENCES if any(k in t for t in texts))  # as a source, or named in an assumption
    if args.json:
        json.dump({"presets": docs, "references": {k: REFERENCES[k] for k in cited}}, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    for d in docs:
        print(f"{d['name']}: {d['title']}")
        for key, f in d["figures"].items():
            print(f"  {key:<18} {_value(f['value'], f['unit']):<26} [{f['source']}]")
        print()
    print("references:")
    for k in cited:
        print(f"  [{k}] {REFERENCES[k]}")
    return 0
