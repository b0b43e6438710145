"""Batch runs (scanalign.pipelines.batch): manifests, the job records against the synthetic cell's truth,
the same results table from a serial run, the local process pool and a local Ray instance,
failures and native crashes isolated, resume, retries, and the part library reaching the
workers instead of being recomputed."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from scanalign import io
from scanalign.pipelines import batch
from scanalign.pipelines.batch import Job, run_job
from scanalign.grasp.part_library import build_part_library, load_part_library

#: Columns that depend on timing or on the process, not on the job.
TIMING = {"seconds", "worker", "seconds_per_frame"}

JOBS = [Job("rec-0", "reconstruct", seed=0, settings={"pixel_stride": 2}),
        Job("rec-1", "reconstruct", seed=1, noise="zivid", settings={"pixel_stride": 2}),
        Job("pose-0", "pose", seed=0), Job("pose-1", "pose", robot="kr6_r900_sixx", seed=1)]


@pytest.fixture(scope="module")
def corrupt(tmp_path_factory) -> Job:
    path = tmp_path_factory.mktemp("bad") / "corrupt.ply"
    path.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1 2\n")
    return Job("corrupt", "pose", source=str(path))


def crash_runner(job: Job, library):
    """A job function whose job 'crash' kills its worker process (as a segfault in native code would)."""
    if job.id == "crash":
        os.abort()
    return run_job(job, library)


def plain(records):
    """Records with NaN as a string: NaN never equals itself, so equal tables would differ."""
    return [{k: "nan" if isinstance(v, float) and math.isnan(v) else v for k, v in r.items()} for r in records]


def threads_runner(job: Job, library):
    """Reports the OpenMP thread count the job would run with."""
    from threadpoolctl import threadpool_info

    from scanalign import _core  # noqa: F401 -- its libgomp

    counts = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "openmp"]
    return {"id": job.id, "kind": job.kind, "status": "ok", "error": "", "seconds": 0.0, "threads": counts}


def comparable(records):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in records]


def same_table(a, b) -> bool:
    def norm(v):
        return "nan" if isinstance(v, float) and math.isnan(v) else v

    a, b = ([{k: norm(v) for k, v in r.items()} for r in comparable(t)] for t in (a, b))
    for ra, rb in zip(a, b):
        assert ra == rb, {k: (ra.get(k), rb.get(k)) for k in set(ra) | set(rb) if ra.get(k) != rb.get(k)}
    return len(a) == len(b)


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    lib = build_part_library(batch.DEFAULT_PARTS, **batch.jobs.LIBRARY_SETTINGS)
    path = lib.save(tmp_path_factory.mktemp("lib") / "parts.npz")
    return lib, path


@pytest.fixture(scope="module")
def serial(library, corrupt):
    """The reference: every job in this process, one OpenMP thread, as the executors run them."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="openmp"):
        return [run_job(j, library[0]) for j in JOBS + [corrupt]]


# --------------------------------------------------------------------------- jobs against truth


def test_job_records_meet_the_truth(serial):
    rec = {r["id"]: r for r in serial}
    for k in ("rec-0", "rec-1"):
        r = rec[k]
        assert r["status"] == "ok", r["error"]
        assert r["merged"] == 36 and r["ate_rmse_m"] < 0.01 and r["model_to_mesh_mean_m"] < 0.001, r
    assert rec["rec-1"]["ate_rmse_m"] < rec["rec-0"]["ate_rmse_m"]  # zivid-like noise is 10x lower than sr300
    for k in ("pose-0", "pose-1"):
        r = rec[k]
        assert r["status"] == "ok", r["error"]
        assert r["found"] == r["parts"] == 3
        assert r["pose_error_max_m"] < 0.001 and r["pose_error_max_deg"] < 1.0, r
    bad = rec["corrupt"]
    assert bad["status"] == "failed" and "corrupt.ply" in bad["error"] and math.isnan(bad["found"])


def test_run_job_reports_bad_settings_instead_of_raising():
    r = run_job(Job("x", "reconstruct", frames=2, settings={"no_such_setting": 1}))
    assert r["status"] == "failed" and "no_such_setting" in r["error"]
    r = run_job(Job("y", "pick", settings={"pixel_stride": -3}))
    assert r["status"] == "failed" and r["error"]


# --------------------------------------------------------------------------- executors agree


