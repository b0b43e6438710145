// Poses of a part in a table scene. See find_objects.hpp.
#include "scanalign/pose/find_objects.hpp"

#include <chrono>
#include <cstdint>
#include <stdexcept>

#include "scanalign/pose/detail/pose_in_scene.hpp"

namespace scanalign {

FindObjectsResult findObjects(const std::vector<ModelView>& views, const CloudView<double>& scene,
                              const FindObjectsSettings& s, const std::vector<int>& view_ids,
                              const CoarseAligner& aligner, const PoseProgress& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  if (s.max_objects < 1) throw std::invalid_argument("max_objects must be >= 1");
  validate(s.pose);
  detail::requireCoarseMethod(s.pose, aligner, "findObjects");
  FindObjectsResult out;
  out.table = segmentTable(scene, s.table);
  if (out.table.objects.size() > s.max_objects) out.table.objects.resize(s.max_objects);
  std::vector<double> object;
  for (const auto& idx : out.table.objects) {
    object.clear();
    for (std::uint32_t i : idx) object.insert(object.end(), scene.ptr(i), scene.ptr(i) + 3);
    out.poses.push_back(estimatePose(views, CloudView<double>(object.data(), idx.size()), s.pose, view_ids, aligner, progress));
  }
  out.seconds = detail::secondsSince(t0);
  return out;
}

}  // namespace scanalign
