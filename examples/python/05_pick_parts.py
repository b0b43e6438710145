"""05: scan -> part pose -> grasp -> joint targets. A UR5 with a camera on its hand scans the
built-in cell (three parts on a table, SR300-like noise), scanalign reconstructs the scan in the
robot's base frame, finds each part (CBD + ICP), and plans the grasp of each: every grasp,
symmetric copy and IK branch, rejected with a reason or ranked by joint motion. Writes
picks.json, joints.csv, scene.ply and pick.png, and checks each chosen grasp against the truth.

    python examples/python/05_pick_parts.py [--robot kr6_r900_sixx] [--noise zivid] [--out scanalign-05]
"""

from __future__ import annotations

import argparse

from scanalign.pipelines import pick
from scanalign.synthetic.cell import pick_cell, score_picks


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--robot", default="ur5", choices=["ur5", "kr6_r900_sixx"])
    ap.add_argument("--noise", default="sr300")
    ap.add_argument("--out", default="scanalign-05")
    args = ap.parse_args()
    cell = pick_cell(args.robot, noise=args.noise)
    result = pick.pick(cell.scan, cell.parts)  # the robot, its joints and the hand-eye come with the scan
    pick.print_picks(result)
    print("wrote", ", ".join(str(p) for p in result.save(args.out).values()))
    errors = score_picks(result, cell.truth)
    worst = 0.0
    for name, e in errors.items():
        print(f"{name}: chosen grasp {1000 * e['tcp_m']:.3f} mm / {e['tcp_deg']:.3f} deg from the true one")
        worst = max(worst, e["tcp_m"] / 1e-3, e["tcp_deg"] / 0.5)
    return 0 if len(errors) == len(cell.truth) and worst < 1 else 1


if __name__ == "__main__":
    raise SystemExit(main())
