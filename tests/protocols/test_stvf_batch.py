"""STVF's updates of one instant run as one batch: the traces are those of one update per node."""

import tomllib
from pathlib import Path

import pandas as pd

from aquasim_py import scenario
from aquasim_py.estimation import variational as vf
from aquasim_py.protocols.stvf import node as stvf_node

BATCH_UPDATE = vf.variational_update_batch
QUICK = Path(__file__).resolve().parents[2] / "scenarios" / "stvf_quick.toml"


def _estimates(monkeypatch, batch: bool, listen_s: float) -> tuple[pd.DataFrame, list[int]]:
    sizes: list[int] = []

    def counted(z, *args):
        sizes.append(len(z))
        return BATCH_UPDATE(z, *args)

    monkeypatch.setattr(stvf_node.StvfNode, "batch_updates", batch)
    monkeypatch.setattr(vf, "variational_update_batch", counted)
    raw = tomllib.loads(QUICK.read_text())
    raw.pop("variants", None)
    sets = ["simulation.duration_s=8.0"] + [f"nodes.{g}.params.listen_s={listen_s}" for g in (0, 1)]
    sc = scenario.load_dict(raw, QUICK, overrides=sets)
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    return sim.trace.frames()["estimates"], sizes


def test_batched_updates_give_the_inline_trace(monkeypatch):
    inline, inline_sizes = _estimates(monkeypatch, batch=False, listen_s=0.9)
    batched, sizes = _estimates(monkeypatch, batch=True, listen_s=0.9)
    assert len(inline) > 100
    pd.testing.assert_frame_equal(batched, inline, check_exact=True)
    # the inline run updates node by node (batches of one); the batched run had every
    # localizing node of an instant in one batch
    assert set(inline_sizes) == {1}
    assert sum(sizes) == len(inline) and max(sizes) > 30


def test_no_batch_when_the_next_period_starts_at_the_localization_instant(monkeypatch):
    """listen_s = period_s: a node localizes at the instant its next period starts, when it
    reads its own confidence for its beacon; deferring the update to the end of the instant
    would change what it sends, so such nodes update inline."""
    inline, _ = _estimates(monkeypatch, batch=False, listen_s=1.0)
    batched, sizes = _estimates(monkeypatch, batch=True, listen_s=1.0)
    assert inline["is_reference"].any()  # promoted nodes beacon: the case that would differ
    pd.testing.assert_frame_equal(batched, inline, check_exact=True)
    assert set(sizes) == {1}
