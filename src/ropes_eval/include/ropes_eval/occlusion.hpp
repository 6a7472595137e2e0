#pragma once
/// @file occlusion.hpp
/// The paper's occlusion test ("Robustness to Occlusion"): at test time a white square of
/// `size` x `size` pixels is painted into every camera image of a sample, at a position drawn
/// by seed. The model never saw occlusions in training.
///
/// Position of the square of (seed, sample, camera): the PhiloxStream (seed, stream) with
/// stream = sample * 2^16 + camera draws the top-left corner x, then y, each uniform on the
/// positions that keep the whole square inside the image. The same seed, sample and camera
/// give the same square whatever order or chunking the samples come in.
#include <cstdint>
#include <vector>

namespace ropes::eval {

/// A square's top-left corner (column x, row y) and side, in pixels.
struct OcclusionSquare {
  std::int64_t x = 0, y = 0, size = 0;
};

/// The square for camera `camera` of sample `sample` (a dataset row) in a width x height
/// image. Throws std::invalid_argument unless 1 <= size <= min(width, height) and
/// 0 <= camera < 65536 (naming the values).
OcclusionSquare occlusion_square(std::uint64_t seed, std::int64_t sample, std::int64_t camera,
                                 std::int64_t width, std::int64_t height, std::int64_t size);

/// Paints the squares into `images`, u8 [samples.size(), cameras, height, width] (row-major,
/// the dataset's layout): every pixel of each camera's square becomes 255. `samples[i]` is
/// the dataset row of image block i. `only_cameras` empty (the paper's test): every camera's
/// image; otherwise only these cameras' (a diagnostic: one camera occluded, the other
/// clean), the squares where they would be with every camera occluded. Throws
/// std::invalid_argument as occlusion_square does, when images.size() is not samples.size() *
/// cameras * height * width, or when a camera of `only_cameras` is not in [0, cameras).
void occlude(std::vector<std::uint8_t>& images, const std::vector<std::int64_t>& samples,
             std::int64_t cameras, std::int64_t height, std::int64_t width, std::int64_t size,
             std::uint64_t seed, const std::vector<std::int64_t>& only_cameras = {});

/// The cameras `occlude` paints for `only_cameras`: [0, cameras) when it is empty, else it,
/// checked as occlude checks it.
std::vector<std::int64_t> occluded_cameras(std::int64_t cameras,
                                           const std::vector<std::int64_t>& only_cameras);

}  // namespace ropes::eval
