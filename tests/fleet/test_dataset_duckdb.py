"""The fleet's results read by DuckDB straight from the partitioned Parquet layout (issue 11:
"a Parquet dataset ... that pandas, Dask and DuckDB read directly"), against pandas."""

from __future__ import annotations

import duckdb  # the [test] extra
import pandas as pd
import pytest

from torquemod.fleet.run import process_run
from torquemod.testing import write_short_train_run, write_synthetic_experiment


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("duck")
    write_synthetic_experiment(root / "rig", n_steps=2, n_cycles=1, fmt="hdf5", seed=5)
    write_short_train_run(root / "train", length_m=300.0, seed=4)
    out = root / "out"
    for name, manifest in (("rig", "rig/experiment.toml"), ("train", "train/run.toml")):
        row = process_run(str(root / manifest), str(out), name)
        assert row["status"] == "processed", row["message"]
    return out


@pytest.mark.parametrize("table", ["cycles", "steps", "track"])
def test_duckdb_reads_the_partitioned_tables_as_pandas_does(results, table):
    pattern = str(results / table / "**" / "*.parquet")
    got = duckdb.sql(f"SELECT * FROM read_parquet('{pattern}', hive_partitioning=true)").df()
    ref = pd.read_parquet(results / table)
    assert len(got) == len(ref) > 0
    # the partition keys come back as columns, with the run's name
    assert {"vehicle", "date", "run"} <= set(got.columns)
    assert set(got["run"].astype(str)) == set(ref["run"].astype(str))
    key = "time_s" if table == "track" else ref.columns[0]
    num = [c for c in ref.columns if c not in ("vehicle", "date", "run", "axle")
           and pd.api.types.is_numeric_dtype(ref[c])]
    a = got.sort_values(["run", key]).reset_index(drop=True)[num]
    b = ref.sort_values(["run", key]).reset_index(drop=True)[num]
    pd.testing.assert_frame_equal(a, b, check_dtype=False, rtol=0, atol=0)


def test_duckdb_aggregates_per_run(results):
    pattern = str(results / "track" / "**" / "*.parquet")
    q = (f"SELECT run, count(*) AS n, max(position_m) AS end_m FROM "
         f"read_parquet('{pattern}', hive_partitioning=true) GROUP BY run")
    got = duckdb.sql(q).df().set_index("run")
    ref = pd.read_parquet(results / "track")
    assert int(got.loc["train", "n"]) == len(ref)
    assert float(got.loc["train", "end_m"]) == float(ref["position_m"].max())
