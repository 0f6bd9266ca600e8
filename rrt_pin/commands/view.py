"""``rrt-pin view``: play a trajectory of the arm in the browser (meshcat), or screenshot it."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from rrt_pin.commands._common import (
    add_scene_arguments,
    float_list,
    nonnegative_float,
    params_from_args,
    positive_float,
)
from rrt_pin.errors import InputError, UrdfError

if TYPE_CHECKING:
    import numpy as np
    import pinocchio as pin

    from rrt_pin.params import Params

__all__ = ["HELP", "add_arguments", "configurations", "read_trajectory_csv", "run", "trajectory"]

HELP = "play a trajectory of the arm in the browser (meshcat), or save a screenshot (SI units)"

_EPILOG = """\
The page (meshcat, served locally, no network needed) plays the motion itself:
open Controls > Animations to play, pause, reset or scrub the time. The target
pose is a translucent ghost arm, the path of C3 (the last link's origin) a
magenta line, the ground grid lies under the arm's lowest point.

--trajectory inverse   eq. (30) from q0 to qf in Tp (rests at qf after Tp)
--trajectory simulate  the seed's feedback law, eq. (31), integrated from q0
--trajectory PATH.csv  columns t [s] and one per joint [rad or m]: q1,q2,q3 for
                       the RRT arm; with --urdf q_<joint> (as `rrt-pin inverse
                       --urdf` writes), the joint names, or q1..qn. Other
                       columns are ignored; resampled to --fps linearly.

The server listens on 127.0.0.1 only, unless --host says otherwise; the page has
no authentication, so listen on another interface only on a trusted network.
Without --port, ports 7000, 7001, ... are tried; an explicit --port that is
taken is an error (--port 0: any free port). Serves until Ctrl-C, or for
--serve-for seconds; with --screenshot and no --serve-for it exits once the PNG
is written."""


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"must be in 0..65535: {text!r}")
    return value


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT, e.g. 1280x800: {text!r}"
        ) from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise argparse.ArgumentTypeError(f"each side must be 16..8192 px: {text!r}")
    return w, h


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin view``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument(
        "--trajectory",
        default="inverse",
        metavar="inverse|simulate|PATH.csv",
        help="what to play (default inverse; see below)",
    )
    parser.add_argument(
        "--fps",
        type=positive_float,
        default=30.0,
        metavar="N",
        help="keyframes per second of the animation [1/s] (default 30: 451 keyframes for 15 s)",
    )
    parser.add_argument(
        "--tf",
        type=positive_float,
        default=None,
        metavar="S",
        help="length of an inverse or simulate run [s] (default Tp, 15 s for the seed)",
    )
    parser.add_argument(
        "--q0",
        type=float_list,
        metavar="A,B,...",
        help="start configuration [rad or m] "
        "(default q10,q20,q30; needed with --urdf and --trajectory inverse)",
    )
    parser.add_argument(
        "--qf",
        type=float_list,
        metavar="A,B,...",
        help="target configuration, the ghost "
        "[rad or m] (default q1f,q2f,q3f; needed with --urdf and --trajectory inverse)",
    )
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default 127.0.0.1: this machine only; the page has no "
        "authentication)",
    )
    parser.add_argument(
        "--port",
        type=_port,
        default=None,
        metavar="N",
        help="TCP port; a taken port is an error (default: 7000 or the next free one; 0: any)",
    )
    parser.add_argument(
        "--serve-for",
        type=nonnegative_float,
        default=None,
        metavar="S",
        help="stop serving S seconds after the server starts [s] (default: until Ctrl-C)",
    )
    parser.add_argument(
        "--screenshot",
        metavar="PATH.png",
        help="render the page in headless Chromium and save a PNG (atomically)",
    )
    parser.add_argument(
        "--screenshot-time",
        type=nonnegative_float,
        default=0.0,
        metavar="S",
        help="animation time shown by --screenshot [s] (default 0: the start, ghost at the target)",
    )
    parser.add_argument(
        "--screenshot-size",
        type=_size,
        default=(1280, 800),
        metavar="WxH",
        help="size of the screenshot [px] (default 1280x800)",
    )
    parser.add_argument(
        "--loop",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="repeat the animation forever (default), or play it once",
    )
    parser.add_argument("--paused", action="store_true", help="load the animation paused at t = 0")
    parser.add_argument("--no-ghost", action="store_true", help="do not draw the target pose")
    parser.add_argument(
        "--urdf",
        metavar="PATH",
        help="show another arm; its visual primitives and .dae/.stl/.obj meshes are drawn "
        "(meshes that cannot be found are skipped with a warning)",
    )
    add_scene_arguments(parser)


# ---------------------------------------------------------------------------
# Building the data
# ---------------------------------------------------------------------------
def _model(args: argparse.Namespace, params: Params) -> Any:
    from rrt_pin.model import load_urdf_model, rrt_model

    return rrt_model(params) if args.urdf is None else load_urdf_model(args.urdf)


def _geometry(args: argparse.Namespace, params: Params, model: pin.Model) -> Any:
    """The visual geometry; for a URDF whose meshes cannot be found, the rest of it."""
    from rrt_pin.model import build_geometry

    if args.urdf is None:
        from rrt_pin.urdf import urdf_xml

        return build_geometry(model, urdf_xml(params))
    from pathlib import Path

    path = Path(args.urdf)
    xml = path.read_text(encoding="utf-8")
    dirs = [str(p) for p in [path.resolve().parent, *path.resolve().parents]]
    try:
        return build_geometry(model, xml, package_dirs=dirs)
    except UrdfError as e:
        problem = str(e).removeprefix("URDF geometry does not load: ").rstrip(".")
        print(f"rrt-pin: warning: {problem}; drawing the URDF without its meshes", file=sys.stderr)
        return build_geometry(model, _without_meshes(xml))


def _without_meshes(xml: str) -> str:
    """The URDF text without its <visual> and <collision> elements that use meshes."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml)
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for el in list(link.findall(tag)):
                if el.find("geometry/mesh") is not None:
                    link.remove(el)
    return ET.tostring(root, encoding="unicode")


def _configuration_columns(model: pin.Model) -> list[tuple[int, int, int, str]]:
    """(joint index, idx_q, nq, label) of each joint; labels as `rrt-pin inverse` writes them."""
    out = []
    for j in range(1, model.njoints):
        joint = model.joints[j]
        name = str(model.names[j])
        if joint.nv != 1 or joint.nq not in (1, 2):
            raise UrdfError(
                f"joint {name!r} ({joint.shortname()}, nq={joint.nq}, nv={joint.nv}) is not "
                "supported by the viewer: one revolute or prismatic coordinate per joint"
            )
        out.append((j, joint.idx_q, joint.nq, name))
    return out


def configurations(model: pin.Model, values: np.ndarray) -> np.ndarray:
    """Pinocchio configurations (N, nq) from one coordinate per joint, (N, n) [rad or m].

    Continuous (unbounded revolute) joints take (cos, sin) of their angle.
    """
    import numpy as np

    cols = _configuration_columns(model)
    values = np.asarray(values, dtype=float)
    if values.ndim != 2 or values.shape[1] != len(cols):
        raise InputError(f"{values.shape=} but the model has {len(cols)} joints")
    q = np.empty((values.shape[0], model.nq))
    for k, (_, idx, nq, _) in enumerate(cols):
        if nq == 1:
            q[:, idx] = values[:, k]
        else:
            q[:, idx] = np.cos(values[:, k])
            q[:, idx + 1] = np.sin(values[:, k])
    return q


def _csv_columns(model: pin.Model, header: list[str], path: str) -> list[str]:
    import re

    names = [c[3] for c in _configuration_columns(model)]
    rrt_style = all(re.fullmatch(r"q\d+", n) for n in names)
    choices = [names if rrt_style else [f"q_{n}" for n in names]]
    if not rrt_style:
        choices += [names]
    choices.append([f"q{k + 1}" for k in range(len(names))])
    for cols in choices:
        if all(c in header for c in cols):
            return cols
    first = choices[0]
    missing = next(c for c in first if c not in header)
    raise InputError(
        f"CSV {path!r} lacks column {missing!r}; it needs t and {','.join(first)}; "
        f"it has {','.join(header)}"
    )


def read_trajectory_csv(path: str, model: pin.Model) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) [s] and joint coordinates (N, n) [rad or m] from a CSV, validated.

    Raises:
        InputError: the file cannot be read, a column is missing, a value is
            not a finite number, or the times do not increase strictly.
    """
    import warnings

    import numpy as np

    from rrt_pin.csvio import read_csv

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # numpy's "input contained no data"
        header, data = read_csv(path, required=("t",))
    cols = _csv_columns(model, header, path)
    t = data[:, header.index("t")]
    values = np.column_stack([data[:, header.index(c)] for c in cols])
    steps = np.diff(t)
    if (steps <= 0.0).any():
        k = int(np.argmax(steps <= 0.0))
        raise InputError(
            f"CSV {path!r}: times must increase strictly, but t={float(t[k + 1])!r} s in row "
            f"{k + 3} follows t={float(t[k])!r} s"
        )
    return t, values


def _params_with_targets(args: argparse.Namespace, params: Params) -> Params:
    from dataclasses import replace

    for flag in ("q0", "qf"):
        value = getattr(args, flag)
        if value is not None and len(value) != 3:
            raise InputError(f"--{flag} has {len(value)} values but the RRT arm has 3 joints")
    changes = {}
    if args.q0 is not None:
        changes.update(q10=args.q0[0], q20=args.q0[1], q30=args.q0[2])
    if args.qf is not None:
        changes.update(q1f=args.qf[0], q2f=args.qf[1], q3f=args.qf[2])
    return replace(params, **changes) if changes else params


def trajectory(
    args: argparse.Namespace, params: Params, model: pin.Model
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Keyframe times (N,) [s], configurations (N, nq) and the ghost's configuration (or None)."""
    import numpy as np

    from rrt_pin.viewer.keyframes import keyframe_times, resample

    source = args.trajectory
    rrt = args.urdf is None
    if source in ("inverse", "simulate"):
        if rrt:
            q0, qf, Tp = params.q0, params.qf, params.Tp
        elif source == "simulate":
            raise InputError(
                "--trajectory simulate plays the seed's control law, which needs the RRT arm; "
                "with --urdf give a CSV (e.g. from `rrt-pin simulate --urdf ... --csv`)"
            )
        else:
            n = len(_configuration_columns(model))
            for flag in ("q0", "qf"):
                value = getattr(args, flag)
                if value is None:
                    raise InputError(f"--trajectory inverse with --urdf needs --{flag}")
                if len(value) != n:
                    raise InputError(
                        f"--{flag} has {len(value)} values but the URDF has {n} joints"
                    )
            q0, qf = args.q0, args.qf
            Tp = args.tf if args.tf is not None else params.Tp
        tf = args.tf if args.tf is not None else Tp
        t = keyframe_times(tf, args.fps)
        if source == "inverse":
            from rrt_pin.trajectory import rest_to_rest

            values = np.asarray(rest_to_rest(q0, qf, Tp, t).q)
        else:
            from rrt_pin.control import seed_controller
            from rrt_pin.simulation import simulate

            result = simulate(model, seed_controller(params), params.q0, params.qd0, t)
            values = np.asarray(result.q)
        return t, configurations(model, values), configurations(model, np.atleast_2d(qf))[0]
    if not os.path.isfile(source):
        raise InputError(
            f"--trajectory {source!r}: expected inverse, simulate or the path of a CSV file"
        )
    t_csv, values = read_trajectory_csv(source, model)
    t, values = resample(t_csv, values, args.fps)
    if rrt:
        ghost = configurations(model, np.atleast_2d(params.qf))[0]
    else:
        ghost = configurations(model, values[-1:])[0]
    return t - t[0], configurations(model, values), ghost


