"""The twin's HDF5 files written by h5py's low-level calls (io/hdf5.py ``_create_flat``,
issue 12 fifth round) are the files h5py's high-level ``File`` path writes, byte for byte."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from torquemod.io.experiment import CHANNELS, Recording
from torquemod.io.hdf5 import read_hdf5, write_hdf5


def _recording(n: int, channels: tuple[str, ...]) -> Recording:
    rng = np.random.default_rng(7)
    return Recording({c: rng.standard_normal(n) for c in channels}, fs_hz=16670.0,
                     t0_s=12.345678, source="test")


@pytest.mark.parametrize(("n", "channels", "write_time"), [
    (10_000, CHANNELS[:6], True),
    (3, CHANNELS[:6], False),
    (1_000, ("torque_nm", "wheel_speed_rad_s"), True),
])
def test_low_level_file_is_byte_identical(tmp_path, n, channels, write_time):
    rec = _recording(n, tuple(c for c in channels if c in CHANNELS))
    fast = write_hdf5(tmp_path / "fast.h5", rec, write_time=write_time, data_after_close=True)
    # group="/" is the same root group but takes h5py's high-level File path
    slow = write_hdf5(tmp_path / "slow.h5", rec, group="/", write_time=write_time,
                      data_after_close=True)
    assert fast.read_bytes() == slow.read_bytes()
    back = read_hdf5(fast)
    # with time_s the reader derives the rate from the times (rounding ~1e-15 relative)
    assert back.fs_hz == pytest.approx(rec.fs_hz, rel=1e-12)
    assert back.t0_s == pytest.approx(rec.t0_s, rel=1e-15)
    for c in rec.channels:
        np.testing.assert_array_equal(back.channels[c], rec.channels[c])


def test_existing_file_takes_the_append_path(tmp_path):
    """A second write to the same file replaces the channels (h5py's append path) and
    drops the time_s it no longer writes."""
    path = tmp_path / "x.h5"
    write_hdf5(path, _recording(100, CHANNELS[:6]), write_time=True, data_after_close=True)
    rec2 = _recording(50, CHANNELS[:6])
    write_hdf5(path, rec2, data_after_close=True)
    back = read_hdf5(path)
    assert back.n_samples == 50
    with h5py.File(path, "r") as fh:
        assert "time_s" not in fh
    np.testing.assert_array_equal(back.channels["torque_nm"], rec2.channels["torque_nm"])


def test_run_is_the_same_for_any_number_of_workers(tmp_path):
    """The steps' scheduling (side by side, step 1 started while the others are planned)
    does not change a run: every file of a short run with a slipping last step is
    byte-identical on 1 and 3 threads, and the slipping step leaves no files."""
    from torquemod.twins.vtrack.simulate import load_config, run_simulation

    cfg = load_config(overrides={"procedure": {"dc_torques_nm": [22.84, 44.47, 72.0],
                                               "cycles_per_step": 1, "settle_s": 0.5}})
    runs = []
    for w in (1, 3):
        out = tmp_path / f"w{w}"
        truth = run_simulation(cfg, out, seed=11, fmt="hdf5", progress=False, workers=w)
        runs.append({p.name: p.read_bytes() for p in sorted(out.iterdir())})
        assert truth["slip_step"] == 3
    assert runs[0].keys() == runs[1].keys()
    assert sorted(k for k in runs[0] if k.endswith(".h5")) == ["step01_cycle1.h5",
                                                               "step02_cycle1.h5"]
    for name in runs[0]:
        assert runs[0][name] == runs[1][name], name
