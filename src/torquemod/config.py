"""Parameters of the processing chain, one frozen dataclass per step, defaults from the paper.

Where the V-Track paper gives a value it is used (search band 1.5-2.5 Hz, resampling to
53.344 Hz, notches at the rotation frequency and its 2nd harmonic, 0.36 Hz band-pass, maximum
alignment lag of one modulation period, the middle three modulation periods). Where it gives
none (filter orders, notch Q, high-pass cut-off) the choice is ours and says so.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from .errors import InputError


@dataclass(frozen=True)
class FrequencyParams:
    """Step 1: spectral peak of torque and wheel speed in ``band_hz`` [Hz] (paper)."""

    band_hz: tuple[float, float] = (1.5, 2.5)
    window: str = "hann"  # ours: Hann sidelobes fall 18 dB/octave, away from large tones
    detrend: str = "linear"
    zero_pad: int = 8


@dataclass(frozen=True)
class ResampleParams:
    """Step 2: polyphase resampling to ``target_hz`` [Hz] (paper: 53.344 Hz = 16 670*2/625)."""

    target_hz: float = 53.344
    kaiser_beta: float = 5.0  # MATLAB resample's default
    max_denominator: int = 1000


@dataclass(frozen=True)
class NotchParams:
    """Step 3: zero-phase notches at rotation harmonics (paper: 1st and 2nd)."""

    q: float = 3.0  # ours: bandwidth f0/3, settles in ~q/(pi*f0) = 0.2 s at 4.6 Hz
    wheel_harmonics: tuple[int, ...] = (1, 2)
    platform_harmonics: tuple[int, ...] = (1, 2)
    warn_within_hz: float = 0.3


@dataclass(frozen=True)
class HighpassParams:
    """Step 4: zero-phase Butterworth high-pass removing DC (values ours)."""

    cutoff_hz: float = 0.5
    order: int = 2


@dataclass(frozen=True)
class BandpassParams:
    """Step 5: zero-phase Butterworth band-pass ``width_hz`` wide at f_mod (paper: 0.36 Hz)."""

    width_hz: float = 0.36
    order: int = 2  # ours: prototype order 2, a 4th-order band-pass, applied twice


@dataclass(frozen=True)
class AlignParams:
    """Step 6: cycles 2..n aligned to cycle 1 by unbiased xcorr of the torque (paper)."""

    enabled: bool = True
    max_lag_periods: float = 1.0


@dataclass(frozen=True)
class PhaseParams:
    """Step 7: phase estimator. ``method`` "paper" (peaks/valleys over ``n_periods`` middle
    periods) or "sinefit" (least squares over all whole periods). ``edge_trim_periods``
    modulation periods at each end of a cycle are not used by "paper" (filter transients)."""

    method: str = "paper"
    n_periods: int = 3
    edge_trim_periods: float = 1.0
    sinefit_input: str = "bandpassed"  # or "notched"; band-passed is robust to vibration
    sinefit_trend: bool = True


@dataclass(frozen=True)
class ProcessingConfig:
    """All parameters of the chain; ``nan_policy`` is "raise", "interpolate" or "drop-cycle"."""

    frequency: FrequencyParams = field(default_factory=FrequencyParams)
    resample: ResampleParams = field(default_factory=ResampleParams)
    notch: NotchParams = field(default_factory=NotchParams)
    highpass: HighpassParams = field(default_factory=HighpassParams)
    bandpass: BandpassParams = field(default_factory=BandpassParams)
    align: AlignParams = field(default_factory=AlignParams)
    phase: PhaseParams = field(default_factory=PhaseParams)
    nan_policy: str = "raise"

    def __post_init__(self) -> None:
        if self.phase.method not in ("paper", "sinefit"):
            raise InputError(f"unknown phase method '{self.phase.method}'",
                             hint="use 'paper' or 'sinefit'")
        if self.phase.sinefit_input not in ("bandpassed", "notched"):
            raise InputError(f"unknown sinefit_input '{self.phase.sinefit_input}'",
                             hint="use 'bandpassed' or 'notched'")
        if self.nan_policy not in ("raise", "interpolate", "drop-cycle"):
            raise InputError(f"unknown NaN policy '{self.nan_policy}'",
                             hint="use raise, interpolate or drop-cycle")

    def to_dict(self) -> dict:
        """Every parameter of every step, for provenance.json."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, doc: dict, *, source: str = "[processing]") -> ProcessingConfig:
        """Build from nested dicts, e.g. a manifest's ``[processing]`` table; unknown keys
        raise :class:`InputError` naming them."""
        kwargs = {}
        fields = {f.name: f for f in dataclasses.fields(cls)}
        for key, value in doc.items():
            if key not in fields:
                raise InputError(f"unknown processing key '{key}'", path=source,
                                 hint=f"known keys: {', '.join(fields)}")
            sub = fields[key].default_factory() if isinstance(value, dict) else None
            if sub is None:
                kwargs[key] = value
                continue
            sub_fields = {f.name for f in dataclasses.fields(sub)}
            unknown = set(value) - sub_fields
            if unknown:
                raise InputError(f"unknown key(s) {', '.join(sorted(unknown))} in "
                                 f"'{key}'", path=source,
                                 hint=f"known keys: {', '.join(sorted(sub_fields))}")
            conv = {k: tuple(v) if isinstance(v, list) else v for k, v in value.items()}
            kwargs[key] = dataclasses.replace(sub, **conv)
        return cls(**kwargs)

    def with_phase_method(self, method: str | None) -> ProcessingConfig:
        """A copy with another phase method (None keeps this one)."""
        if method is None:
            return self
        return dataclasses.replace(self, phase=dataclasses.replace(self.phase, method=method))
