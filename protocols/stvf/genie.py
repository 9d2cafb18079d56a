"""The two references STVF and SLMP are measured against (issue 33 item 3): the genie
multilateration (an oracle, its own scenario variant) and the CRB of the geometry each node
used (a metric of the STVF and SLMP runs themselves).

Neither is a protocol a node could run, and no node reads ground truth for them. The oracle
part runs in the metrics, from the trace tables, where truth legitimately lives:

- ``genie_multilateration`` (:class:`GenieMultilaterationNode`): beacon nodes broadcast every
  period exactly as STVF's do; an unknown node measures the one-way delay of every beacon it
  hears with STVF's ranging model (MAC stamps, error std ``noise_ratio`` x delay from its own
  stream) and logs the measurement in the ``genie_ranges`` table, nothing else. Its metrics
  then multilaterate every (node, period) from the beacons' **true** positions at their send
  instants (the ``positions`` table), no promotion, and score the fix against the node's true
  position at the measurement epoch: what multilateration reaches with perfect references.
- :func:`crb_metrics`: for every estimate an STVF or SLMP node logged, the Cramér-Rao bound
  (:func:`aquasim_py.estimation.bounds.range_crb_trace`) of the ranges to the references it
  used (``refs`` column), at their true positions, with the ranging error std the node's
  measurement model draws (``range_rel_std`` x distance; the channel's sound-speed spread is
  left out, which only lowers the bound). A snapshot bound: a filter that carries
  information from earlier periods (STVF's prior) may go below it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from pydantic import Field

from aquasim_py import metrics as generic
from aquasim_py.estimation.bounds import range_crb_trace
from aquasim_py.estimation.errors import DegenerateGeometryError, InsufficientMeasurementsError
from aquasim_py.estimation.lsq import multilaterate
from aquasim_py.estimation.variational import initial_fix
from aquasim_py.node import Role
from aquasim_py.registry import register

from ..common.periodic import PeriodicBeaconNode, PeriodicParams

__all__ = ["GenieMultilaterationNode", "crb_metrics", "genie_fixes"]

KIND = "genie_beacon"
RANGES = "genie_ranges"


class GenieParams(PeriodicParams):
    """The beacon cycle and ranging model of STVF (Table 1 defaults)."""

    noise_ratio: float = Field(0.02, ge=0, description="ranging error std / delay (STVF's measurement model)")
    speed_mps: float = Field(1500.0, gt=0, description="nominal sound speed, delays to ranges (m/s)")
    speed_std_mps: float = Field(10.0, ge=0, description="spread of the true sound speed around it (m/s)")
    start_s: float = Field(0.0, ge=0, description="unknown nodes record ranges from this local time on (s)")
    range_m: float = Field(80.0, gt=0, description="modem range (m): a fix must lie within it of every beacon heard")
    max_std_m: float = Field(
        10.0, gt=0, description="a fix whose geometry gives a std above this in any direction is no fix (m)"
    )


@register
class GenieMultilaterationNode(PeriodicBeaconNode):
    """Oracle reference: beacon nodes broadcast, unknown nodes log what they measure; the
    multilateration on true beacon positions happens in :meth:`metrics` (module docstring)."""

    name = "genie_multilateration"
    trace_tables = ("nodes", "positions", RANGES)
    Params = GenieParams
    beacon_kind = KIND

    def setup(self) -> None:
        self.is_beacon = self.role in (Role.ANCHOR, Role.BUOY)

    def advertises(self) -> bool:
        return self.is_beacon

    def beacon_payload(self) -> None:
        return None  # the genie takes the senders' positions from the truth, not from beacons

    def ready(self, elapsed_s: float) -> bool:
        return elapsed_s >= self.params.start_s

    def localize(self, heard: list[Any]) -> None:
        """Log one row per beacon heard: sender, measured delay (s, with the ranging error),
        how long before now it arrived (local s) and the depth gauge's reading."""
        p: GenieParams = self.params
        if not heard:
            return
        now = self.local_time()
        depth = self.depth()
        z = np.array([r.rx_local - r.packet.tx_local for r in heard])
        if p.noise_ratio > 0:
            z = z * (1.0 + p.noise_ratio * self.rng.standard_normal(z.size))
        # the gate of a fix (genie_fixes): STVF's first-fix test with the node's error model
        rel_std = float(np.hypot(p.noise_ratio, p.speed_std_mps / p.speed_mps))
        for rec, zi in zip(heard, z):
            self.log(
                RANGES,
                src=rec.packet.src,
                delay_s=float(zi),
                age_s=now - rec.rx_local,
                depth_m=depth,
                rel_std=rel_std,
                range_m=p.range_m,
                max_std_m=p.max_std_m,
            )

    @classmethod
    def metrics(cls, tables: Mapping[str, Any]) -> dict[str, float]:
        fixes = genie_fixes(tables)
        nodes = tables.get("nodes")
        out: dict[str, float] = {"fixes": float(len(fixes))}
        if len(fixes) == 0 or nodes is None:
            return out
        err2 = fixes["error_m"].to_numpy() ** 2
        out["rmse_m"] = float(np.sqrt(err2.mean()))
        out["mean_error_m"] = float(fixes["error_m"].mean())
        n_unknown = max(len(generic.evaluated_nodes(nodes)), 1)
        out["coverage"] = float(fixes["node"].nunique() / n_unknown)
        rng = tables.get(RANGES)
        periods = rng["time"].nunique() if rng is not None else 0
        out["period_coverage"] = float(len(fixes) / (n_unknown * max(periods, 1)))
        return out


