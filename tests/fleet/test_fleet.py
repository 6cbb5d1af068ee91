"""The fleet on Dask (torquemod.fleet.run): a LocalCluster of 2 worker processes, a small fleet of
rig experiments and train runs with damaged ones, against the same runs processed one by one
(`process_experiment`, `run_onboard`) in this process."""

from __future__ import annotations

import datetime as dt
import shutil
import tomllib

import pandas as pd
import pytest
import tomli_w

from torquemod.errors import TorquemodError
from torquemod.fleet.run import (
    find_manifests,
    manifest_kind,
    partition_value,
    run_fleet,
    run_names,
)
from torquemod.processing.pipeline import process_experiment
from torquemod.testing import write_short_train_run, write_synthetic_experiment


def _edit_toml(path, change) -> None:
    doc = tomllib.loads(path.read_text())
    change(doc)
    path.write_text(tomli_w.dumps(doc))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    for k, name in enumerate(("axle1", "axle2")):
        write_synthetic_experiment(root / name, n_steps=2, n_cycles=1, fmt="hdf5", seed=k)
    _edit_toml(root / "axle2" / "experiment.toml",
               lambda d: (d["rig"].update(vehicle="V-Track #2"),
                          d["test"].update(date=dt.date(2025, 3, 4))))
    shutil.copytree(root / "axle1", root / "damaged")
    bad = root / "damaged" / "step2_cycle1.h5"
    bad.write_bytes(bad.read_bytes()[:5000])  # truncated, as by a full disk
    # a short train run of the twin (300 m, 15 s), dated; and a copy with a truncated MDF4
    write_short_train_run(root / "train1", length_m=300.0, seed=3)
    # two axles (the second a copy of the first's recording), dated
    shutil.copy(root / "train1" / "run.mf4", root / "train1" / "axle2.mf4")
    _edit_toml(root / "train1" / "run.toml",
               lambda d: (d["recording"][0].update(date="2025-03-05T07:40:00"),
                          d["recording"].append({"file": "axle2.mf4", "axle": 2})))
    shutil.copytree(root / "train1", root / "train_bad")
    mf4 = root / "train_bad" / "run.mf4"
    mf4.write_bytes(mf4.read_bytes()[: mf4.stat().st_size // 3])
    return root


def _one_line(exc: BaseException) -> str:
    """What `torquemod process/onboard` print after 'torquemod: error: '."""
    from torquemod._cli.output import one_line as _one_line
    return _one_line(exc)


def _same(got: pd.DataFrame, alone: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(got.reset_index(drop=True), alone.reset_index(drop=True),
                                  check_dtype=False, rtol=0, atol=0)


@pytest.fixture(scope="module")
def cluster():
    from dask.distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=40) as c:
        yield c


def test_fleet_on_two_worker_processes(fleet, cluster, tmp_path):
    from dask.distributed import Client, get_task_stream

    from torquemod.ontrain import run_onboard
    out = tmp_path / "out"
    links = []
    with Client(cluster) as client, get_task_stream(client) as stream:
        res = run_fleet([fleet], out, scheduler=cluster.scheduler_address,
                        on_dashboard=links.append)
    assert links and links[0].startswith("http")
    # one task per manifest, per recording (axle) and per run's assembly; both workers used
    kinds = [t["key"].split("-")[1][:4] for t in stream.data]
    assert sorted(kinds) == ["fini"] * 5 + ["item"] * 10 + ["plan"] * 5
    assert len({t["worker"] for t in stream.data}) == 2
    status = dict(zip(res.summary["run"], res.summary["status"], strict=True))
    assert status == {"axle1": "processed", "axle2": "processed", "damaged": "failed",
                      "train1": "processed", "train_bad": "failed"}
    kinds = dict(zip(res.summary["run"], res.summary["kind"], strict=True))
    assert kinds["train1"] == kinds["train_bad"] == "train" and kinds["axle1"] == "rig"
    # a mu comes with its standard error; a train row's bound is never above its mu
    summ = res.summary.set_index("run")
    rig = summ.loc[["axle1", "axle2"]]
    assert (rig["mu"].notna() == rig["mu_stderr"].notna()).all()
    train = summ.loc["train1"]
    assert pd.isna(train["mu"]) or train["mu_lower_bound"] <= train["mu"]
    # the damaged runs: one row each, the same one-line message the commands give
    with pytest.raises(TorquemodError) as exc:
        process_experiment(fleet / "damaged" / "experiment.toml", workers=1)
    with pytest.raises(TorquemodError) as exc_train:
        run_onboard(fleet / "train_bad" / "run.toml", tmp_path / "bad_alone")
    msg = dict(zip(res.failures["run"], res.failures["message"], strict=True))
    assert list(msg) == ["damaged", "train_bad"]
    assert msg["damaged"] == _one_line(exc.value) and "step2_cycle1.h5" in msg["damaged"]
    assert msg["train_bad"] == _one_line(exc_train.value) and "run.mf4" in msg["train_bad"]
    assert pd.read_csv(out / "failures.csv")["run"].tolist() == ["damaged", "train_bad"]
    # the rig datasets, partitioned vehicle/date/run, read directly by pandas; numbers
    # identical to single runs
    cycles = pd.read_parquet(out / "cycles")
    assert sorted(cycles["run"].astype(str).unique()) == ["axle1", "axle2"]
    labels = cycles.groupby("run", observed=True)[["vehicle", "date"]].first().astype(str)
    assert labels.loc["axle2"].tolist() == ["V-Track__2", "2025-03-04"]
    assert labels.loc["axle1"].tolist() == ["unknown", "unknown"]
    steps = pd.read_parquet(out / "steps")
    for run in ("axle1", "axle2"):
        alone = process_experiment(fleet / run / "experiment.toml", workers=1)
        for got, ref in ((cycles, alone.cycles), (steps, alone.steps)):
            _same(got[got["run"].astype(str) == run].drop(columns=["run", "vehicle", "date"]),
                  ref)
    assert len(steps) == 4
    # the train run: the same rows `torquemod onboard` writes to track.parquet (and
    # track_axle2.parquet), in files of exactly its 13 columns; vehicle, date, run, axle
    # from the partitions
    run_onboard(fleet / "train1" / "run.toml", tmp_path / "alone")
    alone = pd.read_parquet(tmp_path / "alone" / "track.parquet")
    alone2 = pd.read_parquet(tmp_path / "alone" / "track_axle2.parquet")
    part = (out / "track" / "vehicle=torquemod_train_twin" / "date=2025-03-05" / "run=train1"
            / "axle=1" / "part-0.parquet")
    assert list(pd.read_parquet(part).columns) == list(alone.columns)
    track = pd.read_parquet(out / "track")
    assert {"vehicle", "date", "run", "axle"} <= set(track.columns)
    assert track["run"].astype(str).unique().tolist() == ["train1"]
    import dask.dataframe as dd  # Dask reads the same layout
    lazy = dd.read_parquet(out / "track")
    # computed in this thread: once, under parallel test workers, Dask's configuration
    # still named the distributed scheduler after both clients had closed (a client's close
    # restores it only when no other default client is open; which order they finish in
    # depends on the load)
    assert {"vehicle", "date", "run", "axle"} <= set(lazy.columns)
    assert len(lazy.compute(scheduler="sync")) == len(track)
    axle = track["axle"].astype(int)
    _same(track.loc[axle == 1, list(alone.columns)], alone)
    _same(track.loc[axle == 2, list(alone.columns)], alone2)
    row = res.summary.set_index("run").loc["train1"]
    assert row["n_rows"] == len(alone) + len(alone2)
    assert row["low_adhesion_windows"] == int(alone["low_adhesion"].sum()
                                              + alone2["low_adhesion"].sum())
    assert row["duration_s"] == pytest.approx(15.0, abs=0.3)  # window-covered time [s]
    page = (out / "fleet_report.html").read_text()
    assert "train_bad" in page and "run.mf4" in page and "data:image/png;base64" in page
    assert res.report == out / "fleet_report.html"
    # a rerun skips unchanged runs (same partition file), retries the damaged ones, and
    # reprocesses a run whose manifest changed; a changed date moves the partition
    stamp = part.stat().st_mtime_ns
    rig_part = next((out / "cycles").rglob("run=axle1/part-0.parquet"))
    rig_stamp = rig_part.stat().st_mtime_ns
    _edit_toml(fleet / "axle2" / "experiment.toml",
               lambda d: d["test"].update(date=dt.date(2025, 3, 6)))
    crashed = out / "cycles" / "vehicle=unknown" / "date=unknown" / ".run=axle9.tmp"
    crashed.mkdir()  # what a worker killed while writing leaves
    (crashed / "part-0.parquet").write_bytes(b"half")
    again = run_fleet([fleet], out, scheduler=cluster.scheduler_address)
    assert not crashed.exists()
    status = dict(zip(again.summary["run"], again.summary["status"], strict=True))
    assert status == {"axle1": "skipped", "axle2": "processed", "damaged": "failed",
                      "train1": "skipped", "train_bad": "failed"}
    assert part.stat().st_mtime_ns == stamp and rig_part.stat().st_mtime_ns == rig_stamp
    skipped = again.summary.set_index("run").loc["train1"]
    assert skipped["n_rows"] == row["n_rows"] and skipped["date"] == "2025-03-05"
    dates = pd.read_parquet(out / "steps").groupby("run", observed=True)["date"].first()
    assert dates.astype(str).to_dict() == {"axle1": "unknown", "axle2": "2025-03-06"}
    assert not (out / "steps" / "vehicle=V-Track__2" / "date=2025-03-04").exists()


def test_finding_manifests(fleet, tmp_path):
    lst = tmp_path / "runs.txt"
    lst.write_text(f"# the fleet\n{fleet / 'axle1'}\n{fleet / 'axle2' / 'experiment.toml'}\n"
                   f"{fleet / 'train1' / 'run_h5.toml'}\n")
    found = find_manifests([lst])
    assert [p.parent.name for p in found] == ["axle1", "axle2", "train1"]
    assert [manifest_kind(p) for p in found] == ["rig", "rig", "train"]  # run_h5 by content
    assert run_names(found) == ["axle1", "axle2", "train1-run_h5"]
    # a folder: experiment.toml and run.toml below it (not run_h5.toml)
    assert [p.name for p in find_manifests([fleet])] == ["experiment.toml"] * 3 + \
        ["run.toml"] * 2
    assert len(find_manifests([str(fleet / "*" / "experiment.toml")])) == 3
    same = [fleet / "axle1" / "experiment.toml", tmp_path / "x" / "axle1" / "experiment.toml"]
    names = run_names(same)
    assert names[0] != names[1] and all(n.startswith("axle1-") for n in names)
    with pytest.raises(TorquemodError):
        find_manifests([tmp_path / "nothing-here"])


def test_partition_values():
    assert partition_value(None) == partition_value("  ") == "unknown"
    assert partition_value("BR 185/12=a") == "BR_185_12_a"  # no path or key separators
    assert partition_value(dt.date(2025, 1, 2), day=True) == "2025-01-02"
    assert partition_value(dt.datetime(2025, 1, 2, 23, 59), day=True) == "2025-01-02"
    assert partition_value("2025-01-02T08:00:00Z", day=True) == "2025-01-02"
    assert partition_value("spring 2025", day=True) == "spring_2025"


def test_file_digest_reused_only_while_size_and_mtime_hold(tmp_path):
    import hashlib
    import os

    from torquemod.fleet.plan import _file_digest
    path = tmp_path / "rec.bin"
    path.write_bytes(b"abc" * 1000)
    first = _file_digest(path, {})
    assert first[2] == hashlib.sha256(b"abc" * 1000).hexdigest()
    fake = {str(path): [first[0], first[1], "recorded"]}
    assert _file_digest(path, fake)[2] == "recorded"  # unchanged: not read again
    path.write_bytes(b"abd" * 1000)  # same size, new content and time
    os.utime(path, ns=(first[1] + 10**9, first[1] + 10**9))
    assert _file_digest(path, fake)[2] == hashlib.sha256(b"abd" * 1000).hexdigest()


def test_fleet_command_line(fleet, cluster, tmp_path, capsys):
    """`torquemod fleet` on an existing scheduler: exit 0 with the damaged run named on
    stderr, the dashboard address, the counts, the results folder and the report on stdout;
    a rerun reports the good runs unchanged."""
    from torquemod.cli import main

    out = tmp_path / "fl"
    args = ["fleet", str(fleet / "axle1"), str(fleet / "damaged"), "--out", str(out),
            "--scheduler", cluster.scheduler_address, "--quiet"]
    assert main(args) == 0
    io = capsys.readouterr()
    assert "2 runs: 1 processed, 0 unchanged (skipped), 1 failed" in io.out
    assert "failed: damaged:" in io.err and "step2_cycle1.h5" in io.err
    assert "dashboard: http" in io.err
    assert f"results: {out}" in io.out and "fleet_report.html" in io.out
    assert main(args) == 0
    assert "1 unchanged (skipped)" in capsys.readouterr().out


def test_first_bad_recording_in_manifest_order_names_the_failure(fleet, tmp_path):
    """Recordings are separate tasks; with two damaged files the run fails with the message
    of the first in the manifest, as `process` (which reads them in order) does; an earlier
    good result of the run is removed."""
    from torquemod.fleet.run import process_run
    folder = tmp_path / "two_bad"
    shutil.copytree(fleet / "axle1", folder)
    out = tmp_path / "out"
    assert process_run(str(folder / "experiment.toml"), str(out), "r")["status"] == "processed"
    assert len(pd.read_parquet(out / "cycles")) == 2
    for name in ("step2_cycle1.h5", "step1_cycle1.h5"):
        (folder / name).write_bytes(b"not HDF5")
    with pytest.raises(TorquemodError) as exc:
        process_experiment(folder / "experiment.toml", workers=1)
    row = process_run(str(folder / "experiment.toml"), str(out), "r")
    assert row["status"] == "failed" and "step1_cycle1.h5" in row["message"]
    assert row["message"] == _one_line(exc.value)
    assert not list((out / "cycles").rglob("*.parquet"))
    assert not (out / "_state" / "r.json").exists()


def _set_stream_min_bytes(value: int) -> int:
    """On a worker: the size from which load_and_process streams a file; returns the old."""
    from torquemod.processing import pipeline
    old = pipeline.STREAM_MIN_BYTES
    pipeline.STREAM_MIN_BYTES = value
    return old


@pytest.mark.parametrize("mode", ["whole", "stream"])
def test_long_recordings_one_task_per_revolution_group(cluster, tmp_path, monkeypatch, mode):
    """Files of 3 revolutions without manifest cycles, one revolution per task: a scan task
    and a task per revolution per file; the numbers identical to `process`. A NaN in the
    last revolution of one file fails its run with `process`'s message: read whole (small
    files) the scan meets it and the file becomes one task; streamed (forced on the workers
    and here by lowering STREAM_MIN_BYTES) the revolution's task meets it."""
    import h5py
    import numpy as np
    from dask.distributed import Client, get_task_stream

    from torquemod.processing import pipeline
    root = tmp_path / "fleet"
    write_synthetic_experiment(root / "long", n_steps=2, n_cycles=3, files_per_cycle=False,
                               fmt="hdf5", seed=7)
    shutil.copytree(root / "long", root / "long_bad")
    with h5py.File(root / "long_bad" / "step2.h5", "r+") as fh:
        n = fh["torque_nm"].shape[0]
        fh["torque_nm"][n - n // 6] = np.nan  # in revolution 3
    streamed = mode == "stream"
    if streamed:
        monkeypatch.setattr(pipeline, "STREAM_MIN_BYTES", 0)
    with Client(cluster) as client, get_task_stream(client) as stream:
        old = client.run(_set_stream_min_bytes, 0 if streamed else pipeline.STREAM_MIN_BYTES)
        try:
            res = run_fleet([root], tmp_path / "out", scheduler=cluster.scheduler_address,
                            revolutions_per_task=1, report=False)
        finally:
            client.run(_set_stream_min_bytes, next(iter(old.values())))
    kinds = sorted(t["key"].split("-")[1][:4] for t in stream.data)
    # long: 2 scans, 6 revolutions; long_bad: step 1 the same, step 2 split when streamed,
    # else one task (its scan met the NaN); a file read whole has its first revolution
    # processed by its scan
    parts = 12 if streamed else 6
    assert kinds == sorted(["fini"] * 2 + ["plan"] * 2 + ["scan"] * 4 + ["part"] * parts
                           + ["item"] * (0 if streamed else 1))
    status = dict(zip(res.summary["run"], res.summary["status"], strict=True))
    assert status == {"long": "processed", "long_bad": "failed"}
    alone = process_experiment(root / "long" / "experiment.toml", workers=1)
    assert len(alone.cycles) == 6
    for table, ref in (("cycles", alone.cycles), ("steps", alone.steps)):
        got = pd.read_parquet(tmp_path / "out" / table)
        _same(got.drop(columns=["run", "vehicle", "date"]), ref)
    with pytest.raises(TorquemodError) as exc:
        process_experiment(root / "long_bad" / "experiment.toml", workers=1)
    assert res.failures["message"].tolist() == [_one_line(exc.value)]
    assert "step2.h5" in res.failures["message"][0]
