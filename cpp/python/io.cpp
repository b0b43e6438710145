// _core.io: PCD reading and LZF decompression.  python/scanalign/io.py reads the file,
// names it in error messages and keeps the public signatures.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>

#include "scanalign/io/lzf.hpp"
#include "scanalign/io/pcd.hpp"

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

const char* dataName(PcdData d) {
  switch (d) {
    case PcdData::Ascii: return "ascii";
    case PcdData::Binary: return "binary";
    case PcdData::BinaryCompressed: return "binary_compressed";
  }
  return "";
}

}  // namespace

void defineIo(py::module_& m) {
  py::class_<PcdField>(m, "PcdField", "one FIELDS entry of a PCD header")
      .def_readonly("name", &PcdField::name, "field name, e.g. \"x\", \"normal_x\", \"rgb\"")
      .def_property_readonly(
          "type", [](const PcdField& f) { return std::string(1, f.type); },
          "\"F\" float, \"I\" signed or \"U\" unsigned integer")
      .def_readonly("size", &PcdField::size, "bytes per element")
      .def_readonly("count", &PcdField::count, "elements per point")
      .def_property_readonly("dtype", &fieldDtype, "the NumPy dtype of one element (little-endian)");

  py::class_<PcdHeader>(m, "PcdHeader", "the header of a PCD file")
      .def_readonly("version", &PcdHeader::version, "VERSION as written, empty when absent")
      .def_readonly("fields", &PcdHeader::fields, "list of PcdField, in file order")
      .def_readonly("width", &PcdHeader::width, "points per row")
      .def_readonly("height", &PcdHeader::height, "rows (> 1 for an organised cloud)")
      .def_readonly("points", &PcdHeader::points, "number of points, width * height")
      .def_readonly("viewpoint", &PcdHeader::viewpoint,
                    "acquisition viewpoint (tx, ty, tz, qw, qx, qy, qz): translation in the file's unit, "
                    "unit quaternion")
      .def_property_readonly(
          "data", [](const PcdHeader& h) { return std::string(dataName(h.data)); },
          "\"ascii\", \"binary\" or \"binary_compressed\"");

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
      [](const py::bytes& data, std::int64_t expected_size) {
        if (expected_size < 0) throw std::invalid_argument("expected_size must be >= 0");
        const auto view = bytesView(data);
        std::vector<std::uint8_t> out;
        {
          py::gil_scoped_release release;
          out = lzfDecompress(reinterpret_cast<const std::uint8_t*>(view.data()), view.size(),
                              static_cast<std::size_t>(expected_size));
        }
        return py::bytes(reinterpret_cast<const char*>(out.data()), out.size());
      },
      py::arg("data"), py::arg("expected_size"),
      "Decompresses an LZF stream to exactly expected_size bytes; ValueError when it is "
      "truncated, corrupt, or of another size.");
}

}  // namespace scanalign::python
