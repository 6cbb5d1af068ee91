"""Steps 6 and 7 of the chain for one cycle, and for a step measured while it is read.

:func:`phase_parts` turns one aligned cycle into its row of the cycle table, its details and
its figure traces. :class:`InOrderStep` applies steps 6 and 7 to the cycles of a step that
is one recording split into revolutions as each cycle is done, so that a long recording's
cycles are never all held (:func:`torquemod.processing.pipeline.process_experiment`).
"""

from __future__ import annotations

import numpy as np

from torquemod._util.records import ColumnarRecords
from torquemod.errors import InputError, ProcessingError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Experiment, RecordingEntry
from torquemod.processing import chain
from torquemod.processing.steptable import detect_slip

__all__ = ["InOrderStep", "finish_in_order", "in_order_steps", "measure_at_end",
           "phase_parts"]


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


class InOrderStep:
    """Steps 6 and 7 of a step whose cycles arrive in cycle order.

    The step is one recording split into revolutions, and each cycle is aligned and measured
    as it is done: the first is the alignment reference
    (:func:`torquemod.processing.chain.align_lags`), only it is held, and a cycle keeps its
    row and details in columns (:class:`~torquemod._util.records.ColumnarRecords`, 8 bytes
    a number instead of ~2.5 KiB of dicts a cycle), the values the slip check needs and,
    for the first ``trace_cycles``, its traces. The numbers are those of aligning the whole
    step at the end.

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

    Attributes
    ----------
    cycles : list of int
        The cycles measured, in order.
    slip_inputs : tuple of list of float
        Their creepage [-], CoA [-] and creepage drift [-] (the slip check's inputs).
    rows : ColumnarRecords
        Their rows of the cycle table as tuples in the order of ``columns`` (NaN where a
        row has no value, as :class:`pandas.DataFrame` fills it).
    details : ColumnarRecords
        Their details (``slip`` None until the step's slip check).
    error : InputError or None
        What the first cycle whose phase could not be measured met (raised by the caller in
        step order).
    """

    def __init__(self, step: int, cfg: ProcessingConfig, trace_cycles: int,
                 columns: list[str]):
        self.step, self.cfg, self.ref, self.count = step, cfg, None, 0
        self.trace_cycles, self.columns = trace_cycles, columns
        self.cycles: list[int] = []
        self.slip_inputs: tuple[list, list, list] = ([], [], [])
        self.rows, self.details = ColumnarRecords(), ColumnarRecords()
        self.error: InputError | None = None

    def __call__(self, item: tuple) -> tuple | None:
        """Measure one cycle ``(cycle, CycleSignals, info, raw traces)``; returns
        ``(cycle, None, None, traces)`` for a cycle whose traces are kept, else None
        (everything else is kept here)."""
        cyc, sig, info, raw = item
        if self.ref is None:
            self.ref, lag = sig, chain.align_lags([sig], self.cfg)[0]
        else:
            lag = chain.align_lags([self.ref, sig], self.cfg)[1]
        trace = None
        try:
            row, detail, tr = phase_parts(self.step, cyc, sig, info, lag,
                                           self.ref.torque_filtered.size, self.cfg)
        except InputError as exc:
            if self.error is None:
                self.error = exc
        else:
            if self.error is None:  # the step fails at its first error: keep no more
                self.cycles.append(cyc)
                for col, v in zip(self.slip_inputs,
                                  (sig.creepage, sig.coa, sig.creepage_drift), strict=True):
                    col.append(v)
                self.rows.append(tuple(row.get(k, np.nan) for k in self.columns))
                self.details.append(detail)
            if self.count < self.trace_cycles:
                trace = {**raw, **tr}
        self.count += 1
        return None if trace is None else (cyc, None, None, trace)


def _slip_notes(step: int, cycles, slip, notes: list[str]) -> None:
    for cyc, why in zip(cycles, slip, strict=True):
        if why:
            notes.append(f"step {step}: slip detected in cycle {cyc} ({why}); the step is "
                         "flagged in steps.csv 'slip' and left out of the creep-curve fit")


