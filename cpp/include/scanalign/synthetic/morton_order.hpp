// Morton (Z-curve) order of points: neighbouring points end up close in the order, which
// the synthetic scene uses to lay out a mesh's faces for the renderer's caches.
#pragma once

#include <cstdint>
#include <vector>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// The permutation sorting `points` along a Morton curve of the bounding box of the finite
/// ones, quantised to 21 bits per axis; non-finite points come last, equal codes keep their
/// input order.
std::vector<std::int64_t> mortonOrder(const CloudView<double>& points);

}  // namespace scanalign
