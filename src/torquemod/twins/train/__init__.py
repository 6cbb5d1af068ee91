"""The train twin: a powered wheelset on a running train, its logger, and a run
written in the run format (docs/format.md)."""

from torquemod.twins.train.params import (
    CONDITIONS,
    TrainConfig,
    config_from_dict,
    default_train_config_text,
    is_train_config,
    load_train_config,
)
from torquemod.twins.train.simulate import integrate_run, measure, run_train_simulation, truth_table

__all__ = ["CONDITIONS", "TrainConfig", "config_from_dict", "default_train_config_text",
           "integrate_run", "is_train_config", "load_train_config", "measure",
           "run_train_simulation", "truth_table"]
