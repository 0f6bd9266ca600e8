"""Mass matrix, bias, gravity and forward dynamics generated from a Pinocchio model, compiled.

(rrt_pin.dynamics.forward_source generates, rrt_pin.compiled.forward compiles.) Every
kernel is checked state by state against Pinocchio (``pin.crba`` symmetrised,
``pin.rnea`` with q̈ = 0, ``pin.computeGeneralizedGravity``, ``pin.aba``) at random
states, for every fixed-base robot of example-robot-data the generator supports and for
randomly generated trees; each model is compiled once per session (module-scope
fixtures), and numba is a test dependency: nothing here is skipped.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.compiled.forward import DEFAULT_VARIANT, forward_kernel_for, module_source
from rrt_pin.core.errors import InputError
from rrt_pin.dynamics import forward_source as fs
from rrt_pin.dynamics.rnea_source import UnsupportedJoint
from rrt_pin.robot import robots
from rrt_pin.robot.model import rrt_model
from tests.test_generated_rnea import _trivial, tree_model

#: Agreement asked: per state, max |x − x_pin| over its entries relative to max |x_pin|.
AGREEMENT = 1e-13
ROOT = Path(__file__).resolve().parent.parent
#: The fixed-base robots of example-robot-data that rrt_pin.robot.robots names; all of
#: them have only revolute, prismatic and continuous joints (panda: a branch at the hand;
#: double_pendulum_continuous and kinova: continuous joints).
EXAMPLE_ROBOTS = ("ur5", "panda", "double_pendulum", "double_pendulum_continuous", "kinova")
#: Random trees compiled (more are checked through the plain Python source only).
COMPILED_TREES = (1, 2)

#: URDF joint types and axes of the random trees: x, y, z or an oblique axis each.
_KINDS = ("revolute", "prismatic", "continuous")
_AXES = ("1 0 0", "0 1 0", "0 0 1", None)
_JOINT = """<joint name="j{i}" type="{kind}"><parent link="{parent}"/><child link="l{i}"/>
    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>
    <limit lower="-3" upper="3" effort="100" velocity="1"/></joint>"""
_BODY = """<link name="l{i}"><inertial><origin xyz="{com}" rpy="{rpy}"/><mass value="{m}"/>
    <inertia ixx="{a}" ixy="0" ixz="0" iyy="{b}" iyz="0" izz="{c}"/></inertial></link>"""


def _numbers(xs) -> str:
    return " ".join(f"{x:.4f}" for x in xs)


def random_tree(seed: int, joints: int = 7) -> pin.Model:
    """A random tree: branches, the joint kinds and axes in turn (shuffled), rotated and
    offset joint origins, offset centres of mass with full inertia tensors, armature and
    oblique gravity."""
    rng = np.random.default_rng(seed)
    pairs = [(k, a) for k in _KINDS for a in _AXES]
    order = rng.permutation(len(pairs))
    parts = ['<?xml version="1.0"?>', f'<robot name="random_tree_{seed}">', '<link name="l0"/>']
    for i in range(1, joints + 1):
        parent = 0 if i == 1 else int(rng.integers(max(0, i - 3), i))
        if i == 3:
            parent = 1  # at least one branch: joints 2 and 3 both hang from joint 1's link
        kind, axis = pairs[order[(i - 1) % len(pairs)]]
        if axis is None:
            u = rng.normal(size=3)
            axis = _numbers(u / np.linalg.norm(u))
        moments = rng.uniform(0.02, 0.2, 3)  # principal moments obeying the triangle rule
        a, b, c = moments[1] + moments[2], moments[0] + moments[2], moments[0] + moments[1]
        parts.append(
            _JOINT.format(i=i, kind=kind, parent=f"l{parent}", axis=axis,
                          xyz=_numbers(rng.uniform(-0.3, 0.3, 3)),
                          rpy=_numbers(rng.uniform(-1.5, 1.5, 3)))
        )  # fmt: skip
        parts.append(
            _BODY.format(i=i, com=_numbers(rng.uniform(-0.2, 0.2, 3)),
                         rpy=_numbers(rng.uniform(-1.5, 1.5, 3)),
                         m=f"{rng.uniform(0.3, 3.0):.3f}", a=a, b=b, c=c)
        )  # fmt: skip
    parts.append("</robot>")
    model = pin.buildModelFromXML("\n".join(parts))
    model.armature = rng.uniform(0.0, 0.3, model.nv)
    model.gravity.linear[:] = rng.normal(0, 1, 3) + (0.0, 0.0, -9.81)
    return model


def _armed_tree() -> pin.Model:
    model = pin.Model(tree_model())
    model.armature = np.linspace(0.05, 0.9, model.nv)
    model.name = "tree_with_armature"
    return model


def _models() -> dict:
    return {
        "rrt": rrt_model,
        **{name: (lambda name=name: robots.get(name).model) for name in EXAMPLE_ROBOTS},
        "tree": tree_model,
        "tree_with_armature": _armed_tree,
        **{f"random_tree_{s}": (lambda s=s: random_tree(s)) for s in COMPILED_TREES},
    }


def configuration(model: pin.Model, x: np.ndarray) -> np.ndarray:
    """Pinocchio's configurations (N, nq) of joint coordinates (N, nv): cos, sin for continuous."""
    q = np.empty((x.shape[0], model.nq))
    for jm in model.joints[1:]:
        theta = x[:, jm.idx_v]
        if jm.nq == 2:
            q[:, jm.idx_q], q[:, jm.idx_q + 1] = np.cos(theta), np.sin(theta)
        else:
            q[:, jm.idx_q] = theta
    return q


