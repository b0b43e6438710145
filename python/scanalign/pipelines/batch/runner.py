"""A batch: read the manifest, build the part library once (``parts.npz``), run the jobs on an executor, journal each
record as it arrives (``records.jsonl``: a re-run with the same folder skips the jobs recorded ``ok``), and write
``results.csv``, ``results.parquet`` (pyarrow) and ``summary.json``: the last record of every job, in manifest order.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import multiprocessing
import statistics
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Union

from scanalign.grasp.part_library import build_part_library, load_part_library
from scanalign.io import atomic_open
from scanalign.pipelines.batch.executors import EXECUTORS, LocalExecutor, RayExecutor, Runner
from scanalign.pipelines.batch.jobs import (COUNT_FIELDS, KINDS, LIBRARY_SETTINGS, RECORD_FIELDS, TEXT_FIELDS, Job,
                                            run_job)

__all__ = ["BatchResult", "read_manifest", "run_batch"]

_SETTING_FILES = {"joints", "hand_eye", "robot_base"}  # files a pick job's settings name
_JOB_KEYS = {"id", "kind", "source", "robot", "noise", "seed", "frames", "parts", "settings", "save"}


def _jobs_from_entry(entry: Dict[str, Any], defaults: Dict[str, Any], where: str, root: Path) -> List[Job]:
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected a mapping of job fields, got {type(entry).__name__}")
    e = {**defaults, **entry}
    unknown = set(e) - _JOB_KEYS - {"seeds"}
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {sorted(unknown)}; known: {sorted(_JOB_KEYS | {'seeds'})}")
    if "id" not in e or "kind" not in e:
        raise ValueError(f"{where}: every job needs 'id' and 'kind' ({', '.join(KINDS)})")
    for key in ("source", "save"):  # relative paths are relative to the manifest
        if e.get(key) and e[key] != "synthetic" and not Path(e[key]).is_absolute():
            e[key] = str(root / e[key])
    if isinstance(e.get("settings"), dict):
        e["settings"] = {k: str(root / v) if k in _SETTING_FILES and isinstance(v, str) and not Path(v).is_absolute()
                         else v for k, v in e["settings"].items()}
    parts = e.get("parts", ())
    e["parts"] = tuple(p if "/" not in str(p) and not str(p).endswith((".json", ".yaml", ".yml"))
                       or Path(p).is_absolute() else str(root / p) for p in ([parts] if isinstance(parts, str) else parts))
    seeds = e.pop("seeds", None)
    if seeds is None:
        return [Job(**e)]
    values = list(range(seeds)) if isinstance(seeds, int) and not isinstance(seeds, bool) else seeds
    if not isinstance(values, list) or not values or not all(isinstance(s, int) for s in values):
        raise ValueError(f"{where}: seeds must be a count >= 1 or a list of integers, got {seeds!r}")
    return [Job(**{**e, "id": f"{e['id']}-s{s}", "seed": s,
                   "save": f"{e['save']}/s{s}" if e.get("save") else ""}) for s in values]


def _csv_entries(path: Path) -> List[Dict[str, Any]]:
    with open(path, newline="", encoding="utf-8") as f:
        entries = [{k.strip(): v.strip() for k, v in row.items() if k and v is not None and v.strip()}
                   for row in csv.DictReader(f)]
    for e in entries:
        e.update({key: int(e[key]) for key in ("seed", "frames", "seeds") if key in e})
        if "parts" in e:
            e["parts"] = [p for p in e["parts"].split(";") if p]
        if "settings" in e:
            e["settings"] = json.loads(e["settings"])
    return entries


def read_manifest(path: Union[str, Path]) -> List[Job]:
    """The jobs of a manifest file (format in docs/batch.md): YAML (``jobs:``, optional ``defaults:``; ``seeds`` repeats
    a job per seed, ids suffixed ``-s<seed>``) or CSV (a header naming the fields; ``parts`` separated by ``;``,
    ``settings`` as JSON). Relative paths are relative to the manifest's folder.

    Raises:
        ValueError: unreadable or malformed manifest, an unknown field or kind, or two jobs
            with the same id (the message names the file and the entry).
    """
    import yaml

    path = Path(path)
    try:
        if path.suffix.lower() == ".csv":
            entries, defaults = _csv_entries(path), {}
        else:
            doc = yaml.safe_load(path.read_text(encoding="utf-8"))
            if not isinstance(doc, dict) or not isinstance(doc.get("jobs"), list):
                raise ValueError("expected a mapping with a 'jobs' list")
            entries, defaults = doc["jobs"], doc.get("defaults") or {}
            if not isinstance(defaults, dict):
                raise ValueError("'defaults' must be a mapping")
        jobs = list(itertools.chain.from_iterable(
            _jobs_from_entry(e, defaults, f"job {i}", path.parent) for i, e in enumerate(entries)))
    except (OSError, yaml.YAMLError, ValueError, TypeError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: {e}") from None
    twice = [i for i, n in Counter(j.id for j in jobs).items() if n > 1]
    if twice:
        raise ValueError(f"{path}: job id {twice[0]!r} appears twice (ids are the resume key)")
    if not jobs:
        raise ValueError(f"{path}: no jobs")
    return jobs


@dataclass
class BatchResult:
    """What :func:`run_batch` did: ``records`` (one per job, manifest order), ``paths`` of the files written,
    ``seconds`` of wall time, ``skipped`` jobs already done before, and ``executor`` described."""

    records: List[Dict[str, Any]]
    paths: Dict[str, Path]
    seconds: float
    skipped: int
    executor: str

    @property
    def ok(self) -> bool:
        """Every job's last record says ``ok``."""
        return all(r["status"] == "ok" for r in self.records)


