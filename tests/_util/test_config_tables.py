"""Every configuration table a user writes (processing, the rig and train twins, [onboard],
sweep files, experiment.toml, run.toml) is read by one reader
(:func:`torquemod._util.tomlcheck.read_table`): for each, a misspelt key is refused with the
nearest known key, a value of the wrong type and a value out of range are refused, and the
message names the file and the dotted key."""

from __future__ import annotations

import dataclasses
import tomllib

import pytest
import tomli_w

from torquemod._util.tomlcheck import POSITIVE, Check, check_fields, checked, read_table
from torquemod.errors import InputError
from torquemod.io.config import ProcessingConfig
from torquemod.io.manifest import experiment_from_doc
from torquemod.io.run import read_run
from torquemod.ontrain.estimator import OnboardConfig
from torquemod.sweep.spec import parse_sweep
from torquemod.twins.train.params import default_train_config_text, load_train_config
from torquemod.twins.vtrack.params import DEFAULT_DOC, ModulationParams, ProcedureParams
from torquemod.twins.vtrack.simconfig import SimTables, default_tables, load_config

MANIFEST = {"rig": {"wheel_radius_m": 0.0675, "platform_radius_m": 2.0},
            "test": {"normal_load_n": 4200.0, "modulation_frequency_hz": 2.0,
                     "modulation_amplitude_nm": 8.0},
            "recording": [{"step": 1, "dc_torque_nm": 10.0, "file": "s1.csv"}]}
RUN = {"vehicle": {"wheel_radius_m": 0.46, "normal_load_n": 2e5, "inertia_kg_m2": 270.0},
       "test": {"modulation_frequency_hz": 5.0, "modulation_amplitude_nm": 1500.0},
       "recording": [{"file": "run.csv"}]}


def _read(kind: str, doc: dict, path):
    """Write ``doc`` to ``path`` (for the file readers) and read it as ``kind`` does."""
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    if kind == "processing":
        return ProcessingConfig.from_dict(doc["processing"], source=str(path))
    if kind == "onboard":
        return OnboardConfig.from_dict(doc["onboard"], source=str(path))
    if kind == "rig twin":
        return load_config(path)
    if kind == "train twin":
        return load_train_config(path)
    if kind == "sweep":
        return parse_sweep(path.read_text(encoding="utf-8"), path=path)
    if kind == "run":
        return read_run(path)
    return experiment_from_doc(doc, path)


@dataclasses.dataclass(frozen=True)
class Misspelt:
    """The key given under another name (the manifest's [rig] and [test] keep keys they do
    not know: there a misspelt key is a missing one)."""

    key: str


def _doc(kind: str, dotted: str, value) -> dict:
    """The smallest valid document of ``kind`` with ``dotted`` set to ``value`` (a list
    index in the key, ``recording.0.step``, reaches into an array of tables)."""
    doc = {"manifest": lambda: tomllib.loads(tomli_w.dumps(MANIFEST)),
           "run": lambda: tomllib.loads(tomli_w.dumps(RUN)),
           "train twin": lambda: tomllib.loads(default_train_config_text())}.get(kind, dict)()
    *parents, leaf = dotted.split(".")
    node = doc
    for p in parents:
        node = node[int(p)] if p.isdigit() else node.setdefault(p, {})
    if isinstance(value, Misspelt):
        node[value.key] = node.pop(leaf)
    else:
        node[leaf] = value
    return doc


CASES = [  # (config, key, value, what the message says besides the file)
    ("processing", "processing.bandpas.width_hz", 0.3,
     ["'processing.bandpas'", "did you mean 'bandpass'"]),
    ("processing", "processing.phase.n_periods", 2.5,
     ["'processing.phase.n_periods'", "whole number", "2.5"]),
    ("processing", "processing.highpass.cutoff_hz", -0.5,
     ["'processing.highpass.cutoff_hz'", "> 0", "-0.5"]),
    ("processing", "processing.frequency.band_hz", [2.5, 1.5],
     ["'processing.frequency.band_hz'", "low < high"]),
    ("processing", "processing.phase.method", "median",
     ["'processing.phase.method'", "'paper'", "'median'"]),
    ("rig twin", "modulation.frequncy_hz", 2.0,
     ["'modulation.frequncy_hz'", "did you mean 'frequency_hz'"]),
    ("rig twin", "rig.normal_load_n", "heavy", ["'rig.normal_load_n'", "finite number"]),
    ("rig twin", "contact.poisson_ratio", 0.7, ["'contact.poisson_ratio'", "(0, 0.5)", "0.7"]),
    ("rig twin", "procedure.cycles_per_step", 0,
     ["'procedure.cycles_per_step'", "whole number >= 1"]),
    ("rig twin", "contact.preset", "icy", ["'contact.preset'", "'vtrack'", "'icy'"]),
    ("rig twin", "disturbances.speed_wobble_band_hz", [0.6, 0.2],
     ["'disturbances.speed_wobble_band_hz'", "low <= high"]),
    ("train twin", "vehicle.wheel_radius", 0.46,
     ["'vehicle.wheel_radius'", "did you mean 'wheel_radius_m'"]),
    ("train twin", "run.substeps", 2.5, ["'run.substeps'", "whole number"]),
    ("train twin", "sensors.torque_noise_nm", -1.0, ["'sensors.torque_noise_nm'", ">= 0"]),
    ("onboard", "onboard.hopp_s", 0.5, ["'onboard.hopp_s'", "did you mean 'hop_s'"]),
    ("onboard", "onboard.memory_m", "far", ["'onboard.memory_m'", "finite number"]),
    ("onboard", "onboard.info_utilisation", 1.5, ["'onboard.info_utilisation'", "(0, 1]"]),
    ("sweep", "recommend.max_swing", 1.0, ["'recommend.max_swing'", "max_creepage_swing"]),
    ("sweep", "recommend.min_coverage", "most", ["'recommend.min_coverage'", "finite number"]),
    ("sweep", "steps.fractions_of_peak", [0.5, 1.2],
     ["'steps.fractions_of_peak[1]'", "[0, 1)"]),
    ("sweep", "fixed.contact.mu0", -0.3, ["[fixed]", "'contact.mu0'", "> 0"]),
    ("sweep", "grid.procedure.substeps", [1, True], ["[grid]", "'procedure.substeps'",
                                                      "whole number"]),
    ("manifest", "rig.wheel_radius_m", Misspelt("wheel_radius"),
     ["missing key 'rig.wheel_radius_m'", "is 'wheel_radius' meant to be 'wheel_radius_m'"]),
    ("manifest", "test.normal_load_n", "4200", ["'test.normal_load_n'", "finite number"]),
    ("manifest", "rig.platform_radius_m", 0.0, ["'rig.platform_radius_m'", "positive"]),
    ("manifest", "recording.0.dc_torqe_nm", 1.0, ["recording #1", "'dc_torqe_nm'",
                                                   "did you mean 'dc_torque_nm'"]),
    ("manifest", "recording.0.step", 0, ["recording #1", "'step'", "whole number >= 1"]),
    ("manifest", "recording.0.sample_rate_hz", "fast", ["recording #1", "'sample_rate_hz'"]),
    ("run", "vehicle.wheel_radius", 0.46, ["'vehicle.wheel_radius'",
                                           "did you mean 'wheel_radius_m'"]),
    ("run", "vehicle.torque_lag_s", "2 ms", ["'vehicle.torque_lag_s'", "finite number"]),
    ("run", "vehicle.speed_delay_s", 1.5, ["'vehicle.speed_delay_s'", "a time in seconds",
                                           "e.g. 0.002 for 2 ms"]),
    ("run", "recording.0.axle", 0, ["recording #1", "'axle'", "whole number >= 1"]),
]


