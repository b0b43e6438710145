"""Where batch jobs run: a local process pool, or a Ray cluster.

Both yield ``(job, record)`` as jobs finish, in any order; each job runs with ``threads_per_job`` OpenMP threads (the
count the scheduler reserves). The part library reaches each worker once (local: loaded from its ``.npz`` at worker
start-up; Ray: put in the object store once). A worker that dies (a native crash, the OOM killer) does not end the
batch: the local pool's jobs in flight are run again one at a time, so only the job that breaks a pool of its own is
recorded ``crashed``; a Ray task whose ``ray.get`` raises is. Workers dying as they start raise (no job is to blame).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import platform
import sys
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple

import scanalign
from scanalign.grasp.part_library import load_part_library
from scanalign.pipelines.batch.jobs import Job, empty_record, run_job

__all__ = ["EXECUTORS", "LocalExecutor", "RayExecutor", "crashed_record"]

EXECUTORS = ("local", "ray")
#: What a worker calls per job: ``(job, library) -> record`` (default :func:`run_job`); a
#: module-level function, so that it pickles by reference to spawned processes and Ray.
Runner = Callable[[Job, Any], Dict[str, Any]]

_worker_library: Any = None  # the part library of this worker process (local pool only)


def crashed_record(job: Job, message: str) -> Dict[str, Any]:
    """The record of a job whose worker died."""
    return {**empty_record(job), "status": "crashed", "error": message}


def _limit_threads(threads: int) -> None:
    """OpenMP threads of this process (the engine's 0 = 'all cores' then means these)."""
    from threadpoolctl import threadpool_limits

    from scanalign import _core  # noqa: F401 -- loads libgomp, so threadpoolctl finds it

    threadpool_limits(limits=threads, user_api="openmp")


def _init_local_worker(library_path: Optional[str], threads: int, stage: Any) -> None:
    global _worker_library
    with stage.get_lock():  # this worker imported the main script and scanalign
        stage.value = max(stage.value, 1)
    _limit_threads(threads)
    if library_path:
        _worker_library = load_part_library(library_path)
    stage.value = 2  # ready for jobs


def _startup_error(stage: int, library_path: Optional[str]) -> RuntimeError:
    """Why the local pool broke before any worker was ready (``stage``: how far the furthest got)."""
    if stage == 1:
        return RuntimeError(f"the local pool's workers died loading the part library {library_path} (or limiting "
                            "their OpenMP threads), before running any job; their error is printed above")
    main = getattr(sys.modules["__main__"], "__file__", None)
    return RuntimeError(
        "the local pool's workers died while starting, before running any job: a worker (start method 'spawn') "
        f"first imports the main script{f' {main}' if main else ''} again, then scanalign, and that failed (the "
        "error is printed above). A script that calls run_batch must call it under 'if __name__ == \"__main__\":' "
        "(docs/batch.md), else every worker runs the script again instead of its jobs.")


def _run_local(job: Job, runner: Runner) -> Dict[str, Any]:
    return runner(job, _worker_library)


class LocalExecutor:
    """A pool of ``workers`` processes on this machine (``spawn``: no state inherited)."""

    def __init__(self, workers: Optional[int] = None, threads_per_job: int = 1):
        self.workers = max(1, workers or (os.cpu_count() or 1) // max(1, threads_per_job))
        self.threads = threads_per_job

    def describe(self) -> str:
        return f"local pool, {self.workers} worker(s) x {self.threads} thread(s) on {platform.node()}"

    def _pool(self, workers: int, library_path: Optional[str], stage: Any) -> cf.ProcessPoolExecutor:
        return cf.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                      initializer=_init_local_worker, initargs=(library_path, self.threads, stage))

    def run(self, jobs: Sequence[Job], library_path: Optional[Path], library: Any = None, runner: Runner = run_job
            ) -> Iterator[Tuple[Job, Dict[str, Any]]]:
        path = str(library_path) if library_path else None
        suspects: List[Job] = []
        stage = multiprocessing.get_context("spawn").Value("i", 0)  # how far the workers' start-up got (0, 1, 2)
        with self._pool(self.workers, path, stage) as pool:
            futures = {pool.submit(_run_local, job, runner): job for job in jobs}
            for future in cf.as_completed(futures):
                try:
                    yield futures[future], future.result()
                except cf.process.BrokenProcessPool:
                    if stage.value < 2:  # no worker got as far as a job: not the jobs' fault
                        raise _startup_error(stage.value, path) from None
                    suspects.append(futures[future])
        for job in suspects:  # one at a time: the crash is the job's own
            with self._pool(1, path, stage) as pool:
                try:
                    yield job, pool.submit(_run_local, job, runner).result()
                except cf.process.BrokenProcessPool:
                    yield job, crashed_record(job, "the worker process died (a crash in native code, or killed) "
                                                   "while running this job alone")

    def close(self) -> None:
        pass


def _run_ray(job: Job, library: Any, threads: int, runner: Runner) -> Dict[str, Any]:
    _limit_threads(threads)
    return runner(job, library)


class RayExecutor:
    """Tasks on the Ray cluster at ``address`` (None: a local instance of ``workers`` x
    ``threads_per_job`` CPUs), each reserving ``threads_per_job`` CPUs; ``workers`` caps the
    tasks in flight (None: as many as the cluster's CPUs take)."""

    def __init__(self, address: Optional[str] = None, workers: Optional[int] = None, threads_per_job: int = 1):
        try:
            import ray
        except ImportError:
            raise ImportError("the ray executor needs Ray: pip install 'scanalign[ray]' (or pip install ray)") from None
        self.ray, self.threads, self.workers = ray, threads_per_job, workers
        self._started = not ray.is_initialized()
        if self._started:
            kw: Dict[str, Any] = dict(include_dashboard=False, log_to_driver=False, configure_logging=False)
            if address is None and workers:
                kw["num_cpus"] = workers * threads_per_job
            # the workers import scanalign from where this process does (a source checkout too)
            kw["runtime_env"] = {"env_vars": {"PYTHONPATH": str(Path(scanalign.__file__).resolve().parent.parent)}}
            ray.init(address=address, **kw)
        self._task = ray.remote(num_cpus=threads_per_job, max_retries=0)(_run_ray)

    def describe(self) -> str:
        cpus = self.ray.cluster_resources().get("CPU", 0)
        nodes = len([n for n in self.ray.nodes() if n.get("Alive")])
        return f"Ray, {nodes} node(s), {cpus:g} CPU(s), {self.threads} thread(s) per job"

    def run(self, jobs: Sequence[Job], library_path: Optional[Path], library: Any = None, runner: Runner = run_job
            ) -> Iterator[Tuple[Job, Dict[str, Any]]]:
        ray = self.ray
        ref = ray.put(library)  # once: every task gets this reference, not a copy per task
        queue = list(jobs)
        limit = self.workers or len(queue)
        pending: Dict[Any, Job] = {}
        while queue or pending:
            while queue and len(pending) < limit:
                job = queue.pop(0)
                pending[self._task.remote(job, ref, self.threads, runner)] = job
            done, _ = ray.wait(list(pending), num_returns=1)
            job = pending.pop(done[0])
            try:
                yield job, ray.get(done[0])
            except (ray.exceptions.RayError, OSError) as e:
                yield job, crashed_record(job, f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}")

    def close(self) -> None:
        if self._started:
            self.ray.shutdown()
