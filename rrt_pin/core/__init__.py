"""The foundation every layer stands on: errors, checks of inputs, words, machine limits.

* :mod:`~rrt_pin.core.errors`: the exception classes (one line each, exit status 2);
* :mod:`~rrt_pin.core.validate`: the one module that checks inputs at the boundary;
* :mod:`~rrt_pin.core.text`: how numbers, names and arguments are spelled in messages;
* :mod:`~rrt_pin.core.backends`: the registry of dynamics engines (and where each
  task's entry point lives: the front doors call them through it);
* :mod:`~rrt_pin.core.cpus`, :mod:`~rrt_pin.core.memory`: threads and memory that fit;
* :mod:`~rrt_pin.core.grid`: time grids; :mod:`~rrt_pin.core.expr`: numbers as
  expressions (``pi/2``); :mod:`~rrt_pin.core.extras`: optional packages and their
  pip extras; :mod:`~rrt_pin.core.identity`: caches keyed by an object's identity;
  :mod:`~rrt_pin.core._logging`, :mod:`~rrt_pin.core._quiet`: logging and quieting C
  libraries.

May import: nothing of rrt_pin.
"""
