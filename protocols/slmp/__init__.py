"""SLMP (Zhou et al., IEEE TMC 2011): scalable localization with mobility prediction, the
baseline of the STVF paper; and ``multilateration_bound``, every-period multilateration on all
references (an upper bound for multilateration, docs/stvf.md)."""

from .bound import MultilaterationBoundNode, MultilaterationBoundParams
from .node import SlmpNode, SlmpParams

__all__ = ["MultilaterationBoundNode", "MultilaterationBoundParams", "SlmpNode", "SlmpParams"]
