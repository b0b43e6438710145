// Settings of the assembly job. See assembly_settings.hpp.
#include "scanalign/grasp/assembly_settings.hpp"

#include <stdexcept>

#include "scanalign/common/nested_validation.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign {

void AssemblySettings::validate() const {
  validateNested("assembly settings: find_parts: table: ", [this] { scanalign::validate(find_parts.table); });
  validateNested("assembly settings: find_parts: ", [this] { scanalign::validate(find_parts); });
  if (views != PickViews::Upper && views != PickViews::All)
    throw std::invalid_argument("assembly settings: views must be 'upper' or 'all'");
  validateNested("assembly settings: refine_2d: ", [this] { refine_2d.validate(); });
  validateNested("assembly settings: view: ", [this] { view.validate(); });
  validateNested("assembly settings: planner: ", [this] { planner.validate(); });
}

}  // namespace scanalign
