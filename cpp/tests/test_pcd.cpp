// The PCD reader against files assembled by hand, with known content, for each DATA kind,
// and against truncated, corrupt and oversized headers.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "scanalign/io/mesh_text.hpp"
#include "scanalign/io/pcd.hpp"
#include "scanalign/io/ply_header.hpp"

namespace {

using scanalign::PcdCloud;
using scanalign::PcdData;

// Three points: x, y, z (float32), label (uint16), hist (3 x int32), curvature (float64).
const float kXyz[3][3] = {{0.5f, -1.25f, 2.0f}, {1e-3f, 0.0f, -7.5f}, {3.0f, 4.0f, 5.0f}};
const std::uint16_t kLabel[3] = {7, 0, 65535};
const std::int32_t kHist[3][3] = {{-1, 2, -3}, {100000, -100000, 0}, {5, 6, 7}};
const double kCurvature[3] = {0.125, -2.5, 1e-9};

std::string header(const std::string& data, const std::string& points = "3") {
  return "# .PCD v0.7 - Point Cloud Data file format\n"
         "VERSION 0.7\n"
         "FIELDS x y z label hist curvature\n"
         "SIZE 4 4 4 2 4 8\n"
         "TYPE F F F U I F\n"
         "COUNT 1 1 1 1 3 1\n"
         "WIDTH " + points + "\nHEIGHT 1\n"
         "VIEWPOINT 1 2 3 1 0 0 0\n"
         "POINTS " + points + "\n"
         "DATA " + data + "\n";
}

template <typename T>
void append(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

std::string asciiFile() {
  return header("ascii") +
         "0.5 -1.25 2 7 -1 2 -3 0.125\n"
         "0.001 0 -7.5 0 100000 -100000 0 -2.5\n"
         "3 4 5 65535 5 6 7 1e-9\n";
}

std::string binaryFile() {
  std::string out = header("binary");
  for (int i = 0; i < 3; ++i) {
    for (float v : kXyz[i]) append(out, v);
    append(out, kLabel[i]);
    for (std::int32_t v : kHist[i]) append(out, v);
    append(out, kCurvature[i]);
  }
  return out;
}

/// The structure-of-arrays block stored as LZF literal runs (at most 32 bytes each).
std::string compressedFile() {
  std::string raw;
  for (int axis = 0; axis < 3; ++axis)
    for (int i = 0; i < 3; ++i) append(raw, kXyz[i][axis]);
  for (auto v : kLabel) append(raw, v);
  for (const auto& row : kHist)
    for (auto v : row) append(raw, v);
  for (auto v : kCurvature) append(raw, v);
  std::string packed;
  for (std::size_t at = 0; at < raw.size(); at += 32) {
    const std::string chunk = raw.substr(at, 32);
    packed += static_cast<char>(chunk.size() - 1);
    packed += chunk;
  }
  std::string out = header("binary_compressed");
  append(out, static_cast<std::uint32_t>(packed.size()));
  append(out, static_cast<std::uint32_t>(raw.size()));
  return out + packed;
}

template <typename T>
std::vector<T> values(const PcdCloud& cloud, const std::string& name) {
  for (const auto& c : cloud.columns)
    if (c.field.name == name) {
      std::vector<T> out(c.bytes.size() / sizeof(T));
      std::memcpy(out.data(), c.bytes.data(), c.bytes.size());
      return out;
    }
  ADD_FAILURE() << "no field " << name;
  return {};
}

void expectKnownContent(const PcdCloud& cloud) {
  ASSERT_EQ(cloud.header.points, 3);
  ASSERT_EQ(cloud.columns.size(), 6u);
  EXPECT_EQ(cloud.header.version, "0.7");
  EXPECT_EQ(cloud.header.viewpoint[0], 1.0);
  EXPECT_EQ(cloud.header.viewpoint[3], 1.0);
  const char* axes[3] = {"x", "y", "z"};
  for (int axis = 0; axis < 3; ++axis) {
    const auto v = values<float>(cloud, axes[axis]);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(v[i], kXyz[i][axis]) << axes[axis] << i;
  }
  EXPECT_EQ(values<std::uint16_t>(cloud, "label"), std::vector<std::uint16_t>(kLabel, kLabel + 3));
  EXPECT_EQ(values<std::int32_t>(cloud, "hist"), std::vector<std::int32_t>(&kHist[0][0], &kHist[0][0] + 9));
  EXPECT_EQ(values<double>(cloud, "curvature"), std::vector<double>(kCurvature, kCurvature + 3));
}

std::string errorOf(const std::string& file) {
  try {
    scanalign::parsePcd(file);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

#define EXPECT_ERROR(file, text)                               \
  do {                                                         \
    const std::string message = errorOf(file);                 \
    EXPECT_NE(message.find(text), std::string::npos) << message; \
  } while (0)

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  s.replace(s.find(from), from.size(), to);
  return s;
}

}  // namespace

TEST(Pcd, AsciiKnownContent) {
  const auto cloud = scanalign::parsePcd(asciiFile());
  EXPECT_EQ(cloud.header.data, PcdData::Ascii);
  expectKnownContent(cloud);
}

TEST(Pcd, BinaryKnownContent) {
  const auto cloud = scanalign::parsePcd(binaryFile());
  EXPECT_EQ(cloud.header.data, PcdData::Binary);
  expectKnownContent(cloud);
}

TEST(Pcd, BinaryCompressedKnownContent) {
  const auto cloud = scanalign::parsePcd(compressedFile());
  EXPECT_EQ(cloud.header.data, PcdData::BinaryCompressed);
  expectKnownContent(cloud);
}

TEST(Pcd, AsciiPackedColourAsIntegerOrFloatAndNan) {
  const std::string head = "FIELDS x rgb\nSIZE 4 4\nTYPE F F\nWIDTH 2\nPOINTS 2\nDATA ascii\n";
  // Newer PCL writes the colour's bit pattern as an integer.
  auto cloud = scanalign::parsePcd(head + "nan 16711680\n1 255\n");
  const auto rgb = values<std::uint32_t>(cloud, "rgb");
  EXPECT_EQ(rgb, (std::vector<std::uint32_t>{0xFF0000u, 0xFFu}));
  EXPECT_TRUE(std::isnan(values<float>(cloud, "x")[0]));
  // Older PCL writes it as a float.
  cloud = scanalign::parsePcd(head + "0 2.5\n1 255\n");
  EXPECT_EQ(values<float>(cloud, "rgb"), (std::vector<float>{2.5f, 255.0f}));
}

TEST(Pcd, OrganisedCloudAndPaddingDropped) {
  std::string file = "FIELDS x _\nSIZE 4 1\nTYPE F U\nCOUNT 1 4\nWIDTH 2\nHEIGHT 2\nDATA binary\n";
  for (int i = 0; i < 4; ++i) {
    append(file, static_cast<float>(i));
    file += std::string(4, '\x7f');
  }
  const auto cloud = scanalign::parsePcd(file);
  EXPECT_EQ(cloud.header.points, 4);  // POINTS defaults to WIDTH * HEIGHT
  ASSERT_EQ(cloud.columns.size(), 1u);
  EXPECT_EQ(values<float>(cloud, "x"), (std::vector<float>{0, 1, 2, 3}));
}

TEST(Pcd, TruncatedPayloads) {
  const auto ascii = asciiFile();
  EXPECT_ERROR(ascii.substr(0, ascii.size() - 12), "truncated");
  const auto binary = binaryFile();
  EXPECT_ERROR(binary.substr(0, binary.size() - 1), "truncated");
  const auto compressed = compressedFile();
  EXPECT_ERROR(compressed.substr(0, compressed.size() - 1), "truncated");
  EXPECT_ERROR(header("binary_compressed") + "abc", "no size header");
}

TEST(Pcd, MalformedHeaders) {
  const auto file = binaryFile();
  EXPECT_ERROR(file.substr(0, 60), "no DATA line");
  EXPECT_ERROR(replaced(file, "DATA binary", "DATA lzma"), "unknown PCD DATA type 'lzma'");
  EXPECT_ERROR(replaced(file, "POINTS 3", "POINTS 4"), "does not equal WIDTH*HEIGHT");
  EXPECT_ERROR(replaced(file, "TYPE F F F U", "TYPE F F Q U"), "field 'z' has unsupported TYPE Q");
  EXPECT_ERROR(replaced(file, "SIZE 4 4 4 2", "SIZE 4 4 4 3"), "field 'label' has unsupported");
  EXPECT_ERROR(replaced(file, "COUNT 1 1 1 1 3 1", "COUNT 1 1 1 1 3"), "lengths differ");
  EXPECT_ERROR(replaced(file, "COUNT 1 1 1 1 3 1", "COUNT 1 1 1 1 0 1"), "field 'hist' has COUNT 0");
  EXPECT_ERROR(replaced(file, "FIELDS", "FIELDZ"), "lacks FIELDS");
  EXPECT_ERROR(replaced(file, "WIDTH 3", "WIDTH three"), "malformed WIDTH");
  EXPECT_ERROR(replaced(file, "VIEWPOINT 1 2 3 1 0 0 0", "VIEWPOINT 1 2"), "VIEWPOINT");
  EXPECT_ERROR(replaced(asciiFile(), "0.125", "zz"), "field 'curvature'");
  EXPECT_ERROR(replaced(asciiFile(), "65535", "65536"), "field 'label'");
}

TEST(Pcd, OversizedHeadersFailBeforeAllocating) {
  // Headers that claim far more data than the file holds: clear errors, no bad_alloc.
  const std::string huge = "4000000000000";
  EXPECT_ERROR(replaced(replaced(binaryFile(), "WIDTH 3", "WIDTH " + huge), "POINTS 3", "POINTS " + huge),
               "truncated");
  EXPECT_ERROR(replaced(replaced(asciiFile(), "WIDTH 3", "WIDTH " + huge), "POINTS 3", "POINTS " + huge),
               "truncated");
  EXPECT_ERROR(replaced(replaced(binaryFile(), "WIDTH 3", "WIDTH 4611686018427387904"), "POINTS 3",
                        "POINTS 4611686018427387904"),
               "impossible");
  // A compressed block whose claimed sizes the few bytes present cannot deliver.
  std::string file = "FIELDS x\nSIZE 4\nTYPE F\nWIDTH 1000000000\nDATA binary_compressed\n";
  append(file, std::uint32_t{4});
  append(file, std::uint32_t{4000000000u});
  EXPECT_ERROR(file + "\x02" "abc", "cannot decompress");
  EXPECT_ERROR(file + "ab", "truncated");
}

TEST(Pcd, ReadPcdNamesTheFile) {
  const std::string path = ::testing::TempDir() + "scanalign_bad.pcd";
  std::ofstream(path, std::ios::binary) << "FIELDS x\n";
  try {
    scanalign::readPcd(path);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
  }
  std::ofstream(path, std::ios::binary) << binaryFile();
  expectKnownContent(scanalign::readPcd(path));
}

// The mesh readers and the PLY header check share the PCD reader's rule (a header's claims are
// checked against the bytes present before anything is read or allocated); here so that the
// sanitizer build (scripts/sanitize.sh) watches them for out-of-bounds reads.
namespace {

std::string meshError(const std::string& bytes, char format) {
  try {
    format == 'o' ? scanalign::parseOff(bytes) : scanalign::parseStl(bytes);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

std::string plyError(const std::string& head, std::uint64_t size) {
  try {
    scanalign::checkPlyHeader(head, size);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(MeshText, OffCountsThatOverflowAreRefusedNotReadPastTheEnd) {
  // nv + nf wraps to a negative number: the old check passed and vertex lines past the end were read.
  EXPECT_NE(meshError("OFF\n9223372036854775807 9223372036854775807 0\n0 0 0\n", 'o').find("truncated"),
            std::string::npos);
  // A face claiming INT64_MAX corners: k + 1 overflowed and indices past the line were read.
  EXPECT_NE(meshError("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n9223372036854775807 0 1 2\n", 'o').find("fewer than"),
            std::string::npos);
  EXPECT_NE(meshError("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 99999999999999999999\n", 'o').find("64-bit"),
            std::string::npos);
  EXPECT_NE(meshError("OFF\n3 1 0\n0 0 inf\n1 0 0\n0 1 0\n3 0 1 2\n", 'o').find("finite"), std::string::npos);
  const auto good = scanalign::parseOff("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(good.vertices, (std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(good.faces, (std::vector<std::int64_t>{0, 1, 2}));
}

TEST(MeshText, StlTruncatedOrLyingIsRefused) {
  std::string binary = "solid but binary";
  binary.resize(80, ' ');
  append(binary, std::uint32_t{2});  // claims 2 triangles, holds 1
  for (float v : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) append(binary, v);
  binary += std::string(2, '\0');
  EXPECT_NE(meshError(binary, 's').find("the header claims 2 triangles"), std::string::npos);
  EXPECT_NE(meshError("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                      "endloop\nendfacet\n", 's').find("endsolid"),
            std::string::npos);
  EXPECT_NE(meshError(std::string(10, '\0'), 's').find("shorter than"), std::string::npos);
}

TEST(MeshText, PlyHeaderCountsAreCheckedAgainstTheFileSize) {
  const std::string head =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  EXPECT_EQ(plyError(head, head.size() + 36 + 13), "no error");
  EXPECT_EQ(plyError(head, head.size() + 36 + 1), "no error");  // the list's items are the reader's business
  EXPECT_NE(plyError(head, head.size() + 36).find("claims 1 'face' elements"), std::string::npos);
  std::string huge = head;
  huge.replace(huge.find("vertex 3"), 8, "vertex 18446744073709551615");
  EXPECT_NE(plyError(huge, huge.size() + 49).find("claims 18446744073709551615 'vertex'"), std::string::npos);
  std::string negative = head;
  negative.replace(negative.find("face 1"), 6, "face -1");
  EXPECT_NE(plyError(negative, 1 << 20).find("count '-1'"), std::string::npos);
  std::string ascii = head;
  ascii.replace(ascii.find("binary_little_endian"), 20, "ascii");
  EXPECT_NE(plyError(ascii, ascii.size() + 7).find("at least 6 bytes"), std::string::npos);
  EXPECT_EQ(plyError("not a ply file\n", 10), "no error");  // left to the reader to report
}
