"""Beacon timing of the period cycle (STVF, SLMP, multilateration_all_refs; issue 33 item 1).

A beacon carries its sender's position *at the send instant* (the MAC transmit stamp the
receivers measure their delays from), not at the period start up to ``send_window_s``
earlier; an estimate is the position at its measurement epoch (the mean receive stamp of its
ranges) and is carried from there to the instants it is logged and advertised at. These
tests failed on the code before the fix (a beacon anchor's payload off by up to 0.67 m; a
noise-free multilateration stamped at the end of the listening window, 0.7 m behind its node;
with promotion 6.1 m; SLMP's ``beacon_payload`` added a fix to the anchor's predictor on every
call)."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from aquasim_protocols.common.track import EpochTrack
from aquasim_py import scenario
from aquasim_py.node import Node

QUICK = Path(__file__).resolve().parents[2] / "scenarios" / "stvf_quick.toml"


def _sim(sets: list[str], seed: int = 1):
    raw = tomllib.loads(QUICK.read_text())
    raw.pop("variants", None)
    sc = scenario.load_dict(raw, QUICK, overrides=sets, seed=seed)
    sim = scenario.build(sc)
    return sim, sc.simulation.duration_s


def _spy_broadcasts(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, float, object]]:
    """(node, local time, payload) of every broadcast, recorded when the node calls it."""
    sent: list[tuple[int, float, object]] = []
    orig = Node.broadcast

    def spy(self, kind, payload=None, bits=256):
        sent.append((self.id, self.local_time(), payload))
        return orig(self, kind, payload, bits)

    monkeypatch.setattr(Node, "broadcast", spy)
    return sent


def test_beacon_nodes_advertise_their_position_at_the_send_instant(monkeypatch):
    """stvf_quick's beacon nodes have exact position fixes and perfect clocks: the (x, y)
    a beacon carries is the sender's true position when it goes out."""
    sent = _spy_broadcasts(monkeypatch)
    sim, until = _sim(["simulation.duration_s=6.0"])
    sim.run(until)
    anchors = [(i, t, p) for i, t, p in sent if i < 10]
    assert len(anchors) >= 50
    ids = np.array([a[0] for a in anchors])
    t = np.array([a[1] for a in anchors])  # perfect clocks: local = true time
    truth = np.array([sim.positions_at(ids[k : k + 1], t[k : k + 1])[0] for k in range(len(ids))])
    payload = np.array([a[2][:2] for a in anchors], float)
    np.testing.assert_allclose(payload, truth[:, :2], rtol=0, atol=1e-9)


_NOISE_FREE = [
    f"nodes.{g}.{k}"
    for g in (0, 1)
    for k in ("protocol=multilateration_all_refs", "params.training_s=10.0", "params.noise_ratio=0.0")
] + ["channel.sound_speed_std_mps=0.0", "simulation.duration_s=40.0"]


def test_a_fix_is_the_position_at_its_measurement_epoch(monkeypatch):
    """Noise-free ranges to beacon nodes only (no promotion): multilateration fixes the node
    where it was while its ranges came in (the mean receive stamp), to centimetres; at the end
    of the listening window, 0.35-0.85 s later, the node has drifted ~0.7 m from there."""
    from aquasim_protocols.slmp import all_refs

    seen = []
    orig = all_refs.MultilaterationAllRefsNode.log_estimate

    def spy(self, x, y, z, **kw):
        seen.append((self.id, self.local_time(), *self.last))
        return orig(self, x, y, z, **kw)

    monkeypatch.setattr(all_refs.MultilaterationAllRefsNode, "log_estimate", spy)
    sim, until = _sim([*_NOISE_FREE, "nodes.0.params.delta=1.0", "nodes.1.params.delta=1.0"])
    sim.run(until)
    rows = [r for r in seen if r[1] >= 15.0]
    assert len(rows) > 100
    ids = np.array([r[0] for r in rows])
    fix = np.array([r[3] for r in rows])

    def truth(times):  # perfect clocks: local = true time
        return np.array([sim.positions_at(ids[k : k + 1], times[k : k + 1])[0, :2] for k in range(len(ids))])

    at_epoch = np.linalg.norm(fix - truth(np.array([r[2] for r in rows])), axis=1)
    at_listen_end = np.linalg.norm(fix - truth(np.array([r[1] for r in rows])), axis=1)
    assert np.median(at_epoch) < 0.15
    assert np.median(at_listen_end) > 0.4


def test_promoted_references_carry_their_fixes_to_the_send_instant():
    """Noise-free ranges with promotion: a promoted node's beacon is its fix carried to the
    send instant, so the references' errors do not compound into a common lag (the former
    stamps: median error 6.1 m, 5.3 m of it along-track behind the node; now 1.5 m)."""
    sim, until = _sim(_NOISE_FREE)
    sim.run(until)
    est = sim.trace.frames()["estimates"]
    est = est[(est["time"] >= 25.0) & (est["method"] == "multilateration")]
    assert len(est) > 200
    ids, t = est["node"].to_numpy(), est["time"].to_numpy()
    v = np.array([sim.velocities_at(ids[k : k + 1], t[k])[0, :2] for k in range(len(ids))])
    u = v / np.linalg.norm(v, axis=1, keepdims=True)
    d = est[["x", "y"]].to_numpy() - est[["true_x", "true_y"]].to_numpy()
    assert np.median(np.linalg.norm(d, axis=1)) < 3.0
    assert np.median((d * u).sum(axis=1)) > -2.5


def test_slmp_beacon_payload_has_no_side_effects():
    """Composing an SLMP anchor's beacon twice gives the same beacon and teaches its mobility
    predictor nothing: the anchor's own localization is :meth:`localize_reference`."""
    sets = [f"nodes.{g}.{k}" for g in (0, 1) for k in ("protocol=slmp", "params.training_s=3.0")]
    sim, _ = _sim([*sets, "simulation.duration_s=5.0"])
    sim.run(5.0)
    anchor = sim.nodes[0]
    before = list(anchor.predictor.times)
    assert before  # it localized against the buoys every period
    first, second = anchor.beacon_payload(), anchor.beacon_payload()
    assert first == second
    assert anchor.predictor.times == before


def test_track_velocity_is_the_least_squares_slope_over_the_window():
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 40.0) + rng.uniform(-0.2, 0.2, 40)
    v = np.array([0.8, -0.3])
    xy = v * t[:, None] + rng.normal(0.0, 2.0, (40, 2))
    tr = EpochTrack(20.0)
    for k in range(40):
        tr.add(t[k], xy[k])
    keep = t >= t[-1] - 20.0
    keep[np.flatnonzero(keep)[0] - 1] = True  # and the one before the window
    ref = np.polyfit(t[keep], xy[keep], 1)[0]
    np.testing.assert_allclose(tr.velocity(), ref, rtol=1e-10)
    np.testing.assert_allclose(tr.at(t[-1] + 0.5), xy[-1] + 0.5 * ref, rtol=1e-12)
    two = EpochTrack(0.0)  # the former one-period difference
    for k in range(3):
        two.add(t[k], xy[k])
    np.testing.assert_allclose(two.velocity(), (xy[2] - xy[1]) / (t[2] - t[1]), rtol=1e-12)
    with pytest.raises(ValueError):
        two.add(t[1], xy[1])