def genie_fixes(tables: Mapping[str, Any], speed_mps: float = 1500.0) -> pd.DataFrame:
    """One genie fix per (node, period) with >= 3 beacons heard whose geometry can fix the
    node: columns node, time (s, the log instant), epoch (s, true time of the mean reception),
    x, y, true_x, true_y, error_m. The gate is STVF's first-fix test
    (:func:`aquasim_py.estimation.variational.initial_fix`: worst-direction std of the linear
    fix at most ``max_std_m``, within ``range_m`` of every beacon), the fix then refined by
    Gauss-Newton: three beacons near one line give a mirror image as good as the fix, and no
    reference should report those.

    Receptions happened ``age_s`` local seconds before the row's (true) log time; local and
    true durations differ by the clock's skew (40 ppm at most in the shipped scenarios: a few
    micrometres of motion), so ages are taken as true. The sender was at its true position
    one delay earlier; the delay is projected on the node's depth plane with the depth gauge,
    as the protocols do."""
    rng = tables.get(RANGES)
    pos = tables.get("positions")
    cols = ["node", "time", "epoch", "x", "y", "true_x", "true_y", "error_m"]
    if rng is None or pos is None or len(rng) == 0:
        return pd.DataFrame(columns=cols)
    t_rx = rng["time"].to_numpy(float) - rng["age_s"].to_numpy(float)
    delay = rng["delay_s"].to_numpy(float)
    src_pos = generic.positions_at(pos, rng["src"].to_numpy(), t_rx - delay)
    dz = src_pos[:, 2] - rng["depth_m"].to_numpy(float)
    horiz = np.sqrt(np.maximum((speed_mps * delay) ** 2 - dz**2, 0.0))
    keys = rng[["node", "time"]].to_numpy()
    rows = []
    # one small least-squares problem per (node, period); groups are formed once by a sort
    order = np.lexsort((keys[:, 1], keys[:, 0]))
    _, starts = np.unique(keys[order], axis=0, return_index=True)
    for grp in np.split(order, starts[1:]):
        if grp.size < 3:
            continue
        a, r, first = src_pos[grp, :2], horiz[grp], grp[0]
        if initial_fix(a, r, rng["rel_std"].iat[first], rng["max_std_m"].iat[first], rng["range_m"].iat[first]) is None:
            continue
        try:
            xy = multilaterate(a, r, refine=5)
        except (DegenerateGeometryError, InsufficientMeasurementsError, np.linalg.LinAlgError):
            continue
        rows.append((keys[grp[0], 0], keys[grp[0], 1], float(t_rx[grp].mean()), xy[0], xy[1]))
    if not rows:
        return pd.DataFrame(columns=cols)
    df = pd.DataFrame(rows, columns=cols[:5])
    truth = generic.positions_at(pos, df["node"].to_numpy(), df["epoch"].to_numpy())
    df["true_x"], df["true_y"] = truth[:, 0], truth[:, 1]
    df["error_m"] = np.hypot(df["x"] - df["true_x"], df["y"] - df["true_y"])
    return df


def crb_metrics(tables: Mapping[str, Any], protocol: str) -> dict[str, float]:
    """``crb_rmse_m``: sqrt of the mean CRB over the protocol's estimates (evaluated nodes, the
    metrics' window) of the ranges to the references each used, at their true positions;
    ``crb_rows``: how many estimates had a defined bound. Empty without the ``refs`` and
    ``range_rel_std`` columns or the ``positions`` table."""
    est = tables.get("estimates")
    nodes = tables.get("nodes")
    pos = tables.get("positions")
    if est is None or pos is None or len(est) == 0 or "refs" not in est.columns:
        return {}
    e = generic.select_rows(est, nodes, protocol=protocol)
    e = e[e["refs"].notna() & (e["refs"].astype(str) != "")]
    if len(e) == 0:
        return {}
    refs = [np.array(str(s).split(), dtype=np.int64) for s in e["refs"]]
    width = max(len(r) for r in refs)
    ids = np.zeros((len(refs), width), dtype=np.int64)
    mask = np.zeros((len(refs), width), dtype=bool)
    for i, r in enumerate(refs):  # ragged -> padded (one row per estimate)
        ids[i, : len(r)] = r
        mask[i, : len(r)] = True
    epoch = e["time"].to_numpy(float) - e["epoch_lag_s"].to_numpy(float)
    node_pos = generic.positions_at(pos, e["node"].to_numpy(), epoch)
    ref_pos = generic.positions_at(pos, ids.ravel(), np.repeat(epoch, width)).reshape(len(refs), width, 3)
    ref_pos = np.where(mask[..., None], ref_pos, node_pos[:, None, :] + 1.0)  # absent: any distinct point
    crb = range_crb_trace(node_pos, ref_pos, rel_std=float(e["range_rel_std"].iloc[0]), mask=mask)
    ok = np.isfinite(crb)
    if not ok.any():
        return {"crb_rows": 0.0}
    return {"crb_rmse_m": float(np.sqrt(crb[ok].mean())), "crb_rows": float(ok.sum())}
