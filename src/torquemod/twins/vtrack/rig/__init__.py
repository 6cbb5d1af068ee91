"""The V-Track digital twin: parameters, equations of motion, sensors."""

from torquemod.twins.vtrack.params import (
    ContactParams,
    DisturbanceParams,
    ModulationParams,
    ProcedureParams,
    RigParams,
    SensorParams,
    SimConfig,
)

__all__ = [
    "ContactParams",
    "DisturbanceParams",
    "ModulationParams",
    "ProcedureParams",
    "RigParams",
    "SensorParams",
    "SimConfig",
]
