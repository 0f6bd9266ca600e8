"""URDF validation with the standard library, before Pinocchio sees the text.

Pinocchio parses URDFs with urdfdom, which drops an element it cannot parse
(an ``<inertial>`` whose mass reads ``ninety``: the link becomes massless),
prints the reason on stderr and goes on: the run then succeeds with the wrong
physics. :func:`check_urdf_xml` refuses such files first, with one line naming
the link or joint, the element and the attribute, e.g.::

    link 'link1' <inertial><mass value="ninety">: not a number

It also refuses what could hang or crash the process: a document type
declaration (``<!DOCTYPE``, ``<!ENTITY``: the "billion laughs" and external
entities), text beyond :data:`MAX_URDF_BYTES`, more than :data:`MAX_JOINTS`
joints (a 10,000-joint chain crashes urdfdom) and elements nested more than
:data:`MAX_DEPTH` deep; and bodies that cannot exist: a negative mass, or
principal moments of inertia that are negative or break the triangle
inequality (each at most the sum of the other two).

``<mimic>`` joints: Pinocchio's model (as built here) treats a mimic joint as
an independent joint, so e.g. the Panda's two fingers move independently. By
default (``mimic="warn"``) they are loaded that way with a warning on the
``rrt_pin`` logger naming them; ``mimic="refuse"`` refuses them.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from typing import Literal
from xml.parsers import expat

from rrt_pin.core._logging import logger
from rrt_pin.core.errors import UrdfError

__all__ = [
    "INERTIA_RTOL",
    "MAX_DEPTH",
    "MAX_JOINTS",
    "MAX_URDF_BYTES",
    "MimicPolicy",
    "check_urdf_xml",
    "mimic_joints",
]

#: Largest URDF accepted [bytes of a file, characters of a text].
MAX_URDF_BYTES = 20 << 20
#: Most ``<joint>`` elements accepted in a URDF (links: one more).
MAX_JOINTS = 1000
#: Deepest element nesting accepted (URDFs nest about 5 deep).
MAX_DEPTH = 64
#: Relative tolerance (of the trace) of the triangle inequality of principal moments;
#: URDFs print rounded inertias, so it is looser than ``Params``' 1e-12.
INERTIA_RTOL = 1e-5

#: What to do with ``<mimic>`` joints: warn and load them as independent
#: joints, refuse the URDF, or load them silently (``allow``).
MimicPolicy = Literal["warn", "refuse", "allow"]

_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_ATTRIBUTE_VALUE = re.compile(r"""=[ \t\r\n]*(?:"[^"<]*"|'[^'<]*')""")
_RAW_WHITESPACE_VALUE = re.compile(
    r"""=[ \t\r\n]*(?:"[^"<]*[\t\r\n][^"<]*"|'[^'<]*[\t\r\n][^'<]*')"""
)
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)\Z", re.IGNORECASE)

# (element path below the link or joint, {attribute: count of numbers})
_ORIGIN = {"xyz": 3, "rpy": 3}
_GEOMETRY = (
    ("geometry/box", {"size": 3}),
    ("geometry/cylinder", {"radius": 1, "length": 1}),
    ("geometry/sphere", {"radius": 1}),
    ("geometry/capsule", {"radius": 1, "length": 1}),
    ("geometry/mesh", {"scale": 3}),
    ("material/color", {"rgba": 4}),
)
_LINK_NUMBERS = (
    ("inertial/origin", _ORIGIN),
    ("inertial/mass", {"value": 1}),
    ("inertial/inertia", dict.fromkeys(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), 1)),
    ("visual/origin", _ORIGIN),
    *((f"visual/{path}", attrs) for path, attrs in _GEOMETRY),
    ("collision/origin", _ORIGIN),
    *((f"collision/{path}", attrs) for path, attrs in _GEOMETRY[:-1]),
)
_JOINT_NUMBERS = (
    ("origin", _ORIGIN),
    ("axis", {"xyz": 3}),
    ("limit", {"lower": 1, "upper": 1, "effort": 1, "velocity": 1}),
    ("dynamics", {"damping": 1, "friction": 1}),
    (
        "safety_controller",
        {"soft_lower_limit": 1, "soft_upper_limit": 1, "k_position": 1, "k_velocity": 1},
    ),
    ("calibration", {"rising": 1, "falling": 1, "reference_position": 1}),
    ("mimic", {"multiplier": 1, "offset": 1}),
)


