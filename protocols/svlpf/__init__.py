"""SVL-PF: support-vector-learning particle filter for target localization (Li et al., Sensors
18:8, 2018), with its baselines ToA-PF, LSSVR-PF and Consensus Estimation (``algorithm``)."""

from .node import SvlpfNode, SvlpfParams

__all__ = ["SvlpfNode", "SvlpfParams"]