def random_states(model: pin.Model, n: int, seed: int = 3):
    rng = np.random.default_rng(seed)
    nv = model.nv
    return rng.uniform(-3, 3, (n, nv)), rng.normal(0, 3, (n, nv)), rng.normal(0, 10, (n, nv))


def pinocchio_reference(model: pin.Model, x, qd, tau) -> dict[str, np.ndarray]:
    data = model.createData()
    zero = np.zeros(model.nv)
    out: dict[str, list] = {"mass_matrix": [], "bias": [], "gravity": [], "forward": []}
    for q, v, u in zip(configuration(model, x), qd, tau, strict=True):
        m = np.triu(pin.crba(model, data, q))
        out["mass_matrix"].append(m + np.triu(m, 1).T)
        out["bias"].append(pin.rnea(model, data, q, v, zero).copy())
        out["gravity"].append(pin.computeGeneralizedGravity(model, data, q).copy())
        out["forward"].append(pin.aba(model, data, q, v, u).copy())
    return {k: np.array(v) for k, v in out.items()}


def worst(a: np.ndarray, ref: np.ndarray) -> float:
    """max over states of max |a − ref| / max |ref| (each state's own scale)."""
    n = ref.shape[0]
    err = np.abs(a - ref).reshape(n, -1).max(axis=1)
    return float((err / np.abs(ref).reshape(n, -1).max(axis=1)).max())


@pytest.fixture(scope="module", params=list(_models()))
def case(request):
    """(name, model, kernels, states, Pinocchio's results), compiled once a session."""
    model = _models()[request.param]()
    kernels = forward_kernel_for(model, request.param)
    states = random_states(model, 200)
    return request.param, model, kernels, states, pinocchio_reference(model, *states)


def test_the_example_robots_are_all_supported_and_named_here():
    """Every fixed-base robot the package knows by name is in EXAMPLE_ROBOTS (or the arm)."""
    assert set(robots.names()) == {"rrt", *EXAMPLE_ROBOTS}
    kinds = {n: {j.shortname() for j in robots.get(n).model.joints[1:]} for n in EXAMPLE_ROBOTS}
    assert "JointModelRUBX" in kinds["double_pendulum_continuous"]
    assert "JointModelPrismaticUnaligned" in kinds["panda"]


