"""The golden numbers: a small fixed experiment through every output, and the script that
regenerates them.

``compute(work)`` runs, in the folder ``work``:

* a short V-Track twin run (3 steps, 1 revolution each, HDF5) through ``read_experiment ->
  process -> analyze -> save``: the numbers of ``fit.json``, ``steps.csv`` and ``cycles.csv``;
* a short train twin run (300 m) through ``read_run -> onboard -> save``: ``track.parquet``;
* a fleet of two synthetic rig experiments on one Dask worker: its ``steps`` and ``cycles``
  partitions and ``fleet_summary.csv``;
* a two-point full sweep (twin -> files -> chain -> fit), in this process:
  ``sweep.parquet``.

and returns ``{output name: {field: value or list of values}}`` holding every numeric field
(booleans, integers and floats; strings, timestamps, paths, versions and provenance left out).

Run ``python tests/golden/regen.py`` to rewrite ``tests/golden/golden.json`` when a change
moves the numbers on purpose (a bug fix); a relayout must leave them equal.
"""

from __future__ import annotations

import json
import math
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
GOLDEN = HERE / "golden.json"

#: keys of the JSON documents that are not numbers of the measurement
SKIP_KEYS = {"torquemod_version", "created_utc", "source", "provenance", "command", "path",
             "paths", "created", "software", "elapsed_s", "hostname", "python", "platform"}

#: columns that time the computer, not the measurement
TIMING = re.compile(r"seconds|wall|elapsed|_at$|date|time_utc")

TWIN_OVERRIDES = {"procedure": {"dc_torques_nm": [22.84, 44.47, 60.0], "cycles_per_step": 1,
                                "settle_s": 1.0}}

SWEEP = """
mode = "full"
seeds = [2]
[fixed]
procedure.cycles_per_step = 1
procedure.settle_s = 1.5
[steps]
fractions_of_peak = [0.0, 0.4, 0.7]
[grid]
modulation.amplitude_nm = [6.0, 8.0]
"""


def _numbers(obj, prefix: str, out: dict) -> None:
    """Flatten the numeric leaves of a JSON document into ``out`` (``a.b[2]`` keys)."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k not in SKIP_KEYS:
                _numbers(v, f"{prefix}.{k}" if prefix else str(k), out)
    elif isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            _numbers(v, f"{prefix}[{i}]", out)
    elif isinstance(obj, bool):
        out[prefix] = int(obj)
    elif isinstance(obj, int | float):
        out[prefix] = float(obj)
    elif obj is None:
        out[prefix] = None


def _frame(df: pd.DataFrame, sort: list[str] | None = None) -> dict:
    """The numeric (and boolean) columns of a table, as lists (NaN as None)."""
    df = df.drop(columns=[c for c in df.columns if TIMING.search(str(c))])
    if sort:
        df = df.sort_values(sort, kind="stable").reset_index(drop=True)
    out = {}
    for col in df.columns:
        s = df[col]
        if s.dtype == bool or pd.api.types.is_numeric_dtype(s.dtype):
            vals = s.to_numpy(dtype=float, na_value=np.nan)
            out[col] = [None if math.isnan(v) else float(v) for v in vals]
    return out


def _twin_rig(work: Path) -> dict:
    import torquemod as tm
    from torquemod.twin import load_config, run_simulation

    cfg = load_config(overrides=TWIN_OVERRIDES)
    run_simulation(cfg, work / "exp", seed=7, fmt="hdf5", progress=False, workers=1)
    exp = tm.read_experiment(work / "exp" / "experiment.toml")
    res = tm.process(exp)
    ana = tm.analyze(res)
    tm.save(res, ana, work / "results")
    fit: dict = {}
    _numbers(json.loads((work / "results" / "fit.json").read_text()), "", fit)
    return {"fit.json": fit,
            "steps.csv": _frame(pd.read_csv(work / "results" / "steps.csv")),
            "cycles.csv": _frame(pd.read_csv(work / "results" / "cycles.csv"))}


def _onboard(work: Path) -> dict:
    import torquemod as tm
    from torquemod.testing import write_short_train_run

    write_short_train_run(work / "train", length_m=300.0, seed=3)
    ob = tm.onboard(tm.read_run(work / "train" / "run.toml"))
    folder = ob.save(work / "onboard")
    return {"track.parquet": _frame(pd.read_parquet(Path(folder) / "track.parquet"))}


def _fleet(work: Path) -> dict:
    from torquemod.testing import write_synthetic_experiment

    try:
        from torquemod.fleet.run import run_fleet  # packages by stage
    except ImportError:  # the flat layout before (relayout: keep)
        from torquemod.fleet import run_fleet  # relayout: keep
    root = work / "fleet_in"
    for k, name in enumerate(("axle1", "axle2")):
        write_synthetic_experiment(root / name, n_steps=2, n_cycles=1, fmt="hdf5", seed=k)
    out = work / "fleet_out"
    run_fleet([root], out, n_workers=1, report=False)
    got = {}
    for kind, keys in (("steps", ["run", "step"]), ("cycles", ["run", "step", "cycle"])):
        parts = sorted((out / kind).rglob("*.parquet"))
        frames = []
        for p in parts:
            df = pd.read_parquet(p)
            df["run"] = next(s.split("=", 1)[1] for s in p.parts if s.startswith("run="))
            frames.append(df)
        df = pd.concat(frames, ignore_index=True)
        got[f"fleet/{kind}"] = _frame(df, [k for k in keys if k in df.columns])
    got["fleet/fleet_summary.csv"] = _frame(pd.read_csv(out / "fleet_summary.csv"), ["run"])
    return got


def _sweep(work: Path) -> dict:
    from torquemod.sweep import parse_sweep, run_sweep

    res = run_sweep(parse_sweep(SWEEP), work / "sweep", in_process=True, report=False)
    tab = pd.read_parquet(work / "sweep" / "sweep.parquet")
    assert res.count("done") == 2, res.failures
    sort = [c for c in ("point", "seed", "step") if c in tab.columns]
    return {"sweep.parquet": _frame(tab, sort)}


def compute(work: str | Path) -> dict:
    """Every golden number, computed in the folder ``work`` (see the module docstring)."""
    work = Path(work)
    got: dict = {}
    for part in (_twin_rig, _onboard, _fleet, _sweep):
        got.update(part(work))
    return got


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        got = compute(tmp)
    GOLDEN.write_text(json.dumps(got, indent=0, sort_keys=True, allow_nan=False) + "\n")
    n = sum(len(v) for v in got.values())
    print(f"wrote {GOLDEN} ({len(got)} outputs, {n} fields)")


if __name__ == "__main__":
    sys.exit(main())
