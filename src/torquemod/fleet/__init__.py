"""Many runs in parallel on Dask: partitioned datasets, summary, report."""
