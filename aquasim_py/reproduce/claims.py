"""What a reproduction is made of, as plain data: a paper's claims, the readings of its open
choices, and the scales (``--quick`` / ``--full``) they run at.

A :class:`Claim` compares one statistic of ours with the paper's number (or ordering):

- ``value``: ours = the statistic of quantity ``a``; compared with ``paper`` within the band
  of :data:`REL_TOL` (declared once, for every claim of every paper);
- ``less``: quantity ``a`` below quantity ``b`` (paired over seeds: the same network and
  seeds in both); ours = stat(a) - stat(b);
- ``gap_pct``: ours = 100 (stat(b) - stat(a)) / stat(``of``), how much b is above a, in %
  of a (``of = "a"``) or of b (``of = "b"``), compared with ``paper`` as a ``value``;
- ``ratio``: ours = stat(a) / stat(b), compared with ``paper`` as a ``value``; with
  ``bound = True`` b is a lower bound (a CRB), and a ratio below 1 beyond its CI is flagged;
- ``reference``: a number shown beside the claims (a bound, a genie), no verdict.

Where the paper's number is one example run (``paper_runs = "one"``), a ``value`` claim is
compared with the spread of single runs: the paper's number inside our 95 % prediction
interval of one run holds, outside it does not.

A :class:`Quantity` is one metric of one scenario variant (a column of the sweep rows:
``aquasim-py sweep`` writes the same), summarized over seeds by its ``statistic``: ``mean``;
``rms`` = sqrt(mean of squares), the pooled RMSE of per-run RMSEs over equally long runs; or
``time_mean_rms``, the time average over a run's intervals of the RMS over runs of each
interval's value (MSWPF's eq 37: ``metric`` then names a per-interval series,
``<metric>[k]`` in the rows); or ``interval_mean``, each interval's mean over runs (a curve
over iterations, as ITMTL's Figs 11-12), which the claim compares interval by interval and
reduces to one number (``reduce``). A :class:`Reading` names one resolution of the paper's open
choices: it maps the claim's scenario and variants to others, adds ``--set`` overrides (to
every run, or to one variant's runs only: a parameter other protocols do not have), or
reads the same runs differently (metrics scored over another time window of the scale's
``windows``, another metric or statistic); every claim is reported under every reading of
its paper (``readings`` narrows that).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

__all__ = ["MIN_RUNS", "REL_TOL", "Claim", "Paper", "Quantity", "Reading", "Scale"]

#: a ``value`` claim holds when our 95 % CI lies within +-25 % of the paper's number, does not
#: when it lies wholly outside that band, and is inconclusive otherwise (one rule for every claim)
REL_TOL = 0.25
#: no verdict from fewer runs ("too few runs"), on every path: below 10 runs a nominal 95 %
#: percentile-bootstrap interval of a mean covers the true mean in under 90 % of normal
#: samples (83 % at 5 runs, 48 % at 2), and a t-interval of a few skewed values is no better
#: (82-83 % for lognormal values at 5-10 runs); measured in docs/reproductions/README.md
MIN_RUNS = 10

Kind = Literal["value", "less", "gap_pct", "ratio", "reference"]
Statistic = Literal["mean", "rms", "time_mean_rms", "interval_mean"]


@dataclass(frozen=True)
class Quantity:
    """``metric`` of scenario variant ``variant`` (None: the file as written) over seeds."""

    metric: str
    variant: str | None = None
    statistic: Statistic = "mean"
    label: str = ""  #: how the tables name it (default: variant / metric)
    #: ``--set`` overrides of this quantity's runs only (a parameter only its protocol has, such
    #: as STVF's Nr); its runs are then a unit of their own, paired with the other quantity's
    #: by seed (every unit of a scenario file runs the same seeds)
    overrides: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return self.label or (f"{self.variant}: {self.metric}" if self.variant else self.metric)


@dataclass(frozen=True)
class Claim:
    """One claim of a paper (see the module docstring for ``kind``)."""

    id: str  #: unique within the paper, e.g. "table1_rmse"
    figure: str  #: where the paper states it ("Table 1", "Fig. 9")
    text: str  #: the claim in words
    kind: Kind
    a: Quantity
    scenario: str  #: key into the scale's scenarios
    b: Quantity | None = None
    paper: float | None = None  #: the paper's number (``value``, ``gap_pct``, ``ratio``)
    paper_text: str = ""  #: the paper's number as it states it, and what it is a statistic of
    statistic: str = ""  #: what our number is a statistic of (runs, nodes, frames)
    of: Literal["a", "b"] = "a"  #: ``gap_pct``: percent of which quantity
    overrides: tuple[str, ...] = ()  #: ``--set`` overrides of this claim's runs (e.g. a table cell)
    readings: tuple[str, ...] = ()  #: readings it is reported under (empty: all the paper's)
    paper_runs: Literal["many", "one"] = "many"  #: "one": the paper's number is one example run
    #: ``interval_mean`` quantities: how the per-interval numbers (a gap at each iteration)
    #: become one ("max": the paper's "up to"; "median": its "about")
    reduce: Literal["", "max", "median"] = ""
    bound: bool = False  #: ``ratio``: b is a lower bound of a (a ratio below 1 is flagged)
    note: str = ""


@dataclass(frozen=True)
class Reading:
    """One resolution of the paper's open choices (see the module docstring)."""

    name: str
    description: str
    variants: dict[str, str] = field(default_factory=dict)  #: claim variant -> variant run instead
    scenarios: dict[str, str] = field(default_factory=dict)  #: claim scenario key -> key run instead
    overrides: tuple[str, ...] = ()  #: ``--set`` overrides on every run of the reading
    #: variant -> ``--set`` overrides of that variant's runs only (a parameter only its protocol has)
    variant_overrides: dict[str, tuple[str, ...]] = field(default_factory=dict)
    window: str = ""  #: read the metrics scored over this window of the scale (``Scale.windows``)
    #: metric -> (metric, statistic) read instead (another statistic of the same runs)
    metrics: dict[str, tuple[str, Statistic]] = field(default_factory=dict)


@dataclass(frozen=True)
class Scale:
    """Where and how long: scenario files by key, seeds per quantity, and overrides."""

    scenarios: dict[str, str]  #: key -> scenario file (relative to the repository root)
    runs: int  #: seeds per quantity (run_seed(scenario seed, r), r = 0..runs-1)
    overrides: tuple[str, ...] = ()  #: ``--set`` overrides on every run of the scale
    note: str = ""  #: what this scale is, against the paper's
    #: variant -> ``--set`` overrides of that variant's runs only (before the reading's)
    variant_overrides: dict[str, tuple[str, ...]] = field(default_factory=dict)
    #: name -> time (s): every run's metrics are also scored from that time on, as
    #: ``<name>.<metric>`` in its row (the run's traces re-read as it finishes; no second run)
    windows: dict[str, float] = field(default_factory=dict)
    #: scenario key -> seeds per quantity, where it differs from ``runs`` (the paper's own count)
    runs_by_scenario: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class Paper:
    """A paper's reproduction: its claims, readings and scales."""

    key: str  #: the CLI name
    title: str
    claims: tuple[Claim, ...]
    readings: tuple[Reading, ...]
    quick: Scale
    full: Scale
    doc: str = ""  #: the project's doc page of the paper (reconstruction, open choices)

    def claim_readings(self, claim: Claim) -> tuple[Reading, ...]:
        names = claim.readings or tuple(r.name for r in self.readings)
        return tuple(r for r in self.readings if r.name in names)
