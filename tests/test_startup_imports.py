"""What a command imports before its first stage line (benchmarks/startup.py times it): the
CLI, the API and reading a manifest stay clear of scipy, pandas, matplotlib, numba and the
readers' libraries, which load when first used."""

from __future__ import annotations

import json
import subprocess
import sys

from torquemod.testing import write_synthetic_experiment

HEAVY = ("scipy", "pandas", "matplotlib", "numba", "h5py", "pyarrow")


def test_manifest_read_before_the_heavy_imports(tmp_path):
    write_synthetic_experiment(tmp_path, n_steps=1, n_cycles=1, fmt="hdf5")
    code = ("import sys, json; import torquemod.cli, torquemod.api as api, torquemod._util.fsutil; "
            f"api.read_experiment({str(tmp_path / 'experiment.toml')!r}); "
            "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))")
    loaded = json.loads(subprocess.run([sys.executable, "-c", code], check=True,
                                       capture_output=True, text=True).stdout)
    assert not set(HEAVY) & set(loaded)
    # ... and the lazy names still resolve, to the modules that define them
    import torquemod.api as api
    from torquemod.processing.pipeline import process_experiment
    from torquemod.results.folder import save
    assert api.save is save and api.process_experiment is process_experiment


def test_twin_config_checked_before_the_simulator_loads():
    """``torquemod simulate`` checks its configuration (a bad file refused before any stage)
    with the Hertz ellipse and Kalker's coefficients only: the compiled kernels (numba), the
    large-signal theory's solvers and the writers load once the simulation stage has begun."""
    code = ("import sys, json; from torquemod.twins.vtrack.simconfig import load_config; "
            "cfg = load_config(); assert cfg.rig.contact.a_m > 0; "
            "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))")
    loaded = json.loads(subprocess.run([sys.executable, "-c", code], check=True,
                                       capture_output=True, text=True).stdout)
    assert not {"numba", "pandas", "matplotlib", "h5py", "pyarrow"} & set(loaded)
    # the re-exported names are the configuration module's own
    from torquemod.twins.vtrack import simconfig, simulate
    assert simulate.load_config is simconfig.load_config