def test_the_random_trees_branch_and_mix_every_joint_kind():
    for seed in COMPILED_TREES:
        model = random_tree(seed)
        parents = list(model.parents)[1:]
        assert len(set(parents)) < len(parents)  # a parent with two children
        names = [j.shortname() for j in model.joints[1:]]
        assert any("RUB" in n or "Unbounded" in n for n in names)  # continuous
        assert any(n.startswith("JointModelP") for n in names)  # prismatic
        assert any(n in ("JointModelRX", "JointModelRY", "JointModelRZ") or
                   n == "JointModelRevoluteUnaligned" for n in names)  # fmt: skip
        assert model.nq > model.nv and np.all(model.armature > 0)
    every = {j.shortname() for s in range(6) for j in random_tree(s).joints[1:]}
    assert len(every) == 12  # R, P and continuous, each about x, y, z and an oblique axis


@pytest.mark.parametrize("quantity", ["mass_matrix", "bias", "gravity"])
def test_the_kernels_agree_with_pinocchio(case, quantity):
    name, model, kernels, (x, qd, tau), ref = case
    got = getattr(kernels, quantity)(x, qd) if quantity == "bias" else getattr(kernels, quantity)(x)
    assert got.shape == ref[quantity].shape
    assert worst(got, ref[quantity]) <= AGREEMENT, (name, worst(got, ref[quantity]))


@pytest.mark.parametrize("variant", ["aba", "crba"])
def test_forward_dynamics_agrees_with_pin_aba(case, variant):
    name, model, kernels, (x, qd, tau), ref = case
    qdd = kernels.forward_dynamics(x, qd, tau, variant=variant)
    assert qdd.shape == (x.shape[0], model.nv)
    assert worst(qdd, ref["forward"]) <= AGREEMENT, (name, variant, worst(qdd, ref["forward"]))


def test_the_two_forward_variants_agree_and_the_default_is_one_of_them(case):
    name, model, kernels, (x, qd, tau), ref = case
    aba = kernels.forward_dynamics(x, qd, tau, variant="aba")
    crba = kernels.forward_dynamics(x, qd, tau, variant="crba")
    assert worst(aba, crba) <= AGREEMENT, name
    assert np.array_equal(
        kernels.forward_dynamics(x, qd, tau), {"aba": aba, "crba": crba}[DEFAULT_VARIANT]
    )
    # and q̈ solves M q̈ + b = τ with the kernels' own M and b (relative to the terms' size)
    inertial = np.einsum("nij,nj->ni", kernels.mass_matrix(x), crba)
    residual = np.abs(inertial + kernels.bias(x, qd) - tau).max(axis=1)
    assert (residual / np.abs(inertial).max(axis=1)).max() <= AGREEMENT, name


def test_the_check_can_fail():
    """A model with one body 1 % heavier is told apart from the original, in every quantity."""
    model = robots.get("ur5").model
    heavier = pin.Model(model)
    heavier.inertias[3].mass *= 1.01
    states = random_states(model, 50)
    ref = pinocchio_reference(model, *states)
    kernels = forward_kernel_for(heavier, "ur5_heavier")
    x, qd, tau = states
    got = {
        "mass_matrix": kernels.mass_matrix(x),
        "bias": kernels.bias(x, qd),
        "gravity": kernels.gravity(x),
        "forward": kernels.forward_dynamics(x, qd, tau),
    }
    for quantity, value in got.items():
        assert worst(value, ref[quantity]) > 1e-5, quantity
    assert worst(got["forward"], pinocchio_reference(heavier, *states)["forward"]) <= AGREEMENT


