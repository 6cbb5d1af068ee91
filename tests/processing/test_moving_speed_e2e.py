"""End to end on a moving speed (issue 8): a synthetic experiment whose speed loop wobbles,
written as loggers write it (MDF4, TDMS, .mat v5 at 10-25.6 kHz, own channel names and units),
processed by ``process_experiment`` with both phase methods, checked against the injected
truth per step with the issue's acceptance tolerances (sine fit 0.3 deg, paper 0.5 deg,
creepage 2e-5, CoA 5e-4)."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.io import read_experiment, write_manifest
from torquemod.io.config import ProcessingConfig
from torquemod.processing.pipeline import process_experiment
from torquemod.testing import SyntheticSpec, synthetic_recording

NAMES = {"torque_nm": "Torque", "wheel_speed_rad_s": "WheelSpeed",
         "platform_speed_rad_s": "PlatformSpeed", "fx_n": "Fx", "fy_n": "Fy", "fz_n": "Fz"}
UNITS = {"torque_nm": "N*m", "wheel_speed_rad_s": "rpm", "platform_speed_rad_s": "rad/s",
         "fx_n": "N", "fy_n": "N", "fz_n": "kN"}
SCALE = {"wheel_speed_rad_s": 60 / (2 * np.pi), "fz_n": 1e-3}


@pytest.mark.parametrize("fmt,fs_hz", [("mdf", 10_000.0), ("tdms", 25_600.0),
                                       ("mat5", 16_670.0)])
def test_logger_experiment_with_wobble(fmt, fs_hz, tmp_path, write_columns):
    suffix = {"mdf": "mf4", "tdms": "tdms", "mat5": "mat"}[fmt]
    rng = np.random.default_rng(7)
    truth, entries = [], []
    for step, (lag, xi, dc, amp) in enumerate([(11.0, 2e-3, 5.0, 0.03),
                                               (24.0, 6e-3, 40.0, 0.06),
                                               (52.0, 1.4e-2, 60.0, 0.11)], start=1):
        for cyc in (1, 2):
            spec = SyntheticSpec(
                fs_hz=fs_hz, phase_lag_deg=lag, creepage=xi, dc_torque_nm=dc,
                wheel_mod_amplitude_rad_s=amp, modulation_hz=2.0 + rng.uniform(-4e-3, 4e-3),
                modulation_phase_rad=float(rng.uniform(0, 6.3)),
                speed_wobble=((0.003 * np.sqrt(2), float(rng.uniform(0.2, 0.6)),
                               float(rng.uniform(0, 6.3))),),
                speed_wobble_rev=((0.002, 1.0), (0.001, 2.0)), seed=int(rng.integers(1e6)))
            rec = synthetic_recording(spec)
            cols = {NAMES[k]: v * SCALE.get(k, 1.0) for k, v in rec.channels.items()}
            name = f"s{step}c{cyc}.{suffix}"
            write_columns(fmt, tmp_path / name, cols,
                          units={NAMES[k]: u for k, u in UNITS.items()}, fs_hz=fs_hz,
                          t0_s=1.7e9 if fmt == "mdf" else 0.0)
            entries.append({"step": step, "cycle": cyc, "dc_torque_nm": dc, "file": name})
            truth.append((step, lag, xi, spec.coa))
    write_manifest(tmp_path / "experiment.toml",
                   rig={"wheel_radius_m": 0.0675, "platform_radius_m": 2.0},
                   test={"normal_load_n": 4200.0, "modulation_frequency_hz": 2.0,
                         "modulation_amplitude_nm": 8.0},
                   recordings=entries,
                   extra={"channels": {"torque": "Torque",
                                       "wheel_speed": {"name": "WheelSpeed", "unit": "rpm"},
                                       "platform_speed": "PlatformSpeed", "fx": "Fx",
                                       "fy": "Fy", "fz": {"name": "Fz", "unit": "kN"}}})
    exp = read_experiment(tmp_path / "experiment.toml")
    for method, tol in (("sinefit", 0.3), ("paper", 0.5)):
        res = process_experiment(exp, config=ProcessingConfig().with_phase_method(method),
                                 workers=1)
        assert not res.steps.slip.any()
        for step, lag, xi, coa in truth[::2]:
            row = res.steps[res.steps.step == step].iloc[0]
            assert abs(row.phase_deg - lag) < tol, (method, step, row.phase_deg - lag)
            assert abs(row.creepage - xi) < 2e-5
            assert abs(row.coa - coa) < 5e-4
