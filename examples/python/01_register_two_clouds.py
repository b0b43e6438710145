"""01: register a camera frame to a model with scanalign's ICP, and check it.

Run after the README's set-up:  .venv/bin/python examples/python/01_register_two_clouds.py
"""

import numpy as np

from scanalign.data import parts
from scanalign.features import estimate_normals
from scanalign.registration import Box, icp

# Model (target frame): the built-in part 40 cm in front of the camera, metres.
part, _ = parts.builtin_object(n_points=30000)
model = part + [0.0, 0.0, 0.4]
model_normals = estimate_normals(model, radius=0.005, viewpoint=(0, 0, 0))

# The camera moved: a new frame sees the part from T_model_camera (2 degrees, 5 mm).
angle = np.deg2rad(2.0)
T_model_camera = np.eye(4)
T_model_camera[:3, :3] = [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
T_model_camera[:3, 3] = [0.004, -0.002, 0.003]
frame = (model - T_model_camera[:3, 3]) @ T_model_camera[:3, :3]  # p_camera = T^-1 p_model

result = icp(frame, model, model_normals, max_correspondence_distance=0.02, box=Box.free_hand_preset())
print(result)
print("T_model_camera estimated:\n", np.round(result.T_target_source, 6))
assert result.converged and np.allclose(result.T_target_source, T_model_camera, atol=1e-5)
