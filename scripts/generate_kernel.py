#!/usr/bin/env python3
"""Regenerate rrt_pin/dynamics/_kernel_terms.py from the sympy derivation (``--check`` only compares).

Same as ``python -m rrt_pin.dynamics.symbolic.codegen``; run it after changing rrt_pin/dynamics/symbolic.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rrt_pin.dynamics.symbolic.codegen import main  # noqa: E402

if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
