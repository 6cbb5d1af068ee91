"""The one results writer and the one resume record.

* every command's folder (``process``, ``onboard``, a fleet, a sweep) carries the same
  provenance block, read back by the one reader, whose SHA-256 are the files' own;
* a failure or Ctrl-C in the middle of a write leaves no folder and no temporary, in each of
  the writer's modes, and an old folder or summary untouched;
* the fleet's and the sweep's skip/redo decisions go through the one record: its reader is
  called for each part, an unchanged part is skipped, a changed parameter redoes it with a
  message saying so.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
from pathlib import Path

import pytest

import torquemod as tm
from torquemod._util import daskutil
from torquemod._util.fsutil import sha256_file
from torquemod.errors import InputError, OutputError
from torquemod.processing.provenance import BLOCK_KEYS, SOFTWARE_KEYS
from torquemod.results import resume
from torquemod.results.writer import PROVENANCE_FILE, read_provenance, write_folder
from torquemod.testing import write_short_train_run, write_synthetic_experiment

THEORY = """mode = "theory"
[grid]
modulation.frequency_hz = [1.0, 2.0]
"""


@pytest.fixture(scope="module")
def experiment(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("writer") / "exp"
    write_synthetic_experiment(d, n_steps=2, n_cycles=1, seed=4)
    return d


@pytest.fixture
def in_process_cluster(monkeypatch):
    """The fleet's tasks on an in-process cluster of one thread (fast, no worker start)."""
    @contextlib.contextmanager
    def client(scheduler=None, n_workers=None, on_dashboard=None, **_kw):
        from dask.distributed import Client, LocalCluster
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                          dashboard_address=None) as cluster, Client(cluster) as c:
            yield c
    monkeypatch.setattr(daskutil, "dask_client", client)


def _four_folders(experiment: Path, tmp_path: Path) -> dict[str, Path]:
    from torquemod.fleet.run import run_fleet
    from torquemod.sweep.run import run_sweep
    from torquemod.sweep.spec import parse_sweep
    res = tm.process(tm.read_experiment(experiment))
    out = {"results": tm.save(res, None, tmp_path / "process")}
    train = write_short_train_run(tmp_path / "train", length_m=200.0, seed=2)
    out["onboard"] = tm.onboard(tm.read_run(train / "run.toml")).save(tmp_path / "onboard")
    run_fleet([experiment], tmp_path / "fleet", report=False, fit=False)
    out["fleet"] = tmp_path / "fleet"
    sweep_file = tmp_path / "sweep.toml"
    sweep_file.write_text(THEORY, encoding="utf-8")
    run_sweep(parse_sweep(sweep_file.read_text(), path=sweep_file), tmp_path / "sweep",
              in_process=True, report=False)
    out["sweep"] = tmp_path / "sweep"
    return {k: Path(v) for k, v in out.items()}


def test_every_command_folder_carries_the_same_provenance_block(experiment, tmp_path,
                                                                in_process_cluster):
    folders = _four_folders(experiment, tmp_path)
    blocks = {kind: read_provenance(folder) for kind, folder in folders.items()}
    for kind, doc in blocks.items():
        assert set(BLOCK_KEYS) <= set(doc), kind
        assert doc["kind"] == kind
        assert sorted(doc["software"]) == sorted(SOFTWARE_KEYS)
        assert doc["software"] == blocks["results"]["software"]
        assert doc["torquemod_version"] == tm.__version__
        assert isinstance(doc["parameters"], dict) and doc["parameters"], kind
        assert doc["inputs"], kind
        for entry in doc["inputs"]:  # the digests are the files' own
            assert entry["sha256"] == sha256_file(entry["file"]), (kind, entry["file"])
    # what each block names as inputs: the recordings, run.toml and its axles, the
    # manifests, the sweep file
    assert {Path(e["file"]).name for e in blocks["fleet"]["inputs"]} == {"experiment.toml"}
    assert [Path(e["file"]).name for e in blocks["sweep"]["inputs"]] == ["sweep.toml"]
    assert "run.toml" in {Path(e["file"]).name for e in blocks["onboard"]["inputs"]}
    assert len(blocks["results"]["inputs"]) == 2  # 2 steps x 1 cycle
    # the onboard.json of earlier versions keeps its keys, taken from the same block
    meta = json.loads((folders["onboard"] / "onboard.json").read_text())
    assert meta["created_utc"] == blocks["onboard"]["created_utc"]
    assert meta["software"] == blocks["onboard"]["software"]


def test_the_reader_names_a_missing_key(tmp_path):
    (tmp_path / PROVENANCE_FILE).write_text(json.dumps({"torquemod_version": "x"}))
    with pytest.raises(InputError, match="created_utc") as info:
        read_provenance(tmp_path)
    assert str(tmp_path / PROVENANCE_FILE) in str(info.value)
    with pytest.raises(InputError, match="no provenance"):
        read_provenance(tmp_path / "nothing")


class Boom(Exception):
    pass


@pytest.mark.parametrize("exc", [Boom, KeyboardInterrupt])
def test_a_failure_mid_write_of_a_new_folder_leaves_nothing(tmp_path, exc):
    target = tmp_path / "deep" / "out"
    with pytest.raises(exc), write_folder(target, provenance={"kind": "t"}) as w:
        (w.path / "half.csv").write_text("a,b\n1,")
        raise exc
    assert list(tmp_path.iterdir()) == []  # no folder, no temporary, no lock, no parents


