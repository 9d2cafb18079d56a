"""SLMP (Zhou et al., IEEE TMC 2011): scalable localization with mobility prediction, the
baseline of the STVF paper; and ``multilateration_all_refs``, every-period multilateration on
all references in range (a baseline, not a bound: docs/stvf.md)."""

from .all_refs import MultilaterationAllRefsNode, MultilaterationAllRefsParams
from .node import SlmpNode, SlmpParams

__all__ = ["MultilaterationAllRefsNode", "MultilaterationAllRefsParams", "SlmpNode", "SlmpParams"]
