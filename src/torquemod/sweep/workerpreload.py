"""What a sweep's worker needs before its first point, imported by the fork server the local
workers are forked from (:func:`torquemod._util.daskutil.start_worker_server`, named by
:data:`torquemod.sweep.run.WORKER_MODULES`): the sweep's code, the twin, the processing chain
and the fits, and the creep-law family's tables (read once into the server and shared by
the workers it forks, not read by each)."""

from __future__ import annotations

import torquemod.analysis.analyzer
import torquemod.analysis.fit
import torquemod.analysis.phasefit
import torquemod.api
import torquemod.processing.pipeline
import torquemod.sweep.run
import torquemod.twins.vtrack.simulate  # noqa: F401
from torquemod.analysis.creeplaws import family_tables

family_tables(True)
family_tables(False)
