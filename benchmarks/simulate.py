"""Throughput of the V-Track digital twin: simulated seconds per wall-clock second.

Run: ``python benchmarks/simulate.py``. Prints the figure for the integrator alone (the
default procedure's rig time, settling included, at 16 670 Hz) and for a complete
``run_simulation`` of the default experiment writing HDF5 and CSV. Target: >= 100x real time.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from torquemod.rig.dynamics import OUT_COLUMNS, initial_state, integrate, pack_parameters
from torquemod.simulate import load_config, run_simulation
from torquemod.theory import operating_point


def integrator_throughput(config) -> tuple[float, float]:
    """(simulated seconds, wall seconds) of the bare integrator over the default procedure."""
    rig, proc, mod = config.rig, config.procedure, config.modulation
    fs = config.sensors.sample_rate_hz
    p = pack_parameters(rig, config.disturbances)
    op = operating_point(proc.dc_torques_nm[0], rig)
    n_step = math.ceil((proc.settle_s + proc.cycles_per_step * rig.revolution_s) * fs)
    out = np.empty((n_step, len(OUT_COLUMNS)))
    # compile outside the timing
    y = initial_state(rig, creepage=op.creepage, dc_torque_nm=proc.dc_torques_nm[0],
                      contact_fx_n=op.fx_n)
    integrate(y.copy(), 0.0, 10, 1 / fs, proc.substeps, p, 0.0, 0.0, 0.0, 0.5, 8.0, 12.6, 0.0,
              0.0, proc.slip_creepage, out)
    t_sim, t0, prev = 0.0, time.perf_counter(), proc.dc_torques_nm[0]
    for dc in proc.dc_torques_nm[:6]:
        n, _slipped = integrate(y, t_sim, n_step, 1 / fs, proc.substeps, p, prev, dc, t_sim,
                                proc.ramp_s, mod.amplitude_nm,
                                2 * np.pi * mod.actual_frequency_hz, 0.3, t_sim,
                                proc.slip_creepage, out)
        t_sim += n / fs
        prev = dc
    return t_sim, time.perf_counter() - t0


def main() -> None:
    config = load_config()
    sim_s, wall_s = integrator_throughput(config)
    print(f"integrator: {sim_s:.1f} s of rig time in {wall_s:.2f} s wall "
          f"-> {sim_s / wall_s:.0f} x real time")
    for fmt in ("hdf5", "csv"):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            truth = run_simulation(config, Path(tmp) / "exp", seed=0, fmt=fmt, progress=False)
            wall = time.perf_counter() - t0
            n_rec = sum(1 for s in truth["steps"] if not s["slipped"])
            rec_s = n_rec * config.procedure.cycles_per_step * config.rig.revolution_s
            print(f"run_simulation ({fmt}): {rec_s:.1f} s recorded (7 channels at "
                  f"{config.sensors.sample_rate_hz:g} Hz) in {wall:.2f} s wall "
                  f"-> {rec_s / wall:.0f} x real time")


if __name__ == "__main__":
    main()
