// PCL baselines as a coarse aligner. See coarse_aligner.hpp.
#include "scanalign/pose/pcl/coarse_aligner.hpp"

#include <vector>

#include "scanalign/common/build_info.hpp"

namespace scanalign {

namespace {
std::vector<float> toFloat(const std::vector<double>& v) { return std::vector<float>(v.begin(), v.end()); }
}  // namespace

PclFeatureAlignmentSettings thesisPclPreset(PclDescriptor descriptor, PclMatcher matcher) {
  PclFeatureAlignmentSettings s;  // the defaults are the FPFH/SHOT/PPF preset
  s.descriptor = descriptor;
  s.matcher = matcher;
  if (descriptor == PclDescriptor::ShapeContext3D) s.normal_radius = s.feature_radius = 0.04;
  return s;
}

CoarseAligner pclCoarseAligner(const PclFeatureAlignmentSettings& settings) {
  return [settings](const ModelView& view, const PreparedScene& scene) {
    const std::vector<float> src = toFloat(view.points), dst = toFloat(scene.points);
    const PclFeatureAlignmentResult r = pclFeatureAlignment(CloudView<float>(src.data(), src.size() / 3),
                                                            CloudView<float>(dst.data(), dst.size() / 3), settings);
    CoarseResult out;
    out.T_scene_model = r.T_target_source;
    out.found = r.converged;
    out.message = r.message;
    return out;
  };
}

std::string pclBaselineName(const PclFeatureAlignmentSettings& settings) {
  const PclDescriptor d = settings.descriptor;  // PPF, GASD and VFH have no matcher
  const bool sac_ia = settings.matcher == PclMatcher::SacIA && d != PclDescriptor::PPF && d != PclDescriptor::GASD &&
                      d != PclDescriptor::VFH;
  return std::string(toString(settings.descriptor)) + (sac_ia ? "_sac_ia" : "");
}

void requirePclBaselines(const PclFeatureAlignmentSettings& settings) {
  // Without PCL, pclFeatureAlignment is the stub of common/without_pcl.cpp: it throws the
  // build's NotBuiltError (naming the baseline and the CMake option) whatever its input.
  if (!builtWithPcl()) pclFeatureAlignment(CloudView<float>(), CloudView<float>(), settings);
}

}  // namespace scanalign