def test_armature_changes_the_result_as_in_pinocchio():
    states = random_states(tree_model(), 50)
    bare = pinocchio_reference(tree_model(), *states)["forward"]
    armed = pinocchio_reference(_armed_tree(), *states)["forward"]
    assert worst(bare, armed) > 1e-3  # the armature matters here
    got = forward_kernel_for(_armed_tree()).forward_dynamics(*states)
    assert worst(got, armed) <= AGREEMENT


@pytest.mark.parametrize("seed", range(3, 9))
def test_the_plain_python_source_agrees_on_more_random_trees(seed):
    """The generator alone (no numba): more random trees, run by Python."""
    model = random_tree(seed, joints=5 + seed % 4)
    x, qd, tau = random_states(model, 20, seed=seed)
    ref = pinocchio_reference(model, x, qd, tau)
    namespace = {"cos": math.cos, "sin": math.sin}
    gens = {
        "mass_matrix": (fs.mass_matrix_source(model), (x,)),
        "bias": (fs.bias_source(model), (x, qd)),
        "gravity": (fs.gravity_source(model), (x,)),
        "forward": (fs.forward_source(model, "aba"), (x, qd, tau)),
        "forward_crba": (fs.forward_source(model, "crba"), (x, qd, tau)),
    }
    for quantity, (gen, args) in gens.items():
        exec(gen.function(), namespace)
        fn = namespace[gen.name]
        got = np.array([fn(*row, np.empty(gen.shape)) for row in zip(*args, strict=True)])
        want = ref[quantity.removesuffix("_crba")]
        assert worst(got, want) <= AGREEMENT, (seed, quantity)
        assert gen.flops > 0 and not _trivial(gen.lines), quantity


def test_structural_zeros_are_dropped_and_the_tree_is_exploited():
    """Panda's two fingers hang from the hand: their pair of M is a constant 0, never computed."""
    model = robots.get("panda").model
    gen = fs.mass_matrix_source(model)
    assert gen.shape == (9, 9) and gen.outputs[7 * 9 + 8] == "0.0" == gen.outputs[8 * 9 + 7]
    assert all(gen.outputs[r * 9 + c] == gen.outputs[c * 9 + r] for r in range(9) for c in range(9))
    assert not _trivial(gen.lines)
    gravity = fs.gravity_source(model)
    assert gravity.flops < fs.bias_source(model).flops / 2  # q̇ = 0 folded away
    for variant in fs.VARIANTS:
        gen = fs.forward_source(model, variant)
        # the first joint turns about gravity's axis: its angle drops out of everything
        assert 0 < gen.flops < 3000 and gen.transcendentals == 2 * 6
        # one division a revolute joint; a finger's pivot is a constant (its mass)
        assert sum("1.0 /" in line for line in gen.lines) == 7


def test_a_non_finite_input_is_named():
    kernels = forward_kernel_for(robots.get("ur5").model, "ur5")
    x, qd, tau = random_states(kernels._model, 30)
    for name, array in (("q", x), ("qd", qd), ("tau", tau)):
        bad = array.copy()
        bad[7, 2] = np.nan
        args = {"q": x, "qd": qd, "tau": tau, name: bad}
        with pytest.raises(InputError, match=rf"{name}\[7, 2\]=nan"):
            kernels.forward_dynamics(args["q"], args["qd"], args["tau"])
    bad = x.copy()
    bad[4, 0] = np.inf
    with pytest.raises(InputError, match=r"q\[4, 0\]=inf"):
        kernels.mass_matrix(bad)


def test_an_overflowing_result_is_refused_naming_the_sample():
    kernels = forward_kernel_for(robots.get("ur5").model, "ur5")
    x, qd, tau = random_states(kernels._model, 30)
    qd[11] = 1e200  # finite, but its squares are not
    with pytest.raises(InputError, match=r"the bias of ur5 is not finite: bias\[11, \d\] = "):
        kernels.bias(x, qd)
    with pytest.raises(InputError, match=r"forward dynamics of ur5 is not finite: .* at sample 11"):
        kernels.forward_dynamics(x, qd, tau)


