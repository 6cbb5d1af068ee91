"""Reading and writing experiments: the TOML manifest and one module per recording format."""

from .manifest import read_experiment, write_manifest
from .recording import read_recording, write_recording

__all__ = ["read_experiment", "read_recording", "write_manifest", "write_recording"]
