"""Numbers that summarise a run: settling times, distance to the target, peaks.

Pure functions of arrays (SI units), shared by the CLI's summaries and the library.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["SETTLING_BAND", "settling_times"]

#: The share of the initial distance to qf inside which a joint counts as settled.
SETTLING_BAND = 0.02


def settling_times(
    t: np.ndarray, q: np.ndarray, q0: Any, qf: Any, band: float = SETTLING_BAND
) -> list[float | None]:
    """Per joint, the first sample time [s] after which |q − qf| stays within ``band``·|q0 − qf|.

    A joint that starts at its target uses ``band`` times its largest excursion.
    None: still outside the band at the last sample.
    """
    dist = np.abs(np.asarray(q) - np.asarray(qf))
    out: list[float | None] = []
    for k in range(dist.shape[1]):
        scale = abs(float(q0[k]) - float(qf[k])) or float(dist[:, k].max())
        outside = np.flatnonzero(dist[:, k] > band * scale)
        if outside.size == 0:
            out.append(float(t[0]))
        elif outside[-1] == t.size - 1:
            out.append(None)
        else:
            out.append(float(t[outside[-1] + 1]))
    return out
