"""Time the CGA core (scanalign.cga, C++) against the `clifford` package on the same work.

Geometric products of random multivector pairs, and a motor applied to points
(``M up(x) ~M`` then ``down``). scanalign uses its batched C++ bindings; clifford uses its
numba-compiled product function (``layout.gmt_func``) over the same coefficient arrays,
and ``MVArray`` for the motor (clifford's vectorised path). Prints operations per second
and the ratio. Usage: ``python bench/bench_cga.py [--n 20000]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from scanalign import cga


def best(f, repeat=3):
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        t.append(time.perf_counter() - t0)
    return min(t)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=20000, help="operations per timing")
    args = ap.parse_args()
    n = args.n
    rng = np.random.default_rng(0)
    from clifford import g3c

    layout = g3c.layout
    perm = np.array([layout.bladeTupList.index(tuple(i + 1 for i in range(5) if b >> i & 1)) for b in range(32)])
    a = rng.standard_normal((n, 32))
    b = rng.standard_normal((n, 32))
    ca = np.zeros_like(a)
    cb = np.zeros_like(b)
    ca[:, perm] = a
    cb[:, perm] = b
    gmt = layout.gmt_func
    gmt(ca[0], cb[0])  # compile

    rows = []
    t_ours = best(lambda: cga.geometric_product_many(a, b))
    t_cl = best(lambda: [gmt(ca[i], cb[i]) for i in range(n)])
    ours = cga.geometric_product_many(a[:100], b[:100])
    theirs = np.array([gmt(ca[i], cb[i]) for i in range(100)])[:, perm]
    assert np.allclose(ours, theirs, atol=1e-10)
    rows.append(("geometric product", t_ours, t_cl))

    x = rng.uniform(-1, 1, (n, 3))
    q = rng.standard_normal(4)
    t = rng.uniform(-1, 1, 3)
    M = cga.Motor.from_quaternion(q, t)
    t_ours = best(lambda: M.apply_points(x))
    Mc = layout.MultiVector(np.zeros(32))
    Mc.value[perm] = M.multivector.orthonormal_coefficients()
    from clifford import MVArray

    def clifford_motor():
        P = MVArray([g3c.up(p[0] * g3c.e1 + p[1] * g3c.e2 + p[2] * g3c.e3) for p in x])
        Y = Mc * P * ~Mc
        return [g3c.down(y) for y in Y]

    n_cl = min(n, 2000)
    x_full = x
    x = x_full[:n_cl]
    t_cl = best(clifford_motor, repeat=1) * (n / n_cl)
    x = x_full
    rows.append(("motor on point (up, M X ~M, down)", t_ours, t_cl))

    print(f"{'operation':38s} {'scanalign ops/s':>16s} {'clifford ops/s':>16s} {'ratio':>8s}")
    for name, to, tc in rows:
        print(f"{name:38s} {n / to:16.3g} {n / tc:16.3g} {tc / to:7.1f}x")


if __name__ == "__main__":
    main()
