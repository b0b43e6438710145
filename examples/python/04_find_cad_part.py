"""04: find a CAD part on a table (thesis ch. 6): segment the table with CGA RANSAC, cluster
the objects, match the part's 42 tessellated-sphere views with the curvature-based
descriptor, refine with ICP, and write poses.json, the placed model (PLY) and a PNG overlay.

The part is CGAL's fandisk (Debian libcgal-demo, fetched by scanalign.data.downloads) scaled to
120 mm; the "scan" is one of its views moved to a known pose above a table plane.

    python examples/python/04_find_cad_part.py [--out scanalign-04]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from scanalign import pose
from scanalign.pose import model_views as cad
from scanalign.data import downloads as datasets
from scanalign.viz.reports import write_pose_outputs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="scanalign-04")
    args = ap.parse_args()
    m = datasets.load_cgal_mesh("fandisk")
    v = m.vertices - m.vertices.mean(axis=0)
    mesh = (v * (0.12 / np.ptp(v, axis=0).max()), m.faces)  # metres

    # The scene (camera frame): view 5 of the part at T_true, on a table 3 mm below it.
    T_true = np.eye(4)
    T_true[:3, :3] = Rotation.from_rotvec([0.4, -0.9, 0.3]).as_matrix()
    T_true[:3, 3] = [0.03, -0.02, 0.5]
    part = cad.render_views(mesh, resolution=300)[5].points @ T_true[:3, :3].T + T_true[:3, 3]
    up = -part.mean(axis=0) / np.linalg.norm(part.mean(axis=0))  # the table faces the camera
    e1 = np.cross(up, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    g = np.mgrid[-0.2:0.2:0.002, -0.2:0.2:0.002].reshape(2, -1).T
    base = part.mean(axis=0) + (np.min(part @ up) - part.mean(axis=0) @ up - 0.003) * up
    scene = np.vstack([part, base + g[:, :1] * e1 + g[:, 1:] * e2])

    found = pose.find_objects(mesh, scene, up=up, table_threshold=0.001, resolution=300, progress=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    r = found.poses[0]
    dR = r.T_scene_model[:3, :3].T @ T_true[:3, :3]
    ang = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
    dist = 1000 * np.linalg.norm(r.T_scene_model[:3, 3] - T_true[:3, 3])
    print(f"{len(found.objects)} object(s); best view {r.view}, fitness {r.fitness:.3f}, coverage {r.coverage:.3f}, "
          f"RMSE {1000 * r.inlier_rmse:.3f} mm, {r.seconds:.1f} s; error {ang:.4f} deg, {dist:.4f} mm")
    paths = write_pose_outputs(mesh, scene, r, out / "object0", object_indices=found.objects[0])
    (out / "poses.json").write_text(json.dumps([r.as_dict()], indent=2))
    print("wrote", ", ".join(str(p) for p in paths.values()))
    return 0 if r.found and ang < 0.2 and dist < 0.5 else 1


if __name__ == "__main__":
    raise SystemExit(main())
