"""Parameters of the processing chain, one frozen dataclass per step, defaults from the paper.

Where the V-Track paper gives a value it is used (search band 1.5-2.5 Hz, resampling to
53.344 Hz, notches at the rotation frequency and its 2nd harmonic, 0.36 Hz band-pass, maximum
alignment lag of one modulation period, the middle three modulation periods). Where it gives
none (filter orders, notch Q, high-pass cut-off) the choice is ours and says so.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from torquemod._util.tomlcheck import (
    NON_NEGATIVE,
    POSITIVE,
    Check,
    check_fields,
    checked,
    one_of,
    read_table,
)
from torquemod.errors import InputError, OptionError

#: How :meth:`ProcessingConfig.for_modulation` scales the defaults with the modulation frequency f.
FREQUENCY_RULE = ("band, band-pass width, high-pass cut-off, slow model's top x f/2; "
                  "resampling rate x max(f/2, 1)")


#: rotation harmonics to notch: whole numbers >= 1 (none: no notch)
_HARMONICS = Check(lo=1, allow_empty=True)


@dataclass(frozen=True)
class FrequencyParams:
    """Step 1: the spectral peak of torque and wheel speed in the search band.

    Attributes
    ----------
    band_hz : tuple of float
        Search band [Hz]. Default (1.5, 2.5), the V-Track paper's [1]_.
    window : str
        Window of the spectrum (:func:`scipy.signal.get_window` name). Default "hann" (ours:
        Hann sidelobes fall 18 dB/octave, away from large tones).
    detrend : {"linear", "constant"}
        Trend removed before the spectrum. Default "linear".
    zero_pad : int
        Zero-padding factor of the coarse grid [-]. Default 8.
    refine : bool
        Refine each peak to the least-squares frequency of the speed model (ours). Default
        True.
    tolerance_hz : float
        Tolerance of that refinement [Hz]. Default 1e-6.
    common : {"torque", "mean"}
        The common modulation frequency: the torque's peak (ours, the excitation's), or the
        mean of the torque's and the wheel speed's peaks (the paper's Table 2). Where the
        operating point moves, the wheel's answer drifts in phase and its peak moves with it
        (docs/processing.md). Default "torque".

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Section 2.4.
    """

    band_hz: tuple[float, float] = checked((1.5, 2.5), Check(
        lo=0.0, lo_open=True, test=lambda b: len(b) == 2 and b[0] < b[1],
        need="[low, high] with 0 < low < high"))
    #: ours: Hann sidelobes fall 18 dB/octave, away from large tones
    window: str = checked("hann", Check(test=lambda w: w == "hann" or _is_window(w),
                                        need="a scipy window name"))
    detrend: str = checked("linear", one_of("linear", "constant"))
    zero_pad: int = checked(8, POSITIVE)
    #: ours: each peak refined to the least-squares frequency of the speed model
    #: (torquemod.processing.speedmodel._SlowOrdersRemoval.refine) to ``tolerance_hz`` [Hz]
    refine: bool = True
    tolerance_hz: float = checked(1e-6, POSITIVE)
    #: the common modulation frequency: the "torque"'s peak (ours, the excitation's), or
    #: the "mean" of the torque's and the wheel speed's peaks (the paper's Table 2, taken
    #: at a steady speed). Where the operating point moves, the wheel's answer drifts in
    #: phase and its peak moves with it: the mean was up to 8.6e-4 Hz off under a 0.3 %
    #: wobble at 60-90 % utilisation, the torque's 9e-5 Hz (docs/processing.md)
    common: str = checked("torque", one_of("torque", "mean"))

    def __post_init__(self) -> None:
        check_fields(self, "processing.frequency")


@dataclass(frozen=True)
class ResampleParams:
    """Step 2: polyphase resampling to a common rate.

    Attributes
    ----------
    target_hz : float
        Target rate [Hz]. Default 53.344 (the V-Track paper's: 16 670*2/625).
    kaiser_beta : float
        Kaiser window beta of the FIR [-]. Default 5 (MATLAB ``resample``'s).
    max_denominator : int
        Largest ``down`` of the rational ratio [-]. Default 1000.
    method : {"two_stage", "polyphase"}
        "two_stage" (ours): an integer Kaiser-FIR decimation first, then ``resample_poly``
        for the rest (the same samples to 1e-7 deg of phase at 2 Hz, 4x cheaper);
        "polyphase": one ``resample_poly`` pass, as the paper's MATLAB ``resample``. Default
        "two_stage".
    """

    target_hz: float = checked(53.344, POSITIVE)
    kaiser_beta: float = 5.0  # MATLAB resample's default
    max_denominator: int = checked(1000, POSITIVE)
    #: "two_stage" (ours): an integer Kaiser-FIR decimation first (numba), then
    #: resample_poly for the rest; the same samples to 1e-7 deg of phase at 2 Hz, 4x cheaper.
    #: "polyphase": one resample_poly pass, as the paper's MATLAB resample.
    method: str = checked("two_stage", one_of("two_stage", "polyphase"))

    def __post_init__(self) -> None:
        check_fields(self, "processing.resample")


@dataclass(frozen=True)
class SlowParams:
    """The slow speed model (ours): the rolling speed of every rig and train moves.

    Speed variation below ``max_hz`` (a speed loop's wobble, the platform's revolution
    harmonics, a ramp) is modelled by Legendre polynomials and Slepian sequences
    (:func:`torquemod.dsp.basis.slow_basis`) and the encoders' eccentricity by rotation orders
    that follow the integrated angle; both are fitted jointly with the modulation and removed
    before steps 1 and 3-5, and step 8 takes every channel's mean through the same model, so a
    speed variation that wheel and platform share cancels in the creepage.

    Attributes
    ----------
    enabled : bool
        Use the model; False gives the previous chain (a line and fixed-frequency tones).
        Default True.
    max_hz : float
        The slow band's top where the speed varies above ``quiet_max_hz`` [Hz]. Default 1.2
        (a speed loop's wobble up to 1.2 Hz is removed).
    quiet_max_hz : float
        The slow band's top when the platform speed does not vary above it [Hz]
        (:func:`torquemod.dsp.basis.needs_wide_band`). Default 0.8 (0.4 x f at 2 Hz keeps the
        sidebands of a moving operating point out of the slow model); equal to ``max_hz``:
        always the full band.
    extra_sequences : int
        Slepian sequences beyond twice the time-bandwidth product [-]. Default 2.
    polynomial_degree : int
        Highest Legendre degree [-]. Default 5.
    modulation_harmonics : int
        The modulation's harmonics 2..this are fitted beside it and removed with the slow
        part [-]; 1 fits none. Default 3.
    """

    enabled: bool = True
    #: ours: the slow band's top [Hz] where the speed varies above ``quiet_max_hz``: a
    #: speed loop's wobble up to 1.2 Hz is removed
    max_hz: float = checked(1.2, POSITIVE)
    #: ours: the slow band's top [Hz] when the platform speed does not vary above it
    #: (torquemod.dsp.basis.needs_wide_band): 0.4 x f keeps the sidebands that a moving operating
    #: point puts on the wheel's answer (f +- f_w for a wobble at f_w) out of the slow model;
    #: 1.2 Hz took up to 0.5 deg of the phase at 80-90 % of the peak under a 0.3 % wobble at
    #: 0.2-0.6 Hz (docs/processing.md). Equal to ``max_hz``: always the full band
    quiet_max_hz: float = checked(0.8, POSITIVE)
    extra_sequences: int = checked(2, NON_NEGATIVE)
    polynomial_degree: int = checked(5, NON_NEGATIVE)
    #: the modulation's harmonics 2..this fitted beside it and removed with the slow part
    #: (torquemod.processing.speedmodel.modulation_harmonics); 1 fits none
    modulation_harmonics: int = checked(3, POSITIVE)

    def __post_init__(self) -> None:
        check_fields(self, "processing.slow")


@dataclass(frozen=True)
class NotchParams:
    """Step 3: zero-phase notches at rotation harmonics.

    Attributes
    ----------
    q : float
        Quality factor of each notch, f0/bandwidth [-]. Default 3 (ours: settles in
        ~q/(pi*f0) = 0.2 s at 4.6 Hz).
    wheel_harmonics : tuple of int
        Harmonics of the wheel's rotation notched. Default (1, 2), the V-Track paper's.
    platform_harmonics : tuple of int
        Harmonics of the platform's rotation notched. Default (1, 2).
    warn_within_hz : float
        A note when a wheel notch lies this close to the modulation [Hz]. Default 0.3.
    """

    #: ours: bandwidth f0/3, settles in ~q/(pi*f0) = 0.2 s at 4.6 Hz
    q: float = checked(3.0, POSITIVE)
    wheel_harmonics: tuple[int, ...] = checked((1, 2), _HARMONICS)
    platform_harmonics: tuple[int, ...] = checked((1, 2), _HARMONICS)
    warn_within_hz: float = checked(0.3, NON_NEGATIVE)

    def __post_init__(self) -> None:
        check_fields(self, "processing.notch")


@dataclass(frozen=True)
class HighpassParams:
    """Step 4: zero-phase Butterworth high-pass removing DC (values ours).

    Attributes
    ----------
    cutoff_hz : float
        Cut-off frequency [Hz]. Default 0.5.
    order : int
        Filter order [-], applied forward and backward. Default 2.
    """

    cutoff_hz: float = checked(0.5, POSITIVE)
    order: int = checked(2, POSITIVE)

    def __post_init__(self) -> None:
        check_fields(self, "processing.highpass")


@dataclass(frozen=True)
class BandpassParams:
    """Step 5: zero-phase Butterworth band-pass at the modulation frequency.

    Attributes
    ----------
    width_hz : float
        Band width [Hz]. Default 0.36, the V-Track paper's.
    order : int
        Prototype order [-] (ours: a 4th-order band-pass, applied twice). Default 2.
    """

    width_hz: float = checked(0.36, POSITIVE)
    #: ours: prototype order 2, a 4th-order band-pass, applied twice
    order: int = checked(2, POSITIVE)

    def __post_init__(self) -> None:
        check_fields(self, "processing.bandpass")


@dataclass(frozen=True)
class AlignParams:
    """Step 6: cycles 2..n aligned to cycle 1 by unbiased cross-correlation of the torque.

    Attributes
    ----------
    enabled : bool
        Align the cycles. Default True.
    max_lag_periods : float
        Largest lag, in modulation periods [-]. Default 1, the V-Track paper's.
    """

    enabled: bool = True
    max_lag_periods: float = checked(1.0, POSITIVE)

    def __post_init__(self) -> None:
        check_fields(self, "processing.align")


@dataclass(frozen=True)
class PhaseParams:
    """Step 7: the phase estimator.

    Attributes
    ----------
    method : {"paper", "sinefit"}
        "paper": peaks and valleys (the V-Track paper's); "sinefit": least squares over the
        cycle. Default "paper".
    n_periods : int
        Modulation periods "paper" uses around the aligned middle [-]. Default 3, the
        paper's.
    edge_trim_periods : float
        Modulation periods at each end of a cycle left out by "paper" (filter transients)
        [-]. Default 1.
    paper_window : {"cycle", "middle"}
        Which peaks and valleys "paper" pairs: every whole period between the trimmed edges
        (ours) or the ``n_periods`` nearest the aligned middle (the paper's). Where the
        operating point moves within a cycle the phase of its middle is not the cycle's
        (docs/processing.md). Default "cycle".
    sinefit_input : {"bandpassed", "notched", "model"}
        What "sinefit" fits: the band-passed signals over whole periods, the notched ones, or
        the speed model's own least-squares modulation. Default "bandpassed".
    sinefit_trend : bool
        Fit a line beside the sine. Default True.
    """

    method: str = checked("paper", one_of("paper", "sinefit"))
    n_periods: int = checked(3, POSITIVE)
    edge_trim_periods: float = checked(1.0, NON_NEGATIVE)
    #: which peaks and valleys "paper" pairs: "cycle" (ours: every whole period between the
    #: trimmed edges) or "middle" (the paper's: the ``n_periods`` nearest the aligned middle).
    #: Where the operating point moves within a cycle the phase of its middle is not the
    #: cycle's: up to 2.7 deg apart at 90 % of the peak under a 0.3 % speed wobble, and the
    #: middle periods were 1.1 deg off the cycle's phase where the whole cycle is 0.3 deg off
    #: (docs/processing.md, "The phase of a moving operating point")
    paper_window: str = checked("cycle", one_of("cycle", "middle"))
    #: "bandpassed" (the band-passed signals over whole periods; robust to vibration lines
    #: and noise away from the modulation), "notched", or "model" (the speed model's own
    #: least-squares modulation over the cycle; 3-4 x the scatter of "bandpassed" on records
    #: with vibration lines, docs/processing.md "The phase of a moving operating point")
    sinefit_input: str = checked("bandpassed", one_of("bandpassed", "notched", "model"))
    sinefit_trend: bool = True

    def __post_init__(self) -> None:
        check_fields(self, "processing.phase")


@dataclass(frozen=True)
class SlipParams:
    """Slip detection per step (values ours; :func:`torquemod.processing.steptable.detect_slip`).

    A step is flagged as slipping when one of its cycles shows a creepage jump above the
    step's other cycles, a falling CoA while the creepage rises (the falling branch of the
    creep curve), or a creepage drift within the cycle (near saturation a wheel's creepage
    follows the speed loop's wobble by tens of per cent up and down, measured on the twin; a
    runaway grows it far more). Flagged steps stay in ``steps.csv`` (column ``slip``) and are
    left out of the Polach fit.

    Attributes
    ----------
    enabled : bool
        Check for slip. Default True.
    creepage_jump_abs : float
        A jump needs a cycle's creepage above the median of the step's other cycles by more
        than this [-]. Default 0.002.
    creepage_jump_k : float
        It also needs more than this many robust standard deviations (1.4826 MAD) of those
        others [-]. Default 5.
    coa_drop_abs : float
        A falling CoA: by more than this from the previous cycle [-]. Default 0.005.
    creepage_rise_abs : float
        While the creepage rises by more than this [-]. Default 0.0005.
    within_cycle_abs : float
        A drift: the creepage's trend over a cycle rises by more than this [-]. Default
        0.002.
    within_cycle_rel : float
        It also rises by more than this times the cycle's creepage [-]. Default 0.5.
    """

    enabled: bool = True
    creepage_jump_abs: float = checked(2e-3, NON_NEGATIVE)
    creepage_jump_k: float = checked(5.0, NON_NEGATIVE)
    coa_drop_abs: float = checked(5e-3, NON_NEGATIVE)
    creepage_rise_abs: float = checked(5e-4, NON_NEGATIVE)
    within_cycle_abs: float = checked(2e-3, NON_NEGATIVE)
    within_cycle_rel: float = checked(0.5, NON_NEGATIVE)

    def __post_init__(self) -> None:
        check_fields(self, "processing.slip")


@dataclass(frozen=True)
class ProcessingConfig:
    """All parameters of the processing chain, one frozen dataclass per step.

    Defaults are the V-Track paper's [1]_ where it gives a value, ours (and said so) where it
    gives none; :meth:`for_modulation` scales them to another modulation frequency and
    :meth:`from_dict` reads a manifest's ``[processing]`` table.

    Attributes
    ----------
    frequency : FrequencyParams
        Step 1, the modulation frequency.
    resample : ResampleParams
        Step 2, resampling.
    notch : NotchParams
        Step 3, notches at the rotation harmonics.
    highpass : HighpassParams
        Step 4, high-pass.
    bandpass : BandpassParams
        Step 5, band-pass.
    align : AlignParams
        Step 6, alignment of the cycles.
    phase : PhaseParams
        Step 7, the phase estimator.
    nan_policy : {"raise", "interpolate", "drop-cycle"}
        What NaN/inf in a recording does. Default "raise".
    slip : SlipParams
        Slip detection.
    slow : SlowParams
        The slow speed model.

    Raises
    ------
    InputError
        A value out of its range or an unknown choice.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Section 2.4.
    """

    frequency: FrequencyParams = field(default_factory=FrequencyParams)
    resample: ResampleParams = field(default_factory=ResampleParams)
    notch: NotchParams = field(default_factory=NotchParams)
    highpass: HighpassParams = field(default_factory=HighpassParams)
    bandpass: BandpassParams = field(default_factory=BandpassParams)
    align: AlignParams = field(default_factory=AlignParams)
    phase: PhaseParams = field(default_factory=PhaseParams)
    nan_policy: str = checked("raise", one_of("raise", "interpolate", "drop-cycle"))
    slip: SlipParams = field(default_factory=SlipParams)
    slow: SlowParams = field(default_factory=SlowParams)

    def __post_init__(self) -> None:
        check_fields(self, "processing")

    def to_dict(self) -> dict:
        """Every parameter of every step, for provenance.json."""
        return dataclasses.asdict(self)

    @classmethod
    def for_modulation(cls, frequency_hz: float, doc: dict | None = None, *,
                       source: str = "[processing]") -> ProcessingConfig:
        """The defaults for a modulation at ``frequency_hz`` [Hz], then the keys of ``doc``
        (a manifest's ``[processing]`` table, as :meth:`from_dict`) over them.

        The paper's values are tied to its 2 Hz modulation; at another frequency every
        frequency-bound default is scaled by ``frequency_hz/2``: the search band (1.5-2.5
        Hz), the band-pass width (0.36 Hz), the high-pass cut-off (0.5 Hz) and the slow
        model's top (1.2 Hz); above 2 Hz also the resampling rate (53.344 Hz), so that a
        period keeps its 26.7 samples (the paper's peak interpolation is biased at fewer).
        At 2 Hz these are the defaults themselves (:data:`FREQUENCY_RULE`)."""
        d = cls()
        f = float(frequency_hz)
        if not (math.isfinite(f) and f > 0):
            raise InputError(f"modulation frequency must be positive, got {frequency_hz!r}",
                             path=source)
        s = f / 2.0
        base = d if s == 1.0 else dataclasses.replace(
            d, frequency=dataclasses.replace(d.frequency, band_hz=(d.frequency.band_hz[0] * s,
                                                                   d.frequency.band_hz[1] * s)),
            resample=dataclasses.replace(d.resample,
                                         target_hz=d.resample.target_hz * max(s, 1.0)),
            bandpass=dataclasses.replace(d.bandpass, width_hz=d.bandpass.width_hz * s),
            highpass=dataclasses.replace(d.highpass, cutoff_hz=d.highpass.cutoff_hz * s),
            slow=dataclasses.replace(d.slow, max_hz=d.slow.max_hz * s,
                                     quiet_max_hz=d.slow.quiet_max_hz * s))
        return cls.from_dict(doc or {}, source=source, base=base)

    @classmethod
    def from_dict(cls, doc: dict, *, source: str = "[processing]",
                  base: ProcessingConfig | None = None) -> ProcessingConfig:
        """Build from nested dicts, e.g. a manifest's ``[processing]`` table.

        Parameters
        ----------
        doc : dict
            The table; its sub-tables are the steps' (``[processing.phase]``, ...).
        source : str
            What to name in error messages (the file). Default ``"[processing]"``.
        base : ProcessingConfig or None
            The values of the keys ``doc`` leaves out (None: the defaults).

        Returns
        -------
        ProcessingConfig
            The checked configuration.

        Raises
        ------
        InputError
            An unknown key (with the nearest known one), a value of the wrong type or out of
            the range its field declares (:func:`torquemod._util.tomlcheck.read_table`); the
            message names ``source`` and the dotted key.
        """
        try:
            return read_table(cls, doc, section="processing", path=source,
                              base=cls() if base is None else base)
        except InputError as exc:
            if exc.path is not None:
                raise
            raise InputError(str(exc), path=source) from None

    def with_phase_method(self, method: str | None) -> ProcessingConfig:
        """A copy with another phase method (None keeps this one)."""
        if method is None:
            return self
        return dataclasses.replace(self, phase=dataclasses.replace(self.phase, method=method))


def _is_window(name: str) -> bool:
    """Whether scipy knows the window ``name`` (scipy loads only for another than Hann)."""
    from scipy.signal import get_window
    try:
        get_window(name, 8)
    except (ValueError, TypeError):
        return False
    return True


def coerce_options(cls, options, what: str):
    """Options as an instance of a dataclass.

    Parameters
    ----------
    cls : type
        The dataclass.
    options : cls or Mapping or None
        None gives the defaults, an instance passes through, a mapping is checked for unknown
        keys (lists become tuples).
    what : str
        What the options are for, named in messages.

    Returns
    -------
    cls
        The options.

    Raises
    ------
    InputError
        Not an instance or a mapping, or an unknown key.
    """
    if options is None:
        return cls()
    if isinstance(options, cls):
        return options
    if isinstance(options, Mapping):
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(options) - names
        if unknown:
            raise InputError(f"unknown {what} option(s) {sorted(unknown)}; "
                             f"known: {sorted(names)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in options.items()})
    raise InputError(f"{what} options must be {cls.__name__} or a mapping, got {type(options)}")


def check_option_types(instance, what: str) -> None:
    """Check each field of a dataclass instance against its annotated type.

    ``bool`` takes only True/False (not "no", not 0), ``int`` whole numbers (not bool),
    ``float`` real numbers, ``str`` text; ``X | None`` also None; tuples are checked as
    tuples (lists pass).

    Parameters
    ----------
    instance : object
        The dataclass instance.
    what : str
        What the options are for, named in the message.

    Raises
    ------
    OptionError
        Naming the first field whose value is not of its type.
    """
    import numbers
    import types
    import typing

    hints = typing.get_type_hints(type(instance))
    for f in dataclasses.fields(instance):
        value = getattr(instance, f.name)
        hint = hints.get(f.name)
        union = typing.get_origin(hint) in (typing.Union, types.UnionType)
        args = typing.get_args(hint) if union else ()
        optional = type(None) in args
        base = next((a for a in args if a is not type(None)), hint) if args else hint
        if value is None and optional:
            continue
        origin = typing.get_origin(base) or base
        ok = True
        if origin is bool:
            ok = isinstance(value, bool | _np_bool())
        elif origin is int:
            ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        elif origin is float:
            ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
        elif origin is str:
            ok = isinstance(value, str)
        elif origin is tuple:
            ok = isinstance(value, tuple | list)
        if not ok:
            expected = {bool: "True or False", int: "a whole number", float: "a number",
                        str: "a string", tuple: "a sequence"}.get(origin, str(base))
            raise OptionError(f"{what} option {f.name}={value!r}: expected {expected}"
                              + (" or None" if optional else ""))


def _np_bool():
    import numpy as np
    return np.bool_
