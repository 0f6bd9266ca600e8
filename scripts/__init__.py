"""The project's scripts: the benchmarks (``scripts/bench``) and the generators of docs and kernels."""
