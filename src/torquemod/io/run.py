"""The train run manifest ``run.toml`` (format in docs/format.md).

A run extends the experiment manifest: the same ``[test]`` modulation keys, ``[[recording]]``
tables and ``[channels]`` map (read by the same readers), with ``[vehicle]`` in place of
``[rig]`` and the axle in place of step and cycle::

    [vehicle]
    wheel_radius_m = 0.46
    normal_load_n = 200000.0       # the axle's (both wheels)
    inertia_kg_m2 = 270.0          # wheelset + gears + motor rotor, referred to the axle
    # gear_ratio = 4.5             # only when torque and speed are recorded at the motor
    # torque_lag_s = 0.002         # the torque signal's first-order lag (drive's estimate)
    # speed_delay_s = 0.0005       # the speed signal's delay (half an encoder gate)
    # vehicle_damping_n_s_m = 0.0  # the vehicle's force per speed change beyond its inertia

    [test]
    modulation_frequency_hz = 5.0
    modulation_amplitude_nm = 1500.0

    [[recording]]
    file = "run.mf4"
    axle = 1
"""

from __future__ import annotations

import cmath
from dataclasses import dataclass, field, fields
from pathlib import Path

from torquemod._util.tomlcheck import (
    NON_NEGATIVE,
    POSITIVE,
    Check,
    between,
    checked,
    prefixed,
    read_table,
)
from torquemod.errors import ManifestError
from torquemod.io.manifest import _load_toml, checked_channel_map, recording_file

#: the sensors' dynamics: a time constant or delay [s]
_SENSOR_TIME = Check(lo=0.0, hi=1.0, hi_open=True, need="a time in seconds, >= 0 and < 1",
                     hint="e.g. 0.002 for 2 ms; leave it out when unknown")


@dataclass(frozen=True)
class _VehicleTable:
    """``[vehicle]`` as written (:class:`Vehicle` is built from it; ``vehicle`` its name,
    ``mass_kg`` taken and not used)."""

    wheel_radius_m: float = checked(check=POSITIVE)
    normal_load_n: float = checked(check=POSITIVE)
    inertia_kg_m2: float = checked(check=POSITIVE)
    gear_ratio: float | None = checked(None, POSITIVE)
    motor_inertia_kg_m2: float | None = checked(None, POSITIVE)
    coupling_stiffness_nm_rad: float | None = checked(None, POSITIVE)
    coupling_damping_nm_s_rad: float = checked(0.0, NON_NEGATIVE)
    vehicle: object = ""
    mass_kg: object = None
    torque_lag_s: float = checked(0.0, _SENSOR_TIME)
    torque_delay_s: float = checked(0.0, _SENSOR_TIME)
    speed_delay_s: float = checked(0.0, _SENSOR_TIME)
    vehicle_damping_n_s_m: float = checked(0.0, Check(
        lo=0.0, hi=1e9, hi_open=True, need="a damping in N*s/m, >= 0",
        hint="leave it out when unknown (the vehicle is then taken as an inertia)"))


@dataclass(frozen=True)
class _TestTable:
    """``[test]``: the modulation [Hz], [N*m]; other keys are kept, not used."""

    modulation_frequency_hz: float = checked(check=POSITIVE)
    modulation_amplitude_nm: float = checked(check=POSITIVE)
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _RecordingTable:
    """One ``[[recording]]`` of a run: ``file``, ``axle`` (from 1); ``group`` and
    ``sample_rate_hz`` are checked as the experiment manifest's; free ``date``, ``note``,
    ``comment``."""

    file: object = checked()
    axle: int = checked(1, between(1, None))
    group: object = None
    sample_rate_hz: object = None
    date: object = None
    note: object = None
    comment: object = None


