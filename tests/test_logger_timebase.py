"""Logger realities (issue 8): channels on their own time bases are put on the torque
channel's sample times (or refused), never silently misaligned; provenance notes say so.

Truth: smooth signals sampled at known times; a channel written with a start offset or at
another rate must read back as the same signal at the torque's times. Linear interpolation
of a 2 Hz sine sampled at 10 kHz errs by at most (2*pi*2/1e4)^2/8 = 2e-7 of its amplitude;
the tolerance 1e-6 leaves room for the float32/rounding of the formats.
"""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.errors import InputError
from torquemod.io import read_recording
from torquemod.io.validate import sample_rate_from_time

FS = 10_000.0
N = 20_000


def _signal(name: str, t: np.ndarray) -> np.ndarray:
    """Each channel a distinct smooth function of absolute time."""
    k = {"torque_nm": 1.0, "wheel_speed_rad_s": 2.0, "platform_speed_rad_s": 3.0,
         "fx_n": 4.0, "fy_n": 5.0, "fz_n": 6.0}[name]
    return 10 * k + np.sin(2 * np.pi * 2.0 * t + k) + 0.3 * np.cos(2 * np.pi * 0.7 * t * k)


def _write_tdms(path, offsets_s: dict[str, float], rates_hz: dict[str, float] | None = None):
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    rates_hz = rates_hz or {}
    objs = [GroupObject("Meas")]
    for name, off in offsets_s.items():
        fs = rates_hz.get(name, FS)
        n = int(N * fs / FS)
        t = off + np.arange(n) / fs
        objs.append(ChannelObject("Meas", name, _signal(name, t),
                                  properties={"wf_increment": 1.0 / fs, "wf_start_offset": off}))
    with TdmsWriter(str(path)) as w:
        w.write_segment(objs)
    return path


NAMES = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")


@pytest.mark.parametrize("offset_s", [3 / FS, 2.37 / FS, -0.0125])
def test_tdms_start_offsets_are_aligned(tmp_path, offset_s):
    offsets = dict.fromkeys(NAMES, 0.0) | {"wheel_speed_rad_s": offset_s}
    rec = read_recording(_write_tdms(tmp_path / "a.tdms", offsets))
    t = rec.time_s()
    for name in NAMES:
        np.testing.assert_allclose(rec.channels[name], _signal(name, t), atol=1e-6)
    assert any("wheel_speed_rad_s" in n and "own time base" in n for n in rec.notes)
    assert abs(rec.duration_s - N / FS) < abs(offset_s) + 2 / FS  # cut to the common span


def test_tdms_channel_at_another_rate(tmp_path):
    offsets = dict.fromkeys(NAMES, 0.0)
    rec = read_recording(_write_tdms(tmp_path / "b.tdms", offsets, {"fz_n": 2_500.0}))
    assert rec.fs_hz == pytest.approx(FS)
    # fz at 2.5 kHz interpolated: (2*pi*4.2 Hz/2500)^2/8 of its 1.3 amplitude ~ 2e-5
    np.testing.assert_allclose(rec.channels["fz_n"], _signal("fz_n", rec.time_s()), atol=5e-5)


def test_channel_not_covering_the_span_is_refused(tmp_path):
    offsets = dict.fromkeys(NAMES, 0.0) | {"fx_n": 0.5}  # starts 0.5 s late: 75 % of 2 s
    with pytest.raises(InputError, match=r"c\.tdms.*fx_n.*90 %"):
        read_recording(_write_tdms(tmp_path / "c.tdms", offsets))


def test_mdf_groups_on_their_own_time_bases(tmp_path):
    from asammdf import MDF, Signal
    t_main = 1.7e9 + np.arange(N) / FS  # epoch time stamps
    t_force = 1.7e9 + 0.00113 + np.arange(N // 4) / (FS / 4)
    mdf = MDF(version="4.10")
    mdf.append([Signal(_signal(k, t_main - 1.7e9), t_main, name=k)
                for k in ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s")])
    mdf.append([Signal(_signal(k, t_force - 1.7e9), t_force, name=k)
                for k in ("fx_n", "fy_n", "fz_n")])
    path = tmp_path / "groups.mf4"
    mdf.save(path, overwrite=True)
    mdf.close()
    rec = read_recording(path)
    t = rec.time_s() - 1.7e9
    assert rec.fs_hz == pytest.approx(FS, rel=1e-9)
    for name in NAMES:  # forces at 2.5 kHz: interpolation error ~ 3e-5 (see above)
        np.testing.assert_allclose(rec.channels[name], _signal(name, t), atol=1e-4)
    assert sum("own time base" in n for n in rec.notes) == 3


def test_jittered_and_epoch_time_stamps():
    rng = np.random.default_rng(3)
    t = 1.7e9 + np.arange(N) / FS + rng.uniform(-0.2, 0.2, N) / FS
    fs, t0 = sample_rate_from_time(t, path="x")
    assert fs == pytest.approx(FS, rel=1e-6)
    assert abs(t0 - 1.7e9) < 0.05 / FS


def test_int16_channels_with_a_scale(tmp_path):
    """A logger's raw int16 counts scaled to SI (TDMS: the writer stores the scaled floats'
    16-bit grid); the reader returns floats on that grid."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    t = np.arange(N) / FS
    objs = [GroupObject("Meas")]
    for name in NAMES:
        full = 100.0 if name != "fz_n" else 1e4
        x = np.round(_signal(name, t) / full * 32767).astype(np.int16)
        objs.append(ChannelObject("Meas", name, x.astype(np.float64) * full / 32767,
                                  properties={"wf_increment": 1 / FS, "wf_start_offset": 0.0}))
    with TdmsWriter(str(tmp_path / "q.tdms")) as w:
        w.write_segment(objs)
    rec = read_recording(tmp_path / "q.tdms")
    for name in NAMES:
        full = 100.0 if name != "fz_n" else 1e4
        assert rec.channels[name].dtype == np.float64
        np.testing.assert_allclose(rec.channels[name], _signal(name, t), atol=full / 32767)
