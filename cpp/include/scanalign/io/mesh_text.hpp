// Triangle meshes from OFF, OBJ and STL files, polygons fan-triangulated.
//
// Header-only because the library's source list is fixed in the top-level CMakeLists.txt;
// each reader is short. Coordinates are returned as stored (the file's unit). Every
// error is a std::invalid_argument whose message the caller prefixes with the file name.
#pragma once

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace scanalign {

/// A triangle mesh: vertices (V, 3) and faces (F, 3), row-major.
struct TextMesh {
  std::vector<double> vertices;
  std::vector<std::int64_t> faces;
};

namespace mesh_text_detail {

inline std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    std::size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

/// Lines with `#` comments removed, as token lists; blank lines dropped.
inline std::vector<std::vector<std::string_view>> contentLines(std::string_view text) {
  std::vector<std::vector<std::string_view>> lines;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    auto line = text.substr(start, end - start);
    line = line.substr(0, line.find('#'));
    if (auto tokens = split(line); !tokens.empty()) lines.push_back(std::move(tokens));
    start = end + 1;
  }
  return lines;
}

/// A vertex coordinate: a finite number (a NaN or infinite vertex is a corrupt file, not a shape).
inline double number(std::string_view token, const std::string& what) {
  const std::string s(token);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size()) throw std::invalid_argument(what + ": not a number: '" + s + "'");
  if (!std::isfinite(v)) throw std::invalid_argument(what + ": not a finite number: '" + s + "'");
  return v;
}

/// A count or index; one beyond the 64-bit range is refused, not clamped to it.
inline std::int64_t integer(std::string_view token, const std::string& what) {
  const std::string s(token);
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE)
    throw std::invalid_argument(what + ": not a 64-bit integer: '" + s + "'");
  return v;
}

/// Merges corners with equal coordinates (+0 and -0 alike), in order of first appearance.
inline TextMesh mergeCorners(const std::vector<double>& corners) {
  struct Key {
    double x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::size_t h = 0;
      for (double v : {k.x, k.y, k.z}) {
        std::uint64_t bits;
        v = v == 0.0 ? 0.0 : v;
        std::memcpy(&bits, &v, sizeof bits);
        h = h * 1000003u ^ std::hash<std::uint64_t>{}(bits);
      }
      return h;
    }
  };
  TextMesh m;
  std::unordered_map<Key, std::int64_t, Hash> index;
  for (std::size_t i = 0; i + 2 < corners.size(); i += 3) {
    const Key k{corners[i], corners[i + 1], corners[i + 2]};
    auto [it, inserted] = index.emplace(k, static_cast<std::int64_t>(index.size()));
    if (inserted) m.vertices.insert(m.vertices.end(), {k.x, k.y, k.z});
    m.faces.push_back(it->second);
  }
  return m;
}

}  // namespace mesh_text_detail

/// Fan triangulation of polygons given as corner counts and their concatenated vertex
/// indices: (p0, p1, ..., pk) becomes (p0, p1, p2), (p0, p2, p3), ...
/// Throws for a polygon with fewer than 3 corners or an index outside [0, n_vertices).
inline std::vector<std::int64_t> fanTriangulate(const std::vector<std::int64_t>& counts,
                                                const std::vector<std::int64_t>& flat, std::int64_t n_vertices) {
  std::vector<std::int64_t> faces;
  std::size_t start = 0;
  for (std::size_t f = 0; f < counts.size(); ++f) {
    if (counts[f] < 3)
      throw std::invalid_argument("face " + std::to_string(f) + " has " + std::to_string(counts[f]) +
                                  " vertices (at least 3 needed)");
    if (start + counts[f] > flat.size()) throw std::invalid_argument("face counts exceed the face indices given");
    for (std::int64_t k = 0; k < counts[f]; ++k) {
      const std::int64_t v = flat[start + k];
      if (v < 0 || v >= n_vertices)
        throw std::invalid_argument("face vertex index out of range [0, " + std::to_string(n_vertices) +
                                    "): found " + std::to_string(v));
    }
    for (std::int64_t k = 1; k + 1 < counts[f]; ++k)
      faces.insert(faces.end(), {flat[start], flat[start + k], flat[start + k + 1]});
    start += counts[f];
  }
  return faces;
}