def test_local_pool_gives_the_serial_table(serial, corrupt, tmp_path):
    jobs = JOBS + [corrupt]
    result = batch.run_batch(jobs, tmp_path / "out", workers=2, retries=0, progress=False)
    assert [r["id"] for r in result.records] == [j.id for j in jobs]  # manifest order
    assert same_table(result.records, serial)
    assert {r["worker"].split(":")[1] for r in result.records} != {str(os.getpid())}  # ran in other processes
    with open(result.paths["csv"], newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["id"] for r in rows] == [j.id for j in jobs] and rows[4]["status"] == "failed"
    pq = pytest.importorskip("pyarrow.parquet")
    table = pq.read_table(result.paths["parquet"]).to_pydict()
    assert table["id"] == [j.id for j in jobs]
    np.testing.assert_array_equal(table["ate_rmse_m"][:2], [r["ate_rmse_m"] for r in serial[:2]])


@pytest.fixture(scope="module")
def ray_instance():
    ray = pytest.importorskip("ray", reason="the ray executor needs Ray (pip install 'scanalign[ray]')")
    import scanalign

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": str(Path(scanalign.__file__).resolve().parent.parent)}})
    yield ray
    ray.shutdown()


def test_ray_gives_the_serial_table(serial, corrupt, ray_instance, tmp_path):
    jobs = JOBS + [corrupt]
    result = batch.run_batch(jobs, tmp_path / "out", executor="ray", retries=0, progress=False)
    assert same_table(result.records, serial)
    assert result.executor.startswith("Ray, 1 node(s), 2 CPU(s)")


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_each_job_runs_with_threads_per_job_openmp_threads(executor, tmp_path, request):
    if executor == "ray":
        request.getfixturevalue("ray_instance").cloudpickle.register_pickle_by_value(sys.modules[__name__])
    for threads in (1, 2):
        result = batch.run_batch([Job(f"t{k}", "reconstruct") for k in range(2)], tmp_path / f"{threads}",
                                 executor=executor, workers=1, threads_per_job=threads, progress=False,
                                 runner=threads_runner)
        assert [set(r["threads"]) for r in result.records] == [{threads}] * 2, result.records


# --------------------------------------------------------------------------- isolation, retries, resume


def test_a_crashing_job_is_isolated_on_the_local_pool(tmp_path):
    jobs = [Job("pose-a", "pose", seed=2), Job("crash", "pose"), Job("rec-a", "reconstruct", frames=6)]
    result = batch.run_batch(jobs, tmp_path, workers=2, retries=1, progress=False, runner=crash_runner)
    rec = {r["id"]: r for r in result.records}
    assert rec["crash"]["status"] == "crashed" and "died" in rec["crash"]["error"] and rec["crash"]["attempts"] == 2
    assert rec["pose-a"]["status"] == "ok" and rec["pose-a"]["found"] == 3  # in flight beside it, then re-run alone
    assert rec["rec-a"]["status"] == "ok"
    journal = [json.loads(line) for line in (tmp_path / "records.jsonl").read_text().splitlines()]
    assert [r["status"] for r in journal if r["id"] == "crash"] == ["crashed", "crashed"]  # tried twice


def test_a_crashing_job_is_isolated_on_ray(ray_instance, tmp_path):
    ray_instance.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers cannot import this file
    jobs = [Job("crash", "pose"), Job("rec-a", "reconstruct", frames=6)]
    result = batch.run_batch(jobs, tmp_path, executor="ray", retries=0, progress=False,
                             runner=crash_runner)
    rec = {r["id"]: r for r in result.records}
    assert rec["crash"]["status"] == "crashed" and rec["crash"]["error"]
    assert rec["rec-a"]["status"] == "ok"


def test_resume_skips_finished_jobs_and_reruns_the_rest(library, tmp_path):
    first = [JOBS[0]]
    batch.run_batch(first, tmp_path, workers=1, progress=False)
    before = json.loads((tmp_path / "records.jsonl").read_text().splitlines()[0])
    with open(tmp_path / "records.jsonl", "a") as f:  # an interrupted run: a record torn mid-line
        f.write('{"id": "rec-1", "status": "ok", "se')
    result = batch.run_batch(JOBS[:2], tmp_path, workers=2, progress=False)
    assert result.skipped == 1
    assert plain(result.records[:1]) == plain([before])  # not run again: the very same record, timings included
    assert result.records[1]["status"] == "ok" and result.records[1]["merged"] == 36
    again = batch.run_batch(JOBS[:2], tmp_path, workers=2, progress=False)
    assert again.skipped == 2 and plain(again.records) == plain(result.records)


