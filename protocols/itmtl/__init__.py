"""ITMTL: joint time synchronization and localization by iterative tracing, with
its baselines TSHL, MU-Sync and Mobi-Sync on the same Req/Res exchange (:mod:`.reqres`)."""

from .mobi_sync import MobiSyncNode
from .mu_sync import MuSyncNode
from .node import ItmtlNode, ItmtlParams
from .reqres import ReqResNode, ReqResParams
from .tshl import TshlNode

__all__ = ["ItmtlNode", "ItmtlParams", "MobiSyncNode", "MuSyncNode", "ReqResNode", "ReqResParams", "TshlNode"]
