"""The chapter's motion (eq. 30) and feedback law (eq. 31), written out for ``--help``.

Plain text, no imports: building the parser stays cheap. The same formulas are in
the README ("The chapter, eq. (30) and eq. (31)"); tests check both name them.
"""

from __future__ import annotations

SOURCE = (
    'The chapter: "RRT Robot: Lagrange and Kane Equations of Motion", a textbook chapter\n'
    "modelling a robot arm with two revolute joints and one slider (q1, q2 [rad], q3 [m])."
)

EQ30 = f"""{SOURCE}
Eq. (30), its rest-to-rest motion, for each joint r = 1, 2, 3 and 0 <= t <= Tp:
  q_r(t) = q_r0 + (q_rf - q_r0)/Tp * [t - Tp/(2*pi) * sin(2*pi*t/Tp)]
so q_r(Tp) = q_rf, with zero velocity and acceleration at both ends (rest after Tp).
The chapter's values: q0 = (pi/18, pi/6, 0.25 m), qf = (pi/3, pi/3, 0.3 m), Tp = 15 s
(--set q10=..., q1f=..., Tp=...). With --urdf the same profile drives every joint
from --q0 to --qf."""

EQ31 = f"""{SOURCE}
Eq. (31), its feedback law (efforts T01x, T12y [N*m] and F23z [N]):
  T01x = -beta01*qd1 - gamma01*(q1 - q1f)
  T12y = -beta12*qd2 - gamma12*(q2 - q2f) + g*m2*L2*cos(q2) + g*m3*cos(q2)*(L2 + q3)
  F23z = -beta23*qd3 - gamma23*(q3 - q3f) + g*m3*sin(q2)
The chapter's gains: beta01 = 450 N*m*s/rad, gamma01 = 300 N*m/rad, beta12 = 200
N*m*s/rad, gamma12 = 300 N*m/rad, beta23 = 150 N*s/m, gamma23 = 50 N/m (--set
beta01=...); it starts at q0 = (pi/18, pi/6, 0.25 m) at rest and aims at qf."""
