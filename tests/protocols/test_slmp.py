"""SLMP baseline: the pure maths against closed forms / scipy, and the protocol on the quick
scenario."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from aquasim_protocols.slmp import math as sm
from aquasim_py import scenario
from aquasim_py.registry import get

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "scenarios" / "stvf_quick.toml"


def test_linear_predictor_recovers_ar_coefficients():
    """A noise-free AR(2) series per axis: least squares returns its generating coefficients."""
    a = np.array([[1.5, 0.9], [-0.7, -0.2]])  # a[0] multiplies the latest sample
    v = np.zeros((80, 2))
    v[0], v[1] = [1.0, 0.5], [0.8, -0.3]
    for k in range(2, 80):
        v[k] = a[0] * v[k - 1] + a[1] * v[k - 2]
    assert np.allclose(sm.fit_linear_predictor(v, 2), a, atol=1e-8)


def test_predictor_continues_a_sinusoid_exactly():
    """sin(w k) obeys v_k = 2 cos(w) v_{k-1} - v_{k-2}: the fitted order-2 predictor continues it."""
    w = 2 * np.pi / 37
    k = np.arange(100)
    v = np.c_[np.sin(w * k), np.cos(w * k)]
    coef = sm.fit_linear_predictor(v[:60], 2)
    pred = sm.predict_velocities(v[:60], coef, 40)
    assert np.allclose(pred, v[60:], atol=1e-8)


def test_unstable_fit_detected():
    assert sm.is_stable(np.array([[0.5], [0.2]]))
    assert not sm.is_stable(np.array([[2.0], [0.0]]))


def test_mobility_predictor_constant_velocity_and_refit_on_error():
    mp = sm.MobilityPredictor(1.0, window=60, overlap=0.2, order=15, threshold=4.0)
    vel = np.array([0.7, -0.4])
    for t in range(40):
        mp.add(float(t), vel * t)
    assert np.allclose(mp.velocity(), vel)
    assert np.allclose(mp.predict(45.0), vel * 45)
    refits = mp.refits
    mp.add(40.0, vel * 40 + np.array([10.0, 0.0]))  # a 10 m miss > 4 m threshold: refit now
    assert mp.refits == refits + 1 or mp.coef is None


def test_refit_schedule_is_window_times_one_minus_overlap():
    mp = sm.MobilityPredictor(1.0, window=60, overlap=0.2, order=15, threshold=1e9)
    assert mp.refit_every == 48


def test_slmp_confidence_hand_computed():
    refs = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    pos = np.array([3.0, 4.0])  # distances 5, sqrt(65), sqrt(45)
    ranges = np.array([6.0, np.sqrt(65), np.sqrt(45) - 1.0])  # |errors| 1, 0, 1
    want = np.mean([1.0, 0.9, 0.95]) * (1 - 2.0 / ranges.sum())
    assert sm.slmp_confidence([1.0, 0.9, 0.95], pos, refs, ranges) == pytest.approx(want)


def _load(overrides):
    """The quick scenario without its [variants] tables (read before and after the variants loader)."""
    raw = tomllib.loads(QUICK.read_text())
    raw.pop("variants", None)
    return scenario.load_dict(raw, QUICK, overrides=list(overrides))


def _run(overrides):
    sc = _load(overrides)
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    return sim.trace.frames()


# a 20-node network at density ~18 (range 80 m on 150 m x 150 m), SLMP training 5 s
_SMALL = [
    "nodes[0].protocol=slmp",
    "nodes[1].protocol=slmp",
    "nodes[0].count=4",
    "nodes[1].count=16",
    "environment.volume.hi=[150.0, 150.0, 30.0]",
    "nodes[0].params={training_s=3.0}",
    "nodes[1].params={training_s=3.0}",
    "simulation.duration_s=18.0",
    "metrics.warmup_s=0.0",
]


def test_all_refs_quick_run():
    """multilateration_all_refs (the former ``slmp``): every period, all references."""
    frames = _run([s.replace("=slmp", "=multilateration_all_refs") for s in _SMALL] + ["simulation.duration_s=10.0"])
    e = frames["estimates"]
    assert len(e) and (e["time"] >= 3.0).all()  # nothing during the training
    assert set(e["method"]) <= {"multilateration", "self"}
    m = get("multilateration_all_refs").metrics(frames)
    assert m["coverage_ever"] > 0.9
    err = np.hypot(e.x - e.true_x, e.y - e.true_y)
    assert np.median(err) < 10.0
    # references only from trusted multilateration fixes
    refs = e[e["is_reference"]]
    assert (refs["confidence"] >= 0.9).all() and (refs["method"] == "multilateration").all()


def _slmp(error_ratio):
    return _run([*_SMALL, f"nodes[1].params.error_ratio={error_ratio}", f"nodes[0].params.error_ratio={error_ratio}"])


@pytest.fixture(scope="module")
def slmp_runs():
    return {k: _slmp(k) for k in (0.02, 0.05, 0.25)}


def test_slmp_relocalizes_only_on_a_miss(slmp_runs):
    """A least-squares fix happens only without a prediction or when the prediction's RMS range
    residual exceeds error_ratio x range; otherwise the node reports its prediction."""
    for ratio, frames in slmp_runs.items():
        e = frames["estimates"]
        thr = ratio * 80.0
        ls = e[e["method"] == "least_squares"]
        assert len(ls)
        assert (ls["miss_m"].isna() | (ls["miss_m"] > thr)).all()
        # a re-localization is attempted exactly on a miss (it may fail: fewer than 3
        # references, or a fix out of range of one of them; the prediction then stands)
        att = e["attempted"].astype(bool)
        checked = e["miss_m"].notna()
        assert (att[checked] == (e["miss_m"][checked] > thr)).all()
        # unchecked (no prediction yet, or no reference heard): only a node's first fix
        first = ~e["node"].duplicated()
        assert (att[~checked] == first[~checked]).all()
        assert ls["attempted"].astype(bool).all()
        assert set(e["method"]) <= {"least_squares", "predicted"}


def test_slmp_localizations_fall_as_threshold_rises(slmp_runs):
    counts = [int((f["estimates"]["method"] == "least_squares").sum()) for _, f in sorted(slmp_runs.items())]
    assert counts[0] > counts[1] > counts[2], counts
    # every node keeps reporting (its prediction) between localizations
    e = slmp_runs[0.25]["estimates"]
    assert (e["method"] == "predicted").mean() > 0.5


def test_slmp_references_only_above_delta(slmp_runs):
    e = slmp_runs[0.05]["estimates"]
    assert (e["is_reference"] == (e["confidence"] >= 0.9)).all()
    err = np.hypot(e.x - e.true_x, e.y - e.true_y)
    assert np.median(err) < 10.0  # well inside the 80 m range


def test_prediction_residual_hand_computed():
    refs = np.array([[0.0, 0.0], [10.0, 0.0]])
    # at (3, 4): distances 5 and sqrt(65); ranges 6 and sqrt(65) + 2 -> residuals -1, -2
    got = sm.prediction_residual([3.0, 4.0], refs, [6.0, np.sqrt(65) + 2.0])
    assert got == pytest.approx(np.sqrt((1 + 4) / 2))


def test_all_refs_keeps_a_fix_at_the_edge_of_range():
    """A static node 79.9 m from one of four beacons (range 80 m, ranging error 2 % of the
    delay, about 1.6 m there): about half its fixes land beyond 80 m from that beacon by noise
    alone. They are good fixes and must be kept (the former gate, 80 m flat, refused them and
    the node self-estimated instead); the gate allows 3 std of that error."""
    beacons = "[[10.0, 100.0, 25.0], [89.9, 50.0, 25.0], [89.9, 150.0, 25.0], [130.0, 100.0, 25.0]]"
    frames = _run(
        [
            "nodes[0].protocol=multilateration_all_refs",
            "nodes[1].protocol=multilateration_all_refs",
            "nodes[0].count=4",
            "nodes[1].count=1",
            f'nodes[0].placement={{kind="explicit", positions={beacons}}}',
            'nodes[1].placement={kind="explicit", positions=[[89.9, 100.0, 25.0]]}',
            "nodes[0].mobility.model=static",
            "nodes[1].mobility.model=static",
            "channel.sound_speed_std_mps=0.0",
            "nodes[0].params={training_s=0.0}",
            "nodes[1].params={training_s=0.0}",
            "simulation.duration_s=40.0",
        ]
    )
    e = frames["estimates"]
    assert (e["n_refs"] >= 3).all()  # (a beacon arriving while the node itself sends is lost)
    fixes = e["method"] == "multilateration"
    assert fixes.sum() >= 36  # of 40 periods (here 40); the former gate kept 19
    err = np.hypot(e.x - e.true_x, e.y - e.true_y)
    assert err[fixes].max() < 5.0  # what is kept is a good fix


def test_in_range_gate_allows_ranging_noise_only():
    refs = np.array([[0.0, 0.0], [50.0, 0.0]])
    assert sm.in_range([81.0, 0.0], refs, 80.0, 1.6)  # 1 m beyond: noise
    assert sm.in_range([84.7, 0.0], refs, 80.0, 1.6)  # 3 std: 4.8 m
    assert not sm.in_range([85.0, 0.0], refs, 80.0, 1.6)
    assert not sm.in_range([0.0, 95.0], refs, 80.0, 1.6)  # far from both: a failed fix


def test_slmp_least_squares_keeps_fixes_at_the_edge_of_range():
    """SLMP's plain least squares with the same gate as multilateration_all_refs: a node 79.9 m from one of
    four references (range 80 m, ranging error 2 % of the range, 1.6 m there) gets a fix beyond
    80 m from it in about half of the noise draws. Those are good fixes and must be kept (the
    former flat 80-m gate refused about half of them); a fix no node in range could have is
    still refused."""
    from types import SimpleNamespace

    from aquasim_protocols.slmp.node import SlmpNode, SlmpParams

    me = SimpleNamespace(params=SlmpParams())
    refs = np.array([[10.0, 100.0], [89.9, 50.0], [89.9, 150.0], [130.0, 100.0]])
    truth = np.array([89.9, 100.0])
    rho = np.linalg.norm(refs - truth, axis=1)
    rng = np.random.default_rng(7)
    fixes = [
        SlmpNode.least_squares(me, refs, rho * (1.0 + 0.02 * rng.standard_normal(4)))  # type: ignore[arg-type]
        for _ in range(400)
    ]
    kept = [f for f in fixes if f is not None]
    beyond = sum(np.linalg.norm(f - refs[0]) > 80.0 for f in kept)
    assert len(kept) >= 396  # 3 std of the range error: a refusal is a < 1 % event per draw
    assert beyond >= 100  # the case the former gate refused does occur in these draws
    assert max(np.linalg.norm(f - truth) for f in kept) < 6.0  # what is kept is a good fix
    far = np.array([105.0, 100.0])  # 95 m from the first reference: out of its range
    assert SlmpNode.least_squares(me, refs, np.linalg.norm(refs - far, axis=1)) is None  # type: ignore[arg-type]