class _Refused(Exception):
    """Raised inside expat handlers to stop the pre-scan."""


def check_urdf_xml(xml: str, *, mimic: MimicPolicy = "warn") -> ET.Element:
    """Validate URDF text before Pinocchio parses it.

    Args:
        xml: the URDF text.
        mimic: ``"warn"`` (default) loads ``<mimic>`` joints as independent
            joints with a warning naming them, ``"refuse"`` raises, ``"allow"``
            says nothing.

    Returns:
        The parsed ``<robot>`` element.

    Raises:
        UrdfError: one line naming the problem (and the link or joint, the
            element and the attribute for a bad number).
    """
    if not isinstance(xml, str):
        raise UrdfError(f"URDF must be text, not {type(xml).__name__}")
    if len(xml) > MAX_URDF_BYTES:
        raise UrdfError(
            f"URDF text is {len(xml) / (1 << 20):.3g} M characters, "
            f"larger than the {MAX_URDF_BYTES >> 20} MB allowed"
        )
    _prescan(xml)
    try:
        root = ET.fromstring(_keep_attribute_whitespace(xml))
    except ET.ParseError as e:
        raise UrdfError(f"URDF does not parse: {e}") from None
    if root.tag != "robot":
        raise UrdfError(f"URDF root element is <{root.tag}>, not <robot>")
    for element in root.findall("material"):
        _check_numbers(f"material {element.get('name')!r}", element, (("color", {"rgba": 4}),))
    for link in root.findall("link"):
        owner = f"link {link.get('name')!r}"
        _check_numbers(owner, link, _LINK_NUMBERS)
        for inertial in link.findall("inertial"):
            _check_inertial(owner, inertial)
    for joint in root.findall("joint"):
        _check_joint(joint)
    _check_mimic(root, mimic)
    return root


def mimic_joints(root: ET.Element) -> list[tuple[str, str]]:
    """The ``(joint, mimicked joint)`` names of the ``<mimic>`` joints of a ``<robot>``."""
    out = []
    for joint in root.findall("joint"):
        element = joint.find("mimic")
        if element is not None:
            out.append((str(joint.get("name")), str(element.get("joint"))))
    return out


# ---------------------------------------------------------------------------
def _prescan(xml: str) -> None:
    """One streaming pass: no DTD or entity, nesting depth, joint and link counts."""
    parser = expat.ParserCreate()
    depth = 0
    counts = {"joint": 0, "link": 0}
    caps = {"joint": MAX_JOINTS, "link": MAX_JOINTS + 1}

    def doctype(*_: object) -> None:
        raise _Refused(
            "URDF has a document type declaration (<!DOCTYPE>); entities and DTDs are not accepted"
        )

    def entity(name: str, *_: object) -> None:
        raise _Refused(f"URDF declares an entity {name!r} (<!ENTITY>); entities are not accepted")

    def start(tag: str, _attrs: object) -> None:
        nonlocal depth
        depth += 1
        if depth > MAX_DEPTH:
            raise _Refused(f"URDF elements are nested more than {MAX_DEPTH} deep")
        if depth == 2 and tag in counts:
            counts[tag] += 1
            if counts[tag] > caps[tag]:
                raise _Refused(
                    f"URDF has more than {caps[tag]} <{tag}> elements; "
                    f"at most {MAX_JOINTS} joints are supported"
                )

    def end(_tag: str) -> None:
        nonlocal depth
        depth -= 1

    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(xml, True)
    except _Refused as e:
        raise UrdfError(str(e)) from None
    except expat.ExpatError as e:
        raise UrdfError(f"URDF does not parse: {e}") from None
    except (RecursionError, MemoryError):  # pragma: no cover - bounded by the caps
        raise UrdfError("URDF does not parse: too large or nested too deeply") from None


