"""Import meshcat once, quietly, with an install hint when it is missing."""

from __future__ import annotations

import warnings
from typing import Any

from rrt_pin.core.extras import MissingExtra


def import_meshcat() -> Any:
    """The ``meshcat`` package (0.3.2's submodules loaded).

    Raises:
        ImportError: meshcat is not installed (with the pip command that installs it).
    """
    try:
        with warnings.catch_warnings():
            # meshcat 0.3.2 imports pyzmq's deprecated zmq.eventloop.ioloop
            warnings.simplefilter("ignore", DeprecationWarning)
            import meshcat
            import meshcat.animation
            import meshcat.commands
            import meshcat.geometry
            import meshcat.path
            import meshcat.servers.tree
            import meshcat.servers.zmqserver
    except ImportError as e:
        raise MissingExtra("meshcat", "viewer", "the viewer") from e
    return meshcat
