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
