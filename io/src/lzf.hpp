#pragma once
// LZF, the compression of PCD's binary_compressed data (Marc Lehmann's liblzf format, which
// PCL's lzf.cpp implements), written here so that io needs no PCL. The stream is a sequence of
// - a literal run: a control byte c < 32, then c + 1 bytes copied as they are;
// - a back reference: a control byte whose top three bits are a length code L (7: add the next
//   byte), then a byte b: copy L + 2 bytes from ((c & 31) << 8) + b + 1 bytes back in the
//   output (the ranges may overlap).
// Private to io.

#include <cstddef>
#include <cstdint>

namespace nurbsreg::io::detail {

// Compresses in[0, in_size) into out[0, out_capacity): the compressed size, or 0 when it does
// not fit (an output of in_size + in_size / 32 + 1 bytes always does) or in_size is 4 GiB or
// more.
std::size_t lzf_compress(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out,
                         std::size_t out_capacity);

// Decompresses in[0, in_size) into out[0, out_size). Every read and write is bounds-checked:
// false on any inconsistency, and true only when the output is filled exactly.
bool lzf_decompress(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out,
                    std::size_t out_size);

}  // namespace nurbsreg::io::detail
