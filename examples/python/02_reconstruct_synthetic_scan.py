"""02: reconstruct a synthetic eye-in-hand scan frame by frame, as a robot program would.

A camera on the robot's hand circles a part on a table (Fig. 4 of the eye-in-hand paper,
(Comput. Electron. Agric. 180 (2021) 105929)). Each frame is
registered to the model so far and merged; the model lives in the robot base frame
because the first frame is placed at its known pose T_base_camera.

    python examples/python/02_reconstruct_synthetic_scan.py [out_dir]
"""

import sys

import numpy as np

from scanalign import synthetic
from scanalign.evaluation import absolute_trajectory_error
from scanalign.reconstruction import Reconstructor

out = sys.argv[1] if len(sys.argv) > 1 else "example-02"
scan = synthetic.builtin_scan(n_frames=36, noise="sr300", seed=0)

rec = Reconstructor(
    T_model_camera0=scan.frames[0].T_base_camera,    # model frame = robot base frame
    crop_box=(-0.1, 0.1, -0.1, 0.1, 0.1, 1.0),       # the part's workspace in the camera's view (m)
)                                                    # the rest: ReconstructionSettings' defaults
for frame in scan.frames:
    record = rec.integrate(frame)                    # guess: constant velocity
    error = np.linalg.norm(record.T_model_camera[:3, 3] - frame.T_base_camera[:3, 3])
    print(f"frame {record.index:2d} {record.status:12s} {record.iterations:2d} it  "
          f"fitness {record.fitness:.3f}  model {record.model_points:6d}  error {error * 1000:5.2f} mm")

ate = absolute_trajectory_error(rec.trajectory, scan.reference)
print(f"ATE RMSE {ate.translation.rmse * 1000:.2f} mm over {ate.translation.count} poses")
assert ate.translation.count == len(scan.frames) and ate.translation.rmse < 0.006  # every frame, under 6 mm
rec.model.write_ply(f"{out}-model.ply")
rec.trajectory.write_tum(f"{out}-trajectory.txt")
print(f"wrote {out}-model.ply and {out}-trajectory.txt")
