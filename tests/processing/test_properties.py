"""Property-based tests of the processing chain (hypothesis).

* A known delay of the wheel-speed modulation gives that phase, for any modulation amplitude,
  frequency offset and noise level in the method's range, within a tolerance set by the
  Cramér-Rao bound of the noise (plus a small floor for the deterministic tones).
* The phase does not depend on the unit of a channel: scaling the torque channel, or writing it
  in another unit and saying so in the manifest's ``[channels]``, gives the same numbers.
* The order of the manifest's ``[[recording]]`` tables does not change the results.

Recordings are built at 2 000 Hz (the chain resamples to 53.344 Hz, so the rate does not
matter beyond the noise per resampled sample) and example counts are small: the file runs in
well under a minute.
"""

from __future__ import annotations

import dataclasses
import shutil
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from torquemod.dsp.phase import phase_crb_deg
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Recording, Rig
from torquemod.io.units import UNITS
from torquemod.processing import chain
from torquemod.processing.pipeline import process_experiment
from torquemod.testing import SyntheticSpec, synthetic_recording, write_synthetic_experiment

FS_HZ = 2000.0
BASE = SyntheticSpec(fs_hz=FS_HZ)
RIG = Rig(wheel_radius_m=BASE.wheel_radius_m, platform_radius_m=BASE.platform_radius_m)
SETTINGS = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


def _phase(rec: Recording, cfg: ProcessingConfig) -> tuple[float, chain.CycleSignals]:
    """Phase [deg] of one cycle through steps 1-5 and 7 of the chain."""
    sig = chain.process_cycle(rec, RIG, cfg, where="synthetic")
    phase, _, _ = chain.cycle_phase(sig, cfg, center_index=sig.torque_filtered.size / 2)
    return phase, sig


@SETTINGS
@given(lag_deg=st.floats(5.0, 70.0),
       torque_amp=st.floats(4.0, 12.0),
       wheel_amp=st.floats(1.5e-3, 4e-3),
       f_offset=st.floats(-0.02, 0.02),
       noise=st.one_of(st.just(0.0), st.floats(0.05, 1.0)),
       mod_phase=st.floats(0.0, 2 * np.pi),
       method=st.sampled_from(["paper", "sinefit"]),
       seed=st.integers(0, 2**31 - 1))
def test_known_delay_gives_known_phase(lag_deg, torque_amp, wheel_amp, f_offset, noise,
                                       mod_phase, method, seed):
    spec = dataclasses.replace(
        BASE, phase_lag_deg=lag_deg, modulation_amplitude_nm=torque_amp,
        wheel_mod_amplitude_rad_s=wheel_amp, modulation_hz=2.0 + f_offset,
        modulation_phase_rad=mod_phase, seed=seed,
        torque_noise_nm=noise * BASE.torque_noise_nm,
        wheel_noise_rad_s=noise * BASE.wheel_noise_rad_s)
    rec = synthetic_recording(spec)
    phase, sig = _phase(rec, ProcessingConfig().with_phase_method(method))
    assert sig.modulation_hz == pytest.approx(spec.modulation_hz, abs=5e-3)
    # noise bound over the samples the estimator uses (paper: 3 periods; sinefit: whole
    # cycle), at 2 000 Hz; 6 sigma of the paper estimator (1.3x CRB), plus a 0.6 deg floor for
    # the vibration/eccentricity tones and band-pass leakage that do not scale with noise
    n_used = rec.n_samples if method == "sinefit" else round(3 / spec.modulation_hz * FS_HZ)
    sigma = 0.0 if noise == 0 else 1.3 * phase_crb_deg(
        torque_amp, wheel_amp, spec.torque_noise_nm, spec.wheel_noise_rad_s, n_used)
    err = (phase - lag_deg + 180.0) % 360.0 - 180.0
    assert abs(err) < 0.6 + 6 * sigma, (phase, lag_deg, sigma)


