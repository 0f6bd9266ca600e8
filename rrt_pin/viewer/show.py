"""Play a motion in the browser, from the CLI, from Python, or on the user's meshcat server.

``rrt-pin view`` and :func:`show` serve it themselves; ``--zmq-url`` sends it to
a meshcat server the user already runs.

* :func:`geometry`: a robot's visual geometry, its ``package://`` meshes found
  beside the URDF or on ``ROS_PACKAGE_PATH`` (drawn without them, with a warning
  saying so, when they are nowhere).
* :func:`prepare`: the drawing, its meshcat commands and the page (title, legend,
  time readout) for joint coordinates sampled at times ``t``.
* :func:`show`: a result (anything with ``t`` and ``q``) served from a background
  thread of this process; returns its URL (a ``str`` that Jupyter shows as the page).
* :func:`send_to_meshcat_server`: the same commands to ``meshcat-server`` or
  Pinocchio's ``MeshcatVisualizer`` over ZeroMQ.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core._quiet import native_message
from rrt_pin.core.errors import InputError, UrdfError, ViewerError
from rrt_pin.core.text import argument
from rrt_pin.robot.robot import CHAPTER_COLUMNS
from rrt_pin.robot.robots import chapter_arm

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot
    from rrt_pin.viewer.drawing import RobotDrawing

__all__ = ["Prepared", "ViewerURL", "geometry", "prepare", "send_to_meshcat_server", "show"]

logger = logging.getLogger("rrt_pin")

#: Servers started by :func:`show`, kept alive until :meth:`ViewerURL.close` or exit.
_SERVERS: list[Any] = []


def package_dirs(source: Any) -> list[str]:
    """Where ``package://`` meshes are looked for: beside the URDF, its parents, ROS_PACKAGE_PATH."""
    dirs: list[str] = []
    if source is not None:
        path = source.resolve()
        dirs += [str(p) for p in [path.parent, *path.parents]]
    dirs += [d for d in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if d]
    return dirs


def geometry(robot: Robot) -> Any:
    """The visual geometry; for a URDF whose meshes cannot be found, the rest of it (warned)."""
    from rrt_pin.robot.model import build_geometry

    xml = robot.xml()
    if robot.source is None:
        return build_geometry(robot.model, xml)
    try:
        return build_geometry(robot.model, xml, package_dirs=package_dirs(robot.source))
    except UrdfError as e:
        logger.warning("warning: %s", mesh_problem(e))
        return build_geometry(robot.model, _without_meshes(xml))


def mesh_problem(error: UrdfError) -> str:
    """One line for the warning of a URDF whose meshes do not load: the mesh file and why.

    Pinocchio's exception (the ``__cause__``) names C++ source files, functions
    and lines; :func:`rrt_pin.core._quiet.native_message` keeps the mesh and the problem.
    """
    cause = error.__cause__
    text = str(cause) if cause is not None and str(cause).strip() else str(error)
    problem = native_message(text.removeprefix("URDF geometry does not load: "))
    hint = ""
    if "could not be found" in problem and "package://" in problem:
        hint = (
            " (package:// paths are looked up beside the URDF, in its parent folders and on "
            "ROS_PACKAGE_PATH: set ROS_PACKAGE_PATH=/path/to/the/folder/holding/the/package)"
        )
    return f"{problem}; drawing the URDF without its meshes{hint}"


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


@dataclass(frozen=True)
class Prepared:
    """A motion ready to serve.

    Attributes:
        drawing: what is drawn (shapes, keyframes, ghost, path, camera).
        commands: meshcat commands, in sending order.
        page: the HTML page (meshcat's, with title, legend and time readout).
        title: the page's title.
    """

    drawing: RobotDrawing
    commands: list[Any]
    page: str
    title: str


def prepare(
    robot: Robot,
    t: np.ndarray,
    q_config: np.ndarray,
    fps: float,
    *,
    ghost_q: np.ndarray | None = None,
    play: bool = True,
    loop: bool = True,
    ghost: bool = True,
    what: str = "",
    path_frame: str | None = None,
) -> Prepared:
    """The drawing, commands and page of configurations ``q_config`` (Pinocchio's, (N, nq)) at ``t`` [s].

    ``path_frame``: the frame whose path is drawn (default: the tool flange,
    :func:`~rrt_pin.viewer.drawing.default_path_frame`).
    """
    from rrt_pin.viewer.drawing import build_drawing, check_frame
    from rrt_pin.viewer.meshcat_scene import scene_commands
    from rrt_pin.viewer.page import drawing_legend, meshcat_index, page_html

    if path_frame is not None:
        check_frame(robot.model, path_frame)
    drawing = build_drawing(
        robot.model, geometry(robot), t, q_config, fps, ghost_q=ghost_q, path_frame=path_frame
    )
    commands = scene_commands(drawing, play=play, loop=loop, ghost=ghost)
    title = f"{robot.name}: {what}" if what else robot.name
    page = page_html(meshcat_index(), title, drawing_legend(drawing, ghost))
    return Prepared(drawing, commands, page, title)


