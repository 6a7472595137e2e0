#pragma once
// A grey 8-bit PNG in memory, uncompressed (deflate's stored blocks), for images inlined in
// report.html as data: URIs. Private to ropes_eval. PNG: ISO/IEC 15948; zlib: RFC 1950/1951.
#include <cstdint>
#include <string>
#include <vector>

namespace ropes::eval::detail {

// PNG bytes of `grey` [height, width], row-major
std::string grey_png(const std::vector<std::uint8_t>& grey, int width, int height);

// RFC 4648 base64
std::string base64(const std::string& bytes);

}  // namespace ropes::eval::detail
