"""URDF validation before Pinocchio, capped reads of input files, and stderr capture."""

from __future__ import annotations

import logging
import os
import stat
import threading

import pinocchio as pin
import pytest

from rrt_pin.cli.runfile import load_runfile
from rrt_pin.core._quiet import captured_stderr
from rrt_pin.core.errors import RunFileError, UrdfError
from rrt_pin.io._read import read_text_capped
from rrt_pin.robot.model import build_geometry, load_urdf_model, model_from_xml
from rrt_pin.robot.urdf import urdf_xml
from rrt_pin.robot.urdf_check import MAX_DEPTH, MAX_JOINTS, check_urdf_xml, mimic_joints
from tests.bad_inputs import _LAUGHS, chain_urdf
from tests.support import robot_urdf

GOOD = urdf_xml()
MASS = '<mass value="90.0"/>'
INERTIAL_ORIGIN = '<origin xyz="0 0 0.4" rpy="0 0 0"/>\n      <mass'


@pytest.fixture
def no_pinocchio(monkeypatch):
    """Make any call of Pinocchio's URDF parser fail the test: the refusal must come first."""

    def called(*_args, **_kwargs):
        raise AssertionError("Pinocchio was called on a URDF that should have been refused")

    monkeypatch.setattr(pin, "buildModelFromXML", called)
    monkeypatch.setattr(pin, "buildGeomFromUrdfString", called)


BAD_NUMBERS = [
    (
        MASS,
        '<mass value="ninety"/>',
        "link 'link1' <inertial><mass value=\"ninety\">: not a number",
    ),
    (MASS, '<mass value="nan"/>', "link 'link1' <inertial><mass value=\"nan\">: not finite"),
    (MASS, '<mass value="1e999"/>', "not finite"),
    (MASS, '<mass value="1e-400"/>', "underflows"),
    (MASS, '<mass value="90 "/>', "trailing spaces"),
    (MASS, '<mass value="9_0"/>', "not a number"),
    (MASS, '<mass value="-90.0"/>', "link 'link1' <inertial><mass>: negative mass -90.0 kg"),
    (MASS, "", "link 'link1' <inertial> has no <mass"),
    (
        INERTIAL_ORIGIN,
        INERTIAL_ORIGIN.replace("0 0 0.4", "0 nan 0.4"),
        'link \'link1\' <inertial><origin xyz="0 nan 0.4">: "nan" is not finite',
    ),
    (INERTIAL_ORIGIN, INERTIAL_ORIGIN.replace("0 0 0.4", "0\t0\t0.4"), "separated by spaces"),
    (INERTIAL_ORIGIN, INERTIAL_ORIGIN.replace("0 0 0.4", "0 0\n 0.4"), "separated by spaces"),
    (MASS, '<mass value="90\n"/>', "trailing spaces"),
    (INERTIAL_ORIGIN, INERTIAL_ORIGIN.replace("0 0 0.4", "0 0"), "expected 3 numbers, got 2"),
    ('ixx="5.0"', 'ixx="five"', "link 'link3' <inertial><inertia ixx=\"five\">: not a number"),
    (' iyz="0" izz="1.0"', ' izz="1.0"', "link 'link3' <inertial> needs <inertia"),
    ('ixx="5.0"', 'ixx="-5.0"', "negative principal moment of inertia -5.0"),
    ('izz="1.0"', 'izz="10.0"', "link 'link3' <inertial><inertia>: principal moments 4, 5, 10"),
    (
        '<axis xyz="0 1 0"/>',
        '<axis xyz="0 nan 0"/>',
        "joint 'q2' <axis xyz=\"0 nan 0\">: invalid axis",
    ),
    ('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>', "joint 'q2' has a zero axis"),
    ('<origin xyz="0 0 0.8" rpy="0 0 0"/>\n    <axis', '<origin rpy="0 0"/>\n    <axis', "rpy"),
    ('effort="1e9"', 'effort="lots"', "joint 'q1' <limit effort=\"lots\">: not a number"),
    ('lower="-110.00000000000001"', 'lower="-inf"', "joint 'q3' <limit lower=\"-inf\">"),
    ("</joint>", '<dynamics damping="x"/></joint>', "joint 'mount' <dynamics damping=\"x\">"),
    ('radius="0.048"', 'radius="thick"', "link 'link1' <visual><geometry><cylinder radius="),
    ('rgba="0.55 0.57 0.6 1"', 'rgba="0.55 0.57 0.6"', "material 'grey' <color rgba="),
    ('type="revolute"', 'type="hinge"', "joint 'q1' has an unknown type 'hinge'"),
]


@pytest.mark.parametrize("old, new, words", BAD_NUMBERS, ids=[w for _, _, w in BAD_NUMBERS])
def test_bad_numbers_are_refused_before_pinocchio(old, new, words, no_pinocchio):
    assert old in GOOD
    with pytest.raises(UrdfError) as info:
        model_from_xml(GOOD.replace(old, new, 1))
    assert words in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("value", ["ninety", "nan", "1e-400"])