def _keep_attribute_whitespace(xml: str) -> str:
    """``xml`` with tabs and line breaks inside attribute values as character references.

    An XML parser turns them into spaces (attribute-value normalization), but
    urdfdom's does not, and then fails to read ``xyz`` with a tab as numbers;
    written as ``&#9;`` they reach the checks below as they reach urdfdom.
    """
    if not _RAW_WHITESPACE_VALUE.search(xml):
        return xml

    def escape(match: re.Match[str]) -> str:
        text = match.group(0)
        return text.replace("\t", "&#9;").replace("\n", "&#10;").replace("\r", "&#13;")

    return _ATTRIBUTE_VALUE.sub(escape, xml)


def _check_numbers(
    owner: str,
    parent: ET.Element,
    table: tuple[tuple[str, dict[str, int]], ...],
    hints: dict[str, str] | None = None,
) -> None:
    """Refuse the first attribute of ``table`` under ``parent`` that is not finite numbers.

    ``table`` lists (element path, {attribute: count}); ``hints`` prefixes the
    problem for some element tags (e.g. ``{"axis": "invalid axis: "}``).
    """
    for path, attrs in table:
        for element in parent.findall(path):
            for attr, count in attrs.items():
                text = element.get(attr)
                if text is None:
                    continue
                problem = _number_problem(text, count)
                if problem:
                    where = "".join(f"<{p}>" for p in path.split("/")[:-1])
                    hint = (hints or {}).get(element.tag, "")
                    raise UrdfError(
                        f"{owner} {where}<{element.tag} {attr}={_quote(text)}>: {hint}{problem}"
                    )


def _number_problem(text: str, count: int) -> str | None:
    """Why urdfdom would not read ``text`` as ``count`` finite numbers (None if it would)."""
    if count == 1:
        if text != text.rstrip():
            return "not a number (trailing spaces)"
        return _scalar_problem(text.lstrip())
    pieces = [p for p in text.split(" ") if p]
    for piece in pieces:
        problem = _scalar_problem(piece.lstrip())  # urdfdom skips leading whitespace only
        if problem:
            spaces = " (numbers are separated by spaces)" if re.search(r"[\s,;]", piece) else ""
            return f"{_quote(piece)} is {problem}{spaces}"
    if len(pieces) != count:
        return f"expected {count} numbers, got {len(pieces)}"
    return None


def _scalar_problem(text: str) -> str | None:
    if _NONFINITE.match(text):
        return "not finite"
    if not _NUMBER.match(text):
        return "not a number"
    value = float(text)
    if not math.isfinite(value):
        return "not finite (beyond ±1.8e308)"
    if value == 0.0 and re.search(r"[1-9]", text.split("e")[0].split("E")[0]):
        return "not a number (underflows to 0)"
    return None


def _quote(text: str, limit: int = 40) -> str:
    shown = text if len(text) <= limit else text[: limit - 1] + "…"
    return '"' + shown.replace("\n", "\\n").replace("\t", "\\t") + '"'


