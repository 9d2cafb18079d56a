"""Traffic sources and sinks over any MAC: the workload of MAC studies and of ``net.*`` metrics."""

from .node import TrafficNode, TrafficParams

__all__ = ["TrafficNode", "TrafficParams"]
