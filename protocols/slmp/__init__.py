"""SLMP (Zhou et al., IEEE TMC 2011): scalable localization with mobility prediction, the
baseline of the STVF paper."""

from .node import SlmpNode, SlmpParams

__all__ = ["SlmpNode", "SlmpParams"]
