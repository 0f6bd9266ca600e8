"""``rrt-pin view``: play a trajectory of the arm in the browser (meshcat), or screenshot it."""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

from rrt_pin.cli.commands._common import (
    add_param_arguments,
    add_robot_arguments,
    nonempty,
    nonnegative_float,
    params_from_args,
    positive_float,
    robot_from_args,
    termination_as_interrupt,
)
from rrt_pin.core._logging import note

if TYPE_CHECKING:
    pass

__all__ = ["HELP", "add_arguments", "run"]

HELP = "play a trajectory of the arm in the browser (meshcat), or save a screenshot (SI units)"

_EPILOG = """\
The page (meshcat, served locally, no network needed) plays the motion itself:
open Controls > Animations to play, pause, reset or scrub the time. The target
pose is a translucent ghost arm, the path of C3 (the last link's origin) a
magenta line, the ground grid lies under the arm's lowest point.

--trajectory inverse   eq. (30) from q0 to qf in Tp (rests at qf after Tp)
--trajectory simulate  the chapter's feedback law, eq. (31), integrated from q0
                       (with --urdf: PD plus gravity compensation; needs --kp, --kd)
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
        "--path-frame",
        default=None,
        metavar="NAME",
        help="draw the path of this frame of the robot (default: the tool flange — the "
        "chain's last link before any gripper, e.g. UR5's tool0, Panda's panda_hand_tcp)",
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
        help="length of an inverse or simulate run [s] (default Tp, 15 s for the chapter's arm)",
    )
    parser.add_argument(
        "--host",
        type=nonempty,
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
        type=nonempty,
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
        "--zmq-url",
        type=nonempty,
        metavar="URL",
        help="send the animation to a meshcat server you already run (meshcat-server, "
        "Pinocchio's MeshcatVisualizer), e.g. tcp://127.0.0.1:6000, instead of serving it; "
        "prints that server's page URL",
    )
    add_robot_arguments(parser, "view")
    add_param_arguments(parser)


# ---------------------------------------------------------------------------
# Building the data
# ---------------------------------------------------------------------------
# ---------------------------------------------------------------------------
# Serving
# ---------------------------------------------------------------------------
def run(args: argparse.Namespace) -> int:
    """Build the drawing, serve it, screenshot it."""
    if args.screenshot:
        from rrt_pin.io.files import check_outputs

        check_outputs([(args.screenshot, "--screenshot")])  # the one rule for output paths
        from rrt_pin.viewer.browser import find_chromium

        if find_chromium() is None:
            from rrt_pin.core.errors import ViewerError

            raise ViewerError(
                "--screenshot needs headless Chromium: install Debian's chromium and "
                "chromium-driver (or set RRT_PIN_CHROMIUM and RRT_PIN_CHROMEDRIVER)"
            )
    from rrt_pin.viewer.playback import motion_keyframes

    robot = robot_from_args(args, params_from_args(args), "view")
    frames = motion_keyframes(robot, args.trajectory, args.fps, args.tf)

    from rrt_pin.viewer.server import DEFAULT_PORT, ViewerServer
    from rrt_pin.viewer.show import prepare, send_to_meshcat_server

    what = {"inverse": robot.motion, "simulate": f"under {robot.regulator}"}.get(
        args.trajectory, f"playing {os.path.basename(args.trajectory)}"
    )
    prepared = prepare(
        robot, frames.t, frames.q, args.fps, ghost_q=frames.ghost,
        play=not args.paused, loop=args.loop, ghost=not args.no_ghost, what=what,
        path_frame=args.path_frame,
    )  # fmt: skip
    drawing = prepared.drawing
    if args.zmq_url:
        url = send_to_meshcat_server(args.zmq_url, prepared.commands)
        print(url, flush=True)
        note(f"sent to the meshcat server at {args.zmq_url}; Controls → Animations plays it")
        return 0
    start = time.monotonic()
    with (
        termination_as_interrupt(),
        ViewerServer(args.host, args.port, page=prepared.page) as server,
    ):
        for command in prepared.commands:
            server.send(command)
        if server.moved:
            print(
                f"rrt-pin: port {DEFAULT_PORT} is in use; serving on port {server.port}",
                file=sys.stderr,
            )
        serving = not (args.screenshot and args.serve_for is None)
        if serving:
            # Before the URL: a caller that waits for the URL and then stops the server
            # (a signal) must not stop it before the hints are out.
            _hints(server)
        shot = False
        try:  # from the URL on, a caller may stop the server (Ctrl-C, a signal)
            print(server.url, flush=True)
            if args.host not in ("127.0.0.1", "localhost", "::1"):
                print(
                    f"rrt-pin: warning: listening on {args.host}: anyone who can reach it can "
                    "watch (no authentication)",
                    file=sys.stderr,
                )
            if args.screenshot:
                from rrt_pin.viewer.browser import screenshot

                shown = min(args.screenshot_time, drawing.keyframes.duration)
                screenshot(
                    server.url,
                    args.screenshot,
                    clips=len(drawing.keyframes.frames),
                    t=shown,
                    size=args.screenshot_size,
                )
                shot = True
                print(f"rrt-pin: wrote {args.screenshot} (t = {shown:g} s)", file=sys.stderr)
                if args.serve_for is None:
                    return 0
            _serve(args.serve_for, start)
        except KeyboardInterrupt:
            if args.screenshot and not shot:
                raise  # the screenshot was not written: interrupted, not stopped
            print("rrt-pin: viewer stopped", file=sys.stderr)
    return 0


def _hints(server: Any) -> None:
    """How to use the page, on stderr (hidden by -q)."""
    import getpass
    import socket

    note(f"open {server.url} in a browser; Controls → Animations plays, pauses and scrubs "
         "the motion; Ctrl-C stops the server")  # fmt: skip
    if server.host in ("127.0.0.1", "localhost", "::1"):
        who = f"{getpass.getuser()}@{socket.gethostname()}"
        note(f"from another machine: ssh -L {server.port}:127.0.0.1:{server.port} {who}, "
             f"then open http://127.0.0.1:{server.port}/static/ there")  # fmt: skip


def _serve(seconds: float | None, start: float) -> None:
    stop = threading.Event()
    if seconds is None:
        while not stop.wait(3600.0):
            pass
        return
    remaining = seconds - (time.monotonic() - start)
    while remaining > 0 and not stop.wait(min(remaining, 3600.0)):
        remaining = seconds - (time.monotonic() - start)