@dataclass(frozen=True)
class Vehicle:
    """The vehicle of a train run: run.toml's ``[vehicle]`` table.

    Attributes
    ----------
    wheel_radius_m : float
        Rolling radius R [m].
    normal_load_n : float
        Axle load N (both wheels) [N].
    inertia_kg_m2 : float
        Rotating inertia referred to the axle J [kg*m^2] (the drive line's included).
    gear_ratio : float or None
        Motor turns per axle turn [-] when torque and speed are recorded at the motor, else
        None.
    motor_inertia_kg_m2 : float or None
        The motor's share of ``inertia_kg_m2``, referred to the axle [kg*m^2], when the drive
        line is known.
    coupling_stiffness_nm_rad : float or None
        Stiffness of the coupling between motor and axle, referred to the axle [N*m/rad].
    coupling_damping_nm_s_rad : float
        Damping of that coupling [N*m*s/rad]. Default 0.
    name : str
        The vehicle's name. Default "".
    torque_lag_s : float
        Time constant of a first-order lag of the recorded torque [s] (a drive's torque
        estimated from motor current is filtered). Default 0.
    torque_delay_s : float
        Pure delay of the recorded torque [s]. Default 0.
    speed_delay_s : float
        Pure delay of the recorded speed [s] (a speed from counting encoder pulses over a
        gate is late by half the gate). Default 0.
    vehicle_damping_n_s_m : float
        Force with which the vehicle resists a change of its speed at the modulation
        frequency beyond its inertia [N*s/m] (other axles holding the speed, the running
        resistance's slope); 0 takes the vehicle as an inertia
        (:func:`torquemod.ontrain.window.damping_from_ratio`). Default 0.

    Notes
    -----
    The estimator removes the declared signal dynamics from the measured torque-to-speed
    ratio (:meth:`sensor_response`).
    """

    wheel_radius_m: float
    normal_load_n: float
    inertia_kg_m2: float
    gear_ratio: float | None = None
    motor_inertia_kg_m2: float | None = None
    coupling_stiffness_nm_rad: float | None = None
    coupling_damping_nm_s_rad: float = 0.0
    name: str = ""
    torque_lag_s: float = 0.0
    torque_delay_s: float = 0.0
    speed_delay_s: float = 0.0
    vehicle_damping_n_s_m: float = 0.0

    @property
    def has_drive_line(self) -> bool:
        return self.motor_inertia_kg_m2 is not None and \
            self.coupling_stiffness_nm_rad is not None

    def sensor_response(self, frequency_hz: float) -> complex:
        """The recorded signals' own dynamics at a frequency.

        Parameters
        ----------
        frequency_hz : float
            Frequency f [Hz].

        Returns
        -------
        complex
            H = (recorded torque / recorded speed) / (true torque / true speed) [-]; 1 when none
            is declared. Divide a measured ratio by it.

        Notes
        -----
        ``H = exp(-j*Omega*(tau_T - tau_w)) / (1 + j*Omega*tau_lag)``, Omega = 2*pi*f, for the
        declared delays tau_T (``torque_delay_s``), tau_w (``speed_delay_s``) and the torque's
        first-order lag tau_lag (``torque_lag_s``).

        Examples
        --------
        >>> Vehicle(0.46, 80e3, 100.0).sensor_response(4.0)
        (1+0j)
        """
        om = 2.0 * cmath.pi * frequency_hz
        net = self.torque_delay_s - self.speed_delay_s
        return cmath.exp(-1j * om * net) / (1.0 + 1j * om * self.torque_lag_s)


@dataclass(frozen=True)
class RunRecording:
    """One ``[[recording]]`` of a run.

    Attributes
    ----------
    path : pathlib.Path
        The recording's file.
    axle : int
        The axle it holds. Default 1.
    group : str or None
        A group inside the file. Default None.
    sample_rate_hz : float or None
        Its sample rate [Hz]; when given it replaces the file's time base.
    date : str or None
        When it was recorded, as written. Default None.
    index : int
        Position in the manifest, for messages. Default 0.
    """

    path: Path
    axle: int = 1
    group: str | None = None
    sample_rate_hz: float | None = None
    date: str | None = None
    index: int = 0


