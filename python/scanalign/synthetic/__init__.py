"""Synthetic eye-in-hand RGB-D scans with exact ground truth (the simulator; production code does not import it): a
camera on a robot's hand moves around objects on a table, the z-buffer renderer of
:mod:`scanalign.reconstruction.rendering` computes what it sees and a sensor model adds RealSense- or Zivid-like noise.

Frames (``T_a_b`` maps b-coordinates into a; metres, 4x4 float64): ``base``, the scene (world) frame, z up, the table
top at ``z = table_height``, in which every pose and the reconstruction's model are given; ``robot``, the arm's base
at ``T_base_robot`` (:func:`robot_mount`); ``flange``, ``T_base_flange = T_base_robot @ fk(q)``; ``camera``, OpenCV
convention (x right, y down, z along the optical axis), ``T_base_camera = T_base_flange @ T_flange_camera`` (the
hand-eye calibration); ``object``, a mesh's own frame, placed by ``T_base_object``.

Pipeline::

    scene = Scene(table_size=(0.6, 0.6))
    scene.add_object(builtin_mesh(), position=(0.5, 0.0), yaw=0.3)
    traj = loop_trajectory(36, center=scene.center, height=0.40, radius=0.20, robot="ur5")
    scan = render_scan(scene, traj, "sr300", noise="sr300", seed=1)
    scan.joints[0]                     # UR5 joints of frame 0 (rad), from inverse kinematics
    scan.frames[0].depth_metres()      # (480, 640) float32, NaN = no measurement
    scan.reference.poses[0]            # exact T_base_camera of frame 0
    scan.mesh                          # the whole scene in the base frame (for cloud-to-mesh)

or ``builtin_scan(n_frames=36, noise="sr300", seed=0)``, or a JSON / YAML file read by :class:`SyntheticConfig`. With
a robot (:func:`attach_robot`), the reference poses are forward kinematics of its joints, so a reconstruction is
scored against the robot's own pose, as in the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929, §4).
"""

from __future__ import annotations

from scanalign.data.parts import builtin_mesh, normalize_mesh
from scanalign.reconstruction.rendering import RenderResult, look_at, render_depth
from scanalign.synthetic.config import SyntheticConfig, builtin_scan
from scanalign.synthetic.noise import NOISE_PRESETS, SensorNoise
from scanalign.synthetic.scan import SyntheticScan, render_scan
from scanalign.synthetic.scene import Scene, SceneObject
from scanalign.synthetic.trajectories import (DEFAULT_ROBOT_HEIGHT, DEFAULT_T_FLANGE_CAMERA, ScanTrajectory,
                                              attach_robot, hemisphere_trajectory, loop_trajectory, robot_mount)

__all__ = ["RenderResult", "render_depth", "look_at", "builtin_mesh", "normalize_mesh", "SceneObject", "Scene",
           "DEFAULT_T_FLANGE_CAMERA", "ScanTrajectory", "DEFAULT_ROBOT_HEIGHT", "robot_mount", "attach_robot",
           "loop_trajectory", "hemisphere_trajectory", "SensorNoise", "NOISE_PRESETS", "SyntheticScan", "render_scan",
           "SyntheticConfig", "builtin_scan"]
