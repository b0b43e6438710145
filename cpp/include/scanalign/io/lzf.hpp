// LZF decompression: the liblzf format PCL uses for `DATA binary_compressed` point clouds.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace scanalign {

/// Largest output an LZF stream of `input_size` bytes can produce: a 3-byte
/// back-reference yields at most 264 bytes, the best ratio any token reaches.
constexpr std::size_t kLzfMaxExpansion = 88;

/// Decompresses an LZF stream into exactly `expected_size` bytes.
///
/// The stream is a sequence of tokens.  A control byte c < 32 starts a literal run of
/// c + 1 bytes copied from the input.  Otherwise c >> 5 is the match length minus 2
/// (7 means "add the next byte"), and ((c & 31) << 8) + next byte + 1 is the distance
/// back into the output; a match may overlap the bytes it produces.
///
/// Throws std::invalid_argument when the stream is truncated, refers before the start
/// of the output, or does not decompress to exactly `expected_size` bytes; an
/// `expected_size` no stream of `size` bytes can reach is rejected before allocating.
std::vector<std::uint8_t> lzfDecompress(const std::uint8_t* data, std::size_t size, std::size_t expected_size);

}  // namespace scanalign
