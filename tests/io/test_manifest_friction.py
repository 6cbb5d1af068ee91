"""Manifest mistakes a newcomer makes get one clear line (issue 9's friction list)."""

from __future__ import annotations

import tomllib

import pytest
import tomli_w

from torquemod.cli import main
from torquemod.errors import ManifestError
from torquemod.io import read_experiment
from torquemod.testing import write_synthetic_experiment


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    folder = tmp_path_factory.mktemp("exp")
    write_synthetic_experiment(folder, n_steps=1, n_cycles=1, fmt="csv", seed=1)
    return folder


@pytest.mark.parametrize("suffix,kind", [(".csv", "CSV"), (".h5", "HDF5"),
                                         (".tdms", "TDMS"), (".mf4", "MDF4")])
def test_a_recording_given_as_manifest(tmp_path, capsys, suffix, kind):
    rec = tmp_path / f"run{suffix}"
    rec.write_bytes(b"time_s,torque_nm\n0,1\n")
    assert main(["process", str(rec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(rec) in err
    assert f"is a {kind} recording, not an experiment manifest" in err
    assert "TOML" not in err and "[[recording]]" in err
    assert not (tmp_path / "out").exists()


def test_unknown_recording_key_names_it_and_the_nearest(experiment, tmp_path):
    doc = tomllib.loads((experiment / "experiment.toml").read_text(encoding="utf-8"))
    doc["recording"][0]["dc_torqe_nm"] = 1.0  # a typo beside the right key
    bad = tmp_path / "experiment.toml"
    bad.write_text(tomli_w.dumps(doc), encoding="utf-8")
    for f in experiment.iterdir():
        if f.suffix == ".csv":
            (tmp_path / f.name).write_bytes(f.read_bytes())
    with pytest.raises(ManifestError) as exc:
        read_experiment(bad)
    msg = str(exc.value)
    assert "recording #1: unknown key 'dc_torqe_nm'" in msg
    assert "did you mean 'dc_torque_nm'" in msg and str(bad) in msg


def test_valid_keys_still_accepted(experiment):
    exp = read_experiment(experiment / "experiment.toml")
    assert len(exp.recordings) == 1
