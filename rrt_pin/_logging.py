"""The package logger; the library installs only a NullHandler."""

import logging

logger = logging.getLogger("rrt_pin")
logger.addHandler(logging.NullHandler())
