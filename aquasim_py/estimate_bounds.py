"""The Cramér-Rao bound beside each estimate that declared its references, computed once per
run after the simulation, vectorized over the rows, from the trace tables.

A node that logs ``log_estimate(..., refs=ids, range_std=..., range_rel_std=...,
depth_known=...)`` says which references' ranges the estimate used and what noise it assumed
for them. For every such row this module computes, at the references' true positions at the
row's time (the ``positions`` table, linearly interpolated) and the node's own true position
(the row's ``true_x/y/z``):

- ``crb_h_m``: the horizontal bound with the noise **the simulation applied** to a range
  (:class:`RangeNoise`, from the scenario's configuration: MAC and clock timestamp jitter,
  sound-speed deviation). The same noise model for every protocol and variant of a run, so
  errors divided by it compare across variants.
- ``crb_h_declared_m``: the same geometry with the noise the node declared (its own model).
- ``gdop``: the same geometry with 1 m of range noise.

The table (:func:`estimate_bounds`) is written beside the traces as ``bounds.csv``; the
metrics ``localization.crb_h_m``, ``rmse_over_crb`` (and its ``_declared`` twin) read it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .estimation.bounds import range_crb_trace
from .metrics import positions_at, positions_source

__all__ = ["BOUND_COLUMNS", "RangeNoise", "applied_range_noise", "estimate_bounds", "parse_refs"]

#: the columns of the bounds table, in order
BOUND_COLUMNS = (
    "row",
    "time",
    "node",
    "protocol",
    "is_reference",
    "error_h",
    "crb_h_m",
    "crb_h_declared_m",
    "gdop",
    "range_std_m",
)


@dataclass(frozen=True)
class RangeNoise:
    """The noise the simulation applies to a range measured from a two-way exchange.

    ``stamp_std_s`` (one per node id): std of one MAC timestamp of that node, the channel's
    jitter and the node's clock read jitter combined (independent Gaussians:
    sqrt(jitter_std_s^2 + clock.jitter_std_s^2)). ``speed_mps``: the sound speed that turns
    time into range. ``rel_std``: the relative std of a range from the sound-speed deviation
    (``channel.sound_speed_std_mps`` / ``speed_mps``: the path-mean speed off the profile
    scales the delay, the same on both legs of an exchange).

    A two-way exchange between node i and reference j measures the time of flight as half the
    round trip from four stamps, two of each node: var = (s_i^2 + s_j^2) / 2 s^2, so a range
    has variance speed^2 (s_i^2 + s_j^2) / 2 + (rel_std r)^2 (m^2); with equal stamp noise s
    its std is speed x s. A one-way range between synchronized clocks has twice the stamp
    variance: the bound of the two-way exchange is the lower of the two. The channel applies
    no other ranging noise: stamps are not quantized (no timestamp resolution), and the stamp
    of a reception does not depend on its SNR.

    ``meas_std_m``, ``meas_rel_std`` (one per node id, or None for none): the noise a node's
    protocol draws onto the ranges it measures itself (its measurement model, e.g. STVF's ToA
    error of 2 % of the delay; :meth:`aquasim_py.node.Node.measurement_noise`), added to the
    ranges that node measures: variance + meas_std^2 + (meas_rel_std r)^2."""

    stamp_std_s: NDArray[np.float64]
    speed_mps: float
    rel_std: float = 0.0
    meas_std_m: NDArray[np.float64] | None = None
    meas_rel_std: NDArray[np.float64] | None = None

    def fixed_std(self, node: NDArray[np.int64], refs: NDArray[np.int64]) -> NDArray[np.float64]:
        """The part of the range std (m) that does not grow with the range, from ``node``
        (..., 1) to ``refs`` (..., N): the stamps' and the node's own absolute noise."""
        s = self.stamp_std_s
        var = self.speed_mps**2 * (s[node] ** 2 + s[refs] ** 2) / 2.0
        if self.meas_std_m is not None:
            var = var + self.meas_std_m[node] ** 2
        return np.sqrt(var)

    def relative_std(self, node: NDArray[np.int64]) -> NDArray[np.float64]:
        """The relative std of the ranges ``node`` (...) measures: the sound-speed deviation's
        and the node's own relative noise."""
        rel = np.full(np.shape(node), self.rel_std)
        if self.meas_rel_std is not None:
            rel = np.hypot(rel, self.meas_rel_std[node])
        return rel

    def range_std(
        self, node: NDArray[np.int64], refs: NDArray[np.int64], r: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Std (m) of the range from ``node`` (..., 1) to ``refs`` (..., N) at distance ``r`` (..., N)."""
        return np.hypot(self.fixed_std(node, refs), self.relative_std(node) * r)

    @property
    def zero(self) -> bool:
        """True when no noise is applied (every bound is 0)."""
        own = [a for a in (self.meas_std_m, self.meas_rel_std) if a is not None]
        return not (np.any(self.stamp_std_s > 0.0) or self.rel_std > 0.0 or any(np.any(a > 0.0) for a in own))


def applied_range_noise(sc: Any) -> RangeNoise:
    """The :class:`RangeNoise` of a resolved scenario: per node, in the groups' id order, the
    channel's ``jitter_std_s`` and its group's ``clock.jitter_std_s``, and the noise its
    protocol's own measurement model adds (:meth:`~aquasim_py.node.Node.measurement_noise` of
    the group's protocol with its parameters); the speed is the mean of the sound-speed
    profile over the volume's depths (at its centre for a range-dependent field)."""
    from . import registry
    from .scenario.build import make_ssp

    stamp: list[float] = []
    own_std: list[float] = []
    own_rel: list[float] = []
    for g in sc.nodes:
        n = int(g.count or 0)
        stamp.extend([math.hypot(sc.channel.jitter_std_s, g.clock.jitter_std_s)] * n)
        cls: Any = registry.get(g.protocol, base=sc.base_dir)  # a Node subclass (registry checks)
        std_m, rel = cls.measurement_noise(cls.Params.model_validate(dict(g.params)))
        own_std.extend([float(std_m)] * n)
        own_rel.extend([float(rel)] * n)
    lo, hi = sc.environment.volume.lo[2], sc.environment.volume.hi[2]
    speed = float(np.mean(make_ssp(sc).speed(np.linspace(lo, hi, 101))))
    return RangeNoise(
        np.asarray(stamp, dtype=float),
        speed,
        sc.channel.sound_speed_std_mps / speed,
        np.asarray(own_std, dtype=float),
        np.asarray(own_rel, dtype=float),
    )


def parse_refs(refs: pd.Series) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """The ``refs`` column (ids separated by spaces) as padded ids (rows, widest) and the mask
    of the ids present."""
    lists = [np.array(str(s).split(), dtype=np.int64) for s in refs]
    width = max((len(r) for r in lists), default=0)
    ids = np.zeros((len(lists), width), dtype=np.int64)
    mask = np.zeros((len(lists), width), dtype=bool)
    for i, r in enumerate(lists):  # ragged -> padded: one pass over the rows, no per-pair loop
        ids[i, : len(r)] = r
        mask[i, : len(r)] = True
    return ids, mask


_NEEDED = ("time", "node", "refs", "range_std", "range_rel_std", "true_x", "true_y", "true_z", "x", "y")


def estimate_bounds(tables: Mapping[str, Any], noise: RangeNoise | None) -> pd.DataFrame | None:
    """The bounds table (:data:`BOUND_COLUMNS`, one row per estimate that declared references;
    ``row`` is its index in ``estimates``) of a run's ``tables``; None when no estimate
    declared references or there is no ``positions`` table. ``noise``: the applied noise (None:
    ``crb_h_m`` and ``range_std_m`` are NaN)."""
    est = tables.get("estimates")
    if est is None or len(est) == 0 or "refs" not in est.columns or "positions" not in tables:
        return None
    refs_col = est["refs"]
    declared = refs_col.notna() & (refs_col.astype(str).str.strip() != "")
    if not declared.any():
        return None
    e = est[declared]
    ids, mask = parse_refs(e["refs"])
    n, width = ids.shape
    t = e["time"].to_numpy(float)
    here = e[["true_x", "true_y", "true_z"]].to_numpy(float)
    ref_pos = positions_at(positions_source(tables), ids.ravel(), np.repeat(t, width)).reshape(n, width, 3)
    ref_pos = np.where(mask[..., None], ref_pos, here[:, None, :] + 1.0)  # absent: any distinct point
    r = np.linalg.norm(here[:, None, :] - ref_pos, axis=-1)
    # no bound where a reference is where the node is, or a reference's position is unknown
    ok = ~np.any(mask & ((r == 0.0) | ~np.isfinite(r)), axis=1) & (mask.sum(axis=1) > 0)
    depth_known = _flags(e["depth_known"]) if "depth_known" in e.columns else np.ones(n, dtype=bool)
    std = e["range_std"].to_numpy(float)
    rel = e["range_rel_std"].to_numpy(float)
    node = e["node"].to_numpy(np.int64)

    gdop = np.full(n, np.nan)
    declared_crb = np.full(n, np.nan)
    applied = np.full(n, np.nan)
    range_std = np.full(n, np.nan)
    n_ids = 0 if noise is None else len(noise.stamp_std_s)
    # the applied noise needs every id of the row among the scenario's nodes
    ok_noise = ok & (node < n_ids) & np.all(~mask | (ids < n_ids), axis=1)
    for plane in (True, False):
        sel = ok & (depth_known == plane)
        if not sel.any():
            continue
        gdop[sel] = _crb_h(here[sel], ref_pos[sel], mask[sel], plane, 1.0, 0.0)
        # a declared noise of 0: a zero bound (where the geometry fixes the position)
        noisy = sel & ((std > 0.0) | (rel > 0.0))
        declared_crb[sel & ~noisy] = 0.0 * gdop[sel & ~noisy]
        if noisy.any():
            declared_crb[noisy] = _crb_h(
                here[noisy], ref_pos[noisy], mask[noisy], plane, std[noisy, None], rel[noisy, None]
            )
        idx = np.flatnonzero(sel & ok_noise)
        if noise is None or not idx.size:
            continue
        m = mask[idx]
        sd = noise.range_std(node[idx, None], ids[idx], r[idx])
        range_std[idx] = np.sqrt((sd**2 * m).sum(axis=1) / m.sum(axis=1))
        # links without noise (no jitter at either end, no sound-speed deviation): a zero bound
        # when all are, none computed when some are (their information is unbounded)
        quiet = m & (sd == 0.0)
        none = quiet.sum(axis=1) == m.sum(axis=1)
        applied[idx[none]] = 0.0 * gdop[idx[none]]
        calc = ~quiet.any(axis=1)
        if calc.any():
            i = idx[calc]
            fixed = noise.fixed_std(node[i, None], ids[i])
            rel_i = noise.relative_std(node[i])[:, None]
            applied[i] = _crb_h(here[i], ref_pos[i], mask[i], plane, np.where(mask[i], fixed, 1.0), rel_i)
    d = e[["x", "y"]].to_numpy(float) - here[:, :2]
    out = pd.DataFrame(
        {
            "row": np.flatnonzero(declared.to_numpy()),
            "time": t,
            "node": node,
            "protocol": e["protocol"].to_numpy(object) if "protocol" in e.columns else None,
            "is_reference": e["is_reference"].to_numpy(object) if "is_reference" in e.columns else False,
            "error_h": np.hypot(d[:, 0], d[:, 1]),
            "crb_h_m": applied,
            "crb_h_declared_m": declared_crb,
            "gdop": gdop,
            "range_std_m": range_std,
        }
    )
    return out


def _crb_h(
    here: NDArray[np.float64],
    ref_pos: NDArray[np.float64],
    mask: NDArray[np.bool_],
    plane: bool,
    std: Any,
    rel_std: Any,
) -> NDArray[np.float64]:
    """sqrt of the horizontal part of the range CRB, one per row (NaN where the references
    cannot fix the position)."""
    tr = range_crb_trace(here, ref_pos, std=std, rel_std=rel_std, mask=mask, plane=plane, index=(0, 1))
    return np.sqrt(tr)


def _flags(col: pd.Series) -> NDArray[np.bool_]:
    """A boolean column as written and read back (True / "True" / "true"; missing: True)."""
    v = col.to_numpy(object)
    return np.array(
        [True if x is None or (isinstance(x, float) and math.isnan(x)) else x in (True, "True", "true") for x in v]
    )
