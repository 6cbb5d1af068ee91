"""Helpers that know nothing of friction: files, locks, JSON, TOML checks, BLAS threads, Dask,
progress bars."""
