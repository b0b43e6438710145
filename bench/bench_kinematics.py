"""Inverse and forward kinematics through Python: scanalign.kinematics (the CGA solver in
C++) against the fastest independent analytic IKs on PyPI, in one run, on the same poses.

For the KUKA KR6 R900 sixx and the UR5: N random joint vectors (uniform inside the joint
limits, limits wider than +-pi clamped to +-pi, seed 0) and their forward-kinematics poses
(reachable by construction). Timed, median of ``--repeats`` passes over the same poses:

- all IK solutions, batched: ``Robot.ik_batch`` (one C++ call) against EAIK's
  ``IK_batched`` (Ostermeier et al., subproblem decomposition, C++), both with ``--threads``
  worker threads, and both single-threaded;
- all IK solutions, one Python call per pose (on ``--per-call`` poses): ``Robot.ik`` against
  ``ur_analytic_ik.ur5.inverse_kinematics`` (UR5 only, C++ via nanobind) and EAIK's ``IK``;
- forward kinematics: ``Robot.fk`` batched, and one call per pose against EAIK's ``fwdKin``;
- optionally ikpy (numerical, one solution from a start guess) on ``--ikpy`` poses.

Poses are prepared outside the timed region (EAIK takes a list of 4x4 arrays, built once).
Ratios are peer time / scanalign time in the same mode. Agreement is checked on the side:
every peer solution must be one of ours (all joints equal modulo 2 pi to 1e-6 rad, ours
computed without joint limits, as the peers know none) and every one of our solutions one
of the peer's; the largest FK residual of each side's solutions is printed too. When the
C++ benchmark (bench/bench_ik.cpp, built as build/py/cpp/tests/bench_ik) exists, it runs
afterwards (``--no-cpp`` skips it).

    python bench/bench_kinematics.py [--poses 100000] [--per-call 20000] [--threads 0]
                                     [--repeats 5] [--ikpy 20] [--no-cpp]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from scanalign import kinematics as kin

ROOT = Path(__file__).resolve().parent.parent
CPP_BENCH = ROOT / "build" / "py" / "cpp" / "tests" / "bench_ik"


def timed(fn: Callable[[], object], repeats: int) -> Tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def wrap(x: np.ndarray) -> np.ndarray:
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


def pose_residual(A: np.ndarray, B: np.ndarray) -> float:
    """Max |entry| of A - B over the 3x4 top block (metres and rotation entries)."""
    return float(np.abs(A[..., :3, :] - B[..., :3, :]).max()) if np.size(A) else 0.0


def random_joints(robot: kin.Robot, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lim = robot.limits
    lo, hi = np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi)
    return rng.uniform(lo, hi, (n, 6))


def match(a: np.ndarray, b: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """For each row of a (K, 6): whether some row of b (M, 6) equals it modulo 2 pi."""
    if len(a) == 0:
        return np.zeros(0, bool)
    if len(b) == 0:
        return np.zeros(len(a), bool)
    d = np.abs(wrap(a[:, None, :] - b[None, :, :])).max(axis=2)
    return d.min(axis=1) <= tol


class Agreement:
    """Counts of solutions matched both ways between scanalign and a peer."""

    def __init__(self) -> None:
        self.peer = self.peer_matched = self.ours = self.ours_matched = self.poses = self.poses_equal = 0
        self.peer_residual = 0.0

    def add(self, ours: np.ndarray, peer: np.ndarray, peer_residual: float) -> None:
        m_peer, m_ours = match(peer, ours), match(ours, peer)
        self.poses += 1
        self.peer += len(peer)
        self.peer_matched += int(m_peer.sum())
        self.ours += len(ours)
        self.ours_matched += int(m_ours.sum())
        self.poses_equal += bool(m_peer.all() and m_ours.all())
        self.peer_residual = max(self.peer_residual, peer_residual)

    def line(self, name: str) -> str:
        def pct(a: int, b: int) -> str:
            return f"{100.0 * a / b:.3f} %" if b else "n/a"

        return (f"  {name}: {self.poses} poses; its solutions found by scanalign {pct(self.peer_matched, self.peer)} "
                f"({self.peer}), scanalign's found by it {pct(self.ours_matched, self.ours)} ({self.ours}); "
                f"identical sets on {pct(self.poses_equal, self.poses)} of poses; its max FK residual "
                f"{self.peer_residual:.1e}")


def distinct_rows(q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    out: List[np.ndarray] = []
    for row in q:
        if not any(np.abs(wrap(row - r)).max() <= tol for r in out):
            out.append(row)
    return np.array(out).reshape(-1, 6)


def eaik_robot(robot: kin.Robot):
    """EAIK's DhRobot for our DH table, or None when EAIK is missing. EAIK's joint angle is
    the DH theta, so q_eaik = q + theta_offset."""
    try:
        from eaik.IK_DH import DhRobot
    except ImportError:
        return None
    return DhRobot(np.array(robot.alpha), np.array(robot.a), np.array(robot.d))


def ikpy_chain(robot: kin.Robot):
    try:
        from ikpy.chain import Chain
        from ikpy.link import DHLink, OriginLink
    except ImportError:
        return None
    links = [OriginLink()] + [
        DHLink(name=f"j{i + 1}", d=float(robot.d[i]), a=float(robot.a[i]), alpha=float(robot.alpha[i]),
               theta=float(robot.theta_offset[i]), bounds=tuple(robot.limits[i]), use_symbolic_matrix=False)
        for i in range(6)]
    return Chain(links, active_links_mask=[False] + [True] * 6, name=robot.name)


def bench_robot(name: str, args: argparse.Namespace, rows: List[Dict[str, object]]) -> None:
    robot = kin.Robot.by_name(name)
    n = args.poses
    q = random_joints(robot, n, seed=0)
    T = robot.fk(q)
    # The peers work in DH frame 0 and the DH angle theta = q + offset.
    T_dh0 = np.linalg.inv(robot.T_base_dh0) @ T
    off = np.array(robot.theta_offset)
    threads = args.threads or os.cpu_count() or 1
    print(f"\n{robot.name}: {n} poses ({args.per_call} for per-call timings), {threads} threads for batches")

    def add(what: str, ours_s: float, peer: str = "", peer_s: Optional[float] = None, count: int = n,
            note: str = "") -> None:
        rows.append(dict(robot=robot.name, what=what, ours=ours_s / count * 1e6, peer=peer,
                         peer_us=None if peer_s is None else peer_s / count * 1e6,
                         ratio=None if peer_s is None else peer_s / ours_s, note=note))

    # ---- scanalign
    t_batch, res = timed(lambda: robot.ik_batch(T, num_threads=threads), args.repeats)
    t_batch1, _ = timed(lambda: robot.ik_batch(T, num_threads=1), args.repeats)
    t_fk, T_again = timed(lambda: robot.fk(q, num_threads=threads), args.repeats)
    m = args.per_call
    Tm, qm = T[:m], q[:m]
    t_call, _ = timed(lambda: [robot.ik(t) for t in Tm], max(1, args.repeats // 2))
    t_fk_call, _ = timed(lambda: [robot.fk(x) for x in qm], max(1, args.repeats // 2))
    ok = res.ok
    found = np.array([match(q[i:i + 1], res.q[i][ok[i]])[0] for i in range(min(n, 20000))])
    ours_res = max(pose_residual(robot.fk(res.q[i][ok[i]]), T[i][None]) for i in range(min(n, 2000)))
    print(f"  scanalign: {ok.sum(axis=1).mean():.2f} ok solutions/pose, generating joints among them on "
          f"{100 * found.mean():.3f} % of poses, max FK residual {ours_res:.1e}, fk == fk batched: "
          f"{pose_residual(T_again, T):.0e}")

    # Our solutions without joint limits (the peers know none), for the agreement checks.
    n_check = min(n, args.check)
    free = robot.ik_batch(T[:n_check], respect_limits=False, num_threads=threads)
    ours_free = [distinct_rows(free.q[i][free.status[i] <= 1]) for i in range(n_check)]

    # ---- EAIK
    er = eaik_robot(robot)
    if er is not None:
        fk_check = pose_residual(np.array([er.fwdKin(x + off) for x in q[:200]]), T_dh0[:200])
        if fk_check > 1e-9:
            print(f"  EAIK: its forward kinematics differs from ours by {fk_check:.1e}: skipped")
        else:
            poses = [np.ascontiguousarray(t) for t in T_dh0]
            t_e, sols = timed(lambda: er.IK_batched(poses, threads), args.repeats)
            t_e1, _ = timed(lambda: er.IK_batched(poses, 1), args.repeats)
            t_ec, _ = timed(lambda: [er.IK(p) for p in poses[:m]], max(1, args.repeats // 2))
            t_efk, _ = timed(lambda: [er.fwdKin(x + off) for x in qm], max(1, args.repeats // 2))
            agree = Agreement()
            for i in range(n_check):
                s = sols[i]
                Q = np.asarray(s.Q).reshape(-1, 6)
                Q = Q[~np.asarray(s.is_LS, bool)] if len(Q) else Q
                qe = distinct_rows(wrap(Q - off))
                resid = pose_residual(robot.fk(qe), T[i][None]) if len(qe) else 0.0
                agree.add(ours_free[i], qe, resid)
            add("IK all solutions, batch", t_batch, "EAIK IK_batched", t_e)
            add("IK all solutions, batch, 1 thread", t_batch1, "EAIK IK_batched", t_e1)
            add("IK all solutions, 1 call/pose", t_call, "EAIK IK", t_ec, count=m)
            add("FK, 1 call/pose", t_fk_call, "EAIK fwdKin", t_efk, count=m)
            print(agree.line("EAIK"))
    else:
        add("IK all solutions, batch", t_batch, note="EAIK not installed")
        add("IK all solutions, batch, 1 thread", t_batch1)
        add("IK all solutions, 1 call/pose", t_call, count=m)
        add("FK, 1 call/pose", t_fk_call, count=m)
    add("FK, batch", t_fk)

    # ---- ur_analytic_ik (UR5 only)
    if robot.name == "ur5":
        try:
            from ur_analytic_ik import ur5 as uik
        except ImportError:
            uik = None
        if uik is not None:
            fk_check = pose_residual(np.array([uik.forward_kinematics(*x) for x in q[:200]]), T_dh0[:200])
            if fk_check > 1e-9:
                print(f"  ur_analytic_ik: its forward kinematics differs from ours by {fk_check:.1e}: skipped")
            else:
                Tl = [np.ascontiguousarray(t) for t in T_dh0[:m]]
                t_u, sols = timed(lambda: [uik.inverse_kinematics(t) for t in Tl], max(1, args.repeats // 2))
                t_ufk, _ = timed(lambda: [uik.forward_kinematics(*x) for x in qm], max(1, args.repeats // 2))
                agree = Agreement()
                for i in range(min(m, n_check)):
                    qu = distinct_rows(np.array(sols[i]).reshape(-1, 6))
                    resid = pose_residual(robot.fk(qu), T[i][None]) if len(qu) else 0.0
                    agree.add(ours_free[i], qu, resid)
                add("IK all solutions, 1 call/pose", t_call, "ur_analytic_ik", t_u, count=m)
                add("FK, 1 call/pose", t_fk_call, "ur_analytic_ik", t_ufk, count=m)
                print(agree.line("ur_analytic_ik"))

    # ---- ikpy (numerical: one solution per start guess)
    if args.ikpy > 0:
        chain = ikpy_chain(robot)
        if chain is not None:
            k = args.ikpy
            rng = np.random.default_rng(1)
            starts = np.clip(q[:k] + rng.normal(0, 0.3, (k, 6)), robot.limits[:, 0], robot.limits[:, 1])
            def run_ikpy():
                return [chain.inverse_kinematics_frame(T_dh0[i], initial_position=np.r_[0.0, starts[i]],
                                                       orientation_mode="all")[1:] for i in range(k)]
            t_p, sols = timed(run_ikpy, 1)
            resid = np.array([pose_residual(robot.fk(np.asarray(s)), T[i]) for i, s in enumerate(sols)])
            add("IK 1 solution (ikpy: numerical, start 0.3 rad off)", t_call / m * k, "ikpy", t_p, count=k,
                note=f"{int((resid < 1e-6).sum())}/{k} converged to 1e-6; median residual {np.median(resid):.1e}")


def print_table(rows: List[Dict[str, object]]) -> None:
    print("\n| robot | call | scanalign µs/pose | peer | peer µs/pose | peer / scanalign |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        peer_us = "" if r["peer_us"] is None else f"{r['peer_us']:.3f}"
        ratio = "" if r["ratio"] is None else f"{r['ratio']:.1f}x"
        note = f" ({r['note']})" if r["note"] else ""
        print(f"| {r['robot']} | {r['what']} | {r['ours']:.3f} | {r['peer']}{note} | {peer_us} | {ratio} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=100000, help="poses per robot for batched timings")
    ap.add_argument("--per-call", type=int, default=20000, help="poses for one-call-per-pose timings")
    ap.add_argument("--check", type=int, default=5000, help="poses whose solutions are compared with the peers'")
    ap.add_argument("--threads", type=int, default=0, help="worker threads for batches (0 = all cores)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ikpy", type=int, default=20, help="poses for ikpy (numerical, slow); 0 to skip")
    ap.add_argument("--no-cpp", action="store_true", help=f"do not run {CPP_BENCH.relative_to(ROOT)}")
    args = ap.parse_args()
    args.per_call = min(args.per_call, args.poses)
    rows: List[Dict[str, object]] = []
    for name in ("kr6_r900_sixx", "ur5"):
        bench_robot(name, args, rows)
    print_table(rows)
    if not args.no_cpp:
        if CPP_BENCH.exists():
            print(f"\n{CPP_BENCH.relative_to(ROOT)}:", flush=True)
            subprocess.run([str(CPP_BENCH), "--n", str(min(args.poses * 2, 200000))], check=False)
        else:
            print(f"\n{CPP_BENCH.relative_to(ROOT)} not built (cmake --build build/py --target bench_ik)")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
