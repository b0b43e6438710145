#include "scanalign/io/lzf.hpp"

#include <stdexcept>
#include <string>

namespace scanalign {

std::vector<std::uint8_t> lzfDecompress(const std::uint8_t* data, std::size_t size, std::size_t expected_size) {
  // A bounded allocation: a corrupt size field must not reserve gigabytes.
  if (expected_size > kLzfMaxExpansion * size)
    throw std::invalid_argument("LZF stream of " + std::to_string(size) + " bytes cannot decompress to the " +
                                "expected " + std::to_string(expected_size) + " bytes");
  std::vector<std::uint8_t> out(expected_size);
  std::size_t ip = 0, op = 0;
  while (ip < size) {
    const unsigned ctrl = data[ip++];
    if (ctrl < 32) {  // literal run
      const std::size_t length = ctrl + 1;
      if (length > size - ip)
        throw std::invalid_argument("LZF literal run at input byte " + std::to_string(ip - 1) + " is truncated");
      if (length > expected_size - op) throw std::invalid_argument("LZF output exceeds the expected size");
      std::copy(data + ip, data + ip + length, out.begin() + static_cast<std::ptrdiff_t>(op));
      ip += length;
      op += length;
      continue;
    }
    std::size_t length = ctrl >> 5;
    if (length == 7) {
      if (ip >= size) throw std::invalid_argument("LZF back-reference is truncated");
      length += data[ip++];
    }
    if (ip >= size) throw std::invalid_argument("LZF back-reference is truncated");
    const std::size_t distance = ((ctrl & 31u) << 8) + data[ip++] + 1;
    length += 2;
    if (distance > op)
      throw std::invalid_argument("LZF back-reference at output byte " + std::to_string(op) +
                                  " points before the start");
    if (length > expected_size - op) throw std::invalid_argument("LZF output exceeds the expected size");
    // Byte by byte on purpose: an overlapping match repeats the bytes it has just written.
    for (std::size_t k = 0; k < length; ++k, ++op) out[op] = out[op - distance];
  }
  if (op != expected_size)
    throw std::invalid_argument("LZF stream decompressed to " + std::to_string(op) + " bytes, expected " +
                                std::to_string(expected_size));
  return out;
}

}  // namespace scanalign
