"""Inverse dynamics and the equations behind it.

* :mod:`~rrt_pin.dynamics.inverse`: :func:`inverse_dynamics`, the front door of every
  backend (it reaches the compiled one through :mod:`rrt_pin.core.backends`);
* :mod:`~rrt_pin.dynamics.wrenches`: the joints' reaction wrenches;
* :mod:`~rrt_pin.dynamics.trajectory`: motions (the chapter's rest-to-rest, eq. (30));
* :mod:`~rrt_pin.dynamics.sampled`: a user's motion from samples or a file (``read_motion``),
  its derivatives from a spline where they are not given;
* :mod:`~rrt_pin.dynamics.kinematics`: frames along a motion, their velocities and Jacobians;
* :mod:`~rrt_pin.dynamics.derivatives`: ∂τ/∂(q, q̇, q̈) and ∂q̈/∂(q, q̇, τ), for optimisers;
* :mod:`~rrt_pin.dynamics.kernel`: the chapter arm's closed-form M, b, G and their
  numpy wrappers, over the generated expressions :mod:`~rrt_pin.dynamics._kernel_terms`;
* :mod:`~rrt_pin.dynamics.rnea_source`, :mod:`~rrt_pin.dynamics.forward_source`: the
  source of any robot's unrolled RNEA, CRBA and ABA (compiled by :mod:`rrt_pin.compiled`);
* :mod:`~rrt_pin.dynamics.symbolic`: the chapter's derivations by Lagrange and Kane
  (sympy), from which ``_kernel_terms`` is generated.

May import: rrt_pin.core, rrt_pin.io, rrt_pin.robot.
"""
