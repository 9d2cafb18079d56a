"""The one promotion rule shared by STVF (one confident localization) and ITMTL (several)."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.estimation.promotion import promote


@pytest.mark.parametrize("eta,expected", [(0.8999, False), (0.9, True), (0.9001, True), (0.2, False)])
def test_single_confidence_promotes_at_or_above_threshold(eta, expected):
    assert promote(eta, 0.9) is expected


def test_history_needs_the_last_rounds_all_confident():
    assert not promote([0.9], 0.8, 2)  # too short a history
    assert promote([0.1, 0.85, 0.9], 0.8, 2)  # an old low value does not matter
    assert not promote([0.9, 0.7], 0.8, 2)  # the latest round fell below


def test_a_float_gives_what_a_history_of_one_gives():
    for eta in (0.0, 0.5, 0.8999999999999999, 0.9, 0.9000000000000001, 1.0, float("nan"), float("inf")):
        assert promote(eta, 0.9) is promote([eta], 0.9) is promote(np.float64(eta), 0.9)
