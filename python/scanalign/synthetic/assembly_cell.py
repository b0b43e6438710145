"""The two-robot assembly cell of the two-step pose (Kleppe et al., "Automated assembly using 3D and 2D cameras",
Robotics 6 (2017) 14, the thesis's Paper 3, §2 and Fig. 1): a fixed time-of-flight 3D camera behind the table (Kinect
One-like: :data:`scanalign.synthetic.noise.NOISE_PRESETS` ``"kinect_one"``), a gripper arm and a camera arm, both KUKA
KR6 R900 sixx, the camera arm carrying a colour webcam (:data:`scanalign.synthetic.hand_camera.WEBCAM`), and two parts
on the table: part A, to be placed onto part B at the relative pose of A's part file (``assembly``).

Layout (base frame: the table top is z = 0, m): the table (0.6 x 0.6 m) centred at (0.5, 0); the gripper arm standing
at (0.5, -0.62), facing +y; the camera arm at (0.5, +0.62), facing -y; the 3D camera 0.55 m above the table at
(1.05, 0), 0.75 m from the parts, looking at the table centre. Both parts lie in the reach of both arms (x in [0.38,
0.62], y in [-0.12, 0.12]), at least 90 mm apart, each turned at random.

The hand camera's images are :func:`scanalign.synthetic.hand_camera.render_labels` of every part's top-face label (a
part file's ``reference_image``) in colour, through the exact homography, blurred and noisy: no shading, no occlusion
by the parts' sides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from scanalign.grasp import symmetric_pose_error
from scanalign.grasp.parts import load_part
from scanalign.kinematics import Robot
from scanalign.reconstruction.camera import INTRINSICS_PRESETS, Intrinsics
from scanalign.synthetic.hand_camera import WEBCAM, render_labels
from scanalign.synthetic.scan import SyntheticScan, render_scan
from scanalign.synthetic.scene import Scene
from scanalign.synthetic.trajectories import robot_mount

__all__ = ["ASSEMBLY_MOUNTS", "T_BASE_FIXED_CAMERA", "T_FLANGE_HAND_CAMERA", "PLACEMENT_REGION", "AssemblyCell",
           "assembly_cell", "random_placements", "score_assembly",
           "placement_error"]

#: Arm -> its mounting ``T_base_robot`` (robot base -> cell base, m): both KR6 R900 sixx stand on the floor at the
#: table top's height, facing the table.
ASSEMBLY_MOUNTS: Dict[str, np.ndarray] = {"gripper": robot_mount(0.5, -0.62, 0.0, roll=0.0, yaw=math.pi / 2),
                                          "camera": robot_mount(0.5, 0.62, 0.0, roll=0.0, yaw=-math.pi / 2)}
#: ((x min, x max), (y min, y max)) m: where :func:`random_placements` puts the parts' centres.
PLACEMENT_REGION: Tuple[Tuple[float, float], Tuple[float, float]] = ((0.38, 0.62), (-0.12, 0.12))


def _looking_at(eye: Sequence[float], target: Sequence[float]) -> np.ndarray:
    """T_base_camera of a camera at ``eye`` looking at ``target`` (camera z forward, x right, y down; base z up)."""
    z = np.subtract(target, eye) / np.linalg.norm(np.subtract(target, eye))
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.c_[x, np.cross(z, x), z]
    T[:3, 3] = eye
    return T


#: The fixed 3D camera's pose (camera -> base, m): behind the table, 0.55 m up, looking at the table centre.
T_BASE_FIXED_CAMERA: np.ndarray = _looking_at((1.05, 0.0, 0.55), (0.5, 0.0, 0.0))
#: The webcam on the camera arm's flange (camera -> flange, m): 30 mm off the axis, 60 mm out, looking along the
#: flange's z.
T_FLANGE_HAND_CAMERA: np.ndarray = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.03], [0.0, 0.0, 1.0, 0.06],
                                             [0.0, 0.0, 0.0, 1.0]])


@dataclass
class AssemblyCell:
    """A rendered assembly cell with its truth.

    Attributes:
        part, onto: the loaded parts (:class:`scanalign.grasp.PartGrasps`): ``part`` (A, with its ``assembly``) is
            placed onto ``onto`` (B).
        truth: part name -> its true ``T_base_model`` (m).
        scan: the fixed 3D camera's one frame (``scan.points(0, in_base=True)``: its cloud in the base frame).
        gripper_robot, camera_robot: the arms, placed in the cell (tool: the flange).
        T_flange_camera: the webcam's hand-eye transform on the camera arm; ``intrinsics``: the webcam's.
        scene: the rendered :class:`Scene`; ``seed``: the cell's seed (each hand-camera image has its own noise).
    """

    part: Any
    onto: Any
    truth: Dict[str, np.ndarray]
    scan: SyntheticScan
    gripper_robot: Robot
    camera_robot: Robot
    T_flange_camera: np.ndarray
    intrinsics: Intrinsics
    scene: Scene
    seed: int = 0
    images_taken: int = field(default=0)

    @property
    def parts(self) -> List[Any]:
        return [self.part, self.onto]

    def cloud(self) -> np.ndarray:
        """(N, 3) the fixed 3D camera's points in the base frame, m."""
        return self.scan.points(0, in_base=True)

    def capture(self, T_base_camera: Any) -> np.ndarray:
        """The webcam's (H, W, 3) uint8 RGB image from ``T_base_camera`` (4x4, m): every labelled part where it truly
        lies, a fresh noise draw per image."""
        labels = [(p.reference_image.image, p.reference_image.geometry(), self.truth[p.name]) for p in self.parts
                  if p.reference_image is not None]
        self.images_taken += 1
        return render_labels(labels, T_base_camera, self.intrinsics, seed=self.seed * 1000 + self.images_taken,
                             colour=True)


