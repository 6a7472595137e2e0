#pragma once
/// @file dataset_generator.hpp
/// generate_dataset: the paper's interventional datasets, rendered. For every anchor a of a
/// DatasetConfig, InterventionSampler::sample_anchor(seed, a) gives one configuration per
/// regime (observational, then two interventions per intervened joint); Simbody places the
/// links; every camera of the rig renders every configuration. Row r of the dataset is
/// (anchor r / regimes, regime r % regimes), with columns (ropes_core's dataset container):
///   images  u8  [n, cameras, height, width]   grey, rows top to bottom
///   angles  f32 [n, joints]                   the distribution's joints, radians
///   regime  i32 [n]                           index into the manifest's regime_names
///   anchor  i64 [n]
/// The manifest's metadata records the format, the full config (rig written out), the
/// distribution as read, the URDF's file name and SHA-256, the GL renderer (images are exact
/// for one), the seed, the counts and the camera, joint and regime names, and (since
/// sim_dataset_version 2) "regimes": for each regime {"name", "joint" (a joint name, null
/// when observational), "joint_index" (into joint_names, or null), "intervention" (1 or 2,
/// or null)}, so that a reader never parses a regime's name. Its SHA-256 is
/// the dataset id in every shard marker, so a shard of another dataset (another seed,
/// config or GL) copied into the directory is redone, never mixed in.
///
/// A dataset is a pure function of (config, seed): each anchor draws from its own Philox
/// stream and each image depends only on its configuration and camera, so any thread count
/// and any sharding give the same bytes. Shards are written whole (temporary name and
/// rename) and committed by their marker, so a run killed at any point and run again
/// redoes only the shards without a marker: nothing is lost or duplicated.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "ropes_sim/dataset_config.hpp"

namespace ropes::sim {

/// The dataset directory's layout, on top of the container's (manifest.json, shards/):
/// DIR/generation.json holds the metadata from the first run, so that a rerun can tell
/// its own unfinished dataset from a different one.
inline constexpr const char* kGenerationFile = "generation.json";
/// 2: the metadata's "regimes". 3: the distribution files' TN(mean, x) is read as the paper
/// defines it, x a variance (`variance`, or `std` for a standard deviation); up to 2 the
/// same numbers were standard deviations, so those datasets are not the paper's.
/// generate_dataset refuses to resume or reuse a directory holding one (naming the version
/// and what to do), and ropes-train and ropes-eval refuse to read one
/// (ropes_crl/dataset_version.hpp).
inline constexpr int kSimDatasetVersion = 3;
/// The first sim_dataset_version that read TN(mean, x) with x a variance: generate_dataset
/// refuses a directory holding an older one.
inline constexpr int kFirstVarianceReadingVersion = 3;

struct GenerateOptions {
  std::filesystem::path out;
  std::uint64_t seed = 0;
  int threads = 1;
  /// Which shards this run writes: those with index % shard_count == shard_index.
  int shard_index = 0, shard_count = 1;
  /// Called after each shard is written: (shards done in this run, shards this run has,
  /// message). May be empty.
  std::function<void(int, int, const std::string&)> progress;
  /// Asked after each shard is written (and progress called): false stops the run there, with
  /// the shards written so far kept (a later run resumes) and GenerateResult::complete false.
  /// May be empty (the run goes on to the end).
  std::function<bool()> keep_going;
};

struct GenerateResult {
  int shards_written = 0;             // by this run
  int shards_skipped = 0;             // complete before this run
  bool complete = false;              // manifest.json written (now or before)
  std::int64_t images = 0;            // rendered by this run
  std::vector<std::string> warnings;  // the scene's (missing materials, ...)
};

/// How far the link origins of a rig's robot reach in one camera, over every sample of a
/// dataset: the furthest one from the image's centre, in normalised image coordinates (x
/// right, y up; the image is [-1, 1] x [-1, 1]).
struct FramingReach {
  std::string camera, link, regime;
  std::int64_t anchor = 0;
  std::vector<double> angles;  ///< the sample's angles, the distribution's joints in order
  double x = 0, y = 0;         ///< where the link origin lands (NaN behind the camera)
  double reach = 0;            ///< max(|x|, |y|): 1 is the image's edge; infinite behind
  /// how far past the image's edge it lands, in pixels (max over x and y; <= 0: inside)
  double beyond_pixels = 0;
};

/// How far past the image's edge a link origin may land before check_framing refuses the
/// rig: one pixel. A point there is not in the image, but the link's shape around it is: the
/// Panda's 2C rig puts a finger's origin 0.13 px past the edge (reach 1.002) in one sample of
/// small-2c at seed 1, and refusing that would refuse the paper's camera setup for a pixel's
/// fraction.
inline constexpr double kFramingTolerancePixels = 1.0;

/// The framing check of a config's rig (the numbers behind write_extremes_preview): for each
/// camera, the link origin that reaches furthest over every sample (all regimes) of the
/// config's anchors under `seed`. Cost: one forward kinematics per sample (about 5 us).
std::vector<FramingReach> framing_reach(const DatasetConfig& config, std::uint64_t seed);

/// Throws ConfigError when a link origin lands more than kFramingTolerancePixels past a
/// camera's image's edge (or behind the camera) in any sample,
/// naming the config, the rig, the camera, the link, the anchor, the regime, the angles and
/// where it lands; generate_dataset calls it before the directory is touched. A link's shape
/// may still cross the edge where its origin does not: write_extremes_preview shows them.
void check_framing(const DatasetConfig& config, std::uint64_t seed);

/// Generates (or resumes) the dataset in options.out. Throws std::invalid_argument for bad
/// options (threads < 1, shard index outside [0, count)); std::runtime_error naming the
/// directory and the first field that differs when it holds a different dataset (another
/// config, seed or GL), or is not empty and holds no dataset; ConfigError for a camera that
/// sees (almost) none of the robot in anchor 0's observational configuration (naming the
/// camera and its parameters), for a link that leaves a camera's image (check_framing), for
/// a distribution that names a joint the URDF lacks or lacks a movable joint of the URDF, or
/// for shards too many or too large; ModelError/MeshError/
/// RenderError from loading. All of these are found before the directory is touched. Cost: about a
/// millisecond per 128x128 image of the primitive Panda per thread.
GenerateResult generate_dataset(const DatasetConfig& config, const GenerateOptions& options);

/// Renders anchor `anchor` under `seed` in every regime and camera and writes a PNG contact
/// sheet to `png`: one row per camera, one column per regime, each tile labelled, scaled by
/// `scale` (nearest neighbour). Written through a temporary file and a rename.
void write_preview(const DatasetConfig& config, std::uint64_t seed, std::uint64_t anchor,
                   const std::filesystem::path& png, int scale = 2);

/// The framing check of a rig: over every sample of the config's anchors (all regimes),
/// finds for each camera the samples whose link origins reach furthest left, right, up and
/// down in the image, and writes them as a PNG contact sheet (one row per camera), each
/// tile labelled with the side, how far it reaches (1 is the image's edge) and the anchor.
/// Cost: one FK per sample (about 5 us), then 4 renders per camera.
void write_extremes_preview(const DatasetConfig& config, std::uint64_t seed,
                            const std::filesystem::path& png, int scale = 2);

}  // namespace ropes::sim
