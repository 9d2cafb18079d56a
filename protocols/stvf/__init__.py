"""STVF (Hu et al., Sensors 2018): spatial-temporal variational filtering localization."""

from .node import StvfNode, StvfParams

__all__ = ["StvfNode", "StvfParams"]
