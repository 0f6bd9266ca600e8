"""The CLI's subcommands, one module each.

Each module defines ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``. Importing a command module must stay cheap: heavy
imports (pinocchio, matplotlib, meshcat, sympy) belong inside ``run``.
"""

#: Subcommands in the order ``--help`` lists them; a missing module is skipped.
COMMANDS = ("urdf", "joints", "equations", "inverse", "simulate", "sweep", "view", "bench")