/// OFF (Princeton shape benchmark): OFF, COFF, NOFF, CNOFF, STOFF headers, counts on the
/// header line or the next, extra per-vertex / per-face values (colours) ignored.
inline TextMesh parseOff(std::string_view text) {
  using namespace mesh_text_detail;
  const auto lines = contentLines(text);
  if (lines.empty()) throw std::invalid_argument("empty OFF file");
  const std::string keyword(lines[0][0]);
  // The header is (ST)?(C)?(N)?(4)?(n)?OFF.
  std::string_view prefix(keyword);
  bool ok = prefix.size() >= 3 && prefix.substr(prefix.size() - 3) == "OFF";
  prefix.remove_suffix(ok ? 3 : 0);
  bool higher_dimension = false;
  for (const char* part : {"ST", "C", "N", "4", "n"}) {
    if (prefix.substr(0, std::strlen(part)) != part) continue;
    higher_dimension |= part[0] == '4' || part[0] == 'n';
    prefix.remove_prefix(std::strlen(part));
  }
  if (!ok || !prefix.empty()) throw std::invalid_argument("not an OFF file (header '" + keyword + "')");
  if (higher_dimension) throw std::invalid_argument(keyword + ": only 3D OFF files are supported");
  std::vector<std::string_view> counts(lines[0].begin() + 1, lines[0].end());
  if (!counts.empty() && (counts[0] == "BINARY" || counts[0] == "binary"))
    throw std::invalid_argument("binary OFF files are not supported");
  std::size_t body = 1;
  if (counts.empty()) {  // counts on their own line
    if (lines.size() < 2) throw std::invalid_argument("OFF file has no vertex/face counts");
    counts = lines[1];
    body = 2;
  }
  std::int64_t nv = -1, nf = -1;
  try {
    if (counts.size() >= 2) nv = integer(counts[0], "count"), nf = integer(counts[1], "count");
  } catch (const std::invalid_argument&) {
  }
  if (nv < 0 || nf < 0) {
    std::string joined;
    for (auto c : counts) joined += (joined.empty() ? "" : " ") + std::string(c);
    throw std::invalid_argument("malformed OFF counts line '" + joined + "'");
  }
  // Compared without forming nv + nf, which a lying header can overflow.
  const auto data_lines = static_cast<std::int64_t>(lines.size() - body);
  if (nv > data_lines || nf > data_lines - nv)
    throw std::invalid_argument("OFF file is truncated: " + std::to_string(lines.size() - body) +
                                " data lines for " + std::to_string(nv) + " vertices + " + std::to_string(nf) +
                                " faces");
  TextMesh m;
  std::vector<std::int64_t> sizes, flat;
  const std::string what = "malformed OFF data";
  for (std::int64_t i = 0; i < nv; ++i) {
    const auto& t = lines[body + i];
    if (t.size() < 3) throw std::invalid_argument(what + ": a vertex line has fewer than 3 coordinates");
    for (int k = 0; k < 3; ++k) m.vertices.push_back(number(t[k], what));
  }
  for (std::int64_t i = 0; i < nf; ++i) {
    const auto& t = lines[body + nv + i];
    const std::int64_t k = integer(t[0], what);
    if (k < 0 || static_cast<std::uint64_t>(k) >= t.size())
      throw std::invalid_argument(what + ": face " + std::to_string(i) + " lists fewer than " + std::to_string(k) +
                                  " indices");
    sizes.push_back(k);
    for (std::int64_t j = 1; j <= k; ++j) flat.push_back(integer(t[j], what));
  }
  m.faces = fanTriangulate(sizes, flat, nv);
  return m;
}

/// Wavefront OBJ: `v` and `f` records (`f 1 2 3`, `f 1/1/1 ...`, `f 1//1 ...`, negative
/// indices counting back from the latest vertex, `\` line continuations); everything
/// else is ignored.
inline TextMesh parseObj(std::string_view text) {
  using namespace mesh_text_detail;
  // Continuations joined in one pass (replacing them one by one from the start was quadratic:
  // a 5 MB file of continuation lines took minutes).
  std::string joined;
  joined.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    const bool continuation = text[i] == '\\' && i + 1 < text.size() && text[i + 1] == '\n';
    joined += continuation ? ' ' : text[i];
    i += continuation;
  }
  TextMesh m;
  std::vector<std::int64_t> sizes, flat;
  std::size_t start = 0;
  for (std::int64_t line_no = 1; start <= joined.size(); ++line_no) {
    std::size_t end = joined.find('\n', start);
    if (end == std::string::npos) end = joined.size();
    auto line = std::string_view(joined).substr(start, end - start);
    start = end + 1;
    const auto t = split(line.substr(0, line.find('#')));
    const std::string where = "malformed OBJ: line " + std::to_string(line_no);
    if (t.empty()) continue;
    if (t[0] == "v") {
      if (t.size() < 4) throw std::invalid_argument(where + ": vertex with fewer than 3 coordinates");
      for (int k = 1; k <= 3; ++k) m.vertices.push_back(number(t[k], where));
    } else if (t[0] == "f") {
      const auto n_vertices = static_cast<std::int64_t>(m.vertices.size() / 3);
      for (std::size_t k = 1; k < t.size(); ++k) {
        const std::int64_t index = integer(t[k].substr(0, t[k].find('/')), where);
        if (index == 0) throw std::invalid_argument(where + ": OBJ indices start at 1");
        flat.push_back(index > 0 ? index - 1 : n_vertices + index);
      }
      sizes.push_back(static_cast<std::int64_t>(t.size()) - 1);
    }
  }
  m.faces = fanTriangulate(sizes, flat, static_cast<std::int64_t>(m.vertices.size() / 3));
  return m;
}

