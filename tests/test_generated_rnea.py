"""Inverse dynamics generated from a Pinocchio model (rrt_pin.dynamics.rnea_source) and compiled (rrt_pin.compiled.rnea).

Every kernel is checked sample by sample against ``pin.rnea`` at random states;
each model is compiled once per session (module-scope fixtures).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import platform
import re
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
    assert robot.supports("compiled", "inverse")
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
    runs = {}
    for backend in ("pinocchio", "compiled"):  # simulations too: the generated integrators
        out = tmp_path / f"sim_{backend}.csv"
        argv = ["simulate", "--urdf", urdf, *motion[:4], *gains, "--method", "DOP853"]
        assert main([*argv, "--backend", backend, "--csv", str(out)]) == 0
        runs[backend] = read_csv(out)
    assert "generated integrators of ur5" in capsys.readouterr().err
    assert runs["pinocchio"][0] == runs["compiled"][0]
    assert worst(runs["compiled"][1], runs["pinocchio"][1]) <= 1e-6


# --- the kernel vectorised across samples (rrt_pin.compiled.rnea_vector) ------------------

#: Joint models of random trees: revolute, prismatic and continuous, axes aligned or not
#: (an unaligned continuous joint, which Pinocchio's Python cannot make, is in TREE_URDF).
_JOINTS = (
    lambda axis: pin.JointModelRX(),
    lambda axis: pin.JointModelRUBY(),
    lambda axis: pin.JointModelPrismaticUnaligned(axis),
    lambda axis: pin.JointModelRevoluteUnaligned(axis),
    lambda axis: pin.JointModelRUBZ(),
    lambda axis: pin.JointModelPZ(),
    lambda axis: pin.JointModelRZ(),
    lambda axis: pin.JointModelRY(),
    lambda axis: pin.JointModelPX(),
)


def random_tree(seed: int, joints: int = 6) -> pin.Model:
    """A random tree: random parents, joint kinds, rotated and offset placements, inertias."""
    rng = np.random.default_rng(seed)
    model = pin.Model()
    model.gravity.linear[:] = rng.normal(0, 5, 3)
    for i in range(joints):
        axis = rng.normal(size=3)
        kind = _JOINTS[i] if i < 3 else _JOINTS[int(rng.integers(len(_JOINTS)))]
        parent = int(rng.integers(0, i + 1))
        rotation = pin.exp3(rng.normal(size=3))
        placement = pin.SE3(rotation, rng.uniform(-0.3, 0.3, 3))
        jid = model.addJoint(parent, kind(axis / np.linalg.norm(axis)), placement, f"j{i}")
        a, b, c = rng.uniform(0.01, 0.2, 3)
        r = pin.exp3(rng.normal(size=3))
        inertia = r @ np.diag([b + c, a + c, a + b]) @ r.T
        body = pin.Inertia(float(rng.uniform(0.2, 3)), rng.uniform(-0.2, 0.2, 3), inertia)
        model.appendBodyToJoint(jid, body, pin.SE3.Identity())
    return model


def _raw(model: pin.Model, q, qd, qdd):
    """The compiled kernel's efforts on one thread (Pinocchio's configuration layout)."""
    from rrt_pin.compiled import rnea

    tau, finite = rnea.inverse_dynamics(model, q, qd, qdd, num_threads=1)
    return tau, finite


@needs_numba
@pytest.mark.parametrize("seed", [3, 4])
def test_random_trees_agree_with_pinocchio(seed):
    model = random_tree(seed)
    kinds = {j.shortname() for j in model.joints[1:]}
    assert {"JointModelRUBY", "JointModelPrismaticUnaligned", "JointModelRX"} <= kinds
    assert len(set(model.parents[1:])) > 1 and model.nq > model.nv  # a tree; continuous joints
    q, qd, qdd = random_batch(model, 261, seed=seed)  # two full blocks and a partial one
    tau, finite = _raw(model, q, qd, qdd)
    assert finite and worst(tau, pin_loop(model, q, qd, qdd)) <= AGREEMENT


@needs_numba
@pytest.mark.parametrize("n", [1, 5, 127, 128, 129, 300])
def test_every_sample_gets_the_bits_it_gets_alone(n):
    """Lanes are independent: batch sizes not multiples of a block, samples anywhere in it."""
    from rrt_pin.compiled.rnea_vector import BLOCK

    assert BLOCK == 128  # the sizes above straddle it
    model = _models()["panda"]()
    q, qd, qdd = random_batch(model, n, seed=n)
    tau, finite = _raw(model, q, qd, qdd)
    assert finite and worst(tau, pin_loop(model, q, qd, qdd)) <= AGREEMENT
    for i in sorted({0, n // 2, n - 1}):
        alone, _ = _raw(model, q[i : i + 1], qd[i : i + 1], qdd[i : i + 1])
        assert np.array_equal(alone[0], tau[i])


@needs_numba
def test_a_block_with_a_huge_angle_takes_libm_for_it_only():
    """|q| >= SINCOS_LIMIT: that sample's sine and cosine from libm (as Pinocchio's); the
    other samples of its block keep the polynomial's bits."""
    from rrt_pin.compiled.rnea_vector import SINCOS_LIMIT

    model = _models()["ur5"]()
    q, qd, qdd = random_batch(model, 300, seed=4)
    before, _ = _raw(model, q, qd, qdd)
    for huge in (SINCOS_LIMIT, 3.7e9, -1e15):
        big = q.copy()
        big[140, 2] = huge  # the second block
        big[141, 1] = SINCOS_LIMIT * (1 - 2**-50)  # below the limit: the polynomial
        tau, finite = _raw(model, big, qd, qdd)
        assert finite
        ref = pin_loop(model, big[140:142], qd[140:142], qdd[140:142])
        assert worst(tau[140:142], ref) <= AGREEMENT
        same = np.ones(300, bool)
        same[140:142] = False
        assert np.array_equal(tau[same], before[same])


