"""A simulated run of the V-Track twin held in memory: its recordings, manifest and truth.

:func:`torquemod.simulate.simulate_run` returns a :class:`SimulatedRun`; ``write(folder)``
turns it into the experiment folder that ``torquemod simulate`` writes (``experiment.toml``,
one file per recording, ``truth.json``), and ``experiment()`` with ``recording(entry)`` hand
it to the processing chain without files: the recordings come out as the HDF5 reader would
give them after a write and a read (the same channels, sample times, rate and start time,
value for value), so that a sweep can run twin -> chain in memory.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..data import CHANNEL_UNITS, Experiment, Recording, RecordingEntry
from ..fsutil import atomic_dir
from ..io import write_manifest, write_recording
from ..jsonutil import dump_json

__all__ = ["SimulatedRun"]

_SUFFIX = {"csv": ".csv", "hdf5": ".h5"}


@dataclass(frozen=True)
class SimulatedRun:
    """One run of the twin in memory.

    Attributes
    ----------
    truth : dict
        The ``truth.json`` document (``format`` None until written): per step the steady
        state, the theory phases and what was simulated (:mod:`torquemod.rig.truth`).
    rig, test, extra : dict
        The ``[rig]``, ``[test]`` and other tables of ``experiment.toml``.
    entries : tuple of dict
        The ``[[recording]]`` tables (``step``, ``dc_torque_nm``, ``file`` stem without a
        suffix, ``cycle`` when one file per revolution), in order.
    recordings : tuple of Recording
        The sensor channels of each entry [SI units], sample times from ``t0_s`` [s] at
        ``fs_hz`` [Hz].
    """

    truth: dict
    rig: dict
    test: dict
    extra: dict
    entries: tuple[dict, ...]
    recordings: tuple[Recording, ...] = field(repr=False)

    @property
    def slip_step(self) -> int | None:
        """The step in which the wheel slipped (None: none did)."""
        return self.truth["slip_step"]

    def _manifest_entries(self, fmt: str) -> list[dict]:
        return [{**e, "file": e["file"] + _SUFFIX[fmt]} for e in self.entries]

    def write(self, folder: str | Path, *, fmt: str = "hdf5", force: bool = False) -> Path:
        """Write the experiment folder ``folder`` (``experiment.toml``, the recordings in
        ``fmt``, ``truth.json``), atomically as ``torquemod simulate`` does; an existing
        non-empty folder is replaced only with ``force``. Returns the manifest's path."""
        folder = Path(folder)
        with atomic_dir(folder, force=force) as tmp:
            for e, rec in zip(self._manifest_entries(fmt), self.recordings, strict=True):
                if fmt == "hdf5":
                    write_recording(tmp / e["file"], rec, fmt=fmt, write_time=True,
                                    data_after_close=True)
                else:
                    write_recording(tmp / e["file"], rec, fmt=fmt)
            write_manifest(tmp / "experiment.toml", rig=self.rig, test=self.test,
                           recordings=self._manifest_entries(fmt), extra=self.extra)
            (tmp / "truth.json").write_text(dump_json({**self.truth, "format": fmt}),
                                            encoding="utf-8")
        return folder / "experiment.toml"

    def experiment(self, folder: str | Path = "twin (in memory)") -> Experiment:
        """The :class:`~torquemod.data.Experiment` that reading ``write(folder)``'s
        manifest gives (HDF5 recordings; nothing is written). The recordings' paths, which
        messages name, lie in ``folder``."""
        from ..io.manifest import experiment_from_doc
        path = Path(folder) / "experiment.toml"
        doc = {"rig": dict(self.rig), "test": dict(self.test), **self.extra,
               "recording": self._manifest_entries("hdf5")}
        return experiment_from_doc(doc, path)

    def recording(self, experiment: Experiment, entry: RecordingEntry) -> Recording:
        """The recording of ``entry`` (of :meth:`experiment`) as the HDF5 reader returns it
        from the written file: the same channel lookup, units, time base and checks
        (:func:`torquemod.io.timebase.assemble_recording`), on the values in memory."""
        from ..io.channels import RawChannel, resolve_channel_map, source_name
        from ..io.timebase import assemble_recording
        from ..io.validate import check_channels
        rec = self.recordings[entry.index]
        cmap = resolve_channel_map(experiment.channel_map, entry.path).with_sample_rate(
            entry.sample_rate_hz, path=entry.path)
        time = rec.time_s()

        def lookup(name: str) -> RawChannel | None:
            if name == "time_s":
                return RawChannel(time, CHANNEL_UNITS["time_s"])
            values = rec.channels.get(name)
            return None if values is None else RawChannel(values, CHANNEL_UNITS[name])

        out = assemble_recording(cmap, lookup, path=entry.path,
                                 source=source_name(entry.path, entry.group),
                                 native_rate=(float(rec.fs_hz), float(rec.t0_s)),
                                 available=lambda: ["time_s", *rec.channels], notes=[])
        check_channels(out, path=entry.path)
        return out
