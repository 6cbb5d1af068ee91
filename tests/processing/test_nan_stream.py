"""`--nan-policy interpolate|drop-cycle` on long recordings streamed revolution by revolution
(torquemod.processing.nanfill): a first pass over the chunks finds the runs of NaN/inf samples,
the second fills each chunk from them. The reference is the whole-file path (the record read
at once, filled by numpy.interp over all its finite samples, split by revolution_bounds): the
cycles, NaN actions and notes must be equal bit for bit, for any chunk size."""

from __future__ import annotations

import shutil
import tracemalloc

import h5py
import numpy as np
import pytest

import torquemod.processing.pipeline as pl
from load_compare import same_items
from torquemod.errors import InputError
from torquemod.io import read_experiment
from torquemod.io.experiment import Recording
from torquemod.processing import nanfill
from torquemod.processing.cycles import revolution_bounds
from torquemod.testing import write_synthetic_experiment


# ----------------------------------------------------------------------------- unit level
def _damaged(rng, n: int) -> dict[str, np.ndarray]:
    """Channels with runs at the start, the end, single samples, +-inf, runs one finite
    sample apart, and one finite sample only."""
    ch = {c: rng.standard_normal(n) * 10 ** k for k, c in enumerate("abcde")}
    ch["a"][:5] = np.nan
    ch["a"][17] = np.inf
    ch["a"][40:61] = np.nan
    ch["b"][-9:] = -np.inf
    ch["b"][0] = np.nan
    ch["c"][30:41:2] = np.nan  # five runs, one finite sample between each
    ch["c"][n // 2] = np.nan
    ch["d"][:] = np.nan
    ch["d"][n // 3] = 2.5  # one finite value: the whole channel takes it
    for a in rng.integers(0, n - 4, 25):  # random short runs
        ch["e"][a:a + rng.integers(1, 4)] = np.nan
    return ch


def _chunked(ch: dict[str, np.ndarray], rows: int):
    n = next(iter(ch.values())).size
    for a in range(0, n, rows):
        yield {c: x[a:a + rows].copy() for c, x in ch.items()}


@pytest.mark.parametrize("rows", [1, 2, 3, 7, 64, 1000])
def test_chunks_filled_from_the_runs_equal_the_whole_record_filled(rows):
    rng = np.random.default_rng(rows)
    ch = _damaged(rng, 1000)
    whole = Recording({c: x.copy() for c, x in ch.items()}, 100.0)
    notes = nanfill.fill_record(whole, "f.h5")
    runs = nanfill.scan_nonfinite(_chunked(ch, rows))
    assert runs.notes("f.h5") == notes and len(notes) == 5
    assert runs.n_samples == 1000
    for c in ch:  # the runs themselves, by brute force
        bad = ~np.isfinite(ch[c])
        edges = np.diff(bad.astype(int), prepend=0, append=0)
        r = runs.channels[c]
        assert np.array_equal(r.start, np.flatnonzero(edges == 1))
        assert np.array_equal(r.stop, np.flatnonzero(edges == -1))
    for fill_rows in (rows, 13):  # filled in chunks of any size
        got = {c: [] for c in ch}
        pos = 0
        for chunk in _chunked(ch, fill_rows):
            for c, x in runs.fill(pos, chunk).items():
                got[c].append(x)
            pos += fill_rows
        for c, parts in got.items():
            assert np.array_equal(np.concatenate(parts), whole.channels[c]), c  # bit for bit
    bad = np.zeros(1000, dtype=bool)
    for x in ch.values():
        bad |= ~np.isfinite(x)
    clean = dict(a=np.arange(10.0))
    assert not nanfill.scan_nonfinite([clean]).channels
    for a, b in [(0, 1), (5, 17), (18, 30), (61, 62), (990, 1000), *rng.integers(0, 1000, (40, 2))]:
        a, b = sorted((int(a), int(b)))
        assert runs.touches(a, b) == bool(bad[a:b].any()), (a, b)


def test_interp_between_two_neighbours_is_interp_over_all_samples():
    """numpy.interp reads only the two finite neighbours of a sample: given just them (and
    the absolute row indices), it gives the same bits as over every finite sample."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal(5000) * np.exp(rng.uniform(-30, 30, 5000))
    bad = rng.random(5000) < 0.3
    bad[[0, -1]] = False
    good = np.flatnonzero(~bad)
    rows = np.flatnonzero(bad)
    ref = np.interp(rows, good, x[good])
    j = np.searchsorted(good, rows) - 1
    got = np.array([np.interp(float(r), [float(good[k]), float(good[k + 1])],
                              [x[good[k]], x[good[k + 1]]]) for r, k in zip(rows, j, strict=True)])
    assert np.array_equal(got, ref)


def test_a_channel_without_finite_value():
    ch = {"a": np.array([1.0, np.nan]), "b": np.full(4, np.nan)[:2]}
    runs = nanfill.scan_nonfinite(_chunked(ch, 1))
    with pytest.raises(InputError, match="no finite value") as err:
        runs.notes("f.h5")
    assert "f.h5" in str(err.value) and "'b'" in str(err.value)


# ---------------------------------------------------------------------- the pipeline's paths
@pytest.fixture(scope="module")
def damaged(tmp_path_factory):
    """One step, one HDF5 file of 4 revolutions, NaN/inf runs in every channel: at the
    start and the end of a channel, single samples, at chunk boundaries (chunks of 5000
    rows), across revolution boundaries, in the platform speed (which cuts the revolutions);
    revolution 3 is clean. Returns (folder, the clean revolution bounds)."""
    root = tmp_path_factory.mktemp("damaged")
    write_synthetic_experiment(root, n_steps=1, n_cycles=4, files_per_cycle=False,
                               fmt="hdf5", seed=11)
    with h5py.File(root / "step1.h5", "r+") as fh:
        x = {c: fh[c][...] for c in ("torque_nm", "wheel_speed_rad_s",
                                     "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")}
        bounds = revolution_bounds(x["platform_speed_rad_s"], float(fh.attrs["sample_rate_hz"]))
        b1 = bounds[0][1]
        n = x["torque_nm"].size
        x["torque_nm"][:37] = np.nan
        x["torque_nm"][5000] = np.nan
        x["torque_nm"][9990:10010] = np.nan
        x["torque_nm"][14990:15000] = np.nan
        x["torque_nm"][25000:25003] = np.inf
        x["fy_n"][0] = np.nan
        x["fz_n"][20001:20012:2] = np.nan
        x["wheel_speed_rad_s"][b1 - 40:b1 + 25] = np.nan
        x["platform_speed_rad_s"][b1 - 10:b1 + 300] = np.nan
        x["wheel_speed_rad_s"][b1 + 5000] = np.inf
        x["fx_n"][b1 + 7000] = -np.inf
        x["platform_speed_rad_s"][b1 + 12345] = np.nan
        x["fx_n"][bounds[-1][1] - 50:] = np.nan  # into revolution 4 from the end
        x["fy_n"][n - 1] = np.nan
        for c, v in x.items():
            fh[c][...] = v
    return root, bounds


def _load(folder, policy, monkeypatch, *, streamed, chunk_rows=None):
    exp = read_experiment(folder / "experiment.toml")
    cfg = pl.resolve_config(exp, nan_policy=policy)
    with monkeypatch.context() as m:
        scans = []
        real = nanfill.scan_nonfinite
        m.setattr(nanfill, "scan_nonfinite", lambda c: scans.append(1) or real(c))
        if streamed:
            m.setattr(pl, "STREAM_MIN_BYTES", 0)
            m.setattr(pl, "read_entry", None)  # never read whole
        if chunk_rows:
            m.setattr(pl, "STREAM_CHUNK_ROWS", chunk_rows)
        out = pl.load_and_process(exp.recordings[0], exp, cfg)
    assert len(scans) == int(streamed and policy != "raise")  # no first pass for raise
    return out


@pytest.mark.parametrize("policy", ["interpolate", "drop-cycle"])
def test_streamed_policy_equals_the_whole_file(damaged, monkeypatch, policy):
    folder, _ = damaged
    whole = _load(folder, policy, monkeypatch, streamed=False)
    assert len(whole[3]) == 6 + (3 if policy == "drop-cycle" else 0)  # 6 channels filled
    assert len(whole[5]) == (4 if policy == "interpolate" else 1)  # drop-cycle keeps rev 3
    for rows in (5000, 4999, None):
        same_items(_load(folder, policy, monkeypatch, streamed=True, chunk_rows=rows), whole)


def test_streamed_experiment_equals_the_whole_file(damaged, monkeypatch):
    """`process_experiment` end to end: cycles, steps, warnings and NaN actions."""
    import pandas as pd
    folder, _ = damaged
    manifest = folder / "experiment.toml"
    whole = pl.process_experiment(manifest, workers=1, config=pl.resolve_config(
        read_experiment(manifest), nan_policy="interpolate"))
    monkeypatch.setattr(pl, "STREAM_MIN_BYTES", 0)
    monkeypatch.setattr(pl, "read_entry", None)
    got = pl.process_experiment(manifest, workers=1, config=whole.config)
    pd.testing.assert_frame_equal(got.cycles, whole.cycles, check_exact=True)
    pd.testing.assert_frame_equal(got.steps, whole.steps, check_exact=True)
    assert got.nan_actions == whole.nan_actions and len(got.nan_actions) == 6
    assert got.warnings == whole.warnings


def test_channel_without_finite_value_streamed(damaged, tmp_path, monkeypatch):
    folder = tmp_path / "allnan"
    shutil.copytree(damaged[0], folder)
    with h5py.File(folder / "step1.h5", "r+") as fh:
        fh["fx_n"][...] = np.nan
    with pytest.raises(InputError) as whole:
        _load(folder, "interpolate", monkeypatch, streamed=False)
    with pytest.raises(InputError) as streamed:
        _load(folder, "interpolate", monkeypatch, streamed=True)
    assert str(streamed.value) == str(whole.value)
    assert "step1.h5" in str(streamed.value) and "fx_n" in str(streamed.value)
    assert "no finite value" in str(streamed.value)


def test_streamed_policy_memory_is_that_of_raise(damaged, tmp_path, monkeypatch):
    """Peak traced allocations of a streamed recording with NaN runs under `interpolate`:
    those of the clean file under `raise` (the first pass holds a chunk), far below the file
    read whole."""
    folder, _ = damaged
    clean = tmp_path / "clean"
    write_synthetic_experiment(clean, n_steps=1, n_cycles=4, files_per_cycle=False,
                               fmt="hdf5", seed=11)

    def peak(where, policy, streamed):
        tracemalloc.start()
        try:
            _load(where, policy, monkeypatch, streamed=streamed, chunk_rows=1 << 14)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    with h5py.File(clean / "step1.h5") as fh:
        decoded = 8 * 6 * fh["torque_nm"].size  # one copy of the samples [bytes]
    _load(clean, "raise", monkeypatch, streamed=True)  # kernels loaded, caches filled
    ref = peak(clean, "raise", True)
    nan = peak(folder, "interpolate", True)
    whole = peak(folder, "interpolate", False)
    assert nan < ref + 0.05 * decoded, (nan, ref, decoded)
    assert whole > nan + 0.5 * decoded, (whole, nan, decoded)


# ------------------------------------------------------------------- the fleet's groups
@pytest.mark.parametrize("mode", ["whole", "stream"])
@pytest.mark.parametrize("policy", ["interpolate", "drop-cycle"])
def test_groups_of_revolutions_merge_to_load_and_process(damaged, monkeypatch, mode, policy):
    """torquemod.processing.revtasks: each group fills its rows from the plan's runs and
    drops what drop-cycle drops; merged, the groups are load_and_process's result (cycles,
    NaN actions, notes) in both of its ways of reading the file."""
    from torquemod.processing.revtasks import (
        merge_revolutions,
        plan_revolutions,
        process_revolutions,
        scan_revolutions,
    )
    folder, _ = damaged
    if mode == "stream":
        monkeypatch.setattr(pl, "STREAM_MIN_BYTES", 0)
    ref = _load(folder, policy, monkeypatch, streamed=mode == "stream")
    exp = read_experiment(folder / "experiment.toml")
    cfg = pl.resolve_config(exp, nan_policy=policy)
    entry = exp.recordings[0]
    for per_task in (1, 3):
        plan = plan_revolutions(entry, exp, cfg, revolutions_per_task=per_task)
        assert plan.mode == mode and plan.runs is not None
        parts = [process_revolutions(entry, exp, cfg, plan, a, b)
                 for a, b in plan.groups(per_task)]
        same_items(merge_revolutions(plan, parts), ref)
    if mode == "whole":  # the scan's own first group, from the record it has read
        plan, first = scan_revolutions(entry, exp, cfg, revolutions_per_task=3)
        rest = process_revolutions(entry, exp, cfg, plan, 3, 4)
        same_items(merge_revolutions(plan, [first, rest]), ref)


def test_fleet_run_split_with_a_nan_policy(damaged, tmp_path, monkeypatch):
    """process_run (the fleet's tasks in this process), one revolution per task, under the
    manifest's nan_policy = "drop-cycle": the partitions hold `process_experiment`'s
    tables."""
    import pandas as pd

    from torquemod.fleet.run import process_run
    from torquemod.processing import revtasks
    groups = []
    real = revtasks.process_revolutions
    monkeypatch.setattr(revtasks, "process_revolutions",
                        lambda *a, **k: groups.append(a[4:6]) or real(*a, **k))
    folder = tmp_path / "exp"
    shutil.copytree(damaged[0], folder)
    manifest = folder / "experiment.toml"
    assert "[processing]" not in manifest.read_text()
    with manifest.open("a") as fh:
        fh.write('\n[processing]\nnan_policy = "drop-cycle"\n')
    row = process_run(str(manifest), str(tmp_path / "out"), "r", revolutions_per_task=1)
    assert row["status"] == "processed" and row["n_cycles"] == 1
    # split into 4 tasks, the first computed by the scan from the record it read whole
    assert sorted(groups) == [(1, 2), (2, 3), (3, 4)]
    alone = pl.process_experiment(manifest, workers=1)
    assert len(alone.nan_actions) == 9
    for table, ref in (("cycles", alone.cycles), ("steps", alone.steps)):
        got = pd.read_parquet(tmp_path / "out" / table).drop(columns=["run", "vehicle",
                                                                      "date"])
        pd.testing.assert_frame_equal(got, ref.reset_index(drop=True), check_dtype=False,
                                      rtol=0, atol=0)