def test_failed_jobs_are_retried_as_configured(tmp_path):
    job = Job("missing", "reconstruct", source=str(tmp_path / "no_such_folder"))
    result = batch.run_batch([job], tmp_path / "out", workers=1, retries=2, progress=False)
    assert result.records[0]["status"] == "failed" and result.records[0]["attempts"] == 3
    assert len((tmp_path / "out" / "records.jsonl").read_text().splitlines()) == 3


# --------------------------------------------------------------------------- the part library in workers


def swapped_library(library, tmp_path) -> Path:
    """The library with the block's entry holding the standoff's views: a worker that uses the
    library (instead of rendering and describing the block itself) cannot find the block."""
    lib = load_part_library(library[1])
    lib.parts["block"].views = lib.parts["standoff"].views
    out = tmp_path / "out"
    out.mkdir()
    return lib.save(out / "parts.npz")


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_workers_use_the_saved_part_library(library, tmp_path, executor, request):
    if executor == "ray":
        request.getfixturevalue("ray_instance")
    path = swapped_library(library, tmp_path)
    stamp = path.stat().st_mtime_ns
    job = Job("pose-0", "pose", seed=0)
    result = batch.run_batch([job], tmp_path / "out", executor=executor, workers=1, retries=0, progress=False)
    assert path.stat().st_mtime_ns == stamp  # loaded, not rebuilt
    r = result.records[0]
    detail = json.loads(r["detail"])
    # the block's views are the standoff's: no block found, and the standoff matches two "parts" alike
    assert r["status"] == "ok" and detail["block"]["status"] == "not_found" and r["found"] < 3, r
    assert run_job(job)["found"] == 3  # without the library the job renders the true block


def test_library_round_trip_keeps_views_and_descriptors(library, tmp_path):
    lib, path = library
    loaded = load_part_library(path)
    assert list(loaded.parts) == list(lib.parts) == list(batch.DEFAULT_PARTS)
    for name in lib.parts:
        a, b = lib[name], loaded[name]
        np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
        assert b.symmetry.order == a.symmetry.order
        assert len(a.views) == len(b.views) == 42
        for va, vb in zip(a.views, b.views):
            np.testing.assert_array_equal(va.points, vb.points)
            np.testing.assert_array_equal(va.T_model_camera, vb.T_model_camera)
            assert vb.cbd is not None and len(vb.cbd) == len(va.cbd) > 0
            np.testing.assert_array_equal(va.cbd.descriptors, vb.cbd.descriptors)


def test_library_files_of_another_format_or_corrupt_are_refused(library, tmp_path):
    data = dict(np.load(library[1], allow_pickle=False))
    data["format"] = np.array(99)
    np.savez(tmp_path / "v99.npz", **data)
    with pytest.raises(ValueError, match="format 99, this scanalign reads 1: rebuild"):
        load_part_library(tmp_path / "v99.npz")
    (tmp_path / "junk.npz").write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(ValueError, match="junk.npz: not a readable part library"):
        load_part_library(tmp_path / "junk.npz")
    del data["part1/views"]
    data["format"] = np.array(1)
    np.savez(tmp_path / "cut.npz", **data)
    with pytest.raises(ValueError, match="cut.npz: corrupt part library"):
        load_part_library(tmp_path / "cut.npz")


# --------------------------------------------------------------------------- manifests


