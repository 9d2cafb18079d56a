"""One-way ToA ranging to anchors: the smallest useful protocol, and the template for new ones."""

from .node import BeaconNode, range_errors, true_ranges

__all__ = ["BeaconNode", "range_errors", "true_ranges"]
