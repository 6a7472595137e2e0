#include "ropes_eval/occlusion.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <set>
#include <utility>
#include <vector>

#include "expect_message.hpp"

namespace ropes::eval {
namespace {

using test_support::expect_message;

// every square has the requested side, lies wholly inside the image, and is the same for a
// seed; the corners spread over the whole range of places (a draw stuck at one corner fails)
TEST(Occlusion, SquaresHaveTheRequestedSizeLieInsideAndFollowTheSeed) {
  for (std::int64_t size : {1, 16, 32, 64, 128}) {
    std::set<std::int64_t> xs, ys;
    for (std::int64_t sample = 0; sample < 400; ++sample)
      for (std::int64_t camera = 0; camera < 2; ++camera) {
        const OcclusionSquare s = occlusion_square(7, sample, camera, 128, 128, size);
        EXPECT_EQ(s.size, size);
        EXPECT_GE(s.x, 0);
        EXPECT_GE(s.y, 0);
        EXPECT_LE(s.x + size, 128);
        EXPECT_LE(s.y + size, 128);
        const OcclusionSquare again = occlusion_square(7, sample, camera, 128, 128, size);
        EXPECT_EQ(std::make_pair(s.x, s.y), std::make_pair(again.x, again.y));
        xs.insert(s.x);
        ys.insert(s.y);
      }
    const std::int64_t places = 128 - size + 1;
    // 800 draws over `places` positions: most are hit, and with few places both ends
    EXPECT_GE(static_cast<std::int64_t>(xs.size()), places * 3 / 5) << size;
    EXPECT_GE(static_cast<std::int64_t>(ys.size()), places * 3 / 5) << size;
    if (places <= 65) {
      EXPECT_EQ(*xs.begin(), 0) << size;
      EXPECT_EQ(*xs.rbegin(), 128 - size) << size;
    }
  }
  // a non-square image: the square stays inside the shorter side too
  for (std::int64_t sample = 0; sample < 200; ++sample) {
    const OcclusionSquare s = occlusion_square(1, sample, 0, 40, 20, 16);
    EXPECT_LE(s.x + 16, 40);
    EXPECT_LE(s.y + 16, 20);
  }
  // another seed, sample or camera moves the square
  int moved_seed = 0, moved_camera = 0;
  for (std::int64_t sample = 0; sample < 100; ++sample) {
    const OcclusionSquare a = occlusion_square(7, sample, 0, 128, 128, 32);
    const OcclusionSquare b = occlusion_square(8, sample, 0, 128, 128, 32);
    const OcclusionSquare c = occlusion_square(7, sample, 1, 128, 128, 32);
    moved_seed += a.x != b.x || a.y != b.y;
    moved_camera += a.x != c.x || a.y != c.y;
  }
  EXPECT_GT(moved_seed, 90);
  EXPECT_GT(moved_camera, 90);
}

// occlude paints exactly the square white in every camera image of every sample and leaves
// every other pixel as it was
TEST(Occlusion, PaintsExactlyTheSquareInEveryCameraImage) {
  const std::int64_t cameras = 2, h = 32, w = 48, size = 16;
  const std::vector<std::int64_t> samples = {5, 900, 3};
  std::vector<std::uint8_t> images(samples.size() * cameras * h * w);
  for (std::size_t i = 0; i < images.size(); ++i)
    images[i] = static_cast<std::uint8_t>(i % 200);  // never 255 before
  const std::vector<std::uint8_t> before = images;
  occlude(images, samples, cameras, h, w, size, 3);
  for (std::size_t i = 0; i < samples.size(); ++i)
    for (std::int64_t c = 0; c < cameras; ++c) {
      const OcclusionSquare s = occlusion_square(3, samples[i], c, w, h, size);
      std::int64_t white = 0;
      for (std::int64_t r = 0; r < h; ++r)
        for (std::int64_t x = 0; x < w; ++x) {
          const std::size_t at = static_cast<std::size_t>(
              ((static_cast<std::int64_t>(i) * cameras + c) * h + r) * w + x);
          const bool inside = r >= s.y && r < s.y + size && x >= s.x && x < s.x + size;
          if (inside) {
            EXPECT_EQ(images[at], 255);
            ++white;
          } else {
            EXPECT_EQ(images[at], before[at]);
          }
        }
      EXPECT_EQ(white, size * size);
    }
  // the chunk a sample arrives in does not matter: sample 900 alone gets the same square
  std::vector<std::uint8_t> one(before.begin() + cameras * h * w,
                                before.begin() + 2 * cameras * h * w);
  occlude(one, {900}, cameras, h, w, size, 3);
  EXPECT_TRUE(std::equal(one.begin(), one.end(), images.begin() + cameras * h * w));
}

// one camera occluded: its squares are where they are with every camera occluded, and the
// other camera's images keep every byte
TEST(Occlusion, OneCameraOccludedLeavesTheOtherAsItWas) {
  const std::int64_t cameras = 2, h = 32, w = 32, size = 8;
  const std::vector<std::int64_t> samples = {7, 11};
  std::vector<std::uint8_t> before(samples.size() * cameras * h * w);
  for (std::size_t i = 0; i < before.size(); ++i)
    before[i] = static_cast<std::uint8_t>(i % 200);
  std::vector<std::uint8_t> both = before, first = before;
  occlude(both, samples, cameras, h, w, size, 9);
  occlude(first, samples, cameras, h, w, size, 9, {0});
  const std::size_t plane = static_cast<std::size_t>(h * w);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const std::size_t cam0 = (i * cameras) * plane, cam1 = cam0 + plane;
    EXPECT_TRUE(
        std::equal(first.begin() + cam0, first.begin() + cam0 + plane, both.begin() + cam0));
    EXPECT_TRUE(
        std::equal(first.begin() + cam1, first.begin() + cam1 + plane, before.begin() + cam1));
    EXPECT_FALSE(
        std::equal(both.begin() + cam1, both.begin() + cam1 + plane, before.begin() + cam1));
  }
  EXPECT_EQ(occluded_cameras(3, {}), (std::vector<std::int64_t>{0, 1, 2}));
  expect_message([&] { occlude(first, samples, cameras, h, w, size, 9, {2}); },
                 "camera 2 is asked to be occluded; expected a camera in [0, 2)");
}

TEST(Occlusion, RefusesSquaresThatDoNotFitAndMismatchedBuffers) {
  expect_message([] { occlusion_square(0, 0, 0, 32, 32, 33); }, "33 px in a 32x32 image");
  expect_message([] { occlusion_square(0, 0, 0, 32, 32, 0); }, "expected 1 <= size");
  expect_message([] { occlusion_square(0, 0, 70000, 32, 32, 8); }, "camera 70000");
  std::vector<std::uint8_t> images(10);
  expect_message([&] { occlude(images, {0}, 1, 4, 4, 2, 0); }, "10 bytes for 1 samples");
}

}  // namespace
}  // namespace ropes::eval
