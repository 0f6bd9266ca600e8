"""Inverse dynamics generated from a Pinocchio model (rrt_pin.dynamics.rnea_source) and compiled (rrt_pin.compiled.rnea).

Every kernel is checked sample by sample against ``pin.rnea`` at random states;
each model is compiled once per session (module-scope fixtures).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.rnea_source import (
    MAX_JOINTS,
    UnsupportedJoint,
    rnea_source,
    unsupported_joint,
)
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.robot import Robot
from tests.support import robot_urdf

needs_numba = pytest.mark.skipif(importlib.util.find_spec("numba") is None, reason="no numba")

#: Agreement asked of the generated kernels: max |τ − τ_pin| over all samples and
#: joints, relative to the largest |τ_pin|.
AGREEMENT = 1e-13
ROOT = Path(__file__).resolve().parent.parent

#: A tree with every joint type the generator handles: continuous about x and about an
#: unaligned axis, prismatic along an unaligned axis, revolute about an unaligned axis,
#: a branch at link b, offset centres of mass and full inertia tensors, rotated origins.
TREE_URDF = """<?xml version="1.0"?>
<robot name="tree">
  <link name="base"/>
  {links}
  <joint name="j1" type="continuous"><parent link="base"/><child link="a"/>
    <origin xyz="0.1 0 0.3" rpy="0.2 -0.1 0.4"/><axis xyz="1 0 0"/></joint>
  <joint name="j2" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0 0.2 0.1" rpy="0 0.3 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-1" upper="1" effort="100" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="b"/><child link="c"/>
    <origin xyz="0.3 0 0" rpy="0.5 0 -0.2"/><axis xyz="0 0.6 -0.8"/>
    <limit lower="-3" upper="3" effort="100" velocity="1"/></joint>
  <joint name="j4" type="continuous"><parent link="b"/><child link="d"/>
    <origin xyz="-0.2 0.1 0.05" rpy="0 0 1.0"/><axis xyz="0.48 0.6 0.64"/></joint>
  <joint name="j5" type="revolute"><parent link="d"/><child link="e"/>
    <origin xyz="0 0 0.25"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="100" velocity="1"/></joint>
