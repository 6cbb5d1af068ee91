"""Run recordings read by row ranges (torquemod.io.runstream): every row, the time base and
the notes bit for bit those of the whole-file reader (tolerance 0: the stream uses the whole
reader's own element-wise interpolation), on MDF4 (reference speed in its own channel group)
and HDF5 (its own time vector) runs of the twin."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from torquemod.io.recording import read_recording
from torquemod.io.run import read_run
from torquemod.io.runstream import RunStream


@pytest.fixture(scope="module")
def twin_run(tmp_path_factory):
    from torquemod.testing import write_short_train_run
    return write_short_train_run(tmp_path_factory.mktemp("train") / "run", length_m=400.0,
                                 seed=5)


def _open(toml):
    run = read_run(toml)
    e = run.recordings[0]
    kw = dict(group=e.group, channel_map=run.channel_map, sample_rate_hz=e.sample_rate_hz)
    return read_recording(e.path, **kw), RunStream(e.path, **kw)


@pytest.mark.parametrize("manifest", ["run.toml", "run_h5.toml"])
@pytest.mark.parametrize("chunk", [997, 5000])
def test_run_stream_rows_identical_to_whole_file(twin_run, manifest, chunk):
    rec, stream = _open(twin_run / manifest)
    with stream:
        assert stream.streamed
        assert (stream.fs_hz, stream.t0_s, stream.n_samples) == \
            (rec.fs_hz, rec.t0_s, rec.n_samples)
        assert stream.notes == rec.notes
        assert any("own time base" in n for n in stream.notes)  # the slow reference speed
        assert set(stream.channels) == set(rec.channels)
        seen = 0
        for a, rows in stream.chunks(chunk):
            assert a == seen
            for c, x in rows.items():
                np.testing.assert_array_equal(x, rec.channels[c][a:a + x.size], strict=True)
            seen += rows["torque_nm"].size
        assert seen == rec.n_samples
        # random access anywhere gives the same rows
        for a, b in ((0, 1), (rec.n_samples - 3, rec.n_samples), (1234, 4321)):
            rows = stream.read(a, b)
            for c, x in rows.items():
                np.testing.assert_array_equal(x, rec.channels[c][a:b])


def test_unstreamable_layout_falls_back_to_the_whole_read(twin_run):
    """A manifest sample rate beside a slow channel of its own length is not streamed: the
    whole-file reader is used, so the error is exactly its error."""
    from torquemod.errors import InputError
    run = read_run(twin_run / "run_h5.toml")
    e = run.recordings[0]
    cmap = {"torque": "torque_nm", "wheel_speed": "wheel_speed_rad_s"}
    with pytest.raises(InputError) as whole:
        read_recording(e.path, channel_map=cmap, sample_rate_hz=1000.0)
    with pytest.raises(InputError) as streamed:
        RunStream(e.path, channel_map=cmap, sample_rate_hz=1000.0)
    assert str(streamed.value) == str(whole.value)
    assert "has 400 samples" in str(whole.value)


def _whole_track(run, entry, chunk_s):
    """The on-board track the way it was made before streaming: the recording read whole,
    the position integrated over all of it, the rows fed in ``chunk_s`` blocks."""
    import pandas as pd

    from torquemod.ontrain.estimator import OnboardEstimator
    from torquemod.ontrain.onboardconfig import OnboardConfig
    rec = read_recording(entry.path, group=entry.group, channel_map=run.channel_map,
                         sample_rate_hz=entry.sample_rate_hz)
    ch, g = rec.channels, run.vehicle.gear_ratio
    torque, wheel, v = ch["torque_nm"], ch["wheel_speed_rad_s"], ch["vehicle_speed_m_s"]
    if g:
        torque, wheel = torque * g, wheel / g
    x = ch["position_m"] if "position_m" in ch else np.concatenate(
        [[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / rec.fs_hz)])
    est = OnboardEstimator(run.vehicle, run.modulation_frequency_hz, rec.fs_hz,
                           config=OnboardConfig.from_dict(run.extra.get("onboard")),
                           t0_s=rec.t0_s)
    step, rows = round(chunk_s * rec.fs_hz), []
    for a in range(0, torque.size, step):
        rows += est.feed(torque[a:a + step], wheel[a:a + step], v[a:a + step], x[a:a + step])
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def stripped_run(twin_run, tmp_path_factory):
    """The HDF5 run without its position channel, declared recorded at the motor
    (gear_ratio 3.1): the streamed path integrates the position and scales the signals."""
    import shutil

    import h5py
    folder = tmp_path_factory.mktemp("stripped")
    shutil.copy(twin_run / "run.h5", folder / "run.h5")
    with h5py.File(folder / "run.h5", "r+") as f:
        del f["position_m"]
    text = (twin_run / "run_h5.toml").read_text()
    head, tail = text.split("[channels.position]")
    text = head + "[truth]" + tail.split("[truth]")[1]
    text = text.replace("[vehicle]\n", "[vehicle]\ngear_ratio = 3.1\n")
    (folder / "run.toml").write_text(text)
    return folder / "run.toml"


@pytest.mark.parametrize("which", ["mf4", "h5_no_position_geared"])
def test_estimate_axle_streamed_equals_the_whole_recording(twin_run, stripped_run, which):
    """estimate_axle reads its recording in chunks (RunStream): the track is identical
    (tolerance 0) to the recording read whole and fed in the same blocks, including the
    position integrated across chunk edges and the motor-side scaling."""
    import pandas as pd

    from torquemod.ontrain.run import estimate_axle
    run = read_run(twin_run / "run.toml" if which == "mf4" else stripped_run)
    e = run.recordings[0]
    res = estimate_axle(run, e, chunk_s=2.7)
    assert not any("read whole" in n for n in res.notes)
    if which != "mf4":
        assert any("position integrated" in n for n in res.notes)
        assert any("recorded at the motor" in n for n in res.notes)
    ref = _whole_track(run, e, 2.7)
    assert len(ref) > 5
    pd.testing.assert_frame_equal(res.track, ref, check_exact=True)


def test_estimate_axle_nan_names_channel_and_time(stripped_run, tmp_path):
    """A NaN in the torque stops the axle with the file, the channel and the time."""
    import shutil

    import h5py

    from torquemod.errors import InputError
    from torquemod.ontrain.run import estimate_axle
    folder = tmp_path / "nan"
    shutil.copytree(stripped_run.parent, folder)
    with h5py.File(folder / "run.h5", "r+") as f:
        t = f["time_s"][:]
        f["torque_nm"][5000] = np.nan
    run = read_run(folder / "run.toml")
    with pytest.raises(InputError) as err:
        estimate_axle(run, run.recordings[0], chunk_s=2.7)
    msg = str(err.value)
    assert "run.h5" in msg and "torque_nm" in msg and "NaN/inf" in msg
    assert f"t = {t[5000]:.3f} s" in msg


@pytest.mark.parametrize("which", ["mf4", "h5_no_position_geared"])
def test_axle_in_parts_equals_estimate_axle(twin_run, stripped_run, which):
    """An axle measured in parts (plan_axle_chunks / measure_axle_chunk / assemble_axle, the
    fleet's chunk tasks) gives estimate_axle's track with tolerance 0: the same windows,
    the position integrated over the whole run, the state advanced in order."""
    import pandas as pd

    from torquemod.ontrain.run import (
        assemble_axle,
        estimate_axle,
        measure_axle_chunk,
        plan_axle_chunks,
    )
    run = read_run(twin_run / "run.toml" if which == "mf4" else stripped_run)
    e = run.recordings[0]
    ranges = plan_axle_chunks(run, e, None, chunk_s=3.3)
    assert len(ranges) > 3
    assert ranges[0][0] == 0 and all(a[1] == b[0] for a, b in itertools.pairwise(ranges))
    parts = [measure_axle_chunk(run, e, None, a, b) for a, b in ranges]
    got = assemble_axle(run, e, None, parts)
    ref = estimate_axle(run, e)
    pd.testing.assert_frame_equal(got.track, ref.track, check_exact=True)
    assert got.notes == ref.notes and got.n_fits == ref.n_fits


def test_parts_not_planned_for_sequential_files(twin_run, tmp_path):
    """A CSV run is read by passes from its start: no parts (one task)."""
    import pandas as pd

    from torquemod.ontrain.run import plan_axle_chunks
    rec = read_recording((twin_run / "run.h5"), channel_map={
        "vehicle_speed": {"name": "vehicle_speed_m_s", "time": "reference_time_s"},
        "position": {"name": "position_m", "time": "reference_time_s"}})
    pd.DataFrame({"time_s": rec.t0_s + np.arange(rec.n_samples) / rec.fs_hz,
                  **{c: rec.channels[c] for c in rec.channels}}).to_csv(
        tmp_path / "run.csv", index=False)
    text = (twin_run / "run_h5.toml").read_text().replace('"run.h5"', '"run.csv"')
    head, tail = text.split("[channels.vehicle_speed]")
    (tmp_path / "run.toml").write_text(head + "[truth]" + tail.split("[truth]")[1])
    run = read_run(tmp_path / "run.toml")
    assert plan_axle_chunks(run, run.recordings[0], None, chunk_s=3.0) == []


def test_padded_slow_channel_in_a_table(tmp_path):
    """A slow channel with its own time column in a CSV: empty cells below its last sample
    are cut off (noted); an empty cell inside it is still an error naming the channel."""
    import pandas as pd

    from torquemod.errors import InputError
    n, nr = 2000, 21
    t = np.arange(n) / 1000.0
    radar_t = np.concatenate([np.arange(nr) / 10.0 - 0.01, np.full(n - nr, np.nan)])
    radar_v = np.concatenate([np.linspace(20, 21, nr), np.full(n - nr, np.nan)])
    cmap = {"time": "t", "torque": "tq", "wheel_speed": "w",
            "vehicle_speed": {"name": "v", "time": "vt"}}
    for bad in (False, True):
        table = pd.DataFrame({"t": t, "tq": np.sin(t), "w": 40 + np.cos(t), "vt": radar_t,
                              "v": radar_v})
        if bad:
            table.loc[5, "vt"] = np.nan
        table.to_csv(tmp_path / "r.csv", index=False)
        if bad:
            with pytest.raises(InputError) as err:
                read_recording(tmp_path / "r.csv", channel_map=cmap)
            assert "vehicle_speed" in str(err.value) and "r.csv" in str(err.value)
            continue
        rec = read_recording(tmp_path / "r.csv", channel_map=cmap)
        assert any(f"{n - nr} empty rows below its last sample" in s for s in rec.notes)
        np.testing.assert_allclose(rec.channels["vehicle_speed_m_s"],
                                   np.interp(rec.t0_s + np.arange(rec.n_samples) / 1000.0,
                                             radar_t[:nr], radar_v[:nr]), rtol=1e-12)