def _journal(out: Path) -> Dict[str, Dict[str, Any]]:
    """Last record per job id from records.jsonl (a torn last line is ignored)."""
    last: Dict[str, Dict[str, Any]] = {}
    path = out / "records.jsonl"
    for line in path.read_text(encoding="utf-8").splitlines() if path.exists() else ():
        try:
            r = json.loads(line)
            last[r["id"]] = r
        except (ValueError, KeyError, TypeError):
            continue
    return last


def _library(jobs: Sequence[Job], out: Path, progress: bool) -> Any:
    """The part library for the pose and pick jobs: out/parts.npz when it holds their parts
    described with LIBRARY_SETTINGS, else built (once) and saved there."""
    names = list(dict.fromkeys(p for j in jobs if j.kind in ("pose", "pick") for p in j.part_names))
    if not names:
        return None, None
    path = out / "parts.npz"
    if path.exists():
        try:
            lib = load_part_library(path)
            if all(n in lib for n in names) and lib.pose_settings == LIBRARY_SETTINGS:
                return lib, path
        except ValueError:
            pass  # an older format or a corrupt file: rebuilt below
    lib = build_part_library(names, progress=progress, **LIBRARY_SETTINGS)
    return lib, lib.save(path)


def run_batch(jobs: Sequence[Job], out: Union[str, Path], *, executor: str = "local", workers: Optional[int] = None,
              address: Optional[str] = None, threads_per_job: int = 1, retries: int = 1, progress: bool = True,
              runner: Runner = run_job) -> BatchResult:
    """Runs the jobs (ids unique) and writes the results table into ``out``; the jobs an
    earlier run recorded ``ok`` there are skipped (resume).

    Args:
        executor: ``"local"`` (a process pool) or ``"ray"``.
        workers: local: processes (default cores / threads_per_job); ray: at most this many
            jobs at once (default: as the cluster's CPUs take).
        address: Ray cluster address (``"auto"``, ``"ray://head:10001"``); None starts a local Ray instance.
        threads_per_job: OpenMP threads of each job, and CPUs it reserves (Ray).
        retries: times a failed or crashed job is tried again (0: none).
        runner: ``(job, library) -> record`` (default :func:`run_job`), a module-level function (sent to the workers by
            reference); fields of :data:`RECORD_FIELDS` it leaves out are empty in the table.

    Raises:
        ValueError: bad arguments or duplicate job ids.
        RuntimeError: the local pool's workers died while starting, before any job (most often: a script that calls
            run_batch without ``if __name__ == "__main__":``). A failing job never raises: its record says ``failed``
            or ``crashed``, :attr:`BatchResult.ok` is False and :func:`summarize`'s ``verdict`` counts them.
    """
    from tqdm.auto import tqdm

    if getattr(multiprocessing.current_process(), "_inheriting", False):  # multiprocessing's own test (spawn.py)
        raise RuntimeError("run_batch was called by a worker process of the local pool while it imported the main "
                           "script again (start method 'spawn'): call run_batch under 'if __name__ == \"__main__\":'")
    if not isinstance(threads_per_job, int) or threads_per_job < 1:
        raise ValueError(f"threads_per_job must be an integer >= 1, got {threads_per_job!r}")
    if not isinstance(retries, int) or not 0 <= retries <= 100:
        raise ValueError(f"retries must be an integer in [0, 100], got {retries!r}")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if len({j.id for j in jobs}) != len(jobs):
        raise ValueError("job ids must be unique (they are the resume key)")
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {executor!r}")
    if executor == "local" and address is not None:
        raise ValueError("--address applies to the ray executor only")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    last = _journal(out)
    todo = [j for j in jobs if last.get(j.id, {}).get("status") != "ok"]
    library, library_path = _library(todo, out, progress)
    engine = (LocalExecutor(workers, threads_per_job) if executor == "local"
              else RayExecutor(address, workers, threads_per_job))
    attempts = {j.id: int(last.get(j.id, {}).get("attempts", 0)) for j in todo}
    first = dict(attempts)
    try:
        with open(out / "records.jsonl", "a+", encoding="utf-8") as journal, \
                tqdm(total=len(todo), desc="batch", unit="job", file=sys.stderr, disable=not progress) as bar:
            if journal.tell() > 0:  # end the half-written record an interrupted run left, so that _journal skips it
                journal.seek(journal.tell() - 1)
                if journal.read(1) != "\n":
                    journal.write("\n")
            queue = list(todo)
            while queue:
                retry = []
                for job, record in engine.run(queue, library_path, library, runner):
                    attempts[job.id] += 1
                    record["attempts"] = attempts[job.id]
                    journal.write(json.dumps(record, default=float) + "\n")
                    journal.flush()
                    last[job.id] = record
                    if record["status"] != "ok" and attempts[job.id] - first[job.id] <= retries:
                        retry.append(job)
                        continue
                    bar.update(1)
                    bar.set_postfix(failed=sum(last[j.id]["status"] != "ok" for j in todo if j.id in last))
                queue = retry
        description = engine.describe()
    finally:
        engine.close()
    records = [last[j.id] for j in jobs]
    seconds = time.perf_counter() - t0
    result = BatchResult(records, _write_tables(records, out), seconds, len(jobs) - len(todo), description)
    result.paths["summary"] = out / "summary.json"
    with atomic_open(result.paths["summary"], "w", encoding="utf-8") as f:
        json.dump(summarize(result), f, indent=2, default=float)
    return result


