"""How numbers and tables print: a human unit per metric, short numbers, tables that fit.

A metric's unit comes from its name's suffix (the naming rule of docs/metrics.md):
``_s`` seconds, ``_m`` metres, ``_mps`` m/s, ``_db`` dB, ``_pct`` %, ``_ppm`` ppm, ``_deg``
degrees, ``_hz`` Hz. Times are shown in ns, us, ms or s, one unit per row, chosen by the
row's median magnitude (``sync.mean_abs_error_s`` of 3.05e-05 s prints as ``30.52`` in a row
labelled ``sync.mean_abs_error (us)``). Every number has four significant digits, and no
more than 10 characters below 1e100 (fixed notation from 0.001 to 99999, exponent notation
outside).

Tables: :func:`column_blocks` splits value columns into blocks that each fit a width, so a
wide comparison prints as several narrow tables rather than numbers folded or cut, and
:func:`fits` tells whether a text table fits without breaking a word.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "TextTable",
    "Unit",
    "column_blocks",
    "describe_network",
    "fits",
    "format_in",
    "format_number",
    "format_row",
    "label",
    "text_widths",
    "unit_of",
    "wrap_name",
]

#: name suffix -> (unit shown, factor from the stored value)
_SUFFIX_UNITS: dict[str, tuple[str, float]] = {
    "_m": ("m", 1.0),
    "_mps": ("m/s", 1.0),
    "_db": ("dB", 1.0),
    "_pct": ("%", 1.0),
    "_ppm": ("ppm", 1.0),
    "_deg": ("deg", 1.0),
    "_hz": ("Hz", 1.0),
}
#: time units, largest first: (name, seconds)
_TIME_UNITS = (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))


@dataclass(frozen=True)
class Unit:
    """A metric's display: ``stem`` (the name without its unit suffix), the unit shown (""
    for a plain number) and ``scale``: shown value = stored value / scale."""

    stem: str
    unit: str = ""
    scale: float = 1.0


def unit_of(name: str, values: Iterable[Any] = ()) -> Unit:
    """The display unit of metric ``name``; for times, picked from ``values`` (stored, in s)
    so that their median magnitude shows between 1 and 1000 (s at most)."""
    if name.endswith("_s"):
        mags = sorted(abs(v) for v in _finite(values) if v != 0)
        typical = mags[len(mags) // 2] if mags else 1.0
        unit, scale = next(((u, f) for u, f in _TIME_UNITS if typical >= f), _TIME_UNITS[-1])
        return Unit(name[:-2], unit, scale)
    for suffix, (unit, scale) in _SUFFIX_UNITS.items():
        if name.endswith(suffix):
            return Unit(name[: -len(suffix)], unit, scale)
    return Unit(name)


def label(u: Unit) -> str:
    """``stem (unit)`` or the bare stem."""
    return f"{u.stem} ({u.unit})" if u.unit else u.stem


def _finite(values: Iterable[Any]) -> list[float]:
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            try:
                v = float(v)
            except (TypeError, ValueError):
                continue
        if math.isfinite(v):
            out.append(float(v))
    return out


def format_number(v: Any, sig: int = 4) -> str:
    """A number with ``sig`` significant digits in at most 10 characters below 1e100
    (integers whole up to 99999999); ``-`` for a missing or NaN value; other values as ``str``."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, numbers.Integral):
        return str(int(v)) if abs(int(v)) < 10**8 else f"{float(v):.{sig - 1}e}"
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0.0:
        return "0"
    r = float(f"{x:.{sig - 1}e}")  # rounded first: 9.9996 is 10.00, not 9.9996 shown as 10.000
    a = abs(r)
    if 1e-3 <= a < 1e5:
        return f"{r:.{max(0, sig - 1 - math.floor(math.log10(a)))}f}"
    return f"{x:.{sig - 1}e}"


def format_in(u: Unit, v: Any, sig: int = 4) -> str:
    """A stored value shown in unit ``u`` (integers, such as counts, stay whole)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool) and u.scale != 1.0:
        return format_number(float(v) / u.scale, sig)
    return format_number(v, sig)


def format_row(name: str, values: Sequence[Any], sig: int = 4) -> tuple[str, list[str]]:
    """A metric's row: its label with the unit and its values in that unit."""
    u = unit_of(name, values)
    return label(u), [format_in(u, v, sig) for v in values]