@dataclass(frozen=True)
class Run:
    """A parsed ``run.toml``: a train run's vehicle, modulation and recordings.

    Attributes
    ----------
    manifest_path : pathlib.Path
        The manifest.
    vehicle : Vehicle
        The ``[vehicle]`` table.
    modulation_frequency_hz : float
        Declared modulation frequency [Hz] (``[test]``).
    modulation_amplitude_nm : float
        Declared modulation amplitude [N*m] (``[test]``).
    recordings : tuple of RunRecording
        One per axle recording, in the manifest's order.
    channel_map : dict
        The ``[channels]`` table.
    extra : dict
        Other tables: ``[onboard]``, ``[truth]``, ...
    """

    manifest_path: Path
    vehicle: Vehicle
    modulation_frequency_hz: float
    modulation_amplitude_nm: float
    recordings: tuple[RunRecording, ...]
    channel_map: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)  # [onboard], [truth], other tables

    @property
    def folder(self) -> Path:
        return self.manifest_path.parent


def read_run(path: str | Path) -> Run:
    """Parse and check a ``run.toml``; the recordings are not opened.

    Parameters
    ----------
    path : str or pathlib.Path
        The manifest, or a folder holding ``run.toml``.

    Returns
    -------
    Run
        The parsed run.

    Raises
    ------
    InputError
        (:class:`~torquemod.errors.ManifestError`) an unreadable file, a rig experiment, a
        missing section or key, a value of the wrong type or range, naming the file and key.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "run.toml"
    doc = _load_toml(path, "run.toml")
    if "rig" in doc and "vehicle" not in doc:
        raise ManifestError("is a rig experiment (it has [rig], no [vehicle])", path=path,
                            hint="process it with 'torquemod process'")
    for section in ("vehicle", "test"):
        if not isinstance(doc.get(section), dict):
            raise ManifestError(f"missing section [{section}]", path=path,
                                hint="see docs/format.md for the run manifest")
    vt = read_table(_VehicleTable, doc["vehicle"], section="vehicle", path=path,
                    error=ManifestError)
    test = read_table(_TestTable, doc["test"], section="test", path=path, error=ManifestError,
                      extra="extra")
    if (vt.motor_inertia_kg_m2 is None) != (vt.coupling_stiffness_nm_rad is None):
        raise ManifestError("the drive line needs motor_inertia_kg_m2 and "
                            "coupling_stiffness_nm_rad together", path=path,
                            hint="give both, or neither (a rigid drive line)")
    vehicle = Vehicle(**{f.name: getattr(vt, f.name) for f in fields(Vehicle)
                         if f.name != "name"}, name=str(vt.vehicle))
    if vehicle.has_drive_line and vehicle.motor_inertia_kg_m2 >= vehicle.inertia_kg_m2:
        raise ManifestError("vehicle.motor_inertia_kg_m2 must be a part of inertia_kg_m2",
                            path=path, hint="inertia_kg_m2 is the total referred to the axle")
    recs = doc.get("recording", [])
    if not isinstance(recs, list) or not recs:
        raise ManifestError("the run lists no [[recording]]", path=path,
                            hint="add a [[recording]] table with the file of each axle")
    entries = []
    for i, rec in enumerate(recs):
        where = f"recording #{i + 1}"
        r = read_table(_RecordingTable, rec, section="recording", path=path, key_prefix="",
                       error=prefixed(where, ManifestError))
        file, group, fs = recording_file(rec, where, path.parent, path, "run")
        entries.append(RunRecording(file, r.axle, group, fs, r.date, i))
    axles = [e.axle for e in entries]
    if len(set(axles)) != len(axles):
        raise ManifestError("an axle is listed twice", path=path,
                            hint="give one [[recording]] per axle (split long runs later)")
    cmap = checked_channel_map(doc.get("channels", {}), path, [e.sample_rate_hz for e in entries])
    extra = {k: v for k, v in doc.items() if k not in ("vehicle", "test", "recording",
                                                        "channels")}
    return Run(path.resolve(), vehicle, test.modulation_frequency_hz,
               test.modulation_amplitude_nm, tuple(entries), cmap, extra)
