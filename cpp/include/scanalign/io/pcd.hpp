// Reading PCL Point Cloud Data (.pcd, format versions 0.5-0.7) without PCL.
//
// The header is a list of "KEY values" lines (VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH,
// HEIGHT, VIEWPOINT, POINTS) ending with the DATA line; the payload follows it:
//   ascii              whitespace-separated numbers, one point per line;
//   binary             packed little-endian records, one per point (array of structures);
//   binary_compressed  two uint32 (compressed, uncompressed size), then an LZF stream
//                      that decompresses to one block per field (structure of arrays).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace scanalign {

/// One FIELDS entry: a per-point value of `count` elements of `type` ('F' float,
/// 'I' signed, 'U' unsigned integer) and `size` bytes each.
struct PcdField {
  std::string name;
  char type = 'F';
  int size = 4;
  int count = 1;
  std::size_t bytesPerPoint() const { return static_cast<std::size_t>(size) * static_cast<std::size_t>(count); }
};

enum class PcdData { Ascii, Binary, BinaryCompressed };
/// "ascii", "binary", "binary_compressed" (the DATA line's words).
const char* toString(PcdData d);

struct PcdHeader {
  std::string version;  ///< as written ("0.7", ".7", ...), empty when absent
  std::vector<PcdField> fields;
  std::int64_t width = 0;
  std::int64_t height = 1;  ///< > 1 for an organised cloud (rows of `width` points)
  std::int64_t points = 0;  ///< width * height
  /// Acquisition viewpoint: translation (x, y, z) then quaternion (w, x, y, z).
  std::array<double, 7> viewpoint{0, 0, 0, 1, 0, 0, 0};
  PcdData data = PcdData::Ascii;
  std::size_t payload_offset = 0;  ///< byte offset of the payload, just after the DATA line
  std::size_t bytesPerPoint() const;
};

/// One field's values for all points, row-major (point, element), little-endian, in the
/// field's own type: `points * field.count * field.size` bytes.
struct PcdColumn {
  PcdField field;
  std::vector<std::uint8_t> bytes;
};

struct PcdCloud {
  PcdHeader header;
  /// In header order; PCL's padding fields (named "_") are dropped.
  std::vector<PcdColumn> columns;
};

/// Parses the header of a PCD file held in `file`.  Throws std::invalid_argument naming
/// the offending key or field (no DATA line, missing FIELDS/SIZE/TYPE/WIDTH, lengths
/// that differ, an unsupported TYPE/SIZE, POINTS != WIDTH * HEIGHT, unknown DATA kind).
PcdHeader parsePcdHeader(std::string_view file);

/// Parses a whole PCD file held in memory.  Every size the header claims is checked
/// against the bytes present before anything that large is allocated; a truncated or
/// corrupt payload throws std::invalid_argument.
PcdCloud parsePcd(std::string_view file);

/// Reads and parses a PCD file; error messages start with `path`.
PcdCloud readPcd(const std::string& path);

}  // namespace scanalign
