"""The V-Track digital twin under one namespace: its parameters (:mod:`torquemod.twins.vtrack.rig`)
and the
simulation that writes an experiment in the measurement's own format
(:mod:`torquemod.twins.vtrack.simulate`). ``import torquemod as tm; tm.twin.run_simulation(...)``.

The twin is kept apart from the measurement: nothing in the processing or fitting imports it.
"""

from __future__ import annotations

from torquemod.twins.vtrack import rig as _rig
from torquemod.twins.vtrack.rig import *  # noqa: F403 - the parameter classes, listed in rig.__all__
from torquemod.twins.vtrack.rig.batch import simulate_batch
from torquemod.twins.vtrack.simulate import (
    config_from_dict,
    default_config_text,
    load_config,
    run_simulation,
)

__all__ = [*_rig.__all__, "config_from_dict", "default_config_text", "load_config",
           "run_simulation", "simulate_batch"]
