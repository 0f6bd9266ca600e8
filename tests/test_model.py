"""The Pinocchio model against the seed's printed formulas (tests/seed_formulas.py)."""

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import UrdfError
from rrt_pin.robot.model import build_geometry, load_urdf_model, model_from_xml, rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.urdf import urdf_xml
from tests.support import (
    TIGHT,
    holding_efforts,
    kinetic_energy,
    mass_centres,
    random_states,
    seed_to_world,
)


def test_dimensions_and_names(seed_model):
    assert (seed_model.nq, seed_model.nv) == (3, 3)  # revolute, not continuous (nq would be 5)
    assert list(seed_model.names)[1:] == ["q1", "q2", "q3"]
    np.testing.assert_array_equal(seed_model.gravity.linear, [0.0, 0.0, -9.81])


def test_masses_and_central_inertias(seed_model, seed_params):
    p = seed_params
    expected = [
        (p.m1, [0, 0, p.L1], np.diag([p.I1x, p.I1y, p.I1z])),
        (p.m2, [0, 0, p.L2], np.diag([p.I2x, p.I2y, p.I2z])),
        (p.m3, [0, 0, 0], np.diag([p.I3x, p.I3y, p.I3z])),
    ]
    for j, (mass, lever, central) in enumerate(expected, start=1):
        inertia = seed_model.inertias[j]
        assert inertia.mass == mass
        np.testing.assert_array_equal(inertia.lever, lever)
        # Pinocchio stores the inertia about the mass centre, in the joint (= seed's link) frame.
        np.testing.assert_allclose(inertia.inertia, central, rtol=0, atol=1e-15)


def test_mass_centres_where_the_seed_puts_them(seed_model, seed_params, rng):
    data = seed_model.createData()
    qs, _, _ = random_states(rng, 100)
    for q in qs:
        pin.forwardKinematics(seed_model, data, q)
        for j, r_seed in enumerate(mass_centres(seed_params, q), start=1):
            c_world = data.oMi[j].act(seed_model.inertias[j].lever)
            np.testing.assert_allclose(c_world, seed_to_world(r_seed), rtol=0, atol=1e-14)


def test_gravity_holding_efforts_match_eq_15(seed_model, seed_params, rng):
    data = seed_model.createData()
    qs, _, _ = random_states(rng, 100)
    for q in qs:
        g = pin.computeGeneralizedGravity(seed_model, data, q)
        expected = holding_efforts(seed_params, q)
        np.testing.assert_allclose(g, expected, rtol=TIGHT, atol=TIGHT * np.abs(expected).max())


def test_kinetic_energy_from_crba_matches_the_seed(seed_model, seed_params, rng):
    data = seed_model.createData()
    qs, qds, _ = random_states(rng, 100)
    for q, qd in zip(qs, qds, strict=False):
        M = pin.crba(seed_model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        T = 0.5 * qd @ M @ qd
        assert T == pytest.approx(kinetic_energy(seed_params, q, qd), rel=TIGHT)


def test_kinetic_energy_check_can_fail(seed_model, seed_params):
    # With the seed's printed T1 (L1 not squared) the energies disagree: the test above has teeth.
    p, q, qd = seed_params, np.array(seed_params.q0), np.array([1.0, 0.0, 0.0])
    data = seed_model.createData()
    M = pin.crba(seed_model, data, q)
    T = 0.5 * qd @ (np.triu(M) + np.triu(M, 1).T) @ qd
    printed_T1 = 2.0 / 3.0 * p.m1 * p.L1 * qd[0] ** 2
    wrong = kinetic_energy(p, q, qd) - 2.0 / 3.0 * p.m1 * p.L1**2 + printed_T1
    assert abs(T - wrong) > 1.0


def test_other_parameters_flow_through(rng):
    p = Params(m3=7.0, L2=1.3, g=3.7)
    model = rrt_model(p)
    data = model.createData()
    for q in random_states(rng, 10)[0]:
        np.testing.assert_allclose(
            pin.computeGeneralizedGravity(model, data, q), holding_efforts(p, q), atol=1e-11
        )


def test_geometry_only_on_request(seed_model):
    geom = build_geometry(seed_model, urdf_xml())
    parents = sorted(seed_model.names[g.parentJoint] for g in geom.geometryObjects)
    # post on the base; rod and hinge on link 1; rod on link 2; the slider on link 3
    assert parents == ["q1", "q1", "q2", "q3", "universe"]


def test_bad_urdfs_are_refused(tmp_path):
    with pytest.raises(UrdfError, match="does not parse"):
        model_from_xml("<robot name='x'><link></robot>")
    no_inertia = '<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>'
    with pytest.raises(UrdfError, match="moves no mass"):
        model_from_xml(no_inertia)
    with pytest.raises(UrdfError, match="cannot read"):
        load_urdf_model(tmp_path / "missing.urdf")


@pytest.mark.parametrize(
    "old, new, words",
    [
        ('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>', "joint 'q2' has a zero axis"),
        ('<axis xyz="0 1 0"/>', '<axis xyz="0 nan 0"/>', "invalid axis"),
        ('<mass value="90.0"/>', '<mass value="-90.0"/>', "negative mass -90.0 kg"),
        ('ixx="5.0"', 'ixx="-5.0"', "negative principal moment of inertia -5.0"),
        ("</robot>", "", "does not parse"),
    ],
)
def test_urdfs_pinocchio_would_accept_silently_are_refused(old, new, words):
    xml = urdf_xml()
    assert old in xml
    with pytest.raises(UrdfError, match=words):
        model_from_xml(xml.replace(old, new))
