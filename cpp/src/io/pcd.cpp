#include "scanalign/io/pcd.hpp"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "scanalign/io/lzf.hpp"

namespace scanalign {

namespace {

[[noreturn]] void fail(const std::string& message) { throw std::invalid_argument(message); }

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> splitWords(std::string_view s) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && isSpace(s[i])) ++i;
    const std::size_t start = i;
    while (i < s.size() && !isSpace(s[i])) ++i;
    if (i > start) words.push_back(s.substr(start, i - start));
  }
  return words;
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

std::string join(const std::vector<std::string>& words) {
  std::string out;
  for (const auto& w : words) out += (out.empty() ? "" : " ") + w;
  return out;
}

/// Parses all of `token` as a number of type T (a leading '+' is accepted, as by Python).
template <typename T>
bool parseNumber(std::string_view token, T& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  return result.ec == std::errc() && result.ptr == end;
}

bool parseCount(const std::vector<std::string>& values, std::int64_t& out) {
  return values.size() == 1 && parseNumber(values[0], out) && out >= 0;
}

std::size_t checkedProduct(std::size_t a, std::size_t b, const char* what) {
  std::size_t out = 0;
  if (__builtin_mul_overflow(a, b, &out)) fail(std::string("PCD header claims an impossible ") + what);
  return out;
}

using Header = std::map<std::string, std::vector<std::string>>;

const std::vector<std::string>& require(const Header& header, const std::string& key) {
  const auto it = header.find(key);
  if (it == header.end()) fail("PCD header lacks " + key);
  return it->second;
}

bool supportedType(char type, int size) {
  if (type == 'F') return size == 4 || size == 8;
  if (type == 'I' || type == 'U') return size == 1 || size == 2 || size == 4 || size == 8;
  return false;
}

std::vector<PcdField> parseFields(const Header& header) {
  const auto& names = require(header, "FIELDS");
  const auto& sizes = require(header, "SIZE");
  const auto& types = require(header, "TYPE");
  const auto it = header.find("COUNT");
  const std::vector<std::string> counts = it != header.end() ? it->second : std::vector<std::string>(names.size(), "1");
  if (names.size() != sizes.size() || names.size() != types.size() || names.size() != counts.size())
    fail("PCD header FIELDS/SIZE/TYPE/COUNT lengths differ (" + std::to_string(names.size()) + ", " +
         std::to_string(sizes.size()) + ", " + std::to_string(types.size()) + ", " + std::to_string(counts.size()) +
         ")");
  std::vector<PcdField> fields;
  for (std::size_t i = 0; i < names.size(); ++i) {
    PcdField f;
    f.name = names[i];
    const std::string type = upper(types[i]);
    if (type.size() != 1 || !parseNumber(sizes[i], f.size) || !parseNumber(counts[i], f.count) ||
        !supportedType(type[0], f.size))
      fail("PCD field '" + f.name + "' has unsupported TYPE " + types[i] + " SIZE " + sizes[i] + " COUNT " + counts[i]);
    f.type = type[0];
    if (f.count < 1) fail("PCD field '" + f.name + "' has COUNT " + std::to_string(f.count));
    fields.push_back(f);
  }
  return fields;
}

void parseSize(const Header& header, PcdHeader& out) {
  const auto& width = require(header, "WIDTH");
  const auto h = header.find("HEIGHT");
  const auto p = header.find("POINTS");
  if (!parseCount(width, out.width) || (h != header.end() && !parseCount(h->second, out.height)))
    fail("PCD header has a malformed WIDTH, HEIGHT or POINTS");
  std::int64_t product = 0;
  const bool overflow = __builtin_mul_overflow(out.width, out.height, &product);
  out.points = product;
  if (p != header.end() && !parseNumber(p->second.size() == 1 ? p->second[0] : "", out.points))
    fail("PCD header has a malformed WIDTH, HEIGHT or POINTS");
  if (overflow || out.points < 0 || out.points != product)
    fail("PCD POINTS " + std::to_string(out.points) + " does not equal WIDTH*HEIGHT " + std::to_string(out.width) +
         "*" + std::to_string(out.height));
}

void parseViewpoint(const Header& header, PcdHeader& out) {
  const auto it = header.find("VIEWPOINT");
  if (it == header.end()) return;
  bool ok = it->second.size() == 7;
  for (std::size_t k = 0; ok && k < 7; ++k) ok = parseNumber(it->second[k], out.viewpoint[k]);
  if (!ok) fail("PCD header has a malformed VIEWPOINT (expected tx ty tz qw qx qy qz)");
}