def _write_tables(records: List[Dict[str, Any]], out: Path) -> Dict[str, Path]:
    paths = {"csv": out / "results.csv"}
    with atomic_open(paths["csv"], "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=RECORD_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(records)
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:  # the CSV holds the same table
        return paths
    def column(k: str) -> Any:  # typed: a custom runner's record may leave fields out
        if k in TEXT_FIELDS:
            return pa.array(["" if r.get(k) is None else str(r.get(k)) for r in records], pa.string())
        values = [None if v is None or v == "" or (isinstance(v, float) and math.isnan(v)) else v
                  for v in (r.get(k) for r in records)]
        if k in COUNT_FIELDS:
            return pa.array([None if v is None else int(v) for v in values], pa.int64())
        return pa.array([math.nan if v is None else float(v) for v in values], pa.float64())

    paths["parquet"] = out / "results.parquet"
    pq.write_table(pa.table({k: column(k) for k in RECORD_FIELDS}), paths["parquet"])
    return paths


def _median(values: List[float]) -> float:
    v = [x for x in values if isinstance(x, (int, float)) and math.isfinite(x)]
    return statistics.median(v) if v else math.nan


def summarize(result: BatchResult) -> Dict[str, Any]:
    """Counts, throughput and per-kind medians of a batch (what summary.json holds); ``verdict``: how many jobs
    failed or crashed, in words ("all 3 jobs ok", "1 of 3 ...", "every job failed or crashed (3 of 3)")."""
    ran = [r for r in result.records if isinstance(r.get("seconds"), float) and math.isfinite(r["seconds"])]
    kinds = {}
    for kind in KINDS:
        rs = [r for r in result.records if r["kind"] == kind]
        if rs:
            medians = {key + "_median": _median([r.get(key) for r in rs])
                       for key in ("ate_rmse_m", "pose_error_max_m", "pose_error_max_deg", "tcp_error_max_m")}
            kinds[kind] = {"jobs": len(rs), "ok": sum(r["status"] == "ok" for r in rs),
                           "seconds_median": _median([r["seconds"] for r in rs]),
                           **{k: m for k, m in medians.items() if math.isfinite(m)}}
    n, bad = len(result.records), sum(r["status"] != "ok" for r in result.records)
    verdict = (f"all {n} jobs ok" if not bad else f"{bad} of {n} jobs failed or crashed" if bad < n
               else f"every job failed or crashed ({n} of {n})")
    return {"jobs": n, "verdict": verdict, "status": dict(Counter(r["status"] for r in result.records)),
            "skipped_as_done": result.skipped, "wall_seconds": result.seconds, "executor": result.executor,
            "jobs_per_minute": 60 * (len(result.records) - result.skipped) / result.seconds if result.seconds else None,
            "job_seconds_total": sum(r["seconds"] for r in ran), "kinds": kinds,
            "failures": {r["id"]: r["error"] for r in result.records if r["status"] != "ok"}}
