"""Many renders: ``render_many`` with a local worker pool, Ray or any ``concurrent.futures`` executor.

:mod:`.run` (``render_many``), :mod:`.jobs` (``RenderJob``, ``read_jobs``, ``JobStatus``, ``BatchReport``),
:mod:`.manifest` (resume), :mod:`.state` (one run's bookkeeping), :mod:`.importable` (what workers can
import), :mod:`.local` (the local pool), :mod:`.remote` (Ray, futures executors), :mod:`.worker` (the code
that runs one job).
"""

from blendify_core.batch.jobs import BatchReport, JobStatus, RenderJob, read_jobs
from blendify_core.batch.local import DEFAULT_RECYCLE_AFTER
from blendify_core.batch.manifest import MANIFEST_NAME
from blendify_core.batch.run import render_many

__all__ = [
    "RenderJob",
    "JobStatus",
    "BatchReport",
    "render_many",
    "read_jobs",
    "DEFAULT_RECYCLE_AFTER",
    "MANIFEST_NAME",
]
