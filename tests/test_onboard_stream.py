"""Run recordings read by row ranges (torquemod.io.runstream): every row, the time base and
the notes bit for bit those of the whole-file reader (tolerance 0: the stream uses the whole
reader's own element-wise interpolation), on MDF4 (reference speed in its own channel group)
and HDF5 (its own time vector) runs of the twin."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from torquemod.io.recording import read_recording
from torquemod.io.run import read_run
from torquemod.io.runstream import RunStream
from torquemod.train import load_train_config


@pytest.fixture(scope="module")
def twin_run(tmp_path_factory):
    from torquemod.train import run_train_simulation
    cfg = load_train_config()
    cfg = dataclasses.replace(cfg, track=dataclasses.replace(cfg.track, length_m=400.0))
    folder = tmp_path_factory.mktemp("train") / "run"
    run_train_simulation(cfg, folder, seed=5)
    return folder


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
