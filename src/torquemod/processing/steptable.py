"""The steps table: the cycles of each torque step aggregated into one row, with the slip check
that flags the cycles not to average.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from torquemod.io.config import SlipParams

STEP_COLUMNS = ["step", "dc_torque_nm", "phase_deg", "phase_std_deg", "creepage",
                "creepage_std", "coa", "coa_std", "n_cycles", "slip", "phase_se_deg",
                "coa_torque", "coa_source", "speed_m_s", "torque_amplitude_nm",
                "wheel_amplitude_rad_s", "creepage_swing"]


#: Per-cycle quantities averaged per step (mean over the step's cycles).
_STEP_MEANS = ("coa_torque", "speed_m_s", "torque_amplitude_nm", "wheel_amplitude_rad_s",
               "creepage_swing")


def detect_slip(creepage, coa, drift, params: SlipParams) -> list[str | None]:
    """Slip check of one step's cycles, in time order.

    The rules and thresholds are those of :class:`~torquemod.io.config.SlipParams`: a
    creepage jump above the step's other cycles (beyond an absolute threshold and k robust
    standard deviations of the others), a CoA falling from the previous cycle while the
    creepage rises, a creepage rising within the cycle.

    Parameters
    ----------
    creepage : array_like
        Creepage of each cycle [-].
    coa : array_like
        CoA of each cycle [-].
    drift : array_like
        Creepage change within each cycle [-].
    params : SlipParams
        The thresholds.

    Returns
    -------
    list of str or None
        For each cycle the reason it looks like wheel slip, or None.
    """
    xi = np.asarray(creepage, dtype=float)
    c = np.asarray(coa, dtype=float)
    d = np.asarray(drift, dtype=float)
    out: list[str | None] = [None] * xi.size
    if not params.enabled:
        return out
    for i in range(xi.size):
        why = []
        others = np.delete(xi, i)
        if others.size:
            med = float(np.median(others))
            scatter = 1.4826 * float(np.median(np.abs(others - med))) if others.size > 1 else 0.0
            jump = xi[i] - med
            if jump > max(params.creepage_jump_abs, params.creepage_jump_k * scatter):
                why.append(f"creepage {xi[i]:.4g} is {jump:.3g} above the median {med:.4g} of "
                           "the step's other cycles")
        if i > 0:
            rise, drop = xi[i] - xi[i - 1], c[i - 1] - c[i]
            if rise > params.creepage_rise_abs and drop > params.coa_drop_abs:
                why.append(f"CoA fell by {drop:.3g} from the previous cycle while the creepage "
                           f"rose by {rise:.3g}")
        if d[i] > max(params.within_cycle_abs, params.within_cycle_rel * abs(xi[i])):
            why.append(f"creepage rose by {d[i]:.3g} within the cycle")
        out[i] = "; ".join(why) or None
    return out


def aggregate_steps(cycles: pd.DataFrame, dc_torque_nm: dict[int, float],
                    slip: dict[int, bool] | None = None) -> pd.DataFrame:
    """Mean and sample standard deviation per step of the cycle table.

    Parameters
    ----------
    cycles : pandas.DataFrame
        The cycle table.
    dc_torque_nm : dict of int to float
        Each step's DC torque [N*m].
    slip : dict of int to bool or None
        Step -> flagged, for the ``slip`` column (False when not given).

    Returns
    -------
    pandas.DataFrame
        The steps table (:data:`STEP_COLUMNS`); standard deviations with ddof = 1, NaN for a
        single cycle.
    """
    g = cycles.groupby("step", sort=True)
    n = g.size().to_numpy()
    # standard error of the step's mean phase: from the cycles' own standard errors when the
    # estimator gives them (sine fit), else from the cycles' scatter (NaN for one cycle)
    se_model = np.sqrt(g["phase_se_deg"].apply(
        lambda s: float(np.sum(s.to_numpy(float) ** 2))).to_numpy()) / n
    se_scatter = g["phase_deg"].std(ddof=1).to_numpy() / np.sqrt(n)
    out = pd.DataFrame({
        "step": list(g.groups),
        "phase_deg": g["phase_deg"].mean().to_numpy(),
        "phase_std_deg": g["phase_deg"].std(ddof=1).to_numpy(),
        "creepage": g["creepage"].mean().to_numpy(),
        "creepage_std": g["creepage"].std(ddof=1).to_numpy(),
        "coa": g["coa"].mean().to_numpy(),
        "coa_std": g["coa"].std(ddof=1).to_numpy(),
        "n_cycles": n,
    })
    out.insert(1, "dc_torque_nm", [dc_torque_nm[s] for s in out["step"]])
    out["slip"] = [bool((slip or {}).get(s, False)) for s in out["step"]]
    out["phase_se_deg"] = np.where(np.isfinite(se_model), se_model, se_scatter)
    for col in _STEP_MEANS:
        out[col] = g[col].mean().to_numpy()
    out["coa_source"] = g["coa_source"].first().to_numpy()
    return out[STEP_COLUMNS]
