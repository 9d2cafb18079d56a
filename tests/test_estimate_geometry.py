"""The geometry beside each estimate: error_h / error_v, and the CRB / GDOP computed after the
run for the references a node declares (log_estimate(refs=...), aquasim_py.estimate_bounds),
checked against a brute-force Fisher information (Monte Carlo of the score, by numerical
differentiation of the log-likelihood) and against the per-row computation at the kernel's
exact positions; the applied-noise bound against the noise measured in the traces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import BaseModel

from aquasim_py import metrics
from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.estimate_bounds import RangeNoise, estimate_bounds
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node, Role

ANCHORS = np.array([[0.0, 0.0, 10.0], [1500.0, 0.0, 60.0], [0.0, 1500.0, 30.0], [1500.0, 1500.0, 90.0]])
HERE = np.array([600.0, 400.0, 120.0])
GUESS = (610.0, 397.0, 124.0)  # the logged estimate: error (10, -3, 4)


class Declares(Node):
    name = "declares"

    class Params(BaseModel):
        refs: list[int] | None = None
        range_std: float = 0.0
        range_rel_std: float = 0.0
        depth_known: bool = True

    def run(self):
        if self.role is Role.ANCHOR:
            return
        yield self.sleep(5.0)
        p = self.params
        self.log_estimate(
            *GUESS, refs=p.refs, range_std=p.range_std, range_rel_std=p.range_rel_std, depth_known=p.depth_known
        )
        self.log_estimate(*GUESS, n=2)  # no declaration: NaN bound


def _row(noise=None, **params):
    """The estimates of one run, with the bounds table's columns beside the rows it covers."""
    sim = Simulation(seed=1, ssp=Constant(1500.0), channel=ChannelConfig(max_range_m=5000.0))
    sim.add_group(Declares, 4, role=Role.ANCHOR, positions=ANCHORS, params=params)
    sim.add_group(Declares, 1, role=Role.ORDINARY, positions=[HERE], params=params)
    sim.run(10.0)
    tables = sim.trace.frames()
    est = tables["estimates"]
    b = estimate_bounds(tables, noise)
    for c in ("crb_h_m", "crb_h_declared_m", "gdop", "range_std_m"):
        est[c] = np.nan
        if b is not None:
            est.loc[b["row"].to_numpy(), c] = b[c].to_numpy()
    return est


