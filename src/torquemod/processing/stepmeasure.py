"""Steps 6 and 7 of the chain for one cycle, and for a step measured while it is read.

:func:`phase_parts` turns one aligned cycle into its row of the cycle table, its details and
its figure traces. :class:`InOrderStep` applies steps 6 and 7 to the cycles of a step that
is one recording split into revolutions as each cycle is done, so that a long recording's
cycles are never all held (:func:`torquemod.processing.pipeline.process_experiment`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from torquemod.errors import InputError, ProcessingError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Experiment, RecordingEntry
from torquemod.processing import chain

__all__ = ["InOrderStep", "in_order_steps", "phase_parts"]


def phase_parts(step: int, cyc: int, sig: chain.CycleSignals, info: dict, lag: int,
                 n_ref: int, cfg: ProcessingConfig) -> tuple[dict, dict, dict]:
    """Step 7 of one aligned cycle: its table row, details and traces.

    Parameters
    ----------
    step : int
        The step.
    cyc : int
        The cycle.
    sig : CycleSignals
        The cycle after steps 1-5 and 8.
    info : dict
        The cycle's source and sampling.
    lag : int
        Its alignment lag [samples] (step 6).
    n_ref : int
        Samples of the alignment reference.
    cfg : ProcessingConfig
        The parameters.

    Returns
    -------
    row : dict
        The cycle table's row (phase [deg], creepage [-], CoA [-], ...).
    detail : dict
        Its details (``slip`` None until the step's slip check).
    trace : dict
        Its resampled and filtered traces.

    Raises
    ------
    InputError
        The phase cannot be measured.
    """
    try:
        phase, stderr, window = chain.cycle_phase(sig, cfg, center_index=n_ref / 2 + lag)
    except ProcessingError as exc:
        raise InputError(f"phase not measurable: {exc}", path=info["source"],
                         hint="check the modulation in both channels") from None
    row = {"step": step, "cycle": cyc, "torque_peak_hz": sig.torque_peak_hz,
           "wheel_peak_hz": sig.wheel_peak_hz, "modulation_hz": sig.modulation_hz,
           "phase_deg": phase, "creepage": sig.creepage, "coa": sig.coa,
           "phase_se_deg": stderr, "creepage_drift": sig.creepage_drift, **sig.extra}
    detail = {**info, "phase_stderr_deg": stderr, "align_lag_samples": lag,
              "align_lag_s": lag / sig.fs_hz,
              "phase_window_s": [sig.t0_s + w for w in window], "resampled_hz": sig.fs_hz,
              "wheel_rotation_hz": sig.wheel_rotation_hz,
              "platform_rotation_hz": sig.platform_rotation_hz,
              "notches_hz": sig.notches_hz, "speed_m_s": sig.extra["speed_m_s"],
              "slow_band_hz": sig.extra.get("slow_band_hz"),
              "creepage_drift": sig.creepage_drift, "slip": None, **sig.means}
    trace = {"t_s": sig.t0_s + np.arange(sig.torque_filtered.size) / sig.fs_hz,
             "torque_resampled_nm": sig.torque_resampled,
             "wheel_speed_resampled_rad_s": sig.wheel_resampled,
             "torque_filtered_nm": sig.torque_filtered,
             "wheel_speed_filtered_rad_s": sig.wheel_filtered,
             "phase_window_s": sig.t0_s + np.asarray(window)}
    return row, detail, trace


_ABSENT = object()


@dataclass
class _Measured:
    """A cycle measured as soon as it was done (:class:`InOrderStep`): what the step's slip
    check needs, its row (the values of the cycle table's columns, ``_ABSENT`` where the
    row has none: what ``pd.DataFrame(rows, columns=...)`` keeps) and its details (values,
    with the step's shared tuple of keys), or the error its phase met (raised in step
    order). Tuples, not dicts: a recording of thousands of revolutions holds one a cycle."""

    creepage: float
    coa: float
    creepage_drift: float
    row: tuple | None = None
    detail_keys: tuple | None = None
    detail_values: tuple | None = None
    error: InputError | None = None

    def row_dict(self, columns) -> dict:
        return {k: v for k, v in zip(columns, self.row, strict=True) if v is not _ABSENT}

    def detail_dict(self) -> dict:
        return dict(zip(self.detail_keys, self.detail_values, strict=True))


class InOrderStep:
    """Steps 6 and 7 of a step whose cycles arrive in cycle order.

    The step is one recording split into revolutions, and each cycle is aligned and measured
    as it is done: the first is the alignment reference
    (:func:`torquemod.processing.chain.align_lags`), only it is held, and a cycle keeps its
    row, details and, for the first ``trace_cycles``, its traces. The numbers are those of
    aligning the whole step at the end.

    Parameters
    ----------
    step : int
        The step.
    cfg : ProcessingConfig
        The parameters.
    trace_cycles : int
        Cycles whose traces are kept [-].
    columns : list of str
        The cycle table's columns.
    """

    def __init__(self, step: int, cfg: ProcessingConfig, trace_cycles: int,
                 columns: list[str]):
        self.step, self.cfg, self.ref, self.count = step, cfg, None, 0
        self.trace_cycles, self.columns = trace_cycles, columns
        self.keys: tuple = ()

    def __call__(self, item: tuple) -> tuple:
        cyc, sig, info, raw = item
        if self.ref is None:
            self.ref, lag = sig, chain.align_lags([sig], self.cfg)[0]
        else:
            lag = chain.align_lags([self.ref, sig], self.cfg)[1]
        out = _Measured(sig.creepage, sig.coa, sig.creepage_drift)
        trace = None
        try:
            row, detail, tr = phase_parts(self.step, cyc, sig, info, lag,
                                           self.ref.torque_filtered.size, self.cfg)
            out.row = tuple(row.get(k, _ABSENT) for k in self.columns)
            keys = tuple(detail)
            if keys != self.keys:
                self.keys = keys  # one tuple of keys for the step's cycles
            out.detail_keys, out.detail_values = self.keys, tuple(detail.values())
            if self.count < self.trace_cycles:
                trace = {**raw, **tr}
        except InputError as exc:
            out.error = exc
        self.count += 1
        return cyc, out, None, trace


def in_order_steps(exp: Experiment) -> set[int]:
    """The steps that are one recording without a manifest cycle.

    Their cycles are that file's revolutions, numbered and done in order.

    Parameters
    ----------
    exp : Experiment
        The experiment.

    Returns
    -------
    set of int
        The steps.
    """
    entries: dict[int, list[RecordingEntry]] = {}
    for e in exp.recordings:
        entries.setdefault(e.step, []).append(e)
    return {s for s, es in entries.items() if len(es) == 1 and es[0].cycle is None}
