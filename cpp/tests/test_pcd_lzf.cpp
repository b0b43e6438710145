// LZF decompression against streams assembled by hand from the format's definition.
#include <gtest/gtest.h>

#include <string>

#include "scanalign/io/lzf.hpp"

namespace {

std::string decompress(const std::string& stream, std::size_t size) {
  const auto out = scanalign::lzfDecompress(reinterpret_cast<const std::uint8_t*>(stream.data()), stream.size(), size);
  return std::string(out.begin(), out.end());
}

std::string errorOf(const std::string& stream, std::size_t size) {
  try {
    decompress(stream, size);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Lzf, LiteralAndOverlappingReferences) {
  // literal "abc"; length 6 at distance 3 (overlapping); length 3 at distance 1; length 4 at distance 9.
  const std::string stream = std::string("\x02" "abc") + "\x80\x02" + std::string("\x20\x00", 2) + "\x40\x08";
  EXPECT_EQ(decompress(stream, 16), "abcabcabcccc" "abca");
}

TEST(Lzf, LongReferenceWithExtraLengthByte) {
  // literal "xy", then length 7 + 20 + 2 = 29 at distance 2.
  const std::string stream = std::string("\x01xy") + "\xE0\x14\x01";
  std::string expected;
  for (int i = 0; i < 15; ++i) expected += "xy";
  EXPECT_EQ(decompress(stream, 31), expected + "x");
}

TEST(Lzf, EmptyStreamIsEmptyOutput) { EXPECT_EQ(decompress("", 0), ""); }

TEST(Lzf, CorruptStreamsAreRejected) {
  EXPECT_NE(errorOf("\x05" "ab", 6).find("truncated"), std::string::npos);
  EXPECT_NE(errorOf(std::string("\x00" "a", 2) + "\x20\x04", 4).find("before the start"), std::string::npos);
  EXPECT_NE(errorOf("\x02" "abc", 5).find("expected 5"), std::string::npos);
  EXPECT_NE(errorOf("\x02" "abc", 2).find("exceeds"), std::string::npos);
  EXPECT_NE(errorOf(std::string("\x00" "a", 2) + "\xE0", 20).find("truncated"), std::string::npos);
  EXPECT_NE(errorOf(std::string("\x00" "a", 2) + "\x20", 20).find("truncated"), std::string::npos);
}

TEST(Lzf, ImpossibleExpectedSizeIsRejectedBeforeAllocating) {
  // 4 input bytes cannot produce a terabyte: refused by the size bound, not by bad_alloc.
  const std::string message = errorOf("\x02" "abc", std::size_t{1} << 40);
  EXPECT_NE(message.find("cannot decompress"), std::string::npos) << message;
}