def random_placements(seed: int, names: Sequence[str], min_distance: float = 0.09) -> List[Tuple[str, Tuple[float, float], float]]:
    """(name, (x, y) m, yaw rad) per part, uniform in :data:`PLACEMENT_REGION` and in yaw, centres at least
    ``min_distance`` apart (rejection sampling, fixed by ``seed``)."""
    rng = np.random.default_rng(seed)
    (x0, x1), (y0, y1) = PLACEMENT_REGION
    for _ in range(1000):
        xy = np.c_[rng.uniform(x0, x1, len(names)), rng.uniform(y0, y1, len(names))]
        yaw = rng.uniform(-math.pi, math.pi, len(names))
        gaps = [np.linalg.norm(xy[i] - xy[j]) for i in range(len(names)) for j in range(i)]
        if not gaps or min(gaps) >= min_distance:
            return [(n, (float(p[0]), float(p[1])), float(a)) for n, p, a in zip(names, xy, yaw)]
    raise ValueError(f"min_distance: {len(names)} parts {min_distance} m apart do not fit in {PLACEMENT_REGION}")


def _placed_robot(name: str, mount: np.ndarray) -> Robot:
    r = Robot.by_name(name)
    return r.with_base(mount @ r.T_base_dh0).with_tool(np.eye(4))


def assembly_cell(part: Any = "standoff", *, seed: int = 0, noise: str = "kinect_one",
                  placements: Optional[Sequence[Tuple[str, Tuple[float, float], float]]] = None) -> AssemblyCell:
    """Renders the assembly cell (see the module docstring) for ``part`` (a part file, a built-in name or a
    ``PartGrasps`` with an ``assembly``; default the standoff, placed on the bracket) and the part it goes onto, at
    ``placements`` ((name, (x, y) m, yaw rad) for both parts; default :func:`random_placements` of ``seed``), the
    fixed camera's depth with the ``noise`` preset. Part B is the part file ``assembly.onto_file`` names, else the built-in part ``assembly.onto``.
    ValueError: a part without ``assembly`` or ``reference_image``, placements that do not name both parts."""
    a = load_part(part)
    if a.assembly is None:
        raise ValueError(f"part {a.name!r}: its part file has no 'assembly' (onto, T_onto_part, tolerances)")
    b = load_part(a.assembly.onto_source())
    for p in (a, b):
        if p.reference_image is None:
            raise ValueError(f"part {p.name!r}: its part file has no 'reference_image' for the hand camera")
    placed = list(placements) if placements is not None else random_placements(seed, [a.name, b.name])
    if sorted(n for n, _, _ in placed) != sorted([a.name, b.name]):
        raise ValueError(f"placements: give both parts {[a.name, b.name]} once, got {[n for n, _, _ in placed]}")
    by_name = {a.name: a, b.name: b}
    scene = Scene(table_size=(0.6, 0.6))
    truth = {name: np.array(scene.add_object(by_name[name].mesh, position=xy, yaw=yaw, name=name).T_base_object)
             for name, xy, yaw in placed}
    scan = render_scan(scene, T_BASE_FIXED_CAMERA[None], INTRINSICS_PRESETS["kinect_one"], noise=noise, seed=seed,
                       num_threads=1)
    return AssemblyCell(a, b, truth, scan, _placed_robot("kr6_r900_sixx", ASSEMBLY_MOUNTS["gripper"]),
                        _placed_robot("kr6_r900_sixx", ASSEMBLY_MOUNTS["camera"]), T_FLANGE_HAND_CAMERA.copy(), WEBCAM,
                        scene, int(seed))