def test_pinocchio_alone_drops_such_an_inertial(value, capfd):
    # Why the check exists: urdfdom prints an error and returns a massless link.
    model = pin.buildModelFromXML(GOOD.replace(MASS, f'<mass value="{value}"/>'))
    assert model.inertias[1].mass == 0.0
    if value != "1e-400":  # an underflow it drops without a word
        assert "link1" in capfd.readouterr().err


@pytest.mark.parametrize(
    "prolog, words",
    [
        (_LAUGHS, "entities and DTDs are not accepted"),
        ('<!DOCTYPE robot SYSTEM "file:///etc/passwd">\n', "document type declaration"),
        ("<!DOCTYPE robot>\n", "document type declaration"),
    ],
)
def test_dtds_and_entities_are_refused(prolog, words, no_pinocchio):
    xml = GOOD.replace("<robot ", prolog + "<robot ", 1)
    with pytest.raises(UrdfError, match=words):
        model_from_xml(xml)
    with pytest.raises(UrdfError, match=words):
        build_geometry(None, xml)  # type: ignore[arg-type]


def test_an_undeclared_entity_does_not_parse(no_pinocchio):
    with pytest.raises(UrdfError, match="does not parse: undefined entity"):
        model_from_xml(GOOD.replace('name="rrt"', 'name="&x;"'))


def test_ten_thousand_joints_are_refused_before_pinocchio(tmp_path, no_pinocchio):
    # Pinocchio segfaults (exit 139) on this chain: it must never see it.
    path = tmp_path / "chain.urdf"
    path.write_text(chain_urdf(10_000))
    with pytest.raises(UrdfError, match=f"at most {MAX_JOINTS} joints are supported"):
        load_urdf_model(path)


def test_joint_cap_counts_joints():
    xml = chain_urdf(MAX_JOINTS).replace('<link name="l0"/>', "", 1)  # 1000 links, 1000 joints
    xml = xml.replace("</robot>", '<joint name="extra" type="fixed"/></robot>')
    with pytest.raises(UrdfError, match="more than 1000 <joint> elements"):
        check_urdf_xml(xml)


def test_a_thousand_joint_chain_still_loads():
    model = model_from_xml(chain_urdf(MAX_JOINTS))
    assert model.nv == MAX_JOINTS


def test_deep_nesting_is_refused(no_pinocchio):
    deep = "<a>" * (MAX_DEPTH + 1) + "</a>" * (MAX_DEPTH + 1)
    with pytest.raises(UrdfError, match=f"nested more than {MAX_DEPTH} deep"):
        model_from_xml(GOOD.replace("</robot>", deep + "</robot>"))


def test_text_larger_than_the_cap_is_refused(monkeypatch, no_pinocchio):
    import rrt_pin.robot.urdf_check as check

    monkeypatch.setattr(check, "MAX_URDF_BYTES", 1000)
    with pytest.raises(UrdfError, match="larger than"):
        model_from_xml(GOOD)


def test_good_urdfs_still_load():
    assert model_from_xml(GOOD).nv == 3
    assert load_urdf_model(robot_urdf("ur5")).nv == 6


@pytest.mark.parametrize("xyz", ["\n0 0 0.4", "0  0 0.4", " 0 0 +0.4 "])
def test_whitespace_urdfdom_reads_is_accepted(xyz):
    xml = GOOD.replace(INERTIAL_ORIGIN, INERTIAL_ORIGIN.replace("0 0 0.4", xyz))
    assert model_from_xml(xml).inertias[1].lever[2] == 0.4


def test_transmission_joints_are_not_checked_as_joints():
    transmission = (
        '<transmission name="t"><type>x</type><joint name="q1">'
        "<hardwareInterface>EffortJointInterface</hardwareInterface></joint></transmission>"
    )
    assert model_from_xml(GOOD.replace("</robot>", transmission + "</robot>")).nv == 3


# mimic joints ---------------------------------------------------------------
MIMIC = GOOD.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 1 0"/><mimic joint="q1"/>')


def test_mimic_joints_warn_by_default_and_load_independently(caplog):
    with caplog.at_level(logging.WARNING, logger="rrt_pin"):
        model = model_from_xml(MIMIC)
    assert model.nv == 3
    assert "'q2' (mimics 'q1')" in caplog.text and "independent" in caplog.text


def test_mimic_joints_can_be_refused(no_pinocchio):
    with pytest.raises(UrdfError, match="<mimic> joints.*'q2' \\(mimics 'q1'\\)"):
        model_from_xml(MIMIC, mimic="refuse")


def test_pandas_fingers_are_named(caplog):
    path = robot_urdf("panda")
    with caplog.at_level(logging.WARNING, logger="rrt_pin"):
        assert load_urdf_model(path).nv == 9
    assert "'panda_finger_joint2' (mimics 'panda_finger_joint1')" in caplog.text
    with pytest.raises(UrdfError, match="panda_finger_joint2"):
        load_urdf_model(path, mimic="refuse")
    assert mimic_joints(check_urdf_xml(path.read_text(), mimic="allow")) == [
        ("panda_finger_joint2", "panda_finger_joint1")
    ]


