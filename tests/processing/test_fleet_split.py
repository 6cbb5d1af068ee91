"""A long rig recording cut into groups of revolutions (torquemod.processing.revtasks), in this
process:
the merged groups must be exactly what `load_and_process` returns for the whole recording,
in both of its ways of splitting a file (whole-file read; streaming, forced here by lowering
`pipeline.STREAM_MIN_BYTES`), including notes, the NaN error and the file's SHA-256. The
reference is `load_and_process` itself (an independent code path: whole-file
`revolution_bounds` or `RecordingStream.revolutions`), compared bit for bit."""

from __future__ import annotations

import dataclasses
import hashlib

import h5py
import numpy as np
import pytest

from load_compare import same_items
from torquemod.errors import InputError
from torquemod.io import read_experiment
from torquemod.io.stream import open_stream
from torquemod.processing import pipeline
from torquemod.processing.revtasks import (
    merge_revolutions,
    plan_revolutions,
    process_revolutions,
    scan_revolutions,
)
from torquemod.testing import write_synthetic_experiment


@pytest.fixture(scope="module")
def long_exp(tmp_path_factory):
    """One step, one HDF5 file of 4 revolutions (6.5 s each) without a manifest cycle; the
    lateral force clipped for 600 samples in revolution 2 and 3 (a clipping note per
    revolution when streamed, one when read whole)."""
    root = tmp_path_factory.mktemp("long")
    write_synthetic_experiment(root, n_steps=1, n_cycles=4, files_per_cycle=False,
                               fmt="hdf5", seed=5)
    path = root / "step1.h5"
    with h5py.File(path, "r+") as fh:
        w = fh["fy_n"]
        x = w[...]
        top = float(x.max())
        n = x.size // 4
        for k in (1, 2):
            x[k * n + 5000:k * n + 5600] = top
        w[...] = x
    return root


def _split(entry, exp, cfg, per_task):
    plan = plan_revolutions(entry, exp, cfg, revolutions_per_task=per_task)
    assert plan is not None
    parts = [process_revolutions(entry, exp, cfg, plan, a, b)
             for a, b in plan.groups(per_task)]
    return plan, merge_revolutions(plan, parts)


@pytest.mark.parametrize("mode", ["whole", "stream"])
def test_groups_merge_to_load_and_process(long_exp, monkeypatch, mode):
    if mode == "stream":
        monkeypatch.setattr(pipeline, "STREAM_MIN_BYTES", 0)
    exp = read_experiment(long_exp / "experiment.toml")
    cfg = pipeline.resolve_config(exp)
    entry = exp.recordings[0]
    ref = pipeline.load_and_process(entry, exp, cfg)
    assert len(ref[5]) == 4
    clip = [n for n in ref[4] if "sits at its maximum" in n]
    assert len(clip) == 1  # once per channel in both modes (whole: one record)
    plan, got = _split(entry, exp, cfg, 1)
    assert plan.mode == mode and plan.groups(1) == [(0, 1), (1, 2), (2, 3), (3, 4)]
    assert plan.groups(3) == [(0, 3), (3, 4)]
    assert got[2] == hashlib.sha256(entry.path.read_bytes()).hexdigest()
    same_items(got, ref)
    same_items(_split(entry, exp, cfg, 3)[1], ref)
    # the scan computes the first group itself when it has read the file whole
    plan, first = scan_revolutions(entry, exp, cfg, revolutions_per_task=3)
    assert (first is None) == (mode == "stream")
    if first is not None:
        assert first.sha256 == got[2] and len(first.cycles) == 3
        rest = [process_revolutions(entry, exp, cfg, plan, a, b) for a, b in plan.groups(3)[1:]]
        same_items(merge_revolutions(plan, [first, *rest]), ref)


