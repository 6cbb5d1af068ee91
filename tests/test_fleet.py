"""The fleet on Dask (torquemod.fleet): a LocalCluster of 2 worker processes, a small fleet
with a damaged run, against the same runs processed one by one in this process."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest

from torquemod.errors import TorquemodError
from torquemod.fleet import find_manifests, run_fleet, run_names
from torquemod.pipeline import process_experiment
from torquemod.testing import write_synthetic_experiment


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    for k, name in enumerate(("axle1", "axle2")):
        write_synthetic_experiment(root / name, n_steps=2, n_cycles=1, fmt="hdf5", seed=k)
    shutil.copytree(root / "axle1", root / "damaged")
    bad = root / "damaged" / "step2_cycle1.h5"
    bad.write_bytes(bad.read_bytes()[:5000])  # truncated, as by a full disk
    return root


def test_fleet_on_two_worker_processes(fleet, tmp_path):
    out = tmp_path / "out"
    links = []
    res = run_fleet([fleet], out, n_workers=2, on_dashboard=links.append)
    assert res.count("processed") == 2 and res.count("failed") == 1
    # the damaged run: one row, the same one-line message `torquemod process` gives
    with pytest.raises(TorquemodError) as exc:
        process_experiment(fleet / "damaged" / "experiment.toml", workers=1)
    assert res.failures["run"].tolist() == ["damaged"]
    assert res.failures["message"].iloc[0] == str(exc.value).splitlines()[0]
    assert "step2_cycle1.h5" in res.failures["message"].iloc[0]
    assert pd.read_csv(out / "failures.csv")["run"].tolist() == ["damaged"]
    # the dataset, partitioned by run, read directly by pandas; numbers identical to
    # single runs
    cycles = pd.read_parquet(out / "cycles")
    assert sorted(cycles["run"].astype(str).unique()) == ["axle1", "axle2"]
    for run in ("axle1", "axle2"):
        alone = process_experiment(fleet / run / "experiment.toml", workers=1).cycles
        got = cycles[cycles["run"].astype(str) == run].drop(columns="run")
        pd.testing.assert_frame_equal(got.reset_index(drop=True),
                                      alone.reset_index(drop=True), check_dtype=False,
                                      rtol=0, atol=0)
    steps = pd.read_parquet(out / "steps")
    assert len(steps) == 4
    # a rerun skips unchanged runs (same partition file), retries the damaged one, and
    # reprocesses a run whose manifest changed
    part = out / "cycles" / "run=axle1" / "part-0.parquet"
    stamp = part.stat().st_mtime_ns
    manifest = fleet / "axle2" / "experiment.toml"
    manifest.write_text(manifest.read_text() + "\n# edited\n")
    again = run_fleet([fleet], out, n_workers=2)
    status = dict(zip(again.summary["run"], again.summary["status"], strict=True))
    assert status == {"axle1": "skipped", "axle2": "processed", "damaged": "failed"}
    assert part.stat().st_mtime_ns == stamp


def test_finding_manifests(fleet, tmp_path):
    lst = tmp_path / "runs.txt"
    lst.write_text(f"# the fleet\n{fleet / 'axle1'}\n{fleet / 'axle2' / 'experiment.toml'}\n")
    assert [p.parent.name for p in find_manifests([lst])] == ["axle1", "axle2"]
    assert len(find_manifests([str(fleet / "*" / "experiment.toml")])) == 3
    same = [fleet / "axle1" / "experiment.toml", tmp_path / "x" / "axle1" / "experiment.toml"]
    names = run_names(same)
    assert names[0] != names[1] and all(n.startswith("axle1-") for n in names)
    with pytest.raises(TorquemodError):
        find_manifests([tmp_path / "nothing-here"])


def test_file_digest_reused_only_while_size_and_mtime_hold(tmp_path):
    import hashlib
    import os

    from torquemod.fleet import _file_digest
    path = tmp_path / "rec.bin"
    path.write_bytes(b"abc" * 1000)
    first = _file_digest(path, {})
    assert first[2] == hashlib.sha256(b"abc" * 1000).hexdigest()
    fake = {str(path): [first[0], first[1], "recorded"]}
    assert _file_digest(path, fake)[2] == "recorded"  # unchanged: not read again
    path.write_bytes(b"abd" * 1000)  # same size, new content and time
    os.utime(path, ns=(first[1] + 10**9, first[1] + 10**9))
    assert _file_digest(path, fake)[2] == hashlib.sha256(b"abd" * 1000).hexdigest()


def test_fleet_command_line(fleet, tmp_path, capsys):
    """`torquemod fleet`: exit 0 with the damaged run named on stderr, the counts and the
    results folder on stdout; a rerun reports the good runs unchanged."""
    from torquemod.cli import main

    out = tmp_path / "fl"
    args = ["fleet", str(fleet / "axle1"), str(fleet / "damaged"), "--out", str(out),
            "--workers", "1", "--quiet"]
    assert main(args) == 0
    io = capsys.readouterr()
    assert "2 runs: 1 processed, 0 unchanged (skipped), 1 failed" in io.out
    assert "failed: damaged:" in io.err and "step2_cycle1.h5" in io.err
    assert f"results: {out}" in io.out
    assert main(args) == 0
    assert "1 unchanged (skipped)" in capsys.readouterr().out
