"""Reference promotion: when a localized node's own estimate is trusted enough to serve others.

One rule for every protocol family: STVF's Algorithm 1 promotes a node whose confidence eta
reaches delta once (``min_rounds = 1``); ITMTL's network-wide construction asks the same of the
last ``min_rounds`` rounds (its own formula was lost in extraction; see the ITMTL package).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["promote"]


def promote(confidences: ArrayLike, threshold: float, min_rounds: int = 1) -> bool:
    """True when the last ``min_rounds`` confidences (a scalar is a history of one) all reach
    ``threshold``; False while the history is shorter than ``min_rounds``."""
    if min_rounds == 1 and type(confidences) is float:  # one value (STVF, per localization)
        return bool(confidences >= threshold)
    c = np.atleast_1d(np.asarray(confidences, dtype=float))
    return c.size >= min_rounds and bool(np.all(c[-min_rounds:] >= threshold))