class ViewerURL(str):
    """The URL of a page :func:`show` serves; Jupyter displays the page itself.

    ``close()`` stops its server (it also stops when the process exits).
    """

    _server: Any = None

    def _repr_html_(self) -> str:
        return f'<iframe src="{self}" width="100%" height="480" style="border:0"></iframe>'

    def close(self) -> None:
        """Stop serving this page."""
        if self._server is not None:
            self._server.close()
            if self._server in _SERVERS:
                _SERVERS.remove(self._server)
            self._server = None


def show(
    result: Any,
    robot: Robot | None = None,
    *,
    fps: float = 30.0,
    host: str = "127.0.0.1",
    port: int | None = None,
    loop: bool = True,
    path_frame: str | None = None,
) -> ViewerURL:
    """Play ``result`` in the browser and return the page's URL.

    Args:
        result: a :class:`~rrt_pin.simulate.SimulationResult`, a batch's
            ``variant(i)``, or anything with ``t`` [s] (N,) and ``q`` (N, nv)
            [rad or m] (joint coordinates; angles for continuous joints).
        robot: the robot it moves; None for the result's own (a result of
            :func:`rrt_pin.simulate` remembers its robot), else the chapter's arm (a
            result of three coordinates named q1, q2, q3).
        fps: keyframes per second of the animation [1/s].
        host: interface to listen on (127.0.0.1: this machine only).
        port: TCP port; None takes 7000 or the next free one.
        loop: repeat the animation.
        path_frame: the frame whose path is drawn (default the tool flange: UR5's
            ``tool0``, Panda's ``panda_hand_tcp``, the arm's ``link3``).

    Returns:
        The URL (a ``str``; in Jupyter the cell shows the page). The server runs
        in a background thread until ``url.close()`` or the end of the process.

    Raises:
        InputError: ``result`` has no ``t``/``q``, or no robot matches it.
        ViewerError: the server cannot start (port taken …).
    """
    from rrt_pin.viewer.keyframes import resample
    from rrt_pin.viewer.server import ViewerServer

    t = getattr(result, "t", None)
    q = getattr(result, "q", None)
    if t is None or q is None:
        raise InputError(f"show() needs a result with t and q, not {type(result).__name__}")
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if robot is None:
        robot = getattr(result, "robot", None)
    if robot is None:
        names = tuple(getattr(result, "q_names", CHAPTER_COLUMNS[0]))
        if names != CHAPTER_COLUMNS[0]:
            raise InputError(f"show() of a result with coordinates {names[:4]}… needs robot=")

        robot = chapter_arm()
    if q.ndim != 2 or q.shape[1] != robot.nv or q.shape[0] != t.size:
        raise InputError(
            f"show(): q has shape {q.shape}; {robot.name} needs ({t.size}, {robot.nv})"
        )
    tk, qk = resample(t, q, fps)
    target = robot.defaults.qf if robot.defaults.qf is not None else q[-1]
    prepared = prepare(
        robot, tk, robot.configuration(qk), fps,
        ghost_q=robot.configuration(np.asarray(target, dtype=float)), loop=loop, what="motion",
        path_frame=path_frame,
    )  # fmt: skip
    server = ViewerServer(host, port, page=prepared.page)
    try:
        for command in prepared.commands:
            server.send(command)
    except BaseException:
        server.close()
        raise
    _SERVERS.append(server)
    url = ViewerURL(server.url)
    url._server = server
    return url


def send_to_meshcat_server(zmq_url: str, commands: list[Any], timeout: float = 5.0) -> str:
    """Send ``commands`` to a running meshcat server over ZeroMQ; returns its page's URL.

    Speaks the protocol of meshcat's ``ViewerWindow`` (``meshcat-server``,
    Pinocchio's ``MeshcatVisualizer``), with a ``timeout`` [s] on every reply, so
    that a wrong address is one error, not a hang.

    Raises:
        ViewerError: no server answers at ``zmq_url`` within ``timeout``.
    """
    import umsgpack
    import zmq

    context = zmq.Context.instance()
    sock = context.socket(zmq.REQ)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.RCVTIMEO, int(timeout * 1000))
    sock.setsockopt(zmq.SNDTIMEO, int(timeout * 1000))
    try:
        try:
            sock.connect(zmq_url)
            sock.send(b"url")
            web_url = sock.recv().decode("utf-8")
            for command in commands:
                data = command.lower()
                sock.send_multipart(
                    [data["type"].encode(), data["path"].encode(), umsgpack.packb(data)]
                )
                sock.recv()
        except zmq.ZMQError as e:
            raise ViewerError(
                f"{argument('zmq_url')} {zmq_url!r}: no meshcat server answered within {timeout:g} s "
                f"({e}); start one with `meshcat-server` (it prints its zmq_url)"
            ) from None
    finally:
        sock.close(0)
    return web_url
