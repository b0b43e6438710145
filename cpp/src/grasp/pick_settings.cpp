// Settings of the pick job. See pick_settings.hpp.
#include "scanalign/grasp/pick_settings.hpp"

#include <stdexcept>
#include <string>

#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign {

const char* toString(PickViews views) {
  switch (views) {
    case PickViews::Upper: return "upper";
    case PickViews::All: return "all";
  }
  return "?";
}

namespace {

/// Runs `check`, prefixing the message of a std::invalid_argument with `path`.
template <typename Check>
void within(const char* path, Check check) {
  try {
    check();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("pick settings: ") + path + e.what());
  }
}

}  // namespace

void PickSettings::validate() const {
  // validate(ReconstructionSettings) already names itself ("reconstruction: ...").
  within("", [this] { scanalign::validate(reconstruction); });
  within("find_parts: table: ", [this] { scanalign::validate(find_parts.table); });
  within("find_parts: ", [this] { scanalign::validate(find_parts); });
  if (views != PickViews::Upper && views != PickViews::All)
    throw std::invalid_argument("pick settings: views must be 'upper' or 'all'");
  within("planner: ", [this] { planner.validate(); });
}

}  // namespace scanalign