@pytest.mark.parametrize("kind, key, value, words", CASES,
                         ids=[f"{c[0]}:{c[1]}" for c in CASES])
def test_a_mistake_names_the_file_and_the_key(tmp_path, kind, key, value, words):
    path = tmp_path / f"{kind.replace(' ', '_')}.toml"
    with pytest.raises(InputError) as info:
        _read(kind, _doc(kind, key, value), path)
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    for w in words:
        assert w in msg, (w, msg)


def test_valid_tables_read_to_their_values(tmp_path):
    """The same readers take the valid tables, converting as declared (int to float, list
    to tuple) and keeping the rest at its default."""
    cfg = _read("processing", {"processing": {"notch": {"q": 4, "wheel_harmonics": []}}},
                tmp_path / "p.toml")
    assert cfg.notch.q == 4.0 and isinstance(cfg.notch.q, float)
    assert cfg.notch.wheel_harmonics == () and cfg.bandpass == ProcessingConfig().bandpass
    twin = _read("rig twin", {"procedure": {"dc_torques_nm": [10, 20]}}, tmp_path / "t.toml")
    assert twin.procedure.dc_torques_nm == (10.0, 20.0)
    exp = _read("manifest", _doc("manifest", "rig.gauge_m", 1.435), tmp_path / "e.toml")
    assert exp.rig.extra == {"gauge_m": 1.435} and exp.rig.wheel_radius_m == 0.0675


def test_the_rig_twin_defaults_have_one_source():
    """The dataclasses of the rig twin's tables take their defaults from
    vtrack_default.toml (the code reads it): each field's default is the file's value."""
    tables = default_tables()
    assert tables == SimTables()
    for section in dataclasses.fields(SimTables):
        for f in dataclasses.fields(type(getattr(tables, section.name))):
            want = DEFAULT_DOC[section.name][f.name]
            assert f.default == (tuple(want) if isinstance(want, list) else want)
    assert ModulationParams().frequency_offset == DEFAULT_DOC["modulation"]["frequency_offset"]
    assert ProcedureParams().dc_torques_nm == tuple(DEFAULT_DOC["procedure"]["dc_torques_nm"])


@dataclasses.dataclass(frozen=True)
class Leg:
    until_m: float = checked(check=POSITIVE)


@dataclasses.dataclass(frozen=True)
class Plan:
    legs: tuple[Leg, ...] = ()
    band: tuple[float, float] = checked((1.0, 2.0), Check(
        lo=0.0, test=lambda b: b[0] < b[1], need="[low, high] with low < high"))


def test_read_table_nested_lists_and_checks_in_code():
    """Sub-tables and lists of tables are read with their dotted keys; a value built in code
    is checked by the same declaration (:func:`check_fields`)."""
    plan = read_table(Plan, {"legs": [{"until_m": 5}, {"until_m": 9.5}]}, section="plan",
                      path="p.toml")
    assert plan.legs == (Leg(5.0), Leg(9.5))
    with pytest.raises(InputError, match=r"p\.toml: 'plan\.legs\[2\]\.until_m' must be a "
                                         r"positive number \(> 0\), got -1"):
        read_table(Plan, {"legs": [{"until_m": 5}, {"until_m": -1}]}, section="plan",
                   path="p.toml")
    with pytest.raises(InputError, match=r"missing key 'plan\.legs\[1\]\.until_m'"):
        read_table(Plan, {"legs": [{}]}, section="plan", path="p.toml")
    with pytest.raises(InputError, match=r"'plan\.band' must be \[low, high\] with low < high"):
        check_fields(Plan(band=(3.0, 2.0)), "plan")