# capped reads -----------------------------------------------------------------
def _char_device(path):
    """A private /dev/zero node (major 1, minor 5); skips where mknod is not permitted."""
    try:
        os.mknod(path, 0o600 | stat.S_IFCHR, os.makedev(1, 5))
    except PermissionError:
        pytest.skip("creating a device node needs privileges")
    return path


def test_a_zero_device_is_refused_at_once(tmp_path, no_pinocchio):
    node = _char_device(tmp_path / "zero")
    with pytest.raises(UrdfError, match="zero.*character device|cannot read URDF"):
        load_urdf_model(node)
    with pytest.raises(RunFileError, match="zero.*character device|cannot read run file"):
        load_runfile(node)


def test_a_fifo_is_read_only_up_to_the_cap(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    writer_error = []

    def write(n: int) -> None:
        try:
            with open(fifo, "wb") as fh:
                fh.write(b"x" * n)
        except BrokenPipeError:
            pass  # the reader stopped at the cap and closed
        except OSError as e:  # pragma: no cover
            writer_error.append(e)

    thread = threading.Thread(target=write, args=(10_000_000,), daemon=True)
    thread.start()
    with pytest.raises(UrdfError, match="larger than the 1 kB allowed"):
        read_text_capped(fifo, cap=1024, what="URDF", error=UrdfError)
    thread.join(10)
    assert not writer_error and not thread.is_alive()

    thread = threading.Thread(target=write, args=(1024,), daemon=True)
    thread.start()
    assert read_text_capped(fifo, cap=1024, what="URDF", error=UrdfError) == "x" * 1024
    thread.join(10)


def test_regular_files_larger_than_the_cap_are_refused_from_their_size(tmp_path):
    path = tmp_path / "big.urdf"
    with open(path, "wb") as fh:
        fh.truncate((20 << 20) + 1)
    with pytest.raises(UrdfError, match="20971521 bytes, larger than the 20 MB allowed"):
        load_urdf_model(path)


def test_folders_and_non_utf8_are_refused(tmp_path):
    with pytest.raises(UrdfError, match="it is a folder"):
        load_urdf_model(tmp_path)
    path = tmp_path / "latin1.urdf"
    path.write_bytes(GOOD.replace("RRT arm", "caf\xe9").encode("latin-1"))
    with pytest.raises(UrdfError, match="not UTF-8 text \\(byte 0xe9"):
        load_urdf_model(path)


def test_byte_order_marks_are_accepted(tmp_path):
    scene = tmp_path / "bom.toml"
    scene.write_bytes(b"\xef\xbb\xbf" + b'[params]\nm3 = 50\nq1f = "pi/4"\n')
    assert load_runfile(scene).params == {"m3": 50.0, "q1f": pytest.approx(0.7853981633974483)}
    urdf = tmp_path / "bom.urdf"
    urdf.write_bytes(b"\xef\xbb\xbf" + GOOD.encode())
    assert load_urdf_model(urdf).nv == 3


@pytest.mark.parametrize(
    "text, words",
    [
        ("[options]\nq0 = " + "[" * 3000 + "]" * 3000 + "\n", "nested too deeply"),
        ("[params]\nm3 = 1" + "0" * 400 + "\n", "beyond TOML's 64-bit range"),
        ("[options]\nn = 1" + "0" * 30 + "\n", "[options] n is an integer"),
        ('[params]\nm3 = "9**9**9"\n', "m3='9**9**9' is not a number (overflows"),
    ],
)
def test_hostile_run_files_get_one_line(tmp_path, text, words):
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(RunFileError) as info:
        load_runfile(path)
    assert words in str(info.value) and "\n" not in str(info.value)


# stderr capture ---------------------------------------------------------------
def test_captured_stderr_keeps_fd_2_quiet_and_logs_at_debug(capfd, caplog):
    with caplog.at_level(logging.DEBUG, logger="rrt_pin"):
        with captured_stderr("libfoo") as said:
            os.write(2, b"Error: something in C++\n  at line 3\n")
        os.write(2, b"after\n")
    assert said.text.startswith("Error: something in C++") and said.first_line().endswith("C++")
    assert capfd.readouterr().err == "after\n"
    assert "libfoo said on stderr: Error: something in C++" in caplog.text


def test_urdfdom_chatter_is_captured_and_ends_the_error(capfd, caplog):
    with caplog.at_level(logging.DEBUG, logger="rrt_pin"):
        with pytest.raises(UrdfError, match="does not parse.*No name given for the robot"):
            model_from_xml(GOOD.replace('<robot name="rrt">', "<robot>"))
    assert capfd.readouterr().err == ""
    assert "urdfdom said on stderr" in caplog.text