/// Writes one ascii token of `field` into `dst` (the field's own type, little-endian).
bool parseAsciiValue(const PcdField& f, std::string_view token, std::uint8_t* dst) {
  auto store = [dst](auto v) {
    std::memcpy(dst, &v, sizeof(v));
    return true;
  };
  if (f.type == 'F') {
    double v = 0;
    if (!parseNumber(token, v)) return false;
    return f.size == 4 ? store(static_cast<float>(v)) : store(v);
  }
  if (f.type == 'U') {
    std::uint64_t v = 0;
    if (!parseNumber(token, v) || (f.size < 8 && v >> (8 * f.size))) return false;
    switch (f.size) {
      case 1: return store(static_cast<std::uint8_t>(v));
      case 2: return store(static_cast<std::uint16_t>(v));
      case 4: return store(static_cast<std::uint32_t>(v));
      default: return store(v);
    }
  }
  std::int64_t v = 0;
  if (!parseNumber(token, v)) return false;
  const std::int64_t bound = f.size < 8 ? std::int64_t{1} << (8 * f.size - 1) : 0;
  if (f.size < 8 && (v < -bound || v >= bound)) return false;
  switch (f.size) {
    case 1: return store(static_cast<std::int8_t>(v));
    case 2: return store(static_cast<std::int16_t>(v));
    case 4: return store(static_cast<std::int32_t>(v));
    default: return store(v);
  }
}

/// Whether every value of the field at `offset` (`count` values per point) is a plain integer.
bool allDigits(const std::vector<std::string_view>& tokens, std::size_t offset, std::size_t count,
               std::size_t per_point, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < count; ++k) {
      const auto t = tokens[i * per_point + offset + k];
      if (t.empty() || !std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; })) return false;
    }
  return true;
}

std::vector<PcdColumn> readAscii(const PcdHeader& h, std::string_view payload) {
  std::size_t per_point = 0;
  for (const auto& f : h.fields) per_point += static_cast<std::size_t>(f.count);
  const auto n = static_cast<std::size_t>(h.points);
  const std::size_t needed = checkedProduct(n, per_point, "number of values");
  // Every value takes at least two bytes (digit and separator): reject before allocating.
  std::vector<std::string_view> tokens = needed <= payload.size() / 2 + 1 ? splitWords(payload)
                                                                          : std::vector<std::string_view>{};
  if (tokens.size() < needed) {
    if (tokens.empty()) tokens = splitWords(payload);
    fail("PCD ascii data is truncated: " + std::to_string(tokens.size()) + " values for " + std::to_string(n) +
         " points x " + std::to_string(per_point) + " values");
  }
  std::vector<PcdColumn> columns;
  std::size_t offset = 0;  // value index of the field within a point
  for (const auto& f : h.fields) {
    PcdColumn c{f, std::vector<std::uint8_t>(n * f.bytesPerPoint())};
    // Newer PCL writes packed colours as their integer bit pattern, older PCL as a float.
    const bool packed_colour = (f.name == "rgb" || f.name == "rgba") && f.type == 'F' && f.size == 4 &&
                               allDigits(tokens, offset, static_cast<std::size_t>(f.count), per_point, n);
    const PcdField as_read = packed_colour ? PcdField{f.name, 'U', 4, f.count} : f;
    for (std::size_t i = 0; i < n; ++i)
      for (int k = 0; k < f.count; ++k) {
        const auto token = tokens[i * per_point + offset + static_cast<std::size_t>(k)];
        if (!parseAsciiValue(as_read, token, c.bytes.data() + (i * f.count + k) * f.size))
          fail("PCD ascii field '" + f.name + "': cannot read '" + std::string(token) + "' as TYPE " +
               std::string(1, f.type) + " SIZE " + std::to_string(f.size));
      }
    offset += static_cast<std::size_t>(f.count);
    columns.push_back(std::move(c));
  }
  return columns;
}

std::vector<PcdColumn> readBinary(const PcdHeader& h, std::string_view payload) {
  const auto n = static_cast<std::size_t>(h.points);
  const std::size_t point_size = h.bytesPerPoint();
  if (checkedProduct(n, point_size, "payload size") > payload.size())
    fail("PCD binary data is truncated: " + std::to_string(payload.size()) + " bytes for " + std::to_string(n) +
         " points x " + std::to_string(point_size) + " bytes");
  std::vector<PcdColumn> columns;
  std::size_t offset = 0;  // byte offset of the field within a record
  for (const auto& f : h.fields) {
    const std::size_t width = f.bytesPerPoint();
    PcdColumn c{f, std::vector<std::uint8_t>(n * width)};
    for (std::size_t i = 0; i < n; ++i)
      std::memcpy(c.bytes.data() + i * width, payload.data() + i * point_size + offset, width);
    offset += width;
    columns.push_back(std::move(c));
  }
  return columns;
}

