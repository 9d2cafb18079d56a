"""The network stack above the channel: MACs (:mod:`.mac`) and the network metrics computed
from the traces (:mod:`.metrics`)."""
