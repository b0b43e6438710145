// Validation of settings structs that nest other settings: the message of a nested struct's
// std::invalid_argument gains the path to it ("pick settings: find_parts: table: ..."), so a
// config-file user sees which field of which struct is wrong.
#pragma once

#include <stdexcept>
#include <string>

namespace scanalign {

/// Runs `check`; a std::invalid_argument it throws is rethrown with `path` in front.
template <typename Check>
void validateNested(const std::string& path, Check check) {
  try {
    check();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path + e.what());
  }
}

}  // namespace scanalign