@SETTINGS
@given(scale=st.floats(1e-4, 1e4), lag_deg=st.floats(5.0, 60.0),
       method=st.sampled_from(["paper", "sinefit"]), seed=st.integers(0, 1000))
def test_scaling_the_torque_channel_does_not_change_the_phase(scale, lag_deg, method, seed):
    spec = dataclasses.replace(BASE, phase_lag_deg=lag_deg, seed=seed)
    rec = synthetic_recording(spec)
    scaled = Recording({**rec.channels, "torque_nm": rec.channels["torque_nm"] * scale},
                       rec.fs_hz, rec.t0_s, rec.source)
    cfg = ProcessingConfig().with_phase_method(method)
    p0, s0 = _phase(rec, cfg)
    p1, s1 = _phase(scaled, cfg)
    assert p1 == pytest.approx(p0, abs=1e-6)
    assert s1.modulation_hz == pytest.approx(s0.modulation_hz, rel=1e-9)
    assert (s1.creepage, s1.coa) == pytest.approx((s0.creepage, s0.coa), rel=1e-12)


@pytest.fixture(scope="module")
def small_experiment(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("props") / "exp"
    write_synthetic_experiment(folder, n_steps=3, n_cycles=2, fmt="csv", seed=21, base=BASE)
    return folder


@pytest.fixture(scope="module")
def baseline(small_experiment):
    return process_experiment(small_experiment / "experiment.toml", workers=1)


def _frames_equal(a, b) -> None:
    pd.testing.assert_frame_equal(a.cycles.reset_index(drop=True),
                                  b.cycles.reset_index(drop=True), rtol=1e-9, atol=1e-12)
    pd.testing.assert_frame_equal(a.steps, b.steps, rtol=1e-9, atol=1e-12)


@settings(max_examples=6, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(unit=st.sampled_from([u for u in UNITS["torque"] if u != "N*m"]))
def test_torque_unit_in_the_manifest_does_not_change_results(small_experiment, baseline, unit):
    """Every torque file rewritten in ``unit``, declared in ``[channels]``: same results."""
    factor = UNITS["torque"][unit]
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / "exp"
        shutil.copytree(small_experiment, d)
        for path in d.glob("*.csv"):
            df = pd.read_csv(path)
            df["torque_nm"] = df["torque_nm"] / factor
            df.to_csv(path, index=False, float_format="%.17g")
        doc = tomllib.loads((d / "experiment.toml").read_text(encoding="utf-8"))
        doc["channels"] = {"torque": {"name": "torque_nm", "unit": unit}}
        (d / "experiment.toml").write_text(tomli_w.dumps(doc), encoding="utf-8")
        res = process_experiment(d / "experiment.toml", workers=1)
    a, b = baseline.cycles, res.cycles
    assert np.allclose(b["phase_deg"], a["phase_deg"], rtol=0, atol=1e-6)
    assert np.allclose(b["modulation_hz"], a["modulation_hz"], rtol=1e-9)
    assert np.allclose(b[["creepage", "coa"]], a[["creepage", "coa"]], rtol=1e-9)


@settings(max_examples=8, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_manifest_order_does_not_change_results(small_experiment, baseline, data):
    doc = tomllib.loads((small_experiment / "experiment.toml").read_text(encoding="utf-8"))
    doc["recording"] = data.draw(st.permutations(doc["recording"]))
    with tempfile.NamedTemporaryFile("w", suffix=".toml", dir=small_experiment,
                                     delete=False, encoding="utf-8") as fh:
        fh.write(tomli_w.dumps(doc))
    try:
        res = process_experiment(Path(fh.name), workers=data.draw(st.sampled_from([1, 3])))
    finally:
        Path(fh.name).unlink()
    _frames_equal(res, baseline)
    assert sorted(d["source"] for d in res.cycle_details) == sorted(
        d["source"] for d in baseline.cycle_details)
