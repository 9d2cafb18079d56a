"""Behaviour shared by several protocol families (registers no protocol)."""

from .periodic import PeriodicBeaconNode

__all__ = ["PeriodicBeaconNode"]
