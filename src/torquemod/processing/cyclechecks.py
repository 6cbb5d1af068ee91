"""Checks of one cycle before and after it is processed: that it is long enough for the chain and
that its mean operating point makes the creepage and creep-force equations meaningful.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.dsp.numpyblas import vector_sum
from torquemod.errors import InputError
from torquemod.io.config import ProcessingConfig


def check_cycle_length(n_samples: int, fs_hz: float, f_nominal_hz: float,
                       cfg: ProcessingConfig, *, where: str) -> None:
    """Refuse a cycle too short for the phase window plus the trimmed edges.

    Parameters
    ----------
    n_samples : int
        Samples in the cycle [-].
    fs_hz : float
        Its sample rate [Hz].
    f_nominal_hz : float
        Nominal modulation frequency [Hz].
    cfg : ProcessingConfig
        The chain's settings (periods in the phase window, trim).
    where : str
        The recording, named in the message.

    Raises
    ------
    InputError
        The cycle is too short, with what it would need.
    """
    need = (cfg.phase.n_periods + 2 * cfg.phase.edge_trim_periods) / f_nominal_hz
    have = n_samples / fs_hz
    if have < need:
        raise InputError(f"cycle is {have:.2f} s long, too short for {cfg.phase.n_periods} "
                         f"modulation periods after trimming {cfg.phase.edge_trim_periods} "
                         f"period(s) at each end (needs {need:.2f} s)", path=where,
                         hint="record longer cycles")


def check_operating_point(means: dict[str, float], platform_std_rad_s: float, *,
                          where: str) -> None:
    """Refuse a cycle whose means make Eqs. (3) and (4) meaningless.

    A platform that does not turn (its mean speed within its own scatter), wheel and platform
    turning in opposite directions, a wheel that does not turn, or a normal force that is not
    positive. Absent optional channels (platform speed, forces) are not checked.

    Parameters
    ----------
    means : dict of str to float
        Mean of each channel (SI units: rad/s, N).
    platform_std_rad_s : float
        Standard deviation of the platform speed over the cycle [rad/s].
    where : str
        The recording, named in the message.

    Raises
    ------
    InputError
        One of the cases above, naming the channel.
    """
    w_w = means["wheel_speed_rad_s"]
    if "platform_speed_rad_s" in means:
        w_p = means["platform_speed_rad_s"]
        if not abs(w_p) > platform_std_rad_s:
            raise InputError(f"the platform is not turning (mean speed {w_p:.3g} rad/s, "
                             f"scatter {platform_std_rad_s:.3g} rad/s)", path=where,
                             channel="platform_speed_rad_s",
                             hint="record while the platform runs, or check the channel "
                             "mapping and unit in [channels]")
        if w_w * w_p < 0:
            raise InputError(f"wheel and platform speeds have opposite signs (mean {w_w:.4g} "
                             f"and {w_p:.4g} rad/s)", path=where, channel="wheel_speed_rad_s",
                             hint="flip the sign of one speed channel so both are positive "
                             "when rolling forward")
    elif not w_w:
        raise InputError("the wheel is not turning (mean speed 0 rad/s)", path=where,
                         channel="wheel_speed_rad_s", hint="record while the wheel rolls")
    fz = means.get("fz_n")
    if fz is not None and not fz > 0:
        raise InputError(f"mean normal force is {fz:.4g} N; it must be positive (compression)",
                         path=where, channel="fz_n",
                         hint="check the channel mapping, its unit and the load cell's sign")


def record_std(x: np.ndarray) -> float:
    """The standard deviation ``np.std(x)`` of a record (the platform speed's scatter that
    :func:`check_operating_point` takes), by numpy's own steps: the mean, the squared
    deviations, their sum over the count, the square root.

    Parameters
    ----------
    x : ndarray
        1-D record [any unit].

    Returns
    -------
    float
        Its standard deviation [unit]: numpy's number, from one compiled call for a
        contiguous float64 record (:func:`~torquemod.dsp.numpyblas.vector_sum`, numpy's
        pairwise sums).
    """
    x = np.asarray(x)
    if x.dtype == np.float64 and x.ndim == 1 and x.size and x.flags.c_contiguous:
        return _std_compiled(x)
    return float(np.std(x))


@numba.njit(cache=True, nogil=True)
def _std_compiled(x: np.ndarray) -> float:
    """:func:`record_std` of a contiguous float64 record."""
    d = x - vector_sum(x) / x.size
    return math.sqrt(vector_sum(d * d) / x.size)