std::vector<PcdColumn> readCompressed(const PcdHeader& h, std::string_view payload) {
  if (payload.size() < 8) fail("PCD binary_compressed data is truncated (no size header)");
  std::uint32_t compressed = 0, uncompressed = 0;
  std::memcpy(&compressed, payload.data(), 4);
  std::memcpy(&uncompressed, payload.data() + 4, 4);
  const auto n = static_cast<std::size_t>(h.points);
  const std::size_t point_size = h.bytesPerPoint();
  if (checkedProduct(n, point_size, "payload size") != uncompressed)
    fail("PCD binary_compressed uncompressed size " + std::to_string(uncompressed) + " does not match " +
         std::to_string(n) + " points x " + std::to_string(point_size) + " bytes");
  if (payload.size() - 8 < compressed)
    fail("PCD binary_compressed data is truncated: " + std::to_string(payload.size() - 8) + " of " +
         std::to_string(compressed) + " compressed bytes");
  std::vector<std::uint8_t> raw;
  try {
    raw = lzfDecompress(reinterpret_cast<const std::uint8_t*>(payload.data()) + 8, compressed, uncompressed);
  } catch (const std::invalid_argument& e) {
    fail(std::string("corrupt PCD binary_compressed data: ") + e.what());
  }
  std::vector<PcdColumn> columns;
  std::size_t offset = 0;  // structure of arrays: one block per field
  for (const auto& f : h.fields) {
    const std::size_t bytes = n * f.bytesPerPoint();
    columns.push_back(PcdColumn{f, std::vector<std::uint8_t>(raw.begin() + static_cast<std::ptrdiff_t>(offset),
                                                             raw.begin() + static_cast<std::ptrdiff_t>(offset + bytes))});
    offset += bytes;
  }
  return columns;
}

}  // namespace

const char* toString(PcdData d) {
  switch (d) {
    case PcdData::Binary: return "binary";
    case PcdData::BinaryCompressed: return "binary_compressed";
    default: return "ascii";
  }
}

std::size_t PcdHeader::bytesPerPoint() const {
  std::size_t total = 0;
  for (const auto& f : fields) total += f.bytesPerPoint();
  return total;
}

PcdHeader parsePcdHeader(std::string_view file) {
  Header header;
  std::size_t pos = 0;
  for (;;) {
    const std::size_t end = file.find('\n', pos);
    if (end == std::string_view::npos) fail("PCD header has no DATA line (truncated or not a PCD file)");
    const auto words = splitWords(file.substr(pos, end - pos));
    pos = end + 1;
    if (words.empty() || words[0].front() == '#') continue;
    const std::string key = upper(words[0]);
    header[key] = std::vector<std::string>(words.begin() + 1, words.end());
    if (key == "DATA") break;
  }
  PcdHeader out;
  out.payload_offset = pos;
  if (const auto it = header.find("VERSION"); it != header.end() && !it->second.empty()) out.version = it->second[0];
  out.fields = parseFields(header);
  parseSize(header, out);
  parseViewpoint(header, out);
  const auto& data = require(header, "DATA");
  const std::string kind = data.empty() ? "" : upper(data[0]);
  if (kind == "ASCII")
    out.data = PcdData::Ascii;
  else if (kind == "BINARY")
    out.data = PcdData::Binary;
  else if (kind == "BINARY_COMPRESSED")
    out.data = PcdData::BinaryCompressed;
  else
    fail("unknown PCD DATA type '" + join(data) + "'");
  return out;
}

PcdCloud parsePcd(std::string_view file) {
  PcdCloud cloud{parsePcdHeader(file), {}};
  const auto payload = file.substr(cloud.header.payload_offset);
  switch (cloud.header.data) {
    case PcdData::Ascii: cloud.columns = readAscii(cloud.header, payload); break;
    case PcdData::Binary: cloud.columns = readBinary(cloud.header, payload); break;
    case PcdData::BinaryCompressed: cloud.columns = readCompressed(cloud.header, payload); break;
  }
  cloud.columns.erase(std::remove_if(cloud.columns.begin(), cloud.columns.end(),
                                     [](const PcdColumn& c) { return c.field.name == "_"; }),
                      cloud.columns.end());
  return cloud;
}

PcdCloud readPcd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open the file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string bytes = buffer.str();
  try {
    return parsePcd(bytes);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path + ": " + e.what());
  }
}

}  // namespace scanalign
