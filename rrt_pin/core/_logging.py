"""The package logger; the library installs only a NullHandler.

Besides the standard levels, NOTICE (25) carries what a command tells its user by
default ("wrote out.csv"): shown unless ``-q``; ``-v`` adds INFO (what was chosen
and why, timings).
"""

import logging

NOTICE = 25
logging.addLevelName(NOTICE, "NOTICE")

logger = logging.getLogger("rrt_pin")
logger.addHandler(logging.NullHandler())


def note(message: str) -> None:
    """Tell the CLI's user ``message`` on stderr (hidden by ``-q``)."""
    logger.log(NOTICE, message)