/// STL, binary (recognised by its size, 84 + 50 n bytes) or ASCII (`solid` ... `endsolid`);
/// corners with equal coordinates are merged into shared vertices in order of first
/// appearance.  A binary file whose size disagrees with its triangle count (truncated, or
/// a count no file of this size can hold) and an ASCII file without its closing
/// `endsolid` are refused, as are non-finite coordinates.
inline TextMesh parseStl(std::string_view bytes) {
  using namespace mesh_text_detail;
  std::vector<double> corners;
  std::uint32_t n = 0;
  if (bytes.size() >= 84) {
    std::memcpy(&n, bytes.data() + 80, 4);  // little-endian hosts only, as PCD reading
    if (bytes.size() == 84 + 50 * static_cast<std::uint64_t>(n)) {
      corners.reserve(9 * static_cast<std::size_t>(n));  // bounded: the file holds them all
      for (std::uint32_t i = 0; i < n; ++i)
        for (int k = 0; k < 9; ++k) {
          float v;
          std::memcpy(&v, bytes.data() + 84 + 50 * static_cast<std::size_t>(i) + 12 + 4 * k, 4);
          if (!std::isfinite(v))
            throw std::invalid_argument("binary STL triangle " + std::to_string(i) + " has a non-finite coordinate");
          corners.push_back(v);
        }
      return mergeCorners(corners);
    }
  }
  // Binary files often start with "solid" too (the 80-byte header is free text); ASCII
  // STL has no NUL byte, binary STL nearly always has some (the count, zero normals).
  const auto first = bytes.find_first_not_of(" \t\r\n\f\v");
  const bool ascii = first != std::string_view::npos && bytes.substr(first, 5) == "solid" &&
                     bytes.find('\0') == std::string_view::npos;
  if (!ascii)
    throw std::invalid_argument(
        "neither a binary STL (" +
        (bytes.size() < 84 ? std::string("shorter than its 84-byte header")
                           : "the header claims " + std::to_string(n) + " triangles, 84 + 50 * " + std::to_string(n) +
                                 " = " + std::to_string(84 + 50 * static_cast<std::uint64_t>(n)) +
                                 " bytes, but the file has " + std::to_string(bytes.size()) +
                                 ": truncated or corrupt") +
        ") nor an ASCII STL ('solid' ... 'endsolid')");
  const auto t = split(bytes);
  std::size_t loops = 0, endloops = 0, endfacets = 0, last_endfacet = 0, endsolid = 0;
  std::vector<std::size_t> vertex_tokens;
  for (std::size_t i = 0; i < t.size(); ++i) {
    loops += t[i] == "outer" && i + 1 < t.size() && t[i + 1] == "loop";
    endloops += t[i] == "endloop";
    if (t[i] == "endfacet") ++endfacets, last_endfacet = i;
    if (t[i] == "endsolid") endsolid = i;
    if (t[i] == "vertex" && i + 3 < t.size()) vertex_tokens.push_back(i);
  }
  // Structure first: a truncated file is reported as such, not by the cut number.
  if (loops != endloops || loops != endfacets)
    throw std::invalid_argument("ASCII STL is truncated or malformed (unbalanced facet/loop)");
  if (endsolid == 0 || endsolid < last_endfacet)
    throw std::invalid_argument("ASCII STL is truncated: no 'endsolid' after the last facet");
  if (vertex_tokens.size() != 3 * loops)
    throw std::invalid_argument("ASCII STL has " + std::to_string(vertex_tokens.size()) + " vertices for " +
                                std::to_string(loops) + " triangles");
  for (std::size_t i : vertex_tokens)
    for (std::size_t k = 1; k <= 3; ++k) corners.push_back(number(t[i + k], "malformed ASCII STL vertex"));
  return mergeCorners(corners);
}

}  // namespace scanalign
