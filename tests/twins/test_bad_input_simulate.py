"""`torquemod simulate` (rig and --train) under bad configurations and faults: one line on
stderr naming the file and the key, exit code 2, no traceback, nothing left at --out.

Each case edits one line of the shipped default configuration (so the rest stays valid) and
runs the command in this process; the values are refused when the configuration is read,
before anything is simulated.
"""

from __future__ import annotations

import errno
import re
import subprocess
import sys

import pytest

from test_outputs_safety import no_leftovers, one_error_line, raise_in, readonly  # noqa: F401
from torquemod.cli import main
from torquemod.twins.train import default_train_config_text
from torquemod.twins.vtrack.simulate import default_config_text


def _edit(text: str, key: str, value: str | None, section: str | None = None) -> str:
    """``text`` with the line ``key = ...`` set to ``value`` (None: the line removed), or
    with ``key = value`` added under ``[section]`` when the key is not there."""
    pattern = re.compile(rf"^{re.escape(key)}\s*=.*$", re.M)
    if pattern.search(text):
        return pattern.sub("" if value is None else f"{key} = {value}", text, count=1)
    return text.replace(f"[{section}]\n", f"[{section}]\n{key} = {value}\n", 1)


# (id, key, value, section for an added key, words the error line must hold)
TRAIN = [
    ("zero_sample_rate", "sample_rate_hz", "0.0", None, ("sensors.sample_rate_hz", "> 0")),
    ("zero_radius", "wheel_radius_m", "0.0", None, ("vehicle.wheel_radius_m",)),
    ("zero_mass", "mass_share_kg", "0", None, ("vehicle.mass_share_kg",)),
    ("zero_substeps", "substeps", "0", None, ("run.substeps",)),
    ("fraction_substeps", "substeps", "2.5", None, ("run.substeps", "whole number")),
    ("negative_length", "length_m", "-5.0", None, ("track.length_m",)),
    ("negative_inertia", "wheelset_inertia_kg_m2", "-160.0", None,
     ("vehicle.wheelset_inertia_kg_m2",)),
    ("string_number", "mass_share_kg", '"21000"', None, ("vehicle.mass_share_kg", "'21000'")),
    ("inf_value", "davis_a_n", "inf", None, ("vehicle.davis_a_n", "finite")),
    ("nan_value", "modulation_amplitude_nm", "nan", None,
     ("test.modulation_amplitude_nm", "finite")),
    ("typo_key", "modulation_frequncy_hz", "4.0", "test",
     ("test.modulation_frequncy_hz", "did you mean 'modulation_frequency_hz'")),
    ("above_nyquist", "modulation_frequency_hz", "600.0", None,
     ("test.modulation_frequency_hz", "Nyquist", "sensors.sample_rate_hz")),
    ("reference_too_fast", "reference_rate_hz", "5000.0", None,
     ("sensors.reference_rate_hz",)),
    ("unknown_condition", "condition", '"ice"', None, ("condition", "'ice'")),
    ("bad_leg_mode", "mode", '"fly"', None, ("controller.leg[1].mode", "'fly'")),
    ("level_above_one", "levels", "[0.2, 1.5]", None, ("controller.leg[1].levels[1]",)),
    ("poisson_above_half", "poisson_ratio", "0.7", "vehicle", ("vehicle.poisson_ratio",)),
    ("too_many_samples", "length_m", "4.0e9", None, ("samples", "track.length_m")),
    ("speed_leg_without_speed", "mode", '"speed"', None, ("controller.leg[1]", "speed_m_s")),
    ("huge_load_diverges", "normal_load_n", "1e300", None, ("diverged",)),
    ("typo_section", "kind", '"train"\n[vehicel]\nmass_kg = 1.0', None,
     ("unknown key 'vehicel'", "did you mean 'vehicle'")),
]

RIG = [
    ("nan_amplitude", "amplitude_nm", "nan", None, ("modulation.amplitude_nm", "finite")),
    ("above_nyquist", "frequency_hz", "9000.0", None,
     ("modulation.frequency_hz", "Nyquist", "sensors.sample_rate_hz")),
    ("typo_key", "frequncy_hz", "2.0", "modulation",
     ("modulation.frequncy_hz", "did you mean 'frequency_hz'")),
    ("string_number", "normal_load_n", '"4200"', None, ("rig.normal_load_n",)),
    ("poisson_above_half", "poisson_ratio", "0.7", None, ("contact.poisson_ratio",)),
    ("zero_sample_rate", "sample_rate_hz", "0.0", None, ("sensors.sample_rate_hz",)),
]


