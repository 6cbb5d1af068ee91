"""One train axle read and estimated: the pieces the batch path
(:func:`~torquemod.ontrain.run.estimate_axle`) and the fleet's tasks share (the axle's
stream, signals and estimator), and the axle in parts: the windows of a run
measured by several tasks, the estimator's state advanced over them by one.

The on-board estimator's work splits in two (:class:`~torquemod.ontrain.estimator.
OnboardEstimator`): ``measure`` (the sine fit, CoA and creep coefficient of one window:
about a third of the time, no state) and ``update`` (slip, the reference creep coefficient,
the friction-change detector and the μ fit: state carried from window to window).

* :func:`plan_axle_chunks` cuts the run's window starts (every ``hop`` rows from row 0, as
  the estimator places them) into ranges of about ``chunk_s`` seconds;
* :func:`measure_axle_chunk` reads only the rows its windows cover (random row access of
  :class:`~torquemod.io.runstream.RunStream`) and measures them, the position left out;
* :func:`assemble_axle` integrates the position over the run exactly as
  :func:`~torquemod.ontrain.run.estimate_axle` does (the slow reference channels only: no
  pass over the fast ones), gives each window its mean position and runs ``update`` over
  the windows in order.

Each window then holds the very samples the whole run fed in chunks would give it, so the
track is identical to :func:`~torquemod.ontrain.run.estimate_axle`'s (tested with tolerance
0). Memory: a part holds its rows; the assembly holds the windows' measurements (a few
hundred bytes each) and one block of the reference channels. Files read by a pass from
their start (CSV, Parquet) and layouts read whole are not cut (:func:`plan_axle_chunks`
returns no ranges). When several channels are damaged, the part that fails first in row
order names its channel; the position channel is checked only by the assembly.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from torquemod._util.tomlcheck import below_nyquist
from torquemod.errors import InputError
from torquemod.io.run import Run, RunRecording
from torquemod.io.runstream import RunStream
from torquemod.ontrain.estimator import OnboardConfig, OnboardEstimator
from torquemod.ontrain.window import WindowResult

#: seconds of rows read at a time by the batch path (estimate_axle) and the assembly
CHUNK_S = 30.0


@dataclass
class AxlePart:
    """The windows of an axle starting in rows ``[first_row, stop_row)``.

    Attributes
    ----------
    first_row : int
        First row of the range [-].
    stop_row : int
        Row after the range [-].
    starts : list of int
        First row of each measured window.
    windows : list of WindowResult
        Their measurements (``position_m`` NaN until :func:`assemble_axle`; windows that
        could not be measured are absent, as they have no row).
    """

    first_row: int
    stop_row: int
    starts: list[int] = field(default_factory=list)
    windows: list[WindowResult] = field(default_factory=list)


class _AxleSignals:
    """A recording's rows as the estimator's four signals, chunk by chunk: torque [N*m] and
    wheel speed [rad/s] at the axle (times / divided by ``gear_ratio`` when recorded at the
    motor), reference speed [m/s] and position [m] (integrated from the reference speed by the
    trapezoid rule when the run has no position channel; the running sum is carried across
    chunks in the same order as over the whole recording, so it is bit for bit the same)."""

    def __init__(self, run: Run, entry: RunRecording, channels, fs_hz: float,
                 notes: list[str]) -> None:
        veh = run.vehicle
        self.entry, self.fs_hz, self.gear = entry, fs_hz, veh.gear_ratio
        if self.gear:
            notes.append(f"torque and speed recorded at the motor: x{self.gear:g} and "
                         f"/{self.gear:g} to the axle")
        if "vehicle_speed_m_s" not in channels:
            raise InputError("no reference speed (vehicle_speed) in the recording",
                             path=entry.path, channel="vehicle_speed_m_s",
                             hint="map the radar, GNSS or an unpowered axle's speed as "
                                  "vehicle_speed in [channels] (docs/format.md)")
        self.integrate = "position_m" not in channels
        if self.integrate:
            notes.append("no position channel: position integrated from the reference speed")
        self.v_last: float | None = None
        self.x_last = 0.0

    def _check(self, name: str, arr: np.ndarray, row: int, t0_s: float) -> None:
        bad = ~np.isfinite(arr)
        if bad.any():
            first = t0_s + (row + int(np.argmax(bad))) / self.fs_hz
            raise InputError(f"NaN/inf values (the first at t = {first:.3f} s)",
                             path=self.entry.path, channel=name, hint="repair the recording")

    def fast(self, ch: dict[str, np.ndarray], row: int, t0_s: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Torque and wheel speed at the axle and the reference speed of the rows from
        ``row`` on (``t0_s`` [s]: the time of row 0), checked for NaN/inf."""
        torque, wheel, v = ch["torque_nm"], ch["wheel_speed_rad_s"], ch["vehicle_speed_m_s"]
        if self.gear:
            torque = torque * self.gear
            wheel = wheel / self.gear
        for name, arr in (("torque_nm", torque), ("wheel_speed_rad_s", wheel),
                          ("vehicle_speed_m_s", v)):
            self._check(name, arr, row, t0_s)
        return torque, wheel, v

    def position(self, ch: dict[str, np.ndarray], v: np.ndarray, row: int, t0_s: float
                 ) -> np.ndarray:
        """Position [m] of the rows from ``row`` on; consecutive calls when integrated."""
        if not self.integrate:
            x = ch["position_m"]
        elif v.size:
            vv = v if self.v_last is None else np.concatenate([[self.v_last], v])
            inc = 0.5 * (vv[1:] + vv[:-1]) / self.fs_hz
            x = np.cumsum(np.concatenate([[self.x_last], inc]))
            x = x if self.v_last is None else x[1:]
            self.v_last, self.x_last = float(v[-1]), float(x[-1])
        else:
            x = np.zeros(0)
        self._check("position_m", x, row, t0_s)
        return x

    def __call__(self, ch: dict[str, np.ndarray], row: int, t0_s: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        torque, wheel, v = self.fast(ch, row, t0_s)
        return torque, wheel, v, self.position(ch, v, row, t0_s)


def axle_config(run: Run, config: OnboardConfig | None) -> OnboardConfig:
    """The settings an axle is estimated with.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    config : OnboardConfig or None
        Given settings.

    Returns
    -------
    OnboardConfig
        ``config``, or the run's ``[onboard]`` table read (the defaults without one).

    Raises
    ------
    InputError
        A bad ``[onboard]`` table, naming run.toml and the key.
    """
    return config or OnboardConfig.from_dict(run.extra.get("onboard"),
                                             source=str(run.manifest_path))


def axle_stream(run: Run, entry: RunRecording) -> RunStream:
    """The axle's recording, read by row ranges.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    entry : torquemod.io.run.RunRecording
        The axle's recording.

    Returns
    -------
    torquemod.io.runstream.RunStream
        The open stream (a context manager).
    """
    return RunStream(entry.path, group=entry.group, channel_map=run.channel_map,
                     sample_rate_hz=entry.sample_rate_hz)


def axle_estimator(run: Run, stream: RunStream, config: OnboardConfig
                   ) -> OnboardEstimator:
    """A fresh estimator on the stream's sample times.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    stream : torquemod.io.runstream.RunStream
        The axle's stream (sample rate, first sample time).
    config : OnboardConfig
        The settings.

    Returns
    -------
    OnboardEstimator
        The estimator.

    Raises
    ------
    InputError
        A modulation frequency the recording's sample rate cannot carry, or too few samples a
        window, naming the file.
    """
    below_nyquist(run.modulation_frequency_hz, stream.fs_hz, "test.modulation_frequency_hz",
                  "the recording's sample rate", run.manifest_path)
    try:
        return OnboardEstimator(run.vehicle, run.modulation_frequency_hz, stream.fs_hz,
                                config=config, t0_s=stream.t0_s,
                                amplitude_nm=run.modulation_amplitude_nm)
    except InputError as exc:
        if exc.path is not None:
            raise
        raise InputError(str(exc), path=stream.path) from None


def _n_windows(est: OnboardEstimator, n_samples: int) -> int:
    """Windows the estimator completes over ``n_samples`` rows (starts every hop)."""
    return max(0, (n_samples - est.n_win) // est.hop + 1)


def plan_axle_chunks(run: Run, entry: RunRecording, config: OnboardConfig | None = None, *,
                     chunk_s: float) -> list[tuple[int, int]]:
    """Row ranges of the window starts, ``chunk_s`` of them each (whole hops).

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    entry : torquemod.io.run.RunRecording
        The axle's recording.
    config : OnboardConfig or None
        The settings; None: the run's ``[onboard]`` table, else the defaults.
    chunk_s : float
        Time of window starts per range [s].

    Returns
    -------
    list of tuple of int
        ``(first, stop)`` row ranges; empty when the recording cannot be read by row ranges.
    """
    config = axle_config(run, config)
    with axle_stream(run, entry) as stream:
        if not stream.streamed or not stream.random_access:
            return []
        _AxleSignals(run, entry, stream.channels, stream.fs_hz, [])  # the reference speed
        est = axle_estimator(run, stream, config)
        n = _n_windows(est, stream.n_samples)
    per = max(1, round(chunk_s * stream.fs_hz / est.hop))
    return [(k * est.hop, min(n, k + per) * est.hop) for k in range(0, n, per)]


def measure_axle_chunk(run: Run, entry: RunRecording, config: OnboardConfig | None,
                       first: int, stop: int) -> AxlePart:
    """Measure the windows starting in rows ``[first, stop)``.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    entry : torquemod.io.run.RunRecording
        The axle's recording.
    config : OnboardConfig or None
        The settings; None: the run's ``[onboard]`` table, else the defaults.
    first : int
        First row of the range (from :func:`plan_axle_chunks`).
    stop : int
        Row after the range.

    Returns
    -------
    AxlePart
        The windows' measurements, positions left out.

    Raises
    ------
    InputError
        NaN or inf in the rows read, as the batch path raises it.
    """
    config = axle_config(run, config)
    part = AxlePart(first, stop)
    with axle_stream(run, entry) as stream:
        signals = _AxleSignals(run, entry, stream.channels, stream.fs_hz, [])
        est = axle_estimator(run, stream, config)
        starts = range(first, min(stop, _n_windows(est, stream.n_samples) * est.hop),
                       est.hop)
        if not starts:
            return part
        end = starts[-1] + est.n_win
        ch = stream.read(first, end, channels=("torque_nm", "wheel_speed_rad_s",
                                               "vehicle_speed_m_s"))
        torque, wheel, v = signals.fast(ch, first, stream.t0_s)
        buf = np.vstack([np.asarray(a, dtype=np.float64)
                         for a in (torque, wheel, v, np.zeros(torque.size))])
    for s in starts:
        a = s - first
        w = est.measure(buf[:, a:a + est.n_win], est.t0 + (s + est.n_win - 1) / est.fs)
        if w is not None:
            part.starts.append(s)
            part.windows.append(dataclasses.replace(w, position_m=float("nan")))
    return part


def _window_positions(stream: RunStream, signals, starts: list[int], n_win: int
                      ) -> np.ndarray:
    """Mean position [m] over each window (first rows ``starts``, ascending), from the
    position integrated block by block as :func:`~torquemod.ontrain.run.estimate_axle`
    integrates it."""
    out = np.empty(len(starts))
    step = max(1, round(CHUNK_S * stream.fs_hz))
    buf, buf_start, k = np.zeros(0), 0, 0
    for a in range(0, stream.n_samples, step):
        if k == len(starts):
            break
        ch = stream.read(a, min(stream.n_samples, a + step),
                         channels=("vehicle_speed_m_s", "position_m"))
        x = signals.position(ch, ch["vehicle_speed_m_s"], a, stream.t0_s)
        buf = np.concatenate([buf, x])
        end = buf_start + buf.size
        while k < len(starts) and starts[k] + n_win <= end:
            i = starts[k] - buf_start
            out[k] = float(buf[i:i + n_win].mean())
            k += 1
        keep = starts[k] if k < len(starts) else end
        buf, buf_start = buf[keep - buf_start:].copy(), keep
    return out


def assemble_axle(run: Run, entry: RunRecording, config: OnboardConfig | None,
                  parts: list[AxlePart]):
    """The axle's result from its parts.

    Integrates the position over the run as :func:`~torquemod.ontrain.run.estimate_axle`
    does, gives each window its mean position and runs the estimator's ``update`` over the
    windows in order.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    entry : torquemod.io.run.RunRecording
        The axle's recording.
    config : OnboardConfig or None
        The settings; None: the run's ``[onboard]`` table, else the defaults.
    parts : list of AxlePart
        The parts, in row order.

    Returns
    -------
    OnboardResult
        Identical to :func:`~torquemod.ontrain.run.estimate_axle`'s.
    """
    import pandas as pd

    from torquemod.io.truth import load_truth
    from torquemod.ontrain.quality import premise_warnings
    from torquemod.ontrain.result import OnboardResult
    config = axle_config(run, config)
    t_start = time.perf_counter()
    starts = [s for p in parts for s in p.starts]
    windows = [w for p in parts for w in p.windows]
    with axle_stream(run, entry) as stream:
        notes = list(stream.notes)
        signals = _AxleSignals(run, entry, stream.channels, stream.fs_hz, notes)
        est = axle_estimator(run, stream, config)
        positions = _window_positions(stream, signals, starts, est.n_win)
    rows = [est.update(dataclasses.replace(w, position_m=float(x)))
            for w, x in zip(windows, positions, strict=True)]
    track = pd.DataFrame(rows)
    segments = est.finish()
    track, warnings = premise_warnings(run, entry, track, config) if len(track) else (track,
                                                                                      [])
    return OnboardResult(run, entry.axle, track, config, notes,
                         time.perf_counter() - t_start, est.tracker.n_fits,
                         truth=load_truth(run), changes_m=tuple(est.tracker.changes),
                         delay_s=est.delay_s, warnings=warnings, segments=segments)
