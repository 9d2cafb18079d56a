"""STVF (Hu et al., Sensors 2018): spatial-temporal variational filtering localization; and
its two references, the genie multilateration and the CRB of the geometry used (:mod:`.genie`)."""

from .genie import GenieMultilaterationNode
from .node import StvfNode, StvfParams

__all__ = ["GenieMultilaterationNode", "StvfNode", "StvfParams"]
