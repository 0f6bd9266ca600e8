"""Sweeps: many variants of a run, chunked, on Dask, stored as Parquet.

* :mod:`~rrt_pin.sweeps.spec`: the spec (TOML or dict) and every variant's values;
* :mod:`~rrt_pin.sweeps.compute`: one chunk on the fastest batch path, metrics;
* :mod:`~rrt_pin.sweeps.store`: Parquet files and the manifest;
* :mod:`~rrt_pin.sweeps.run`: :func:`~rrt_pin.sweeps.run.sweep` on Dask, progress, summary;
* :mod:`~rrt_pin.sweeps.plot`: a metric over the varied values.

Nothing here is imported by ``import rrt_pin``; ``rrt_pin.sweep`` loads it on first use.

May import: rrt_pin.core, rrt_pin.io, rrt_pin.robot, rrt_pin.dynamics, rrt_pin.simulate,
rrt_pin.compiled, rrt_pin.viewer.
"""
