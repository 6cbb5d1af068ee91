"""Reading and writing experiments: the TOML manifest and one module per recording format."""

from torquemod.io.manifest import read_experiment, write_manifest
from torquemod.io.recording import read_entry, read_recording, supported_suffixes, write_recording

__all__ = ["read_entry", "read_experiment", "read_recording", "supported_suffixes",
           "write_manifest", "write_recording"]
