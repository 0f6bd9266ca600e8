"""Benchmarks: one module a question, each timing both sides in one interleaved run.

Run one from the checkout as ``.venv/bin/python -m scripts.bench.NAME [--help]``;
the figures in docs/benchmarks.md come from these. Shared timing helpers are in
:mod:`scripts.bench.common`.

- ``accuracy``: the accuracy catalogue: the defaults' global error, its estimate and cost;
- ``aot``: ahead-of-time compiled code against the JIT cache: what a process pays;
- ``auto``: the costs the default backend (``auto``) compares, next to the registry's values;
- ``batch_threads``: compiled batches on one thread, two and the default (a busy core too);
- ``defaults``: ``simulate`` and ``inverse_dynamics`` as called plainly (the default backend);
- ``cache``: the compiled backend's import, cache load and compilation;
- ``compiled``: the compiled backend against its baselines (direct, inverse, batches);
- ``direct``: direct dynamics of the chapter's run against the plain scipy baseline;
- ``estimate_grid``: a candidate error estimate (Richardson on DOP853's step grid), measured;
- ``forward``: generated forward dynamics of UR5 and Panda: ABA, CRBA + LDLᵀ, ``pin.aba``;
- ``inverse``: inverse dynamics of the chapter's run: speed and agreement;
- ``kernel``: the inverse-dynamics kernels: ns a sample, flops, the FMA rate;
- ``peers``: rrt-pin against MuJoCo, Drake and scipy at matched accuracy;
- ``physical_cost``: the URDF's limits, damping and friction on a run that hits no limit;
- ``rnea``: the generated RNEA of any robot, vectorised: ns/sample, flops, the machine's rates;
- ``robot_limits_peers``: passive UR5 and Panda at their joint limits against MuJoCo;
- ``robot_peers``: UR5 and Panda batches against ``mujoco.rollout`` at matched error;
- ``startup``: whole-process time of the CLI's two jobs against ``import pinocchio``;
- ``stream``: peak memory and rows/s of streamed ``rrt-pin inverse`` outputs;
- ``sweep``: throughput, scaling and memory of sweeps;
- ``threads``: batched Pinocchio inverse dynamics and its thread choice.

Every benchmark times the backend it names; a call that names none times the engine of
record: importing this package sets ``RRT_PIN_BACKEND=pinocchio`` unless it is set (the
default backend, ``auto``, would run compiled code wherever it is built, which depends on
the machine's cache). ``defaults`` and ``sweep`` remove it: they time the default itself.
"""

import os

os.environ.setdefault("RRT_PIN_BACKEND", "pinocchio")
