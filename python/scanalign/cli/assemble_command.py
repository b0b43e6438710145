"""``scanalign assemble``: the two-step pose and the assembly in the built-in two-robot cell (Kleppe et al., Robotics 6
(2017) 14, the thesis's Paper 3): detect -> refine with the hand camera -> pick -> place, the joint targets of both
arms written, each step's error against the cell's truth printed."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

from scanalign.cli.settings import Alias, Command, add_settings_options
from scanalign.pipelines import assemble as _assemble
from scanalign.synthetic.assembly_cell import assembly_cell, score_assembly
from scanalign.viz.plots import plot_assembly_views

__all__ = ["ASSEMBLE", "add_assemble_parser", "assemble_command"]

#: The assemble command's settings: AssemblySettings (find_parts, views, refine_2d, view, planner).
ASSEMBLE = Command(_assemble.AssemblySettings, (
    Alias("--detector", "refine_2d.matching.detector", choices=["sift", "akaze", "orb"],
          help="keypoints of the 2D step: sift (the paper's), akaze or orb (free substitutes for its SIFT/SURF "
               "hybrid)"),
    Alias("--view-height", "view.height"),
    Alias("--max-steps", "refine_2d.max_steps"),
))


def add_assemble_parser(sub: Any) -> None:
    p = sub.add_parser("assemble", help="two-step pose (3D camera, then a hand camera) and the assembly of part A "
                                        "onto part B in the built-in two-robot cell",
                       description="Renders the built-in assembly cell (a fixed Kinect One-like 3D camera, a gripper "
                                   "arm and a camera arm, both KR6 R900 sixx, part A and part B at random places), "
                                   "finds both parts in the 3D camera's cloud, refines each with the hand camera "
                                   "(SIFT on its top-face label, the homography's planar pose, repeated until it "
                                   "converges), plans the pick of A and its place onto B at the relative pose of A's "
                                   "part file, and scores every step against the cell's truth. Writes assembly.json, "
                                   "joints_gripper.csv, joints_camera.csv, views.png and config.yaml. Exit status 1 "
                                   "unless the placed part lies within its tolerance.")
    p.add_argument("--part", default="standoff", help="part A: a part file with 'assembly' and 'reference_image', or "
                                                      "a built-in part name (default standoff, placed on the bracket)")
    p.add_argument("--seed", type=int, default=0, help="placements and sensor noise (default 0)")
    p.add_argument("--noise", default="kinect_one", help="the 3D camera's noise preset (default kinect_one)")
    p.add_argument("--out", default="scanalign-assemble", help="output folder (default: scanalign-assemble)")
    p.add_argument("--no-plots", action="store_true", help="do not write views.png")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_settings_options(p, ASSEMBLE)


def _mm_deg(e: Dict[str, float]) -> str:
    return f"{1000 * e['xy_m']:.3f} mm / {e['angle_deg']:.3f} deg"


def assemble_command(args: argparse.Namespace) -> int:
    cell = assembly_cell(args.part, seed=args.seed, noise=args.noise)
    images: List[np.ndarray] = []

    def capture(T_base_camera: np.ndarray) -> np.ndarray:
        images.append(cell.capture(T_base_camera))
        return images[-1]

    print(f"scanalign assemble: {cell.part.name} onto {cell.onto.name}, seed {args.seed}, 3D camera noise {args.noise}")
    result = _assemble.assemble(cell.cloud(), cell.part, capture=capture, gripper_robot=cell.gripper_robot,
                                camera_robot=cell.camera_robot, T_flange_camera=cell.T_flange_camera,
                                intrinsics=cell.intrinsics, settings=args.settings, progress=not args.quiet)
    score = score_assembly(result, cell)
    for name, p in result.parts.items():
        e = score["parts"].get(name)
        print(f"  {name:<9} {p.status:<10} {p.reason}")
        if e is not None:
            print(f"{'':12}error: 3D step {_mm_deg(e['3d'])}; one 2D step {_mm_deg(e['one_step'])}; "
                  f"converged {_mm_deg(e['refined'])}")
    print(f"  {result.status}: {result.reason}")
    placement = score["placement"]
    if placement is not None:
        tol = cell.part.assembly
        print(f"  placed {cell.part.name} on {cell.onto.name}: {1000 * placement['translation_m']:.3f} mm / "
              f"{placement['angle_deg']:.3f} deg from the target (tolerance {1000 * tol.tolerance_translation:.1f} mm "
              f"/ {np.degrees(tol.tolerance_angle):.1f} deg): {'success' if placement['success'] else 'FAILED'}")
    paths = result.save(args.out)
    (Path(args.out) / "score.json").write_text(__import__("json").dumps(score, indent=1) + "\n")
    if not args.no_plots:
        last, k = {}, 0
        for name, p in result.parts.items():  # the parts were refined in order, each view one image
            n = 0 if p.refine is None else len(p.refine.views)
            if n:
                last[name] = images[k + n - 1]
            k += n
        refs = {p.name: (p.reference_image.image, p.reference_image.geometry()) for p in cell.parts}
        paths["views"] = plot_assembly_views(result, last, refs, cell.intrinsics, Path(args.out) / "views.png",
                                             truth=cell.truth)
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0 if placement is not None and placement["success"] else 1
