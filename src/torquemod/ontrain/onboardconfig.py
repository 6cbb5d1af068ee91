"""Settings of the on-board estimator: window length and step, the delay search, the creep-curve
fit and the change detector, with their bounds checked when read from TOML.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from torquemod._util.tomlcheck import (
    NON_NEGATIVE,
    Check,
    between,
    default_checks,
    one_of,
    read_table,
)
from torquemod.analysis.phasefit import R_BOUNDS


@dataclass(frozen=True)
class OnboardConfig:
    """Settings of the on-board estimator (``[onboard]`` in run.toml).

    The defaults are the field defaults here (chosen on the twin's and the independent
    generator's train runs; :mod:`torquemod.ontrain.estimator` explains each mechanism).
    :meth:`from_dict` reads and checks a run.toml table.

    Attributes
    ----------
    window_periods : int
        Modulation periods per window [-]. Default 5.
    hop_s : float
        Time between the starts of consecutive windows [s]. Default 0.25.
    memory_m : float
        Longest stretch of track whose windows the mu fit holds [m]. Default 1500.
    bound_m : float
        Stretch over which the lower bound ``mu_low_95`` is taken [m]. Default 1 (the current
        window alone).
    refit_m : float
        Distance between refits of the creep progression [m]. Default 100.
    change_drift : float
        Drift (allowance) of the CUSUM friction-change detector per window, in standard
        deviations of the log creep coefficient [-]. Default 1.
    change_threshold : float
        Alarm threshold of the CUSUM sums [-] (same unit). Default 10.
    max_rel_half_width : float
        Largest relative half-width of mu's 95 % profile interval for mu to be reported [-].
        Default 0.25.
    model_rel_error : float
        Relative systematic error of each grouped point's creep coefficient [-]. Default 0.02:
        on the independent train runs the median measured/true creep coefficient differs
        between the staircase's levels by up to 0.04 (benchmarks/onboard_independent.py).
    max_dc_step_ratio : float
        Largest DC torque step within a window, over the modulation amplitude, for the window
        to count as steady [-]. Default 0.25.
    info_utilisation : float
        Share of mu a steady window must have worked at within ``info_m`` for mu to be
        reported [-]. Default 0.5.
    info_m : float
        Distance over which that evidence counts [m]. Default 30.
    n_bins : int
        Largest number of CoA groups the windows are pooled into for the fit [-]. Default 12.
    min_windows : int
        Fewest steady windows before a fit is tried [-]. Default 12.
    min_coa_ratio : float
        Smallest ratio of the highest to the lowest group CoA for a fit [-]. Default 2.
    ratio_bounds : tuple of float
        Bounds of the fitted ratio of mu to the largest measured CoA [-]. Default
        :data:`torquemod.analysis.phasefit.R_BOUNDS`.
    power_shapes : int
        1: include the saturating power-law shapes in the family of creep laws; 0: leave them
        out. Default 1.
    model_swing : int
        1: fit the windows' slopes as the describing function of the curve over the
        modulation's creepage swing; 0: as small-signal slopes. Default 1.
    baseline_m : float
        Stretch whose low-CoA windows give the reference creep coefficient of the
        ``low_adhesion`` flag [m]. Default 600.
    low_adhesion_ratio : float
        ``low_adhesion`` when k falls below this share of the reference [-]. Default 0.25.
    slip_creepage : float
        ``slip`` when the creepage exceeds this [-]. Default 0.03.
    slip_accel_m_s2 : float
        ``slip`` when the axle accelerates faster than the vehicle by this [m/s^2].
        Default 0.8.
    calibrate_delay : int
        1: estimate the net torque-to-speed delay from the run
        (:class:`~torquemod.ontrain.delay.DelayCalibrator`); 0: do not. Default 1.
    delay_max_s : float
        Largest delay searched, either sign [s]. Default 0.02.
    delay_max_se_s : float
        Standard error below which a delay estimate is used [s]. Default 5e-4.
    delay_min_windows : int
        Fewest steady windows before a delay is estimated [-]. Default 40.
    min_speed_m_s : float
        Reference speed below which the train counts as standing [m/s]. Default 1 (twice the
        0.5 m/s floor of the creepage's reference speed).
    min_modulation_ratio : float
        Share of the declared modulation amplitude the torque's line must reach [-].
        Default 0.25 (windows of the twin's and the independent runs reach > 0.3 even across
        a DC step).
    """

    window_periods: int = 5
    hop_s: float = 0.25
    memory_m: float = 1500.0
    bound_m: float = 1.0
    refit_m: float = 100.0
    change_drift: float = 1.0
    change_threshold: float = 10.0
    max_rel_half_width: float = 0.25
    #: each point's relative systematic error: on the independent train runs the median
    #: measured/true creep coefficient differs between the staircase's levels by up to
    #: 0.04 (0.987 at 20 %, 1.028 at 60 % of the adhesion; benchmarks/onboard_independent.py)
    model_rel_error: float = 0.02
    max_dc_step_ratio: float = 0.25
    info_utilisation: float = 0.5
    info_m: float = 30.0
    n_bins: int = 12
    min_windows: int = 12
    min_coa_ratio: float = 2.0
    ratio_bounds: tuple[float, float] = R_BOUNDS
    power_shapes: int = 1
    #: fit the windows' slopes as the describing function of the curve over the
    #: modulation's creepage swing (1) or as small-signal slopes (0)
    model_swing: int = 1
    baseline_m: float = 600.0
    low_adhesion_ratio: float = 0.25
    slip_creepage: float = 0.03
    slip_accel_m_s2: float = 0.8
    calibrate_delay: int = 1
    delay_max_s: float = 0.02
    delay_max_se_s: float = 5e-4
    delay_min_windows: int = 40
    #: the premise of a window (:mod:`torquemod.ontrain.quality`): the reference speed
    #: [m/s] below which the train counts as standing (twice the 0.5 m/s floor of the
    #: creepage's reference speed; ours) and the share of the declared modulation amplitude
    #: the torque's line must reach (ours: windows of the twin's and the independent runs
    #: reach > 0.3 even across a DC step)
    min_speed_m_s: float = 1.0
    min_modulation_ratio: float = 0.25

    @classmethod
    def from_dict(cls, table: dict | None, *, source: str = "[onboard]") -> OnboardConfig:
        """The settings from run.toml's ``[onboard]`` table.

        Parameters
        ----------
        table : dict or None
            The table; None gives the defaults.
        source : str
            What to name in error messages (the file). Default ``"[onboard]"``.

        Returns
        -------
        OnboardConfig
            The checked settings.

        Raises
        ------
        InputError
            An unknown key (with the nearest known one), a value of the wrong type or out of
            its range (:func:`torquemod._util.tomlcheck.read_table`; ``ratio_bounds``
            ``[low, high]`` with 0 < low < high); the message names ``source`` and the key.
        """
        return read_table(cls, table, section="onboard", path=source, checks=_CHECKS)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["ratio_bounds"] = list(self.ratio_bounds)
        return d


#: ranges of the [onboard] settings (besides their types): positive unless listed here
_CHECKS = default_checks(OnboardConfig, {
    "power_shapes": one_of(0, 1), "calibrate_delay": one_of(0, 1),
    "model_swing": one_of(0, 1),
    "window_periods": between(1, None), "n_bins": between(1, None),
    "min_windows": between(1, None), "delay_min_windows": between(1, None),
    "info_utilisation": between(0.0, 1.0, lo_open=True),
    "min_modulation_ratio": between(0.0, 1.0),
    "low_adhesion_ratio": between(0.0, 1.0, lo_open=True),
    "change_drift": NON_NEGATIVE, "delay_max_s": NON_NEGATIVE,
    "ratio_bounds": Check(lo=0.0, lo_open=True, test=lambda b: b[0] < b[1],
                          need="[low, high] with 0 < low < high")})