def finish_in_order(m: InOrderStep, cfg: ProcessingConfig, notes: list[str], rows: list,
                    details: ColumnarRecords) -> bool:
    """The end of a step measured while read: its slip check, its notes, its rows and
    details appended (its first phase error raised).

    Parameters
    ----------
    m : InOrderStep
        The step.
    cfg : ProcessingConfig
        The parameters.
    notes : list of str
        Where the slip notes are appended.
    rows : list of tuple
        Where the cycle table's rows are appended (in the order of the step's columns).
    details : ColumnarRecords
        Where the details are appended, with their slip reason.

    Returns
    -------
    bool
        Whether a cycle slipped.

    Raises
    ------
    InputError
        The step's first cycle whose phase could not be measured.
    """
    slip = detect_slip(*m.slip_inputs, cfg.slip)
    _slip_notes(m.step, m.cycles, slip, notes)
    if m.error is not None:
        raise m.error
    rows.extend(m.rows)
    for detail, why in zip(m.details, slip, strict=True):
        detail["slip"] = why
        details.append(detail)
    return any(slip)


def measure_at_end(step: int, items: list, cfg: ProcessingConfig, exp: Experiment,
                   notes: list[str], rows: list, details: ColumnarRecords, traces: dict,
                   trace_cycles: int, columns: list[str]) -> bool:
    """Steps 6 and 7 of a step's cycles once all are done: alignment, slip check, rows,
    details and traces.

    Parameters
    ----------
    step : int
        The step.
    items : list of tuple
        Its cycles ``(cycle, CycleSignals, info)``, in any order.
    cfg : ProcessingConfig
        The parameters.
    exp : Experiment
        The experiment (named in errors).
    notes : list of str
        Where the slip notes are appended.
    rows : list of tuple
        Where the cycle table's rows are appended (values in the order of ``columns``, NaN
        where a row has none).
    details : ColumnarRecords
        Where the details are appended.
    traces : dict
        ``(step, cycle)`` -> raw traces: those of the first ``trace_cycles`` cycles are
        completed, the others dropped.
    trace_cycles : int
        Cycles whose traces are kept [-].
    columns : list of str
        The cycle table's columns.

    Returns
    -------
    bool
        Whether a cycle slipped.

    Raises
    ------
    InputError
        Cycle numbers given twice, or a phase that cannot be measured.
    """
    items = sorted(items, key=lambda it: it[0])
    cycles_seen = [c for c, _, _ in items]
    if len(set(cycles_seen)) != len(cycles_seen):
        raise InputError(f"step {step} has cycle numbers {cycles_seen} more than once "
                         "(a file spanning cycles and single-cycle files overlap)",
                         path=exp.manifest_path, hint="give each cycle once")
    sigs = [s for _, s, _ in items]
    slip = detect_slip([s.creepage for s in sigs], [s.coa for s in sigs],
                       [s.creepage_drift for s in sigs], cfg.slip)
    _slip_notes(step, cycles_seen, slip, notes)
    lags = chain.align_lags(sigs, cfg)
    n_ref = sigs[0].torque_filtered.size
    measured = []
    for (cyc, sig, info), lag, why in zip(items, lags, slip, strict=True):
        row, detail, tr = phase_parts(step, cyc, sig, info, lag, n_ref, cfg)
        detail["slip"] = why
        measured.append((row, detail, tr))
    for k, (cyc, _, _) in enumerate(items):  # traces of the first cycles only
        if k >= trace_cycles:
            traces.pop((step, cyc), None)
    for (cyc, _, _), (row, detail, tr) in zip(items, measured, strict=True):
        rows.append(tuple(row.get(k, np.nan) for k in columns))
        details.append(detail)
        if (step, cyc) in traces:
            traces[(step, cyc)].update(tr)
    return any(slip)


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