# ---------------------------------------------------------------------------
# Serving
# ---------------------------------------------------------------------------
class _Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, handled like Ctrl-C."""


@contextmanager
def _termination_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM and SIGHUP into KeyboardInterrupt, so that cleanup runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise _Terminated()

    signums = [signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    previous = {s: signal.signal(s, handler) for s in signums}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def _check_output(path: str) -> None:
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise InputError(f"--screenshot {path!r}: folder {directory!r} does not exist")
    if not os.access(directory, os.W_OK):
        raise InputError(f"--screenshot {path!r}: folder {directory!r} is not writable")
    if os.path.isdir(path):
        raise InputError(f"--screenshot {path!r} is a folder")


def run(args: argparse.Namespace) -> int:
    """Build the scene, serve it, screenshot it."""
    if args.screenshot:
        _check_output(args.screenshot)
    if args.screenshot:
        from rrt_pin.viewer.browser import find_chromium

        if find_chromium() is None:
            from rrt_pin.errors import ViewerError

            raise ViewerError(
                "--screenshot needs headless Chromium: install Debian's chromium and "
                "chromium-driver (or set RRT_PIN_CHROMIUM and RRT_PIN_CHROMEDRIVER)"
            )
    params = params_from_args(args)
    if args.urdf is None:
        params = _params_with_targets(args, params)
    model = _model(args, params)
    t, q, ghost = trajectory(args, params, model)
    geometry = _geometry(args, params, model)

    from rrt_pin.viewer.meshcat_scene import scene_commands
    from rrt_pin.viewer.scene import build_scene
    from rrt_pin.viewer.server import DEFAULT_PORT, ViewerServer

    scene = build_scene(model, geometry, t, q, args.fps, ghost_q=ghost)
    commands = scene_commands(scene, play=not args.paused, loop=args.loop, ghost=not args.no_ghost)
    start = time.monotonic()
    with _termination_as_interrupt(), ViewerServer(args.host, args.port) as server:
        for command in commands:
            server.send(command)
        if server.moved:
            print(
                f"rrt-pin: port {DEFAULT_PORT} is in use; serving on port {server.port}",
                file=sys.stderr,
            )
        print(server.url, flush=True)
        if args.host not in ("127.0.0.1", "localhost", "::1"):
            print(
                f"rrt-pin: warning: listening on {args.host}: anyone who can reach it can watch "
                "(no authentication)",
                file=sys.stderr,
            )
        if args.screenshot:
            from rrt_pin.viewer.browser import screenshot

            shown = min(args.screenshot_time, scene.keyframes.duration)
            screenshot(
                server.url,
                args.screenshot,
                clips=len(scene.keyframes.frames),
                t=shown,
                size=args.screenshot_size,
            )
            print(f"rrt-pin: wrote {args.screenshot} (t = {shown:g} s)", file=sys.stderr)
            if args.serve_for is None:
                return 0
        try:
            _serve(args.serve_for, start)
        except KeyboardInterrupt:
            print("rrt-pin: viewer stopped", file=sys.stderr)
    return 0


def _serve(seconds: float | None, start: float) -> None:
    stop = threading.Event()
    if seconds is None:
        while not stop.wait(3600.0):
            pass
        return
    remaining = seconds - (time.monotonic() - start)
    while remaining > 0 and not stop.wait(min(remaining, 3600.0)):
        remaining = seconds - (time.monotonic() - start)
