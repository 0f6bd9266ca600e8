"""Reference frames (0), (1), (2) and their unit vectors, eqs. (1)–(4).

Frame (0) [ı0, ȷ0, k0] is fixed, ı0 vertical (up). Frame (1) is attached to
link 1, turned by q1 [rad] about ı1 = ı0; frame (2) is attached to link 2,
turned by q2 [rad] about ȷ2 = ȷ1. Link 3 (the slider) moves along k2 and has
the orientation of (2).
"""

from __future__ import annotations

import sympy as sp
from sympy.physics.mechanics import ReferenceFrame

from rrt_pin.dynamics.symbolic.symbols import q1, q2

__all__ = [
    "R10",
    "R21",
    "frame0",
    "frame1",
    "frame2",
    "i0",
    "i1",
    "i2",
    "j0",
    "j1",
    "j2",
    "k0",
    "k1",
    "k2",
]

_LATEX = (r"\hat{\imath}", r"\hat{\jmath}", r"\hat{k}")


def _frame(n: int) -> ReferenceFrame:
    return ReferenceFrame(
        f"F{n}",
        indices=(f"i{n}", f"j{n}", f"k{n}"),
        latexs=tuple(f"{u}_{n}" for u in _LATEX),
    )


#: The fixed frame (0).
frame0 = _frame(0)
#: Frame (1) of link 1: ı1 = ı0, ȷ1 = c1 ȷ0 + s1 k0, k1 = −s1 ȷ0 + c1 k0 (eq. 1).
frame1 = _frame(1)
frame1.orient_axis(frame0, frame0.x, q1)
#: Frame (2) of links 2 and 3: ı2 = c2 ı1 − s2 k1, ȷ2 = ȷ1, k2 = s2 ı1 + c2 k1 (eq. 3).
frame2 = _frame(2)
frame2.orient_axis(frame1, frame1.y, q2)

i0, j0, k0 = frame0.x, frame0.y, frame0.z
i1, j1, k1 = frame1.x, frame1.y, frame1.z
i2, j2, k2 = frame2.x, frame2.y, frame2.z

#: Eq. (2): [ı1 ȷ1 k1]ᵀ = R10 [ı0 ȷ0 k0]ᵀ.
R10: sp.Matrix = frame1.dcm(frame0)
#: Eq. (4): [ı2 ȷ2 k2]ᵀ = R21 [ı1 ȷ1 k1]ᵀ.
R21: sp.Matrix = frame2.dcm(frame1)