def test_shapes_and_variants_are_checked():
    kernels = forward_kernel_for(robots.get("ur5").model, "ur5")
    x, qd, tau = random_states(kernels._model, 5)
    with pytest.raises(InputError, match=r"qd.shape=\(5, 5\).*nv=6"):
        kernels.bias(x, qd[:, :5])
    with pytest.raises(InputError, match=r"q.shape=\(6,\)"):
        kernels.gravity(x[0])
    with pytest.raises(InputError, match="variant='rk4' is not one of aba, crba"):
        kernels.forward_dynamics(x, qd, tau, variant="rk4")
    assert kernels.gravity(np.empty((0, 6))).shape == (0, 6)


def test_inputs_are_not_written_and_outputs_are_new():
    kernels = forward_kernel_for(robots.get("ur5").model, "ur5")
    states = [a.copy() for a in random_states(kernels._model, 40)]
    for a in states:
        a.flags.writeable = False
    first = kernels.forward_dynamics(*states)
    again = kernels.forward_dynamics(*states)
    assert first is not again and np.array_equal(first, again) and first.flags.writeable


def test_one_and_two_threads_give_the_same_bits():
    kernels = forward_kernel_for(robots.get("panda").model, "panda")
    x, qd, tau = random_states(kernels._model, 2 * kernels.kernel("mass_matrix").min_per_thread + 5)
    for call in (lambda **k: kernels.forward_dynamics(x, qd, tau, **k),
                 lambda **k: kernels.mass_matrix(x, **k)):  # fmt: skip
        assert np.array_equal(call(num_threads=1), call(num_threads=2))


def test_an_unsupported_joint_is_refused_naming_it():
    model = pin.buildModelFromUrdf(str(robots.urdf_path("ur5")), pin.JointModelFreeFlyer())
    with pytest.raises(UnsupportedJoint, match="'root_joint' is a FreeFlyer joint"):
        forward_kernel_for(model)
    with pytest.raises(UnsupportedJoint):
        fs.forward_source(model)
    with pytest.raises(InputError, match="variant='rk4' is unknown"):
        fs.forward_source(robots.get("ur5").model, "rk4")


def test_one_kernel_set_per_model_and_a_changed_model_gets_its_own():
    model = rrt_model()
    kernels = forward_kernel_for(model, "rrt")
    assert forward_kernel_for(model) is kernels
    model.inertias[2].mass *= 2.0
    assert forward_kernel_for(model) is not kernels
    assert "def kernel(Q, V, T, out):" in module_source(kernels.source("forward_crba"))


_SECOND = """
import json, logging, sys
logging.basicConfig(level=25, stream=sys.stderr, format="%(message)s")
from rrt_pin.compiled.forward import forward_kernel_for
from rrt_pin.robot import robots
k = forward_kernel_for(robots.get("double_pendulum").model, "double_pendulum")
print(json.dumps({kind: k.kernel(kind).origin for kind in k._kernels}))
"""


def test_the_first_process_announces_and_compiles_a_later_one_loads(tmp_path):
    env = {**os.environ, "RRT_PIN_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    env.pop("NUMBA_CACHE_DIR", None)
    runs = []
    for _ in range(2):
        out = subprocess.run(
            [sys.executable, "-c", _SECOND], capture_output=True, text=True, env=env, cwd=ROOT
        )
        assert out.returncode == 0, out.stderr
        runs.append((json.loads(out.stdout.splitlines()[-1]), out.stderr))
    (first, said), (second, quiet) = runs
    kinds = {"mass_matrix", "bias", "gravity", f"forward_{DEFAULT_VARIANT}"}
    assert first == dict.fromkeys(kinds, "compiled") and second == dict.fromkeys(kinds, "loaded")
    assert said.count("compiling double_pendulum's kernels once (~") == 1
    assert "compiling" not in quiet
    assert len(list((tmp_path / "generated").glob("*.cache.json"))) == len(kinds)
