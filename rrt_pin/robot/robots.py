"""The robots rrt-pin knows by name: the chapter's RRT arm, and example-robot-data's arms.

``get("rrt")`` is the chapter's arm (from :class:`~rrt_pin.robot.params.Params`);
``get("ur5")``, ``get("panda")``, ``get("double_pendulum_continuous")`` …
load the URDFs that the ``example-robot-data`` package installs (when it is
installed); any other URDF is :meth:`Robot.from_urdf(path) <rrt_pin.robot.robot.Robot.from_urdf>`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rrt_pin.core import text
from rrt_pin.core.errors import InputError, ParameterError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.core.text import argument
from rrt_pin.robot.params import Params, param_names
from rrt_pin.robot.robot import CHAPTER_COLUMNS, Joint, Robot, RobotDefaults

if TYPE_CHECKING:
    from rrt_pin.robot.params import Params

__all__ = [
    "CHAPTER_COLUMNS",
    "EXAMPLE_ROBOT_DATA",
    "ROBOTS",
    "chapter_arm",
    "example_robot_data_dir",
    "for_task",
    "get",
    "names",
]


_CHAPTER_JOINTS = (
    Joint("q1", "revolute", idx_q=0, idx_v=0, effort_doc="torque of 0 on 1 about ı1"),
    Joint("q2", "revolute", idx_q=1, idx_v=1, effort_doc="torque of 1 on 2 about ȷ2"),
    Joint("q3", "prismatic", idx_q=2, idx_v=2, effort_doc="force of 2 on 3 along k2"),
)


def chapter_arm(params: Params | None = None) -> Robot:
    """The chapter's RRT arm with ``params`` (the chapter's numbers when None).

    Its defaults are the chapter's q0, qd0, qf, gains (γ as kp, β as kd) and Tp;
    its regulator is eq. (31); all three backends compute it. The Pinocchio
    model is generated from ``params`` on first use.
    """
    p = params if params is not None else Params()
    q, qd, qdd, eff = CHAPTER_COLUMNS

    def build():  # noqa: ANN202
        from rrt_pin.robot.model import rrt_model  # Pinocchio: built on first use

        return rrt_model(p)

    return Robot(
        name="RRT arm",
        joints=_CHAPTER_JOINTS,
        q_names=q,
        qd_names=qd,
        qdd_names=qdd,
        effort_names=eff,
        defaults=RobotDefaults(q0=p.q0, qd0=p.qd0, qf=p.qf, kp=p.kp, kd=p.kd, Tp=p.Tp),
        backends=("pinocchio", "symbolic", "compiled"),
        parameters=tuple(param_names()),
        params=p,
        layout="chapter",
        regulator="the chapter's feedback law, eq. (31)",
        motion="the chapter's rest-to-rest motion, eq. (30)",
        _build=build,
    )


#: Robot name -> URDF path inside example-robot-data's ``robots`` folder.
EXAMPLE_ROBOT_DATA = {
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
    "double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
    "double_pendulum_continuous": "double_pendulum_description/urdf/double_pendulum_continuous.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
}


@functools.cache
def names_chapter_arm(urdf: object, name: object) -> bool:
    """Whether a URDF and a robot's name (each may be None) name the chapter's arm: neither, or ``rrt``."""
    return urdf is None and name in (None, "rrt")


def of_model(model: Any, params: Params | None = None) -> Robot:
    """The robot of a model: the chapter's arm when the model is the arm built from ``params``.

    Anything else (or no ``params``) is :meth:`Robot.from_model` of it.
    """
    robot = Robot.from_model(model)
    if params is not None and robot.layout == "chapter":
        arm = chapter_arm(params)
        if bool(arm.model == model):
            return arm
    return robot


def example_robot_data_dir() -> Path | None:
    """``…/share/example-robot-data/robots`` of the installed package, or None."""
    from importlib.metadata import PackageNotFoundError, distribution

    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        return None
    for f in dist.files or ():
        parts = Path(str(f)).parts
        if "robots" in parts and parts[-1].endswith(".urdf"):
            i = parts.index("robots")
            return Path(dist.locate_file(Path(*parts[: i + 1])))
    return None


def _example(name: str) -> Callable[[Params | None], Robot]:
    def load(params: Params | None = None) -> Robot:
        g = params.g if params is not None else 9.81
        return Robot.from_urdf(urdf_path(name), g=g)

    return load


#: Every robot known by name -> a factory taking the chapter's Params (for g, Tp).
ROBOTS: dict[str, Callable[[Params | None], Robot]] = {
    "rrt": chapter_arm,
    **{name: _example(name) for name in EXAMPLE_ROBOT_DATA},
}


def get(name: str, params: Params | None = None) -> Robot:
    """The robot called ``name`` (see :data:`ROBOTS`).

    Raises:
        InputError: an unknown name (listing the known ones).
    """
    factory = ROBOTS.get(name)
    if factory is None:
        raise InputError(f"robot {name!r} is unknown; known: {', '.join(ROBOTS)}")
    return factory(params)


def urdf_path(name: str) -> Path | None:
    """The URDF file of the robot called ``name``; None for the chapter's arm (generated).

    Raises:
        InputError: an unknown name.
        MissingExtra: example-robot-data is not installed (the ``robots`` extra).
    """
    if name not in ROBOTS:
        raise InputError(f"robot {name!r} is unknown; known: {', '.join(ROBOTS)}")
    if name not in EXAMPLE_ROBOT_DATA:
        return None
    base = example_robot_data_dir()
    if base is None:
        raise MissingExtra("example-robot-data", "robots", f"robot {name!r}")
    return base / EXAMPLE_ROBOT_DATA[name]


def names() -> tuple[str, ...]:
    """The names :func:`get` knows."""
    return tuple(ROBOTS)


#: The defaults each task needs, by task.
TASK_NEEDS = {"inverse": ("q0", "qf"), "simulate": ("q0", "qf", "kp", "kd"), "view": ()}


def _per_joint(name: str, value: Any, robot: Robot, gain: bool) -> list[float]:
    """One value per joint (or, for gains, one for all); gains must be >= 0."""
    value = list(value)
    n = robot.nv
    if gain and len(value) == 1:
        value = value * n
    if len(value) != n:
        extra = " (or one for all)" if gain else ""
        names = text.names(robot.q_names)
        raise InputError(
            f"--{name} has {len(value)} values but the arm has {n} joints ({names}){extra}"
        )
    if gain:
        for i, v in enumerate(value):
            if v < 0.0:
                raise ParameterError(f"--{name}[{i}]", v, "gain must be >= 0")
    return value


def for_task(
    task: str,
    params: Params,
    *,
    urdf: str | Path | None = None,
    name: str | None = None,
    given: set[str] | frozenset[str] = frozenset(),
    **values: Any,
) -> Robot:
    """The robot of one run: ``urdf`` or the chapter's arm, with start, target and gains set.

    Args:
        task: ``inverse``, ``simulate`` or ``view`` (what defaults it needs, see :data:`TASK_NEEDS`).
        params: the chapter's parameters (the arm; g and Tp for a URDF).
        urdf: a URDF file, or None for the chapter's arm.
        name: instead of ``urdf``, a robot known by name (:data:`ROBOTS`).
        given: the parameters the user set (a URDF accepts only g and Tp).
        values: ``q0``, ``qd0``, ``qf`` [rad or m, rad/s or m/s], ``kp``, ``kd``
            (one per joint; gains may be one for all), or None for the robot's default.

    Raises:
        InputError: a parameter that does not apply to the robot, a value list
            of the wrong length, or a default the task needs and the robot lacks.
        UrdfError: the URDF does not describe a usable robot.
    """
    flag = f"{argument('urdf')} {urdf}"
    if name is not None:
        urdf, flag = urdf_path(name), f"{argument('name', '--robot')} {name}"
    if urdf is None:
        robot = chapter_arm(params)
    else:
        robot = Robot.from_urdf(urdf, g=params.g, Tp=params.Tp if "Tp" in given else None)
        unused = sorted(set(given) - set(robot.parameters))
        if unused:
            raise InputError(
                f"parameter {unused[0]} describes the RRT arm and does not apply to {flag} "
                f"(only {' and '.join(robot.parameters)} do)"
            )
    changes = {
        name: _per_joint(name, value, robot, gain=name in ("kp", "kd"))
        for name, value in values.items()
        if value is not None
    }
    robot = robot.with_defaults(**changes) if changes else robot
    missing = [f"--{k}" for k in TASK_NEEDS[task] if getattr(robot.defaults, k) is None]
    if missing:
        flags = ", ".join(missing[:-1]) + " and " + missing[-1] if len(missing) > 1 else missing[0]
        raise InputError(
            f"{flag} needs {flags} ({robot.nv} values each: {text.names(robot.q_names)})"
        )
    return robot
