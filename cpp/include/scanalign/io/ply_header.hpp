// A plausibility check of a PLY header against the size of its file, before a PLY reader
// (plyfile, in python/scanalign/io.py) allocates what the header claims.
//
// PLY (Turk, "The PLY polygon file format", 1994): "ply", "format <ascii |
// binary_little_endian | binary_big_endian> 1.0", then "element <name> <count>" lines each
// followed by "property <type> <name>" or "property list <count type> <item type> <name>"
// lines, "comment"/"obj_info" lines anywhere, and "end_header".  Header-only because the
// library's source list is fixed in the top-level CMakeLists.txt.
#pragma once

#include <algorithm>
#include <cstdint>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace scanalign {

namespace ply_header_detail {

/// Bytes of a PLY scalar type, 0 when the name is not one.
inline int typeSize(std::string_view t) {
  for (auto [name, size] : std::initializer_list<std::pair<std::string_view, int>>{
           {"char", 1},   {"uchar", 1},   {"int8", 1},  {"uint8", 1},  {"short", 2},   {"ushort", 2},
           {"int16", 2},  {"uint16", 2},  {"int", 4},   {"uint", 4},   {"int32", 4},   {"uint32", 4},
           {"float", 4},  {"float32", 4}, {"double", 8}, {"float64", 8}})
    if (t == name) return size;
  return 0;
}

inline std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

}  // namespace ply_header_detail

/// Checks the element counts of the PLY header at the start of `head` (the file's first
/// bytes, at least through "end_header") against `file_size`, the whole file's size in
/// bytes.  Every row of an element takes at least its binary record size (a list property
/// counts its length field only), or in ASCII two bytes per property (a digit and a
/// separator), and at least one byte in any case.  Throws std::invalid_argument for a count
/// that is not a non-negative integer and for counts whose rows cannot fit in the bytes
/// after the header.  Anything else it does not understand (not a PLY file, an unknown
/// format or type, no end_header within `head`) is left to the PLY reader to report.
inline void checkPlyHeader(std::string_view head, std::uint64_t file_size) {
  using namespace ply_header_detail;
  struct Element {
    std::string name;
    std::uint64_t count = 0, row_bytes = 0, properties = 0;
  };
  std::vector<Element> elements;
  bool ascii = false, ended = false;
  std::size_t pos = 0, line_no = 0;
  while (!ended && pos < head.size()) {
    std::size_t end = head.find('\n', pos);
    if (end == std::string_view::npos) return;  // no end_header here: the reader says so
    const auto w = words(head.substr(pos, end - pos));
    pos = end + 1;
    if (line_no++ == 0) {
      if (w.size() != 1 || w[0] != "ply") return;
      continue;
    }
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") ended = true;
    else if (w[0] == "format" && w.size() >= 2) ascii = w[1] == "ascii";
    else if (w[0] == "element" && w.size() == 3) {
      const std::string count(w[2]);
      std::size_t used = 0;
      unsigned long long value = 0;
      try {
        if (count.empty() || count[0] == '-' || count[0] == '+') throw std::invalid_argument("sign");
        value = std::stoull(count, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != count.size())
        throw std::invalid_argument("malformed PLY header: element '" + std::string(w[1]) + "' has count '" + count +
                                    "' (expected an integer >= 0)");
      elements.push_back({std::string(w[1]), value, 0, 0});
    } else if (w[0] == "property" && !elements.empty()) {
      auto& e = elements.back();
      const int size = typeSize(w.size() >= 2 ? w[1] == "list" && w.size() >= 3 ? w[2] : w[1] : "");
      if (size == 0) return;  // unknown type or malformed: the reader reports it
      e.row_bytes += static_cast<std::uint64_t>(size);
      ++e.properties;
    }
  }
  if (!ended) return;
  const std::uint64_t payload = file_size > pos ? file_size - pos : 0;
  std::uint64_t total = 0;
  for (const auto& e : elements) {
    const std::uint64_t row = std::max<std::uint64_t>(1, ascii ? 2 * e.properties : e.row_bytes);
    // total + count * row > payload, without overflow.
    if (e.count > (payload - total) / row)
      throw std::invalid_argument("PLY header claims " + std::to_string(e.count) + " '" + e.name + "' elements of at least " +
                                  std::to_string(row) + " bytes each, but only " + std::to_string(payload - total) +
                                  " bytes of the file are left for them (truncated or corrupt)");
    total += e.count * row;
  }
}

}  // namespace scanalign