def _check_inertial(owner: str, inertial: ET.Element) -> None:
    mass = inertial.find("mass")
    if mass is None or mass.get("value") is None:
        raise UrdfError(f'{owner} <inertial> has no <mass value="...">')
    m = float(mass.get("value", "0"))
    if m < 0.0:
        raise UrdfError(f"{owner} <inertial><mass>: negative mass {m!r} kg")
    inertia = inertial.find("inertia")
    names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    if inertia is None or any(inertia.get(n) is None for n in names):
        raise UrdfError(
            f"{owner} <inertial> needs <inertia ixx ixy ixz iyy iyz izz> (all six attributes)"
        )
    xx, xy, xz, yy, yz, zz = (float(inertia.get(n, "0")) for n in names)
    moments = _eigenvalues([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if moments is None:
        raise UrdfError(f"{owner} <inertial><inertia>: too large (its moments overflow)")
    trace = sum(moments)
    if moments[0] < -INERTIA_RTOL * max(trace, 0.0):
        raise UrdfError(
            f"{owner} <inertial><inertia>: negative principal moment of inertia "
            f"{moments[0]!r} kg·m²"
        )
    if moments[2] > moments[0] + moments[1] + INERTIA_RTOL * trace:
        a, b, c = (f"{v:.6g}" for v in moments)
        raise UrdfError(
            f"{owner} <inertial><inertia>: principal moments {a}, {b}, {c} kg·m² break the "
            f"triangle inequality ({c} > {a} + {b}): no body has this inertia"
        )


def _eigenvalues(matrix: list[list[float]]) -> list[float] | None:
    """Ascending eigenvalues of a symmetric 3×3 matrix (None if not finite)."""
    import numpy as np

    with np.errstate(all="ignore"):
        values = np.linalg.eigvalsh(np.array(matrix, dtype=float))
    if not np.isfinite(values).all():
        return None
    return [float(v) for v in values]


def _check_joint(joint: ET.Element) -> None:
    name = joint.get("name")
    owner = f"joint {name!r}"
    kind = joint.get("type")
    if kind not in _JOINT_TYPES:
        raise UrdfError(f"{owner} has an unknown type {kind!r}; valid: {', '.join(_JOINT_TYPES)}")
    _check_numbers(owner, joint, _JOINT_NUMBERS, {"axis": "invalid axis: "})
    _check_limits(owner, joint)
    axis = joint.find("axis")
    if kind in ("fixed", "floating", "planar") or axis is None:
        return
    text = axis.get("xyz", "1 0 0")
    if math.hypot(*(float(v) for v in text.split())) < 1e-12:
        raise UrdfError(f"{owner} has a zero axis xyz={text!r}")


def _check_limits(owner: str, joint: ET.Element) -> None:
    """Refuse limits no joint can have: lower > upper, a negative effort, velocity, damping or friction.

    Pinocchio would keep some silently and refuse others in its own words.
    """
    limit, dynamics = joint.find("limit"), joint.find("dynamics")
    if limit is not None and limit.get("lower") is not None and limit.get("upper") is not None:
        lower, upper = float(limit.get("lower", "0")), float(limit.get("upper", "0"))
        if lower > upper:
            raise UrdfError(
                f"{owner} <limit lower upper>: lower {lower:.6g} is above upper {upper:.6g}"
            )
    for element, attrs in ((limit, ("effort", "velocity")), (dynamics, ("damping", "friction"))):
        for attr in attrs:
            text = None if element is None else element.get(attr)
            if text is not None and float(text) < 0.0:
                raise UrdfError(f"{owner} <{element.tag} {attr}>: negative, {float(text):.6g}")


def _check_mimic(root: ET.Element, policy: MimicPolicy) -> None:
    if policy not in ("warn", "refuse", "allow"):
        raise ValueError(f"mimic={policy!r}: expected 'warn', 'refuse' or 'allow'")
    pairs = mimic_joints(root)
    if not pairs or policy == "allow":
        return
    listed = ", ".join(f"{j!r} (mimics {t!r})" for j, t in pairs)
    if policy == "refuse":
        raise UrdfError(
            f"URDF has <mimic> joints, which the model would move independently: {listed}"
        )
    logger.warning(
        "URDF <mimic> joints are modelled as independent joints (give them the motion "
        "of the joint they mimic): %s",
        listed,
    )