@pytest.mark.parametrize("exc", [Boom, KeyboardInterrupt])
def test_a_failure_mid_replace_keeps_the_old_part(tmp_path, exc):
    part = tmp_path / "points" / "point=a"
    with write_folder(part, mode="replace") as w:
        (w.path / "part-0.parquet").write_text("old")
    with pytest.raises(exc), write_folder(part, mode="replace") as w:
        (w.path / "part-0.parquet").write_text("new, half")
        raise exc
    assert [p.name for p in (tmp_path / "points").iterdir()] == ["point=a"]
    assert (part / "part-0.parquet").read_text() == "old"
    with write_folder(part, mode="replace") as w:  # and a good write replaces it whole
        (w.path / "part-1.parquet").write_text("new")
    assert [p.name for p in part.iterdir()] == ["part-1.parquet"]


@pytest.mark.parametrize("exc", [Boom, KeyboardInterrupt])
def test_a_failure_mid_summary_keeps_the_old_summary(tmp_path, exc):
    out = tmp_path / "out"
    with write_folder(out, mode="into", provenance={"kind": "t", "n": 1}) as w:
        (w.path / "summary.csv").write_text("old")
        (w.path / "figures").mkdir()
        (w.path / "figures" / "a.png").write_text("old")
    before = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    with pytest.raises(exc), write_folder(out, mode="into",
                                          provenance={"kind": "t", "n": 2}) as w:
        (w.path / "summary.csv").write_text("new")
        (w.path / "figures").mkdir()
        raise exc
    after = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # no staging folder either
    with write_folder(out, mode="into", provenance={"kind": "t", "n": 3}) as w:
        (w.path / "figures").mkdir()
        (w.path / "figures" / "b.png").write_text("new")
        w.drop("summary.csv")
    assert sorted(p.name for p in out.iterdir()) == ["figures", PROVENANCE_FILE]
    assert [p.name for p in (out / "figures").iterdir()] == ["b.png"]  # swapped whole
    assert json.loads((out / PROVENANCE_FILE).read_text())["n"] == 3


def test_process_failing_in_the_report_leaves_no_folder(experiment, tmp_path, monkeypatch):
    import torquemod.results.folder as folder
    res = tm.process(tm.read_experiment(experiment))
    ana = tm.analyze(res)

    def broken(*_a, **_k):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(folder, "write_report", broken)
    with pytest.raises(OutputError, match="No space left"):
        tm.save(res, ana, tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def test_decide_says_what_changed():
    rec = resume.ResumeRecord("p", "f1", parameters_digest="a", inputs_digest="b")
    assert resume.decide(None, "f1") == resume.Decision(True, "new")
    assert not resume.decide(rec, "f1").redo
    assert resume.decide(rec, "f1", force=True).reason == "forced"
    assert resume.decide(rec, "f1", outputs_ok=False).redo
    d = resume.decide(rec, "f2", parameters_digest="c", inputs_digest="b")
    assert d.redo and d.message == "redone: parameters changed"
    d = resume.decide(rec, "f2", parameters_digest="a", inputs_digest="c")
    assert d.message == "redone: inputs changed"
    old = dataclasses.replace(rec, version="0.0.1")
    assert "torquemod version 0.0.1" in resume.decide(old, "f2").message


def test_a_record_of_an_earlier_version_reads_back(tmp_path):
    """The fleet's records before the common keys: ``partitions`` are the outputs."""
    path = resume.record_path(tmp_path, "r")
    path.parent.mkdir()
    path.write_text(json.dumps({"fingerprint": "f", "partitions": ["steps/run=r"],
                                "files": {}, "row": {"mu": 0.3}}))
    rec = resume.read_record(tmp_path, "r")
    assert rec.outputs == ("steps/run=r",) and rec.extra["row"] == {"mu": 0.3}
    path.write_text("{not json")
    assert resume.read_record(tmp_path, "r") is None


@pytest.fixture
def counted(monkeypatch):
    """Count the calls of the one record reader."""
    calls = []
    real = resume.read_record

    def counting(out, name):
        calls.append(name)
        return real(out, name)
    monkeypatch.setattr(resume, "read_record", counting)
    return calls


def test_the_fleet_decides_through_the_record(experiment, tmp_path, counted):
    import shutil

    from torquemod.fleet.plan import process_run
    exp = tmp_path / "exp"
    shutil.copytree(experiment, exp)
    out = str(tmp_path / "out")
    first = process_run(str(exp / "experiment.toml"), out, "e", fit=False)
    assert first["status"] == "processed" and first["message"] == ""
    again = process_run(str(exp / "experiment.toml"), out, "e", fit=False)
    assert again["status"] == "skipped"
    assert counted == ["e", "e"]
    redone = process_run(str(exp / "experiment.toml"), out, "e", fit=True)  # a parameter
    assert redone["status"] == "processed"
    assert redone["message"] == "redone: parameters changed"
    assert resume.read_record(out, "e").extra["manifest"] == str(exp / "experiment.toml")


def test_the_sweep_decides_through_the_record(tmp_path, counted):
    from torquemod.sweep.evaluate import tasks
    from torquemod.sweep.run import run_point
    from torquemod.sweep.spec import parse_sweep
    task = tasks(parse_sweep(THEORY))[0]
    out = str(tmp_path / "out")
    assert run_point(task, out)["status"] == "done"
    assert run_point(task, out)["status"] == "skipped"
    assert counted == [task.point_id] * 2
    changed = dataclasses.replace(task, max_utilisation=task.max_utilisation * 0.9)
    row = run_point(changed, out)
    assert row["status"] == "done" and row["message"] == "redone: parameters changed"
    rec = resume.read_record(out, task.point_id)
    assert rec.outputs == (f"points/point={task.point_id}",) and rec.extra["n_rows"] > 0
