"""Sweeps: many variants of a run, chunked, on Dask, stored as Parquet."""
