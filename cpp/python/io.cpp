// _core.io: PCD reading, LZF decompression, OFF / OBJ / STL meshes, fan triangulation and the
// PLY header check run before plyfile reads a file.
// python/scanalign/io.py reads the file, names it in error messages and keeps the public
// signatures.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include "field_access.hpp"  // Conv for Python objects (the dtype)
#include "fields.hpp"
#include "scanalign/io/lzf.hpp"
#include "scanalign/io/mesh_text.hpp"
#include "scanalign/io/pcd.hpp"
#include "scanalign/io/ply_header.hpp"

namespace py = pybind11;

namespace scanalign::python {

namespace {

std::string_view bytesView(const py::bytes& data) {
  char* buffer = nullptr;
  Py_ssize_t size = 0;
  if (PyBytes_AsStringAndSize(data.ptr(), &buffer, &size) != 0) throw py::error_already_set();
  return {buffer, static_cast<std::size_t>(size)};
}

/// NumPy dtype of a PCD field: TYPE F/I/U and SIZE in bytes, little-endian.
py::dtype fieldDtype(const PcdField& f) {
  const char kind = f.type == 'F' ? 'f' : f.type == 'I' ? 'i' : 'u';
  return py::dtype(std::string("<") + kind + std::to_string(f.size));
}

py::array columnArray(const PcdColumn& c, std::int64_t points) {
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(points)};
  if (c.field.count != 1) shape.push_back(c.field.count);
  py::array a(fieldDtype(c.field), shape);
  if (!c.bytes.empty()) std::memcpy(a.mutable_data(), c.bytes.data(), c.bytes.size());
  return a;
}

using Indices = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

template <typename T>
py::array_t<T> rows3(std::vector<T> values) {
  py::array_t<T> a({static_cast<py::ssize_t>(values.size() / 3), py::ssize_t{3}});
  if (!values.empty()) std::memcpy(a.mutable_data(), values.data(), values.size() * sizeof(T));
  return a;
}

}  // namespace