def test_manifest_yaml_and_csv(tmp_path):
    (tmp_path / "scans").mkdir()
    (tmp_path / "m.yaml").write_text(
        "defaults: {noise: zivid}\n"
        "jobs:\n"
        "  - {id: rec, kind: reconstruct, seeds: 3, frames: 12}\n"
        "  - {id: one, kind: pose, source: scans/a.ply, parts: [block, parts/mine.json], seed: 4, noise: sr300}\n"
        "  - {id: picks, kind: pick, seeds: [5, 9], robot: kr6_r900_sixx, settings: {pixel_stride: 3}}\n"
        "  - {id: real, kind: pick, source: scans/s1, settings: {joints: scans/s1/joints.csv, hand_eye: /etc/T.txt}}\n")
    jobs = batch.read_manifest(tmp_path / "m.yaml")
    assert [j.id for j in jobs] == ["rec-s0", "rec-s1", "rec-s2", "one", "picks-s5", "picks-s9", "real"]
    assert jobs[6].settings == {"joints": str(tmp_path / "scans/s1/joints.csv"), "hand_eye": "/etc/T.txt"}
    assert [j.seed for j in jobs] == [0, 1, 2, 4, 5, 9, 0] and jobs[0].noise == "zivid" and jobs[3].noise == "sr300"
    assert jobs[3].source == str(tmp_path / "scans/a.ply") and jobs[3].parts == ("block", str(tmp_path / "parts/mine.json"))
    assert jobs[4].settings == {"pixel_stride": 3} and jobs[4].n_frames == 24 and jobs[0].n_frames == 12
    (tmp_path / "m.csv").write_text('id,kind,seeds,parts,settings\nrec,reconstruct,2,,\n'
                                    'p,pose,,block;bracket,"{""radius"": 0.008}"\n')
    jobs = batch.read_manifest(tmp_path / "m.csv")
    assert [j.id for j in jobs] == ["rec-s0", "rec-s1", "p"]
    assert jobs[2].parts == ("block", "bracket") and jobs[2].settings == {"radius": 0.008}


@pytest.mark.parametrize("text, message", [
    ("jobs: [{id: a, kind: reconstruct}, {id: a, kind: pose}]", "job id 'a' appears twice"),
    ("jobs: [{id: a, kind: fly}]", "kind must be one of"),
    ("jobs: [{id: a, kind: pose, colour: red}]", "job 0: unknown field\\(s\\) \\['colour'\\]"),
    ("jobs: [{kind: pose}]", "needs 'id' and 'kind'"),
    ("jobs: [{id: a, kind: pose, seeds: 0}]", "seeds must be a count >= 1"),
    ("jobs: [{id: a, kind: pose, seed: -1}]", "seed must be an integer >= 0"),
    ("jobs: [{id: a/b, kind: pose}]", "job id must be"),
    ("jobs: []", "no jobs"),
    ("[1, 2]", "expected a mapping with a 'jobs' list"),
    ("jobs: [{id: a, kind: pose, settings: 3}]", "settings must be a mapping"),
    ("jobs: [{id: a, kind: pose}\n", "m.yaml: "),
])
def test_malformed_manifests_are_refused_naming_the_file(tmp_path, text, message):
    (tmp_path / "m.yaml").write_text(text)
    with pytest.raises(ValueError, match=message) as e:
        batch.read_manifest(tmp_path / "m.yaml")
    assert str(e.value).startswith(str(tmp_path / "m.yaml"))


def test_run_batch_refuses_bad_arguments(tmp_path):
    for kw, message in [(dict(executor="spark"), "executor must be one of"), (dict(workers=0), "workers must be"),
                        (dict(threads_per_job=0), "threads_per_job"), (dict(retries=-1), "retries"),
                        (dict(address="auto"), "--address applies to the ray executor only")]:
        with pytest.raises(ValueError, match=message):
            batch.run_batch([Job("a", "reconstruct", frames=2)], tmp_path, progress=False, **kw)
    with pytest.raises(ValueError, match="unique"):
        batch.run_batch([Job("a", "pose"), Job("a", "pose")], tmp_path, progress=False)


# --------------------------------------------------------------------------- the command line


def test_cli_batch_end_to_end(tmp_path):
    (tmp_path / "m.yaml").write_text("jobs:\n  - {id: rec, kind: reconstruct, frames: 8, seeds: 2}\n"
                                     "  - {id: gone, kind: reconstruct, source: missing_folder}\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    r = subprocess.run([sys.executable, "-m", "scanalign.cli", "batch", str(tmp_path / "m.yaml"), "--workers", "2",
                        "--retries", "0", "--out", str(tmp_path / "out"), "--quiet"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 1, r.stderr  # one job failed
    assert "3 jobs (0 done before), status {'ok': 2, 'failed': 1}" in r.stdout, r.stdout
    assert "gone: FileNotFoundError:" in r.stderr and "missing_folder: no such folder or file" in r.stderr
    for name in ("results.csv", "summary.json", "results.png", "records.jsonl"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == {"ok": 2, "failed": 1} and summary["kinds"]["reconstruct"]["jobs"] == 3
