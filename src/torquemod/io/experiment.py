"""Thin containers for experiments and recordings. No algorithms live here."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from torquemod.io.config import ProcessingConfig

#: The method's channels, SI units, in the order the CSV format lists them.
CHANNELS: tuple[str, ...] = (
    "torque_nm",
    "wheel_speed_rad_s",
    "platform_speed_rad_s",
    "fx_n",
    "fy_n",
    "fz_n",
    "vehicle_speed_m_s",
    "position_m",
)
#: Channels every recording needs (the phase needs nothing else).
REQUIRED_CHANNELS: tuple[str, ...] = ("torque_nm", "wheel_speed_rad_s")
#: Channels that may be absent: without the platform speed no creepage is measured; without
#: forces the CoA is the drive's adhesion from the torque. Forces come as fx, fz (+ fy).
#: A train run adds the reference speed of the vehicle (radar, GNSS or an unpowered axle) and
#: the position along the track (docs/format.md, run.toml).
OPTIONAL_CHANNELS: tuple[str, ...] = ("platform_speed_rad_s", "fx_n", "fy_n", "fz_n",
                                      "vehicle_speed_m_s", "position_m")
#: Units of :data:`CHANNELS` (and of the time column) as written in files and docs.
CHANNEL_UNITS: dict[str, str] = {
    "time_s": "s",
    "torque_nm": "N*m",
    "wheel_speed_rad_s": "rad/s",
    "platform_speed_rad_s": "rad/s",
    "fx_n": "N",
    "fy_n": "N",
    "fz_n": "N",
    "vehicle_speed_m_s": "m/s",
    "position_m": "m",
}


@dataclass(frozen=True)
class Rig:
    """The rig's geometry: the manifest's ``[rig]`` table.

    Attributes
    ----------
    wheel_radius_m : float
        Rolling radius of the wheel R_w [m].
    platform_radius_m : float
        Radius of the wheel's path on the ring R_p [m], the R_p of Eq. (3) of [1]_ (creepage
        from the wheel's and the platform's angular speeds).
    extra : dict
        Further keys of the table, kept as read.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (3).
    """

    wheel_radius_m: float
    platform_radius_m: float
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class TestSetup:
    """The test's nominal settings: the manifest's ``[test]`` table.

    Attributes
    ----------
    normal_load_n : float
        Normal load on the wheel N [N].
    modulation_frequency_hz : float
        Nominal modulation frequency [Hz] (the actual one is measured).
    modulation_amplitude_nm : float
        Nominal modulation amplitude [N*m].
    extra : dict
        Further keys of the table, kept as read.
    """

    normal_load_n: float
    modulation_frequency_hz: float
    modulation_amplitude_nm: float
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RecordingEntry:
    """One ``[[recording]]`` of the manifest.

    Attributes
    ----------
    step : int
        The torque step the recording belongs to.
    dc_torque_nm : float
        The step's nominal DC torque [N*m].
    path : pathlib.Path
        The recording's file.
    cycle : int or None
        The platform revolution it holds; None when the file may span several.
    group : str or None
        A group inside the file (HDF5 group, TDMS group, .mat struct). Default None.
    index : int
        Position in the manifest, for messages. Default 0.
    sample_rate_hz : float or None
        The recording's sample rate [Hz]; when given it replaces the file's time base.
    """

    step: int
    dc_torque_nm: float
    path: Path
    cycle: int | None = None
    group: str | None = None
    index: int = 0  # position in the manifest, for messages
    sample_rate_hz: float | None = None


@dataclass(frozen=True)
class Experiment:
    """A parsed ``experiment.toml``: where it is, the rig, the test and its recordings.

    Attributes
    ----------
    manifest_path : pathlib.Path
        The manifest.
    rig : Rig
        The ``[rig]`` table.
    test : TestSetup
        The ``[test]`` table.
    recordings : tuple of RecordingEntry
        The ``[[recording]]`` entries, in the manifest's order.
    channel_map : dict
        The ``[channels]`` table: the files' column names and units per channel.
    extra : dict
        Other top-level tables, e.g. ``[processing]``.
    """

    manifest_path: Path
    rig: Rig
    test: TestSetup
    recordings: tuple[RecordingEntry, ...]
    channel_map: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)  # other top-level tables, e.g. [processing]

    @property
    def folder(self) -> Path:
        return self.manifest_path.parent

    @property
    def steps(self) -> list[int]:
        return sorted({r.step for r in self.recordings})

    @property
    def processing(self) -> ProcessingConfig:
        """The manifest's ``[processing]`` table as a
        :class:`~torquemod.io.config.ProcessingConfig` over the defaults for the test's
        nominal modulation frequency (:meth:`~torquemod.io.config.ProcessingConfig.
        for_modulation`: the paper's 2 Hz values, scaled at another frequency)."""
        table = self.extra.get("processing")
        return ProcessingConfig.for_modulation(self.test.modulation_frequency_hz, table or {},
                                               source=str(self.manifest_path))


@dataclass
class Recording:
    """Sampled channels of one recording, SI units, uniformly sampled.

    Attributes
    ----------
    channels : dict of str to ndarray
        The names of :data:`CHANNELS` (at least :data:`REQUIRED_CHANNELS`) to 1-D float64
        arrays of equal length, in the units of :data:`CHANNEL_UNITS`.
    fs_hz : float
        Sampling rate [Hz].
    t0_s : float
        Time of the first sample [s]. Default 0.
    source : str
        Where it was read from. Default "".
    notes : list of str
        What the reader did (time bases), for the provenance.
    """

    channels: dict[str, np.ndarray]
    fs_hz: float
    t0_s: float = 0.0
    source: str = ""
    notes: list[str] = field(default_factory=list)  # what the reader did (time bases), for
    # provenance

    @property
    def n_samples(self) -> int:
        return len(next(iter(self.channels.values())))

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.fs_hz

    def time_s(self) -> np.ndarray:
        """Sample times [s]."""
        return self.t0_s + np.arange(self.n_samples) / self.fs_hz

    def slice(self, start: int, stop: int) -> Recording:
        """Samples ``start:stop`` as a new recording (views, no copies)."""
        return Recording({k: v[start:stop] for k, v in self.channels.items()}, self.fs_hz,
                         self.t0_s + start / self.fs_hz, self.source, list(self.notes))