void defineIo(py::module_& m) {
  using F = PcdField;
  fieldsOf(py::class_<F>(m, "PcdField", "one FIELDS entry of a PCD header"))
      .output("name", &F::name, "", "field name, e.g. \"x\", \"normal_x\", \"rgb\"")
      .field(
          "type", [](const F& f) { return std::string(1, f.type); },
          [](F& f, const std::string& t) {
            if (t != "F" && t != "I" && t != "U") throw py::value_error("PcdField.type: expected 'F', 'I' or 'U'");
            f.type = t[0];
          },
          "", "\"F\" float, \"I\" signed or \"U\" unsigned integer", false)
      .output("size", &F::size, "", "bytes per element")
      .output("count", &F::count, "", "elements per point")
      .derived("dtype", &fieldDtype, "", "the NumPy dtype of one element (little-endian)")
      .result();
  using H = PcdHeader;
  fieldsOf(py::class_<H>(m, "PcdHeader", "the header of a PCD file"))
      .output("version", &H::version, "", "VERSION as written, empty when absent")
      .output("fields", &H::fields, "", "list of PcdField, in file order")
      .output("width", &H::width, "", "points per row")
      .output("height", &H::height, "", "rows (> 1 for an organised cloud)")
      .output("points", &H::points, "", "number of points, width * height")
      .output("viewpoint", &H::viewpoint, "",
              "acquisition viewpoint (tx, ty, tz, qw, qx, qy, qz): translation in the file's unit, unit quaternion")
      .name("data", &H::data, 3, "", "\"ascii\", \"binary\" or \"binary_compressed\"", false)
      .output("payload_offset", &H::payload_offset, "", "byte offset of the payload, just after the DATA line")
      .result();

  m.def(
      "parse_pcd",
      [](const py::bytes& data) {
        const auto view = bytesView(data);
        PcdCloud cloud;
        {
          py::gil_scoped_release release;
          cloud = parsePcd(view);
        }
        py::dict columns;
        for (const auto& c : cloud.columns) columns[py::str(c.field.name)] = columnArray(c, cloud.header.points);
        return py::make_tuple(cloud.header, columns);
      },
      py::arg("data"),
      "Parses the bytes of a PCD file: (PcdHeader, {field name: (N,) or (N, COUNT) array}), "
      "padding fields \"_\" dropped.  Raises ValueError for a malformed header or a truncated or "
      "corrupt payload (checked before any large allocation).");

  m.def(
      "lzf_decompress",
      [](const py::object& data, std::int64_t expected_size) {
        if (expected_size < 0) throw std::invalid_argument("expected_size must be >= 0");
        const py::bytes bytes = py::module_::import("builtins").attr("bytes")(data);  // bytearray, memoryview...
        const auto view = bytesView(bytes);
        std::vector<std::uint8_t> out;
        {
          py::gil_scoped_release release;
          out = lzfDecompress(reinterpret_cast<const std::uint8_t*>(view.data()), view.size(),
                              static_cast<std::size_t>(expected_size));
        }
        return py::bytes(reinterpret_cast<const char*>(out.data()), out.size());
      },
      py::arg("data"), py::arg("expected_size"), R"doc(
Decompresses an LZF stream (the liblzf format PCL uses for ``binary_compressed``).

Args:
    data: the compressed bytes (any bytes-like object).
    expected_size: exact size of the decompressed output in bytes (>= 0).

Returns:
    The decompressed bytes, of length ``expected_size``.

Raises:
    ValueError: the stream is truncated, refers before the start of the output, does not
        decompress to exactly ``expected_size`` bytes, or is too short to ever reach
        ``expected_size`` (checked before allocating the output); a negative expected_size.
)doc");

  m.def(
      "parse_mesh",
      [](const py::bytes& data, const std::string& format) {
        const auto view = bytesView(data);
        TextMesh mesh;
        {
          py::gil_scoped_release release;
          if (format == "off") mesh = parseOff(view);
          else if (format == "obj") mesh = parseObj(view);
          else if (format == "stl") mesh = parseStl(view);
          else throw std::invalid_argument("format must be 'off', 'obj' or 'stl', got '" + format + "'");
        }
        return py::make_tuple(rows3(std::move(mesh.vertices)), rows3(std::move(mesh.faces)));
      },
      py::arg("data"), py::arg("format"),
      "Parses the bytes of an OFF, OBJ or STL file: (vertices (V, 3) float64 in the file's unit, "
      "faces (F, 3) int64), polygons fan-triangulated, STL corners with equal coordinates merged in "
      "order of first appearance. Raises ValueError for a malformed or truncated file (counts are "
      "checked against the bytes present before anything is allocated: an OFF header claiming more "
      "lines than the file has, a binary STL whose size is not 84 + 50 * its triangle count, an ASCII "
      "STL without 'endsolid'), a negative or out-of-range count or index, a NaN or infinite vertex "
      "coordinate, a face with fewer than 3 corners or an index out of range.");

  m.def(
      "check_ply_header",
      [](const std::string& path) {
        std::ifstream in(path, std::ios::binary | std::ios::ate);
        if (!in) return;  // the reader reports a missing or unreadable file
        const auto size = static_cast<std::uint64_t>(in.tellg());
        std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(size, 1u << 20)), '\0');
        in.seekg(0);
        in.read(head.data(), static_cast<std::streamsize>(head.size()));
        head.resize(static_cast<std::size_t>(in.gcount()));
        try {
          checkPlyHeader(head, size);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(path + ": " + e.what());
        }
      },
      py::arg("path"),
      "Checks the element counts of a PLY file's header (its first MiB) against the file's size "
      "before a reader allocates them: every row takes at least its binary record size, or two "
      "bytes per property in ASCII. Raises ValueError, message starting with the path, for a "
      "negative or non-integer count or counts the file cannot hold; leaves every other problem "
      "(not a PLY file, unknown type, no end_header) to the reader.");

  m.def(
      "fan_triangulate",
      [](const Indices& counts, const Indices& indices, std::int64_t n_vertices) {
        const auto vec = [](const Indices& a) { return std::vector<std::int64_t>(a.data(), a.data() + a.size()); };
        return rows3(fanTriangulate(vec(counts), vec(indices), n_vertices));
      },
      py::arg("counts"), py::arg("indices"), py::arg("n_vertices"),
      "(F, 3) int64 triangles of polygons given as corner counts and their concatenated vertex "
      "indices: (p0, p1, ..., pk) becomes (p0, p1, p2), (p0, p2, p3), ... Raises ValueError for a "
      "polygon with fewer than 3 corners or an index outside [0, n_vertices).");
}

}  // namespace scanalign::python