def _run_bad(tmp_path, capsys, text: str, *args: str) -> str:
    cfg = tmp_path / "config.toml"
    cfg.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["simulate", str(cfg), "--out", str(out), "--quiet", *args]) == 2
    line = one_error_line(capsys.readouterr().err, str(cfg))
    no_leftovers(tmp_path, "config.toml")
    return line


@pytest.mark.parametrize("key,value,section,words", [pytest.param(*c[1:], id=c[0])
                                                     for c in TRAIN])
def test_train_config_value_refused_with_file_and_key(tmp_path, capsys, key, value, section,
                                                      words):
    text = _edit(default_train_config_text(), key, value, section)
    line = _run_bad(tmp_path, capsys, text, "--train")
    for w in words:
        assert w in line, (w, line)


@pytest.mark.parametrize("key,value,section,words", [pytest.param(*c[1:], id=c[0])
                                                     for c in RIG])
def test_rig_config_value_refused_with_file_and_key(tmp_path, capsys, key, value, section,
                                                    words):
    line = _run_bad(tmp_path, capsys, _edit(default_config_text(), key, value, section))
    for w in words:
        assert w in line, (w, line)


def test_a_train_config_without_train_flag_is_read_as_train(tmp_path, capsys):
    """kind = "train" chooses the train reader (and its checks) without --train."""
    line = _run_bad(tmp_path, capsys, _edit(default_train_config_text(), "mass_share_kg",
                                            "-1.0"))
    assert "vehicle.mass_share_kg" in line


def test_binary_train_config_is_one_line(tmp_path, capsys):
    cfg = tmp_path / "config.toml"
    cfg.write_bytes(b"\xff\xfe\x00garbage\x81")
    assert main(["simulate", "--train", str(cfg), "--out", str(tmp_path / "out")]) == 2
    one_error_line(capsys.readouterr().err, str(cfg), "cannot read")


def test_subprocess_prints_no_traceback(tmp_path):
    cfg = tmp_path / "config.toml"
    cfg.write_text(_edit(default_train_config_text(), "substeps", "0"), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "torquemod.cli", "simulate", "--train",
                           str(cfg), "--out", str(tmp_path / "out")], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2
    one_error_line(proc.stderr, "run.substeps")
    no_leftovers(tmp_path, "config.toml")


# --------------------------------------------------------------------------- faults

SHORT_TRAIN = {"length_m": "60.0"}


@pytest.fixture
def short_train(tmp_path):
    """A 60 m train run's config (a second of simulation)."""
    text = default_train_config_text()
    for k, v in SHORT_TRAIN.items():
        text = _edit(text, k, v)
    text = text.replace("until_m = 4000.0", "until_m = 60.0")
    cfg = tmp_path / "train.toml"
    cfg.write_text(text, encoding="utf-8")
    return cfg


def test_train_disk_full_while_writing_leaves_nothing(short_train, tmp_path, capsys,
                                                      monkeypatch):
    import torquemod.twins.train.simulate as ts
    raise_in(monkeypatch, ts, "_write_h5", errno.ENOSPC)
    out = tmp_path / "out"
    assert main(["simulate", "--train", str(short_train), "--out", str(out), "--quiet"]) == 2
    one_error_line(capsys.readouterr().err, str(out), "No space left on device")
    no_leftovers(tmp_path, "train.toml")


def test_train_interrupt_while_writing_leaves_nothing(short_train, tmp_path, capsys,
                                                      monkeypatch):
    import torquemod.twins.train.simulate as ts

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt
    monkeypatch.setattr(ts, "_write_h5", interrupted)
    assert main(["simulate", "--train", str(short_train), "--out", str(tmp_path / "out"),
                 "--quiet"]) == 130
    assert capsys.readouterr().err.strip() == "torquemod: interrupted"
    no_leftovers(tmp_path, "train.toml")


def test_train_into_a_read_only_parent(short_train, tmp_path, capsys, readonly):  # noqa: F811
    (tmp_path / "ro").mkdir()
    parent = readonly(tmp_path / "ro")
    out = parent / "out"
    assert main(["simulate", "--train", str(short_train), "--out", str(out), "--quiet"]) == 2
    one_error_line(capsys.readouterr().err, str(out), "Permission denied")
    assert list(parent.iterdir()) == []


@pytest.mark.parametrize("train", [[], ["--train"]])
def test_negative_seed_is_one_line(tmp_path, capsys, train):
    assert main(["simulate", *train, "--out", str(tmp_path / "out"), "--seed", "-1"]) == 2
    one_error_line(capsys.readouterr().err, "--seed")
    no_leftovers(tmp_path)