def column_blocks(first: int, widths: Sequence[int], width: int) -> list[list[int]]:
    """Indices of the value columns, in blocks that fit ``width`` characters each beside the
    first (label) column of ``first`` characters, in a rich table with borders (each column
    costs its content + 3: padding and a rule). A column wider than any block gets a block
    of its own."""
    blocks: list[list[int]] = []
    used = first + 4
    for i, w in enumerate(widths):
        if blocks and used + w + 3 <= width:
            blocks[-1].append(i)
            used += w + 3
        else:
            blocks.append([i])
            used = first + 4 + w + 3
    # as many blocks, of even sizes where they still fit (5 columns as 3 + 2, not 4 + 1)
    k, n = len(blocks), len(widths)
    sizes = [n // k + (b < n % k) for b in range(k)] if k else []
    starts = [sum(sizes[:b]) for b in range(k)]
    even = [list(range(a, a + size)) for a, size in zip(starts, sizes)]
    if all(first + 4 + sum(widths[i] + 3 for i in b) <= width for b in even):
        return even
    return blocks


def wrap_name(text: str, width: int) -> str:
    """Each line of ``text`` broken into lines of at most ``width`` characters after a ``.``,
    ``_`` or space, so a metric name keeps its parts whole (a part longer than ``width`` is
    left for the table to fold)."""
    out = []
    for line in text.split("\n"):
        cur = ""
        for part in re.findall(r"[^._ ]*[._ ]?", line):
            if cur and len(cur) + len(part.rstrip(" ")) > width:
                out.append(cur.rstrip(" "))
                cur = ""
            cur += part
        if cur:
            out.append(cur.rstrip(" "))
    return "\n".join(out)


def fits(columns: Mapping[str, Sequence[str]], width: int) -> bool:
    """Whether a rich table of these text columns (header -> cells) fits ``width`` with every
    word whole: rich wraps at spaces once each column has its longest word's width."""
    need = 1
    for header, cells in columns.items():
        longest = max((len(word) for text in [header, *cells] for word in str(text).split()), default=1)
        need += longest + 3
    return need <= width


def text_widths(columns: Mapping[str, Sequence[str]], width: int | None) -> list[int | None]:
    """Widths for text columns (header -> cells) in a bordered table of ``width`` characters:
    each at least its longest word, the room left shared in proportion to what each column
    would need to hold its longest cell on one line. None (rich decides) without a width or
    when even the longest words do not fit (:func:`fits`)."""
    texts = [[h, *cells] for h, cells in columns.items()]
    if width is None or not fits(columns, width):
        return [None] * len(texts)
    most = [max(len(str(t)) for t in col) for col in texts]
    # short texts ("Fig. 10") stay on one line
    least = [max(min(m, 10), *(len(w) for t in col for w in str(t).split())) for m, col in zip(most, texts)]
    if sum(least) + 1 + 3 * len(texts) > width:
        least = [max(len(w) for t in col for w in str(t).split() or [""]) for col in texts]
    room = width - 1 - 3 * len(texts) - sum(least)
    want = [b - a for a, b in zip(least, most)]
    if sum(want) <= room:
        return list(most)
    share = [math.floor(room * w / sum(want)) for w in want]
    return [a + x for a, x in zip(least, share)]


def describe_network(sc: Any) -> str:
    """One line on a scenario's network: nodes per role, volume, sound speed, duration, seed."""
    roles: dict[str, int] = {}
    for g in sc.nodes:
        roles[g.role] = roles.get(g.role, 0) + int(g.count or 0)
    total = sum(roles.values())
    # "ordinary" is an adjective: "6 ordinary", but "3 buoys"
    who = ", ".join(f"{n} {role}{'s' * (n != 1 and role != 'ordinary')}" for role, n in roles.items())
    lo, hi = sc.environment.volume.lo, sc.environment.volume.hi
    size = " x ".join(f"{b - a:g}" for a, b in zip(lo, hi)) + " m"
    ssp = sc.environment.sound_speed
    if ssp.model == "isogradient":
        c = f"c(z) = {ssp.surface_speed_mps:g} + {ssp.gradient_per_s:g} z m/s"
    elif ssp.model == "constant":
        c = f"c = {ssp.speed_mps:g} m/s"
    else:
        c = f"{ssp.model} sound-speed profile"
    sim = sc.simulation
    return f"{total} nodes ({who}) in {size}, {c}, {sim.duration_s:g} s simulated, seed {sim.seed}"


@dataclass
class TextTable:
    """A table of preformatted text: a label column and value columns (cells may hold several
    lines), rendered for a terminal (:meth:`rich`, in column blocks that fit its width) or a
    page (:meth:`html`)."""

    title: str
    header: list[str]  # the label column's header, then one per value column
    rows: list[list[str]]
    sections: set[int] = field(default_factory=set)  # rows that are headings (their label only)
    caption: str | None = None
    notes: list[str] = field(default_factory=list)  # lines printed under the table

    def _widths(self) -> list[int]:
        return [
            max(len(line) for text in [self.header[j], *(r[j] for r in self.rows)] for line in str(text).split("\n"))
            for j in range(len(self.header))
        ]

    def rich(self, width: int | None = None) -> Any:
        """A rich renderable: the table, split into blocks of value columns that each fit
        ``width`` (None: one block), every number whole."""
        from rich.console import Group
        from rich.table import Table
        from rich.text import Text

        widths = self._widths()
        first = widths[0]
        rows = self.rows
        header = list(self.header)
        if width is not None and column_blocks(first, widths[1:], width) != [list(range(len(widths) - 1))]:
            # does not fit whole: headers broken after a "_" to their cells' width, and a
            # narrower label column (names broken after a dot or "_"), leave room for more
            # value columns per block
            cells = [
                max((len(line) for r in rows for line in str(r[j]).split("\n")), default=1) for j in range(len(header))
            ]
            header = [header[0]] + [wrap_name(h, max(c, 8)) for h, c in zip(header[1:], cells[1:])]
            widths = [widths[0]] + [max(c, *(len(x) for x in h.split("\n"))) for h, c in zip(header[1:], cells[1:])]
            whole = [list(range(len(widths) - 1))]
            fitting = (
                n
                for n in range(min(first, max(20, width // 3)), 15, -1)
                if column_blocks(n, widths[1:], width) == whole
            )
            first = next(fitting, min(first, max(20, width // 3)))
            rows = [[wrap_name(r[0], first), *r[1:]] for r in rows]
            first = max(len(line) for r in rows for line in r[0].split("\n"))
        blocks = column_blocks(first, widths[1:], width) if width is not None else [list(range(len(widths) - 1))]
        parts: list[Any] = []
        for b, cols in enumerate(blocks):
            more = f" ({b + 1}/{len(blocks)})" if len(blocks) > 1 else ""
            t = Table(title=self.title + more, title_justify="left", caption_justify="left")
            t.add_column(header[0], overflow="fold", min_width=min(first, 12), max_width=first)
            for j in cols:
                t.add_column(header[j + 1], justify="right", no_wrap=True, min_width=widths[j + 1])
            for i, r in enumerate(rows):
                if i in self.sections:
                    t.add_row(Text(r[0], style="bold"), *("" for _ in cols))
                else:
                    t.add_row(r[0], *(r[j + 1] for j in cols))
            if b == len(blocks) - 1 and self.caption:
                t.caption = self.caption
            parts.append(t)
        parts.extend(Text(n) for n in self.notes)
        return Group(*parts)

    def html(self) -> str:
        """The table as HTML (cells' lines joined with line breaks)."""
        import html as h

        def cell(tag: str, text: str, right: bool) -> str:
            style = ' style="text-align:right"' if right else ""
            return f"<{tag}{style}>" + "<br>".join(h.escape(x) for x in str(text).split("\n")) + f"</{tag}>"

        head = "".join(cell("th", x, j > 0) for j, x in enumerate(self.header))
        span = len(self.header)
        body = "".join(
            f'<tr><th colspan="{span}" style="text-align:left">{h.escape(r[0])}</th></tr>'
            if i in self.sections
            else "<tr>" + "".join(cell("td", x, j > 0) for j, x in enumerate(r)) + "</tr>"
            for i, r in enumerate(self.rows)
        )
        cap = f"<caption>{h.escape(self.title)}</caption>"
        foot = "".join(f"<p>{h.escape(x)}</p>" for x in ([self.caption] if self.caption else []) + self.notes)
        return f"<table>{cap}<tr>{head}</tr>{body}</table>{foot}"