@needs_numba
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("column", [0, 2])  # q[0] reaches no effort of UR5; q[2] does
def test_a_non_finite_angle_is_refused(bad, column):
    model = _models()["ur5"]()
    q, qd, qdd = random_batch(model, 300, seed=6)
    q[200, column] = bad
    tau, finite = _raw(model, q, qd, qdd)
    assert not finite
    assert np.isfinite(np.delete(tau, 200, axis=0)).all()  # the other samples are computed
    robot = Robot.from_model(model)
    with pytest.raises(InputError, match=rf"q\[200, {column}\]={bad!r}"):
        inverse_dynamics(robot, q, qd, qdd, backend="compiled")


def test_the_polynomial_sine_and_cosine_are_within_cephes_bound():
    """The generated sin/cos statements, run as plain Python, against libm."""
    from rrt_pin.compiled.rnea_vector import sincos_lines

    code = "\n".join(sincos_lines("x", "s", "c", "p"))
    rng = np.random.default_rng(0)
    xs = [0.0, -0.0, math.pi / 4, -math.pi / 2, 1e-300, *rng.uniform(-50, 50, 2000)]
    xs += list(rng.uniform(-1e7, 1e7, 200))
    errs = []
    for x in xs:
        scope = {"x": float(x)}
        exec(code, scope)
        errs.append(max(abs(scope["s"] - math.sin(x)), abs(scope["c"] - math.cos(x))))
    assert max(errs) <= 2.3e-16 * max(1.0, max(abs(x) for x in xs) * 1e-9)
    assert max(errs[:2005]) <= 2.3e-16


def test_the_copied_sine_constants_are_the_arm_kernels():
    """rnea_vector copies _jit_dynamics' Cephes constants (that module compiles on import)."""
    import ast

    from rrt_pin.compiled import rnea_vector as rv

    tree = ast.parse((ROOT / "rrt_pin/compiled/_jit_dynamics.py").read_text(encoding="utf-8"))
    values = {
        node.targets[0].id: ast.literal_eval(node.value)
        for node in tree.body
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name)
        and node.targets[0].id in {"SINCOS_LIMIT", "_FOPI", "_DP1", "_DP2", "_DP3", "_S", "_C"}
    }  # fmt: skip
    assert values["SINCOS_LIMIT"] == rv.SINCOS_LIMIT and values["_FOPI"] == rv._FOPI
    assert (values["_DP1"], values["_DP2"], values["_DP3"]) == rv._DP
    assert values["_S"] == rv._S and values["_C"] == rv._C


def test_the_generated_module_runs_as_plain_python():
    """The module's text alone (no numba): the same kernel, interpreted, on a tree."""
    from rrt_pin.compiled.rnea_vector import vector_source

    model = tree_model()
    source, pairs = vector_source(rnea_source(model), block=4)
    assert pairs == 2  # revolute j3 and j5 (the continuous joints read their cos, sin)
    scope: dict = {}
    exec(source, scope)
    q, qd, qdd = random_batch(model, 10, seed=3)
    out = np.empty((10, model.nv))
    assert scope["kernel"](q, qd, qdd, out) == 0.0
    assert worst(out, pin_loop(model, q, qd, qdd)) <= AGREEMENT
    qd[9, 1] = np.nan
    assert math.isnan(scope["kernel"](q, qd, qdd, out))


@needs_numba
def test_the_kernel_is_vectorised_and_counts_its_sines():
    from rrt_pin.compiled import rnea
    from rrt_pin.simulate.codes import SINCOS_FLOPS

    kernel = rnea.kernel_for(_models()["ur5"]())
    assert kernel.vectorised and kernel.sincos == 5  # the shoulder pan's angle reaches no effort
    assert kernel.all_flops == kernel.flops + 5 * SINCOS_FLOPS


@needs_numba
@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 assembly")
def test_the_block_loop_compiles_to_packed_arithmetic():
    """A call or a branch in the body would leave it scalar (compiled here, not from the cache,
    whose code numba does not show)."""
    import numba

    from rrt_pin.compiled import rnea

    scope: dict = {}
    exec(rnea.module_source(rnea_source(rrt_model())), scope)
    kernel = numba.njit(rnea._signature(numba), error_model="numpy")(scope["kernel"])
    asm = kernel.inspect_asm(kernel.signatures[0])
    packed = len(re.findall(r"\bv?mulpd\b", asm))
    scalar = len(re.findall(r"\bv?mulsd\b", asm))
    assert packed >= 0.9 * scalar > 0  # the lanes' body, and the scalar remainder's
