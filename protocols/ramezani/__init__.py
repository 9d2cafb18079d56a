"""Ramezani, Jamali-Rad and Leus (IEEE TSP 2013): ToF localization (GNA) and tracking (EKF)
in an isogradient ocean, with the CRB / PCRB."""

from .node import RamezaniNode

__all__ = ["RamezaniNode"]
