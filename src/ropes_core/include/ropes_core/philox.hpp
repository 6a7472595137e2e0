#pragma once
/// @file philox.hpp
/// Counter-based random numbers: the Philox4x32-10 bijection of Salmon, Moraes, Dror and
/// Shaw, "Parallel random numbers: as easy as 1, 2, 3" (SC 2011), and PhiloxStream, a
/// seeded stream of uniform and normal numbers built on it.
///
/// Why counter-based: every sample of a dataset or every element of an initialiser draws
/// from its own stream, so results do not depend on thread count, sharding or the order in
/// which work is done. The distributions are implemented here, not with std:: distributions,
/// whose output differs between standard libraries.

#include <array>
#include <cstdint>

namespace ropes::core {

/// Four 32-bit words: the counter and the output of one Philox block.
using PhiloxCounter = std::array<std::uint32_t, 4>;
/// Two 32-bit words: the Philox key.
using PhiloxKey = std::array<std::uint32_t, 2>;

/// One Philox4x32-10 block: 10 rounds applied to `counter` under `key`.
/// Matches the Random123 reference implementation bit for bit (its known-answer vectors are
/// in test/philox_test.cpp). Pure function; cost ~10 multiply rounds.
PhiloxCounter philox4x32_10(const PhiloxCounter& counter, const PhiloxKey& key);

/// A stream of random numbers identified by (seed, stream).
///
/// Layout (the stream splitting contract):
///   key     = { seed & 0xffffffff, seed >> 32 }
///   counter = { block & 0xffffffff, block >> 32, stream & 0xffffffff, stream >> 32 }
/// where `block` counts the Philox blocks this stream has used, from 0. Two streams that
/// differ in seed or stream number never evaluate the same (key, counter) pair, so a program
/// gives each independent unit of work (a dataset sample, a parameter tensor, a thread's
/// chunk) its own stream number and obtains the same numbers whatever order units run in.
/// A stream holds 2^64 blocks of four words.
///
/// Not thread-safe: give each thread its own PhiloxStream.
class PhiloxStream {
 public:
  PhiloxStream(std::uint64_t seed, std::uint64_t stream);

  /// The next 32 random bits.
  std::uint32_t next_u32();

  /// Uniform on [0, 1) with 24 random bits (every float in the result is k / 2^24).
  float uniform_float();

  /// Uniform on [0, 1) with 53 random bits (k / 2^53), from two consecutive words.
  double uniform_double();

  /// Standard normal N(0, 1) by the Box-Muller transform on two uniform_double() values.
  /// Normals come in pairs: the second of a pair is kept and returned by the next call.
  double normal();

  /// Standard normal conditioned on [lower, upper], by rejection from normal(): meant for
  /// intervals holding a fair share of the mass, such as Flax's [-2, 2] initialiser.
  /// Throws std::invalid_argument unless lower < upper and the interval holds at least 1 %
  /// of the mass (ropes_sim's TruncatedNormal handles tails by inversion).
  double truncated_normal(double lower, double upper);

  std::uint64_t seed() const { return seed_; }
  std::uint64_t stream() const { return stream_; }
  /// Number of 32-bit words drawn so far (normal() draws four words per pair).
  std::uint64_t words_drawn() const { return words_drawn_; }

 private:
  void refill();

  std::uint64_t seed_;
  std::uint64_t stream_;
  PhiloxKey key_;
  std::uint64_t block_ = 0;  // next block index to evaluate
  PhiloxCounter buffer_{};   // output of the last block
  int used_ = 4;             // words of buffer_ already handed out
  std::uint64_t words_drawn_ = 0;
  bool has_spare_normal_ = false;
  double spare_normal_ = 0.0;
};

}  // namespace ropes::core