def _errors(T: Optional[np.ndarray], truth: np.ndarray, symmetry: Any) -> Dict[str, float]:
    if T is None:
        return {"xy_m": math.nan, "angle_deg": math.nan}
    angle, _ = symmetric_pose_error(np.asarray(T), truth, symmetry)
    return {"xy_m": float(np.linalg.norm(np.asarray(T)[:2, 3] - truth[:2, 3])), "angle_deg": math.degrees(angle)}


def score_assembly(result: Any, cell: AssemblyCell) -> Dict[str, Any]:
    """Errors of a :class:`scanalign.pipelines.assemble.AssemblyResult` against the cell's truth.

    Per part and stage (``"3d"``: the 3D step's pose, ``"one_step"``: after the first 2D view, ``"refined"``: after
    convergence): ``xy_m`` (the model origin's distance in the table plane, m) and ``angle_deg`` (the rotation error up
    to the part's symmetry). ``placement``: with A held as the gripper truly grasped it (the planned TCP on the truly
    placed A), the placed A against ``T_onto_part`` on the true B: ``translation_m`` (at A's symmetry point),
    ``angle_deg`` and ``success`` (both within A's tolerances); None unless planned."""
    out: Dict[str, Any] = {"parts": {}}
    for p in cell.parts:
        r = result.parts.get(p.name)
        if r is None:
            continue
        first = r.refine.views[0].step.T_base_part if r.refine is not None and r.refine.views else None
        out["parts"][p.name] = {"3d": _errors(r.T_base_model_3d, cell.truth[p.name], p.symmetry),
                                "one_step": _errors(first, cell.truth[p.name], p.symmetry),
                                "refined": _errors(r.T_base_model, cell.truth[p.name], p.symmetry),
                                "views": 0 if r.refine is None else len(r.refine.views)}
    out["placement"] = None if result.status != "planned" else placement_error(
        result.T_base_tcp_grasp, result.T_base_tcp_place, cell)
    return out


def placement_error(T_base_tcp_grasp: Any, T_base_tcp_place: Any, cell: AssemblyCell) -> Dict[str, Any]:
    """Where part A truly ends up when the gripper closes at ``T_base_tcp_grasp`` on the truly placed A and lets go at
    ``T_base_tcp_place`` (4x4, m; A does not slip in the hand): its pose on the true B against ``T_onto_part``,
    ``translation_m`` (at A's symmetry point), ``angle_deg`` (up to A's symmetry) and ``success`` (both within A's
    tolerances)."""
    a, b = cell.part, cell.onto
    T_tcp_a = np.linalg.solve(np.asarray(T_base_tcp_grasp, float), cell.truth[a.name])  # A as it sits in the hand
    relative = np.linalg.solve(cell.truth[b.name], np.asarray(T_base_tcp_place, float) @ T_tcp_a)
    angle, distance = symmetric_pose_error(relative, np.asarray(a.assembly.T_onto_part), a.symmetry)
    return {"translation_m": float(distance), "angle_deg": math.degrees(angle),
            "success": bool(distance <= a.assembly.tolerance_translation and angle <= a.assembly.tolerance_angle)}
