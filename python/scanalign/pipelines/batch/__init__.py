"""Batch runs: many reconstruction, pose and pick jobs on a process pool or a Ray cluster.

``scanalign batch MANIFEST --executor local|ray --out DIR`` reads a manifest (:func:`read_manifest`), builds the part
library once (:mod:`scanalign.grasp.part_library`), runs every job (:func:`run_job`, a pure function of the job and the
library) on the executor, and writes one results table (see docs/batch.md).
"""

from scanalign.pipelines.batch.executors import EXECUTORS, LocalExecutor, RayExecutor
from scanalign.pipelines.batch.jobs import DEFAULT_PARTS, KINDS, RECORD_FIELDS, Job, run_job
from scanalign.pipelines.batch.runner import BatchResult, read_manifest, run_batch, summarize

__all__ = ["BatchResult", "DEFAULT_PARTS", "EXECUTORS", "Job", "KINDS", "LocalExecutor", "RECORD_FIELDS",
           "RayExecutor", "read_manifest", "run_batch", "run_job", "summarize"]
