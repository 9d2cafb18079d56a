"""Zhang et al.: multi-sensor weighted particle filter with mutual-information fusion weights
and PCRLB node selection (MSWPF), target tracking from quantized acoustic-pressure reports."""

from .node import MswpfNode

__all__ = ["MswpfNode"]