def _fisher_monte_carlo(std, rel_std, depth_known, n=200_000, batches=10, seed=7):
    """Brute-force Fisher information of ranges r_i ~ N(d_i, std^2 + (rel_std d_i)^2) to
    ANCHORS about HERE: the mean outer product of the score, the score by central differences
    of the log-likelihood over Monte Carlo draws of r. Returns the horizontal CRB (m) of each
    batch's information and of all of them pooled."""
    rng = np.random.default_rng(seed)
    dims = 2 if depth_known else 3
    h = 1e-3  # m: the central-difference error, O(h^2 f'''), is ~1e-9 of the score here

    def loglik(theta, r):
        d = np.linalg.norm(theta[..., None, :] - ANCHORS, axis=-1)
        v = std**2 + (rel_std * d) ** 2
        return -0.5 * np.sum((r - d) ** 2 / v + np.log(v), axis=-1)

    d0 = np.linalg.norm(HERE - ANCHORS, axis=1)
    per_batch, infos = [], []
    for _ in range(batches):
        r = d0 + np.sqrt(std**2 + (rel_std * d0) ** 2) * rng.standard_normal((n // batches, d0.size))
        score = np.empty((len(r), dims))
        for k in range(dims):
            e = np.zeros(3)
            e[k] = h
            score[:, k] = (loglik(HERE + e, r) - loglik(HERE - e, r)) / (2 * h)
        info = score.T @ score / len(r)
        infos.append(info)
        per_batch.append(math.sqrt(np.trace(np.linalg.inv(info)[:2, :2])))
    pooled = math.sqrt(np.trace(np.linalg.inv(np.mean(infos, axis=0))[:2, :2]))
    return np.array(per_batch), pooled


@pytest.mark.parametrize(
    ("std", "rel_std", "depth_known"),
    [(2.0, 0.0, True), (2.0, 0.0, False), (1.0, 0.01, True), (0.0, 0.02, False)],
)
def test_crb_matches_a_brute_force_fisher_information(std, rel_std, depth_known):
    e = _row(refs=[0, 1, 2, 3], range_std=std, range_rel_std=rel_std, depth_known=depth_known)
    got = float(e["crb_h_declared_m"].iloc[0])
    batches, pooled = _fisher_monte_carlo(std, rel_std, depth_known)
    # tolerance: the Monte Carlo's own error, 5 standard errors of the pooled estimate (the
    # spread of 10 independent batches / sqrt(10)), as derived; numerical differentiation adds ~1e-9
    se = batches.std(ddof=1) / math.sqrt(len(batches))
    assert abs(got - pooled) <= 5 * se, (got, pooled, se)
    assert se < 0.01 * pooled  # the check has teeth: 200 000 draws pin the bound to < 1 %


def test_gdop_is_the_bound_for_unit_noise_and_the_rest_is_recorded():
    e = _row(refs=[0, 1, 2, 3], range_std=2.5, depth_known=False)
    first, undeclared = e.iloc[0], e.iloc[1]
    assert math.isclose(first["crb_h_declared_m"], 2.5 * first["gdop"], rel_tol=1e-12)
    # depth known (the gauge fixes z): more information, a lower horizontal bound
    plane = _row(refs=[0, 1, 2, 3], range_std=2.5).iloc[0]
    assert plane["crb_h_declared_m"] < first["crb_h_declared_m"]
    assert (first["refs"], first["range_std"], first["range_rel_std"]) == ("0 1 2 3", 2.5, 0.0)
    assert not first["depth_known"]
    assert math.isnan(undeclared["crb_h_declared_m"]) and math.isnan(undeclared["gdop"])
    # the errors: (10, -3, 4) m
    assert math.isclose(first["error_h"], math.hypot(10.0, 3.0)) and math.isclose(first["error_v"], 4.0)
    assert math.isclose(first["error"], math.sqrt(first["error_h"] ** 2 + first["error_v"] ** 2))


def test_too_few_references_give_no_bound_and_bad_declarations_are_errors():
    e = _row(refs=[0, 1], range_std=1.0, depth_known=False)  # 2 ranges cannot fix (x, y, z)
    assert math.isnan(e["crb_h_declared_m"].iloc[0])
    with pytest.raises(ValueError, match="no node with id 9"):
        _row(refs=[0, 9], range_std=1.0)
    with pytest.raises(ValueError, match="must be >= 0 and finite"):
        _row(refs=[0, 1, 2], range_std=-1.0)
    # noise-free ranges (a declared noise of 0): a zero bound, the geometry's GDOP
    free = _row(refs=[0, 1, 2, 3]).iloc[0]
    assert free["crb_h_declared_m"] == 0.0
    assert math.isclose(free["gdop"], _row(refs=[0, 1, 2, 3], range_std=1.0).iloc[0]["gdop"])


def test_the_applied_bound_uses_the_noise_of_each_link_not_the_declared_one():
    """Stamp noise s_i at the node and s_j at each reference: a two-way range of variance
    c^2 (s_i^2 + s_j^2) / 2; with equal noise s everywhere the bound is c s x GDOP whatever the
    node declared."""
    c = 1500.0
    equal = RangeNoise(np.full(5, 2e-4), c)
    e = _row(noise=equal, refs=[0, 1, 2, 3], range_std=9.0).iloc[0]
    assert math.isclose(e["range_std_m"], c * 2e-4, rel_tol=1e-12)
    assert math.isclose(e["crb_h_m"], c * 2e-4 * e["gdop"], rel_tol=1e-12)
    assert math.isclose(e["crb_h_declared_m"], 9.0 * e["gdop"], rel_tol=1e-12)
    # noise at the node only (perfect references): every link's std is c s / sqrt(2)
    node_only = RangeNoise(np.array([0.0, 0.0, 0.0, 0.0, 2e-4]), c)
    e = _row(noise=node_only, refs=[0, 1, 2, 3], range_std=9.0).iloc[0]
    assert math.isclose(e["crb_h_m"], c * 2e-4 / math.sqrt(2.0) * e["gdop"], rel_tol=1e-12)
    # no applied noise: a zero bound
    e = _row(noise=RangeNoise(np.zeros(5), c), refs=[0, 1, 2, 3], range_std=9.0).iloc[0]
    assert e["crb_h_m"] == 0.0


def test_rmse_h_and_rmse_over_crb():
    import pandas as pd

    est = pd.DataFrame(
        {
            "time": [1.0, 2.0, 3.0],
            "node": [1, 1, 2],
            "x": [3.0, 0.0, 1.0],
            "y": [4.0, 0.0, 0.0],
            "z": [9.0, 2.0, 0.0],
            "true_x": [0.0] * 3,
            "true_y": [0.0] * 3,
            "true_z": [0.0] * 3,
        }
    )
    bounds = pd.DataFrame(
        {
            "time": est["time"],
            "node": est["node"],
            "error_h": [5.0, 0.0, 1.0],
            "crb_h_m": [2.0, np.nan, 1.0],
            "crb_h_declared_m": [1.0, 1.0, 1.0],
            "range_std_m": [0.5, 0.5, 0.5],
        }
    )
    assert math.isclose(metrics.rmse_h(est), math.sqrt((25.0 + 0.0 + 1.0) / 3))
    # over the rows with a bound: sqrt((25 + 1) / 2) / sqrt((4 + 1) / 2)
    assert math.isclose(metrics.rmse_over_crb(bounds), math.sqrt(26 / 5))
    assert math.isclose(metrics.rmse_over_crb(bounds, column="crb_h_declared_m"), math.sqrt(26 / 3))
    # the interval: chi-square with one degree of freedom per node (2 nodes here)
    from scipy import stats

    ratio, low, high = metrics.rmse_over_crb_interval(bounds)
    assert math.isclose(high, ratio * math.sqrt(2 / stats.chi2.ppf(0.025, 2)))
    assert low < ratio < high
    m = metrics.summarize({"estimates": est}, bounds=bounds)
    assert math.isclose(m["localization.rmse_over_crb"], math.sqrt(26 / 5))
    assert math.isclose(m["localization.rmse_over_crb_declared"], math.sqrt(26 / 3))
    assert math.isclose(m["localization.crb_h_m"], math.sqrt(5 / 2))
    assert "localization.rmse_over_crb" not in metrics.summarize(
        {"estimates": est}, bounds=bounds.assign(crb_h_m=np.nan)
    )
    assert "localization.rmse_over_crb" not in metrics.summarize({"estimates": est})


@pytest.mark.parametrize(
    ("file", "variant", "duration"), [("itmtl.toml", "itmtl", 120.0), ("stvf_quick.toml", "stvf", 25.0)]
)
def test_shipped_protocols_declare_their_references(file, variant, duration, tmp_path):
    """Issue 35 acceptance: error_h, error_v, and a finite CRB on every row that declared
    enough references to fix the position, in the estimates.csv the CLI path writes."""
    from pathlib import Path

    import aquasim_py
    from aquasim_py.trace import read_table

    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    res = aquasim_py.run_scenario(
        scenarios / file, variant=variant, overrides={"simulation.duration_s": duration}, out=tmp_path / "out"
    )
    est = read_table(tmp_path / "out" / "estimates.csv")
    bounds = read_table(tmp_path / "out" / "bounds.csv")
    assert {"error_h", "error_v", "refs", "depth_known"} <= set(est.columns)
    assert np.allclose(est["error"] ** 2, est["error_h"] ** 2 + est["error_v"] ** 2)
    n_refs = est["refs"].fillna("").astype(str).str.split().str.len()
    # one bounds row per declaring estimate, pointing at it
    assert bounds["row"].tolist() == np.flatnonzero(n_refs > 0).tolist()
    assert np.allclose(bounds["error_h"], est["error_h"].to_numpy()[bounds["row"]])
    declared = bounds[(n_refs.to_numpy()[bounds["row"]] >= 3)]
    assert len(declared) >= 5
    for c in ("crb_h_m", "crb_h_declared_m", "gdop"):
        assert np.isfinite(declared[c]).all(), c
    assert np.isfinite(res.metrics["localization.rmse_over_crb"])
    assert np.isfinite(res.metrics["localization.rmse_over_crb_declared"])
