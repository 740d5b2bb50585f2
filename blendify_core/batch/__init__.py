"""Many renders: ``render_many`` with a local worker pool, Ray or any ``concurrent.futures`` executor."""

from blendify_core.batch.run import (
    DEFAULT_RECYCLE_AFTER,
    MANIFEST_NAME,
    BatchReport,
    JobStatus,
    RenderJob,
    read_jobs,
    render_many,
)

__all__ = [
    "RenderJob",
    "JobStatus",
    "BatchReport",
    "render_many",
    "read_jobs",
    "DEFAULT_RECYCLE_AFTER",
    "MANIFEST_NAME",
]
