"""Import meshcat once, quietly: its server module imports pyzmq's deprecated ``zmq.eventloop.ioloop`` shim, whose
DeprecationWarning says nothing actionable to mjnav users. ``mjnav.viz`` imports this before anything else."""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message=r"zmq\.eventloop\.ioloop is deprecated", category=DeprecationWarning)
    import meshcat
    import meshcat.servers.zmqserver

__all__ = ["meshcat"]
