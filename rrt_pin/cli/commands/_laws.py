"""The law of ``rrt-pin simulate`` when it is not the robot's regulator.

``--passive`` (no controller), ``--track FILE`` (computed torque along a file's motion),
``--efforts FILE`` (open loop), ``--controller MODULE:FUNCTION`` (a user's law): at most
one, each refusing the flags it does not use.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from rrt_pin.core.errors import InputError

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = ["LAW_FLAGS", "PASSIVE", "law_from_args", "law_source"]

#: The law's name in summaries and metadata of a ``--passive`` run.
PASSIVE = "no controller (passive: zero efforts, no gravity compensation)"

#: The flags that choose the law instead of the robot's regulator (at most one).
LAW_FLAGS = ("passive", "track", "efforts", "controller")


def law_source(args: argparse.Namespace) -> str | None:
    """Which of :data:`LAW_FLAGS` was given (None: the regulator); gains only where they apply."""
    given = [f for f in LAW_FLAGS if getattr(args, f, None) not in (None, False)]
    if len(given) > 1:
        raise InputError(f"--{given[0]} and --{given[1]} both choose the law: give one")
    source = given[0] if given else None
    unused = {"passive": ("kp", "kd", "qf"), "efforts": ("kp", "kd", "qf"),
              "controller": ("kp", "kd"), "track": ("qf",)}.get(source or "", ())  # fmt: skip
    for flag in unused:
        if getattr(args, flag, None) is not None:
            why = "no controller acts" if source == "passive" else f"--{source} sets the law"
            raise InputError(f"--{flag} does not apply with --{source}: {why}")
    return source


def law_from_args(args: argparse.Namespace, robot: Robot, source: str) -> tuple[Any, str, Any]:
    """The law of ``source``, its name for summaries, and the tracked motion's start."""
    import os

    if source == "passive":
        return None, PASSIVE, None
    if source == "track":
        from rrt_pin.dynamics.sampled import read_motion
        from rrt_pin.dynamics.trajectory import Trajectory
        from rrt_pin.simulate.control import tracking_controller

        m = read_motion(args.track, robot)
        kp = args.kp if args.kp is not None else 100.0
        kd = args.kd if args.kd is not None else 20.0
        law = tracking_controller(robot, Trajectory(m.t, m.q, m.qd, m.qdd), kp=kp, kd=kd)
        name = f"computed-torque tracking of {os.path.basename(args.track)}"
        return law, name, (m.q[0], m.qd[0])
    if source == "efforts":
        from rrt_pin.dynamics.sampled import read_playback
        from rrt_pin.simulate.control import OpenLoop

        t, tau, motion = read_playback(args.efforts, robot)
        name = f"the efforts in {os.path.basename(args.efforts)} (open loop)"
        start = None if motion is None else (motion.q[0], motion.qd[0])
        return OpenLoop(t, tau), name, start
    return _user_law(args.controller), f"{args.controller} (your law)", None


def _user_law(spec: str) -> Any:
    """The function ``MODULE:FUNCTION`` names: a module or a ``.py`` file.

    A module is looked for in the current directory first; no ``__pycache__`` is
    written next to the user's code.
    """
    import importlib
    import importlib.util
    import os

    module_name, sep, name = spec.rpartition(":")
    if not sep or not module_name or not name:
        raise InputError(f"--controller {spec!r} must be MODULE:FUNCTION (e.g. mylaw:law)")
    here, writes = os.getcwd(), sys.dont_write_bytecode
    added = here not in sys.path
    if added:
        sys.path.insert(0, here)
    sys.dont_write_bytecode = True
    try:
        if module_name.endswith(".py"):
            if not os.path.isfile(module_name):
                raise InputError(f"--controller {spec!r}: no file {module_name!r}")
            found = importlib.util.spec_from_file_location("rrt_pin_user_law", module_name)
            module = importlib.util.module_from_spec(found)
            found.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except ImportError as e:
        raise InputError(f"--controller {spec!r}: module {module_name!r} not found ({e})") from e
    except InputError:
        raise
    except Exception as e:  # the user's module failed while importing: say how, in one line
        first = str(e).splitlines()[0] if str(e) else ""
        raise InputError(
            f"--controller {spec!r}: importing {module_name!r} raised {type(e).__name__}: {first}"
        ) from e
    finally:
        sys.dont_write_bytecode = writes
        if added:
            sys.path.remove(here)
    law = getattr(module, name, None)
    if not callable(law):
        raise InputError(f"--controller {spec!r}: {module_name} has no function {name!r}")
    return law
