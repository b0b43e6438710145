// Settings of the pick job. See pick_settings.hpp.
#include "scanalign/grasp/pick_settings.hpp"

#include <stdexcept>

#include "scanalign/common/nested_validation.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign {

const char* toString(PickViews views) {
  switch (views) {
    case PickViews::Upper: return "upper";
    case PickViews::All: return "all";
  }
  return "?";
}

void PickSettings::validate() const {
  // validate(ReconstructionSettings) already names itself ("reconstruction: ...").
  validateNested("pick settings: ", [this] { scanalign::validate(reconstruction); });
  validateNested("pick settings: find_parts: table: ", [this] { scanalign::validate(find_parts.table); });
  validateNested("pick settings: find_parts: ", [this] { scanalign::validate(find_parts); });
  if (views != PickViews::Upper && views != PickViews::All)
    throw std::invalid_argument("pick settings: views must be 'upper' or 'all'");
  validateNested("pick settings: planner: ", [this] { planner.validate(); });
}

}  // namespace scanalign
