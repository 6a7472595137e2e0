#include "ropes_eval/occlusion.hpp"

#include <ropes_core/philox.hpp>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace ropes::eval {

OcclusionSquare occlusion_square(std::uint64_t seed, std::int64_t sample, std::int64_t camera,
                                 std::int64_t width, std::int64_t height, std::int64_t size) {
  if (size < 1 || size > std::min(width, height) || camera < 0 || camera >= 65536 || sample < 0)
    throw std::invalid_argument(
        "occlusion_square: a square of " + std::to_string(size) + " px in a " +
        std::to_string(width) + "x" + std::to_string(height) + " image, camera " +
        std::to_string(camera) + ", sample " + std::to_string(sample) +
        "; expected 1 <= size <= the image's shorter side, 0 <= camera < 65536, sample >= 0");
  core::PhiloxStream rng(
      seed, (static_cast<std::uint64_t>(sample) << 16) | static_cast<std::uint64_t>(camera));
  // uniform on the corners that keep the square inside: [0, side - size]
  auto corner = [&](std::int64_t side) {
    const std::int64_t places = side - size + 1;
    return std::min<std::int64_t>(
        places - 1, static_cast<std::int64_t>(rng.uniform_double() * static_cast<double>(places)));
  };
  OcclusionSquare s;
  s.size = size;
  s.x = corner(width);
  s.y = corner(height);
  return s;
}

std::vector<std::int64_t> occluded_cameras(std::int64_t cameras,
                                           const std::vector<std::int64_t>& only_cameras) {
  if (only_cameras.empty()) {
    std::vector<std::int64_t> all(static_cast<std::size_t>(std::max<std::int64_t>(cameras, 0)));
    for (std::size_t c = 0; c < all.size(); ++c)
      all[c] = static_cast<std::int64_t>(c);
    return all;
  }
  for (std::int64_t c : only_cameras)
    if (c < 0 || c >= cameras)
      throw std::invalid_argument("occlude: camera " + std::to_string(c) +
                                  " is asked to be occluded; expected a camera in [0, " +
                                  std::to_string(cameras) + ")");
  return only_cameras;
}

void occlude(std::vector<std::uint8_t>& images, const std::vector<std::int64_t>& samples,
             std::int64_t cameras, std::int64_t height, std::int64_t width, std::int64_t size,
             std::uint64_t seed, const std::vector<std::int64_t>& only_cameras) {
  const std::int64_t plane = height * width;
  if (cameras < 1 || height < 1 || width < 1 ||
      static_cast<std::int64_t>(images.size()) !=
          static_cast<std::int64_t>(samples.size()) * cameras * plane)
    throw std::invalid_argument("occlude: " + std::to_string(images.size()) + " bytes for " +
                                std::to_string(samples.size()) + " samples of " +
                                std::to_string(cameras) + " cameras of " + std::to_string(width) +
                                "x" + std::to_string(height) +
                                "; expected samples * cameras * "
                                "height * width");
  const std::vector<std::int64_t> painted = occluded_cameras(cameras, only_cameras);
  for (std::size_t i = 0; i < samples.size(); ++i)
    for (std::int64_t c : painted) {
      const OcclusionSquare s = occlusion_square(seed, samples[i], c, width, height, size);
      std::uint8_t* img = images.data() + (static_cast<std::int64_t>(i) * cameras + c) * plane;
      for (std::int64_t r = s.y; r < s.y + s.size; ++r)
        std::fill(img + r * width + s.x, img + r * width + s.x + s.size, std::uint8_t{255});
    }
}

}  // namespace ropes::eval