def test_nan_in_a_later_revolution(long_exp, tmp_path, monkeypatch):
    """Streamed: the group holding the damaged revolution raises load_and_process's error
    (the sample index within that revolution); earlier groups succeed. Read whole: the plan
    raises the whole-record error (the caller then runs the recording as one task)."""
    import shutil
    folder = tmp_path / "nan"
    shutil.copytree(long_exp, folder)
    with h5py.File(folder / "step1.h5", "r+") as fh:
        n = fh["torque_nm"].shape[0]
        fh["torque_nm"][3 * n // 4 + 100] = np.nan  # in revolution 4
    exp = read_experiment(folder / "experiment.toml")
    cfg = pipeline.resolve_config(exp)
    entry = exp.recordings[0]
    with pytest.raises(InputError) as whole:
        pipeline.load_and_process(entry, exp, cfg)
    with pytest.raises(InputError) as planned:
        plan_revolutions(entry, exp, cfg, revolutions_per_task=2)
    assert str(planned.value) == str(whole.value)
    monkeypatch.setattr(pipeline, "STREAM_MIN_BYTES", 0)
    with pytest.raises(InputError) as streamed:
        pipeline.load_and_process(entry, exp, cfg)
    assert str(streamed.value) != str(whole.value)  # the two modes word it differently
    plan = plan_revolutions(entry, exp, cfg, revolutions_per_task=2)
    process_revolutions(entry, exp, cfg, plan, 0, 2)
    with pytest.raises(InputError) as part:
        process_revolutions(entry, exp, cfg, plan, 2, 4)
    assert str(part.value) == str(streamed.value)


def test_stays_one_task(long_exp, monkeypatch):
    exp = read_experiment(long_exp / "experiment.toml")
    cfg = pipeline.resolve_config(exp)
    entry = exp.recordings[0]
    assert plan_revolutions(entry, exp, cfg) is None  # 26 s: shorter than 1.5 tasks
    assert plan_revolutions(entry, exp, cfg, revolutions_per_task=4) is None  # one group
    other = dataclasses.replace(cfg, nan_policy="interpolate")  # split as well (its runs
    assert plan_revolutions(entry, exp, other, revolutions_per_task=1).runs is None  # none)
    named = dataclasses.replace(entry, cycle=1)
    assert plan_revolutions(named, exp, cfg, revolutions_per_task=1) is None


def test_read_rows_matches_chunks(long_exp):
    """HDF5 (random access): RecordingStream.read_rows against the same rows of the chunks."""
    exp = read_experiment(long_exp / "experiment.toml")
    with open_stream(exp.recordings[0], experiment=exp) as s:
        assert s.random_access
        whole = {c: np.concatenate([ch[c] for ch in s.chunks(None, 50_000)])
                 for c in s.info.channels}
        seg = s.read_rows(123_457, 201_001)
        assert seg.t0_s == s.info.t0_s + 123_457 / s.info.fs_hz
        for c, v in whole.items():
            assert np.array_equal(seg.channels[c], v[123_457:201_001])
        with pytest.raises(ValueError):
            s.read_rows(5, s.info.n_samples + 1)


def test_process_run_in_sequence_splits_the_same(long_exp, tmp_path):
    """process_run (the fleet's tasks in this process) with one revolution per task: the
    partitions hold exactly `process_experiment`'s tables."""
    import pandas as pd

    from torquemod.fleet.run import process_run
    row = process_run(str(long_exp / "experiment.toml"), str(tmp_path / "out"), "r",
                      revolutions_per_task=1)
    assert row["status"] == "processed" and row["n_cycles"] == 4
    alone = pipeline.process_experiment(long_exp / "experiment.toml", workers=1)
    for table, ref in (("cycles", alone.cycles), ("steps", alone.steps)):
        got = pd.read_parquet(tmp_path / "out" / table).drop(columns=["run", "vehicle",
                                                                      "date"])
        pd.testing.assert_frame_equal(got, ref.reset_index(drop=True), check_dtype=False,
                                      rtol=0, atol=0)


def test_csv_stays_one_task_and_reads_rows_in_order(tmp_path):
    """A CSV file is read in order only: not split (each group would parse every row before
    its own); its read_rows still gives the streamed rows."""
    write_synthetic_experiment(tmp_path, n_steps=1, n_cycles=3, files_per_cycle=False,
                               fmt="csv", seed=2)
    exp = read_experiment(tmp_path / "experiment.toml")
    cfg = pipeline.resolve_config(exp)
    assert plan_revolutions(exp.recordings[0], exp, cfg, revolutions_per_task=1) is None
    with open_stream(exp.recordings[0], experiment=exp) as s:
        assert not s.random_access
        whole = {c: np.concatenate([ch[c] for ch in s.chunks(None, 40_000)])
                 for c in s.info.channels}
        seg = s.read_rows(199_999, 300_001)  # across a 2**18-row chunk edge
        for c, v in whole.items():
            assert np.array_equal(seg.channels[c], v[199_999:300_001])


def test_train_axle_in_chunk_tasks(tmp_path, monkeypatch):
    """A train axle through the fleet's chunk tasks (scan, one task per chunk measuring its
    windows, assembly in finish_run): the track is `onboard`'s with tolerance 0; a failed
    chunk fails the run with its message; a run shorter than one chunk (the default
    AXLE_TASK_S) stays one task."""
    import pandas as pd

    from torquemod.fleet.run import process_run
    from torquemod.ontrain import run as onboard_run
    from torquemod.testing import write_short_train_run
    write_short_train_run(tmp_path / "t", length_m=300.0, seed=3)
    calls = []
    real_measure = onboard_run.measure_axle_chunk

    def measure(run, entry, config, first, stop):
        calls.append((first, stop))
        if calls[0] == "fail" and len(calls) == 3:
            raise InputError("bad chunk", path=entry.path)
        return real_measure(run, entry, config, first, stop)

    monkeypatch.setattr(onboard_run, "measure_axle_chunk", measure)
    onboard_run.run_onboard(tmp_path / "t" / "run.toml", tmp_path / "alone")
    alone = pd.read_parquet(tmp_path / "alone" / "track.parquet")
    for chunk_s, tasks in ((None, 0), (4.0, 4)):
        calls[:] = []
        row = process_run(str(tmp_path / "t" / "run.toml"), str(tmp_path / "out"), "t",
                          force=True, axle_chunk_s=chunk_s)
        assert row["status"] == "processed"
        assert len(calls) >= tasks and (tasks or not calls)
        got = pd.read_parquet(next((tmp_path / "out" / "track").rglob("part-0.parquet")))
        pd.testing.assert_frame_equal(got, alone, check_dtype=False, rtol=0, atol=0)
    calls[:] = ["fail"]
    row = process_run(str(tmp_path / "t" / "run.toml"), str(tmp_path / "out"), "t",
                      force=True, axle_chunk_s=4.0)
    assert row["status"] == "failed" and row["message"].endswith("bad chunk")


def test_digest_hashed_once_when_fresh(long_exp, tmp_path):
    """The plan's fingerprint hashed the file just now: the first group takes that digest
    (no second read); a digest kept from the last run's state (size and mtime unchanged)
    is not taken, the group hashes the file itself."""
    from torquemod.fleet.run import plan_run, process_run
    from torquemod.fleet.tasks import _fresh_sha256
    truth = hashlib.sha256((long_exp / "step1.h5").read_bytes()).hexdigest()
    out = str(tmp_path / "out")
    plan = plan_run(str(long_exp / "experiment.toml"), out, "r")
    assert _fresh_sha256(plan, 0) == truth
    exp, cfg = plan.prep.source, plan.prep.settings
    rplan = plan_revolutions(exp.recordings[0], exp, cfg, revolutions_per_task=2)
    given = process_revolutions(exp.recordings[0], exp, cfg, rplan, 0, 1, sha256="given")
    assert given.sha256 == "given"
    assert process_run(str(long_exp / "experiment.toml"), out, "r")["status"] == "processed"
    again = plan_run(str(long_exp / "experiment.toml"), out, "r", force=True)
    assert _fresh_sha256(again, 0) is None


def test_default_groups_hold_about_a_minute():
    """groups() without revolutions_per_task: round(TASK_SECONDS / revolution length)
    revolutions each (V-Track: 6.46 s revolutions -> 9 per group, 58 s); at least one."""
    from torquemod.processing.revtasks import TASK_SECONDS, RevolutionPlan
    fs = 16_670.0
    rev = round(6.46 * fs)
    bounds = tuple((k * rev, (k + 1) * rev) for k in range(20))
    plan = RevolutionPlan("stream", bounds, fs, (), (), (), 0.0)
    assert TASK_SECONDS == 60.0
    assert plan.groups() == [(0, 9), (9, 18), (18, 20)]
    slow = RevolutionPlan("stream", ((0, int(100 * fs)), (int(100 * fs), int(200 * fs))), fs,
                          (), (), (), 0.0)
    assert slow.groups() == [(0, 1), (1, 2)]  # a revolution longer than a task: one each
    with pytest.raises(ValueError):
        plan.groups(0)


def test_cli_passes_revolutions_per_task(monkeypatch, tmp_path, capsys):
    """`torquemod fleet --revolutions-per-task N` reaches run_fleet; 0 is refused by the
    parser (exit 2, a one-line message, no traceback)."""
    import types

    import pandas as pd

    import torquemod.fleet.run as fleet
    from torquemod.cli import main
    seen = {}

    def fake(runs, out, **kw):
        seen.update(kw)
        empty = pd.DataFrame()
        return types.SimpleNamespace(summary=empty, count=lambda s: 0, wall_s=0.0,
                                     failures=empty, out_dir=out, report=None)

    monkeypatch.setattr(fleet, "run_fleet", fake)
    assert main(["fleet", str(tmp_path), "--out", str(tmp_path / "o"), "--quiet",
                 "--revolutions-per-task", "3"]) == 0
    assert seen["revolutions_per_task"] == 3
    with pytest.raises(SystemExit) as exit_:
        main(["fleet", str(tmp_path), "--out", str(tmp_path / "o"),
              "--revolutions-per-task", "0"])
    assert exit_.value.code == 2
    assert "positive whole number" in capsys.readouterr().err