</robot>
"""
_LINK = """<link name="{name}"><inertial><origin xyz="{com}" rpy="{rpy}"/><mass value="{m}"/>
    <inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/>
  </inertial></link>"""


def _tree_xml() -> str:
    rng = np.random.default_rng(5)
    links = []
    for name in "abcde":
        a, b, c = rng.uniform(0.05, 0.3, 3)  # principal moments obeying the triangle rule
        links.append(
            _LINK.format(
                name=name,
                com=" ".join(f"{x:.3f}" for x in rng.uniform(-0.2, 0.2, 3)),
                rpy=" ".join(f"{x:.3f}" for x in rng.uniform(-1, 1, 3)),
                m=f"{rng.uniform(0.5, 4):.3f}",
                ixx=b + c,
                iyy=a + c,
                izz=a + b,
                ixy=0.0,
                ixz=0.0,
                iyz=0.0,
            )
        )
    return TREE_URDF.format(links="\n  ".join(links))


def tree_model() -> pin.Model:
    model = pin.buildModelFromXML(_tree_xml())
    model.gravity.linear[:] = (0.3, -0.2, -9.81)  # not along an axis: every term counts
    return model


def _models() -> dict:
    return {
        "chapter": lambda: rrt_model(),
        "ur5": lambda: pin.buildModelFromUrdf(str(robot_urdf("ur5"))),
        "panda": lambda: pin.buildModelFromUrdf(str(robot_urdf("panda"))),
        "tree": tree_model,
    }


def random_batch(model: pin.Model, n: int, seed: int = 11):
    """n random states: configurations from uniform joint coordinates (cos, sin for continuous)."""
    rng = np.random.default_rng(seed)
    q = np.array([pin.normalize(model, rng.uniform(-3, 3, model.nq)) for _ in range(n)])
    return q, rng.normal(0, 3, (n, model.nv)), rng.normal(0, 10, (n, model.nv))


def pin_loop(model: pin.Model, q, qd, qdd) -> np.ndarray:
    data = model.createData()
    return np.array([pin.rnea(model, data, *s).copy() for s in zip(q, qd, qdd, strict=True)])


def worst(tau: np.ndarray, ref: np.ndarray) -> float:
    return float(np.abs(tau - ref).max() / np.abs(ref).max())


@pytest.fixture(scope="module", params=list(_models()))
def case(request):
    """(name, model, states, pin.rnea's efforts) with the model's kernel compiled once."""
    model = _models()[request.param]()
    q, qd, qdd = random_batch(model, 300)
    return request.param, model, (q, qd, qdd), pin_loop(model, q, qd, qdd)


def test_the_tree_has_every_joint_type_the_generator_handles():
    model = tree_model()
    names = [j.shortname() for j in model.joints[1:]]
    assert names == [
        "JointModelRUBX",
        "JointModelPrismaticUnaligned",
        "JointModelRevoluteUnaligned",
        "JointModelRevoluteUnboundedUnaligned",
        "JointModelRY",
    ]
    assert list(model.parents) == [0, 0, 1, 2, 2, 4]  # a branch at j2's link
    assert model.nq == 7 and model.nv == 5


def test_the_plain_python_source_agrees_with_pinocchio(case):
    """The generator alone (no numba): its one-sample function, run by Python."""
    name, model, (q, qd, qdd), ref = case
    gen = rnea_source(model)
    namespace = {"cos": math.cos, "sin": math.sin}
    exec(gen.function(), namespace)
    rows = zip(q[:50], qd[:50], qdd[:50], strict=True)
    tau = np.array([namespace["rnea"](*s, np.empty(model.nv)) for s in rows])
    assert worst(tau, ref[:50]) <= AGREEMENT, name
    assert gen.flops > 0 and not _trivial(gen.lines), name


def _trivial(lines) -> list[str]:
    """Statements that multiply by 0, 1 or -1, add 0 or only combine constants."""
    import ast

    out = []
    for line in lines:
        node = ast.parse(line).body[0].value
        if isinstance(node, ast.BinOp):
            sides = [n.value for n in (node.left, node.right) if isinstance(n, ast.Constant)]
            units = (0.0, 1.0, -1.0) if isinstance(node.op, ast.Mult) else (0.0,)
            if len(sides) == 2 or any(v in units for v in sides):
                out.append(line)
    return out


@needs_numba
def test_the_compiled_kernel_agrees_with_pinocchio_sample_by_sample(case):
    name, model, (q, qd, qdd), ref = case
    robot = Robot.from_model(model)  # its coordinates: angles for continuous joints
    tau = inverse_dynamics(robot, robot.coordinates(q), qd, qdd, backend="compiled")
    assert tau.shape == ref.shape
    assert worst(tau, ref) <= AGREEMENT, name


@needs_numba
@pytest.mark.parametrize("robot_name", ["ur5", "panda"])
def test_a_robot_takes_joint_coordinates(robot_name):
    from rrt_pin.robot.robots import get

    robot = get(robot_name)
    assert robot.supports("compiled", "inverse") and not robot.supports("compiled", "simulate")
    rng = np.random.default_rng(3)
    q, qd, qdd = (rng.uniform(-2, 2, (64, robot.nv)) for _ in range(3))
    tau = inverse_dynamics(robot, q, qd, qdd, backend="compiled")
    ref = inverse_dynamics(robot, q, qd, qdd, backend="pinocchio")
    assert worst(tau, ref) <= AGREEMENT
    one = inverse_dynamics(robot, q[3], qd[3], qdd[3], backend="compiled")
    assert one.shape == (robot.nv,) and np.array_equal(one, tau[3])


@needs_numba
def test_continuous_joints_take_angles_through_a_robot():
    from rrt_pin.robot.robot import Robot

    model = tree_model()
    robot = Robot.from_model(model)
    assert robot.has_continuous_joints and robot.supports("compiled", "inverse")
    rng = np.random.default_rng(9)
    x, qd, qdd = (rng.uniform(-3, 3, (40, robot.nv)) for _ in range(3))
    tau = inverse_dynamics(robot, x, qd, qdd, backend="compiled")
    ref = pin_loop(model, robot.configuration(x), qd, qdd)
    assert worst(tau, ref) <= AGREEMENT


@needs_numba
def test_the_chapter_arm_keeps_its_closed_form(monkeypatch):
    """A Robot with Params (or params=) goes to the closed form, never to a generated kernel.

    (Dispatch only: the closed form itself is tested elsewhere, and compiling it cold
    takes ~30 s.)
    """
    import rrt_pin.compiled
    from rrt_pin.compiled import rnea
    from rrt_pin.robot.robots import chapter_arm

    calls = []

    def closed_form(q, qd, qdd, params):
        calls.append(params)
        return np.zeros_like(q)

    def no_kernel(model):
        raise AssertionError("a kernel was generated for the chapter's arm")

    monkeypatch.setattr(rrt_pin.compiled, "inverse_dynamics", closed_form, raising=False)
    monkeypatch.setattr(rnea, "kernel_for", no_kernel)
    arm = chapter_arm()
    q = np.zeros((8, 3))
    inverse_dynamics(arm, q, q, q, backend="compiled")
    inverse_dynamics(chapter_arm(arm.params), q, q, q, backend="compiled")
    assert calls == [arm.params, arm.params]


@needs_numba
def test_one_and_two_threads_give_the_same_bits():
    from rrt_pin.compiled.rnea import kernel_for

    model = _models()["panda"]()
    q, qd, qdd = random_batch(model, 2 * kernel_for(model).min_per_thread + 3, seed=2)
    one = inverse_dynamics(Robot.from_model(model), q, qd, qdd, backend="compiled", num_threads=1)
    two = inverse_dynamics(Robot.from_model(model), q, qd, qdd, backend="compiled", num_threads=2)
    default = inverse_dynamics(Robot.from_model(model), q, qd, qdd, backend="compiled")
    assert np.array_equal(one, two) and np.array_equal(one, default)


@needs_numba
def test_armature_is_added_as_pinocchio_does():
    """A model with rotor inertia (``model.armature``, e.g. from MJCF) gets armature · q̈."""
    model = pin.Model(tree_model())
    model.armature = np.linspace(0.05, 0.9, model.nv)
    q, qd, qdd = random_batch(model, 400, seed=8)
    ref = pin_loop(model, q, qd, qdd)
    without = pin_loop(tree_model(), q, qd, qdd)
    assert worst(without, ref) > 1e-3  # the armature matters here
    robot = Robot.from_model(model)
    assert (
        worst(inverse_dynamics(robot, robot.coordinates(q), qd, qdd, backend="compiled"), ref)
        <= AGREEMENT
    )


@needs_numba
def test_read_only_inputs_are_taken_as_they_are():
    """Read-only arrays (a loaded or shared motion) reach the kernel without a copy."""
    from rrt_pin.compiled import rnea

    model = _models()["ur5"]()
    q, qd, qdd = random_batch(model, 300, seed=5)
    want = inverse_dynamics(Robot.from_model(model), q, qd, qdd, backend="compiled", num_threads=1)
    frozen = []
    for a in (q, qd, qdd):
        a = a.copy()
        a.flags.writeable = False
        frozen.append(a)
    assert all(rnea._c_array(a) is a for a in frozen)  # no copy on the way
    got, finite = rnea.inverse_dynamics(model, *frozen, num_threads=1)  # the kernel takes them
    assert finite and np.array_equal(got, want)


@needs_numba
@pytest.mark.parametrize("array, index", [("q", (7, 2)), ("qd", (1100, 1)), ("qdd", (0, 5))])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input_is_refused_naming_the_array(array, index, bad):
    model = _models()["ur5"]()
    arrays = dict(zip(("q", "qd", "qdd"), random_batch(model, 1200), strict=True))  # 2 threads
    arrays[array][index] = bad
    with pytest.raises(InputError, match=rf"{array}\[{index[0]}, {index[1]}\]={bad!r}"):
        inverse_dynamics(Robot.from_model(model), **arrays, backend="compiled", num_threads=2)


@needs_numba
def test_a_nan_in_any_column_is_refused():
    """The kernel checks every input itself (folded products by 0 would hide some NaNs)."""
    model = rrt_model()
    q, qd, qdd = random_batch(model, 10)
    for k in range(3):
        bad = qdd.copy()
        bad[4, k] = np.nan
        with pytest.raises(InputError, match=rf"qdd\[4, {k}\]=nan"):
            inverse_dynamics(Robot.from_model(model), q, qd, bad, backend="compiled")


@needs_numba
def test_overflowing_efforts_name_the_sample_and_joint():
    from rrt_pin.robot.robots import get

    robot = get("ur5")
    rng = np.random.default_rng(1)
    q, qd, qdd = (rng.uniform(-1, 1, (50, 6)) for _ in range(3))
    qd[17] = 1e200  # finite, but its squares are not
    with pytest.raises(
        InputError, match=r"the efforts overflow: tau_\w+ = (nan|-?inf) at sample 17"
    ):
        inverse_dynamics(robot, q, qd, qdd, backend="compiled")
    model = robot.model  # a bare model (deprecated) names the joint by its index
    with pytest.warns(DeprecationWarning, match="pinocchio.Model is deprecated"):
        with pytest.raises(InputError, match=r"the efforts overflow: joint \d = .* at sample 17"):
            inverse_dynamics(model, q, qd, qdd, backend="compiled")


def test_unsupported_joints_are_refused_naming_the_joint():
    model = pin.buildModelFromUrdf(str(robot_urdf("ur5")), pin.JointModelFreeFlyer())
    assert "FreeFlyer" in unsupported_joint(model)
    with pytest.warns(DeprecationWarning), pytest.raises(UnsupportedJoint) as info:
        inverse_dynamics(model, np.zeros(model.nq), np.zeros(model.nv), np.zeros(model.nv),
                         backend="compiled")  # fmt: skip
    message = str(info.value)
    assert "'root_joint' is a FreeFlyer joint (JointModelFreeFlyer)" in message
    assert "backend='pinocchio'" in message and "\n" not in message
    spherical = pin.Model()
    spherical.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    assert "Spherical" in unsupported_joint(spherical)


def test_too_many_joints_are_refused():
    model = pin.Model()
    for i in range(MAX_JOINTS + 1):
        model.addJoint(i, pin.JointModelRZ(), pin.SE3.Identity(), f"j{i}")
    assert f"at most {MAX_JOINTS}" in unsupported_joint(model)
    with pytest.raises(InputError, match=f"at most {MAX_JOINTS}"):
        rnea_source(model)


def test_the_generator_imports_without_numba():
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "import rrt_pin, rrt_pin.dynamics.rnea_source, rrt_pin.robot.robots\n"
        "from rrt_pin.robot.model import rrt_model\n"
        "g = rrt_pin.dynamics.rnea_source.rnea_source(rrt_model())\n"
        "print(g.nv, g.flops > 0, 'numba' in sys.modules and sys.modules['numba'] is not None)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.stdout.split() == ["3", "True", "False"], out.stderr


_SECOND = """
import json, sys
from rrt_pin.compiled import rnea
from rrt_pin.robot.model import rrt_model
k = rnea.kernel_for(rrt_model())
print(json.dumps({"origin": k.origin, "path": str(k.path),
                  "hits": sum(k.kernel.stats.cache_hits.values()),
                  "misses": sum(k.kernel.stats.cache_misses.values())}))
"""


@needs_numba
def test_a_second_process_loads_the_kernel_from_the_disk_cache(tmp_path):
    env = {**os.environ, "RRT_PIN_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    env.pop("NUMBA_CACHE_DIR", None)
    runs = []
    for _ in range(2):
        out = subprocess.run(
            [sys.executable, "-c", _SECOND], capture_output=True, text=True, env=env, cwd=ROOT
        )
        assert out.returncode == 0, out.stderr
        runs.append(json.loads(out.stdout.splitlines()[-1]))
    first, second = runs
    assert first["origin"] == "compiled" and first["misses"] >= 1 and first["hits"] == 0
    assert second["origin"] == "loaded" and second["hits"] >= 1 and second["misses"] == 0
    path = Path(first["path"])
    assert path == Path(second["path"]) and path.parent == tmp_path / "generated"
    assert path.name.startswith("rnea_") and any((path.parent / "__pycache__").glob("*.nbi"))


@needs_numba
def test_one_kernel_per_source_in_a_process():
    from rrt_pin.compiled import rnea

    a, b = rrt_model(), rrt_model()
    assert rnea.kernel_for(a) is rnea.kernel_for(b)  # two equal models, one kernel
    b.inertias[2].mass *= 2.0  # a changed model gets its own kernel
    assert rnea.kernel_for(b) is not rnea.kernel_for(a)


@needs_numba
def test_the_cli_runs_a_urdf_robot_on_the_compiled_backend(tmp_path, capsys):
    from rrt_pin.cli.app import main
    from rrt_pin.io.csvio import read_csv

    urdf = str(robot_urdf("ur5"))
    motion = ["--q0", "0,-1,1,0,1,0", "--qf", "1,-2,2,-1,0,1", "--tf", "2", "--dt", "0.01"]
    tables = {}
    for backend in ("pinocchio", "compiled"):
        out = tmp_path / f"{backend}.csv"
        argv = ["inverse", "--urdf", urdf, *motion, "--backend", backend, "--csv", str(out)]
        assert main(argv) == 0
        tables[backend] = read_csv(out)
    err = capsys.readouterr().err
    assert "generated inverse dynamics of ur5" in err
    (names, pinocchio), (same, compiled) = tables["pinocchio"], tables["compiled"]
    assert names == same
    efforts = [k for k, n in enumerate(names) if n.startswith("tau_")]
    assert worst(compiled[:, efforts], pinocchio[:, efforts]) <= AGREEMENT
    gains = ["--kp", "1", "--kd", "1", "--tf", "1"]
    code = main(["simulate", "--urdf", urdf, *motion[:4], *gains, "--backend", "compiled"])
    assert code == 2 and "simulates the chapter's RRT arm only" in capsys.readouterr().err
