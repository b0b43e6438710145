#include "scanalign/reconstruction/reconstruction_settings.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace scanalign {

const char* toString(ModelFrame frame) {
  switch (frame) {
    case ModelFrame::Auto: return "auto";
    case ModelFrame::Camera: return "camera";
    case ModelFrame::Base: return "base";
  }
  return "unknown";
}

const char* toString(RegistrationMethod method) {
  switch (method) {
    case RegistrationMethod::Scanalign: return "scanalign";
    case RegistrationMethod::PclSvd: return "pcl_svd";
    case RegistrationMethod::PclDualQuaternion: return "pcl_dual_quaternion";
    case RegistrationMethod::PclPointToPlaneLls: return "pcl_point_to_plane_lls";
  }
  return "unknown";
}

void validate(const ReconstructionSettings& s) {
  const double min_depth = s.min_depth, max_depth = s.max_depth;
  if (!(min_depth >= 0.0 && max_depth > min_depth))
    throw std::invalid_argument("reconstruction: need 0 <= min_depth < max_depth (metres), got min_depth " +
                                std::to_string(min_depth) + ", max_depth " + std::to_string(max_depth));
  if (s.pixel_stride < 1) throw std::invalid_argument("reconstruction: pixel_stride must be >= 1");
  try {
    s.depth_filter.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("reconstruction: depth_filter: ") + e.what());
  }
  try {
    validate(s.frame_to_model);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("reconstruction: frame_to_model: ") + e.what());
  }
  if (s.model_frame != ModelFrame::Auto && s.model_frame != ModelFrame::Camera && s.model_frame != ModelFrame::Base)
    throw std::invalid_argument("reconstruction: model_frame must be auto, camera or base");
  if (!(s.min_merged_fraction >= 0.0 && s.min_merged_fraction <= 1.0))
    throw std::invalid_argument("reconstruction: min_merged_fraction must be in [0, 1], got " +
                                std::to_string(s.min_merged_fraction));
  const int r = static_cast<int>(s.registration);
  if (r < 0 || r > static_cast<int>(RegistrationMethod::PclPointToPlaneLls))
    throw std::invalid_argument("reconstruction: registration out of range");
}

}  // namespace scanalign
