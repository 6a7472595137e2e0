#pragma once
/// @file checkpoint.hpp
/// Module weights and whole training states in .safetensors files.
///
/// save_module / load_module: a module's parameters by dotted name, F32, under an optional
/// prefix; loading is strict (the names match exactly) or not.
///
/// save_checkpoint / load_checkpoint: one file holding everything a training run needs to
/// continue bit for bit (same build, same thread count):
///   tensors   model.<param>                 the module's weights (F32)
///             optimizer.exp_avg.<param>     Adam's first moments, by the optimiser's names
///             optimizer.exp_avg_sq.<param>  second moments
///             optimizer.step.<param>        I64 scalar: the updates that parameter received
///   metadata  "ropes.checkpoint": JSON {"format": "ropes-checkpoint", "format_version": 1,
///             "step", "lr", "adam": {beta1, beta2, eps, weight_decay}, "schedule": the
///             LrSchedule's JSON, "seed", "epoch", "position"}, plus the caller's free-form
///             entries (architecture, config...) under any other key.
/// The weights load alone for inference: load_module(module, file, {"model."}).
/// Files are written to a temporary name, fsync'ed and renamed (core::write_file_atomically): a
/// crash leaves the previous checkpoint or the new one, never half of one. Both kinds of
/// file are sealed (safetensors.hpp: the metadata "ropes.sha256" holds the file's SHA-256),
/// and reading checks the seal, so a file damaged after writing is refused, never loaded.
/// Checkpoints of format_version 1 (before seals) and unsealed weights files still load.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "ropes_core/file_io.hpp"
#include "ropes_nn/adam.hpp"
#include "ropes_nn/lr_schedule.hpp"
#include "ropes_nn/module.hpp"

namespace ropes::nn {

/// Saves every parameter of `module` as F32 under "<prefix><dotted name>", with `metadata`.
/// Sealed. Throws core::FileFormatError naming the file when it cannot be written,
/// std::invalid_argument when `metadata` uses the seal's key "ropes.sha256".
void save_module(const Module& module, const std::filesystem::path& path,
                 const std::map<std::string, std::string>& metadata = {},
                 const std::string& prefix = "");

struct LoadOptions {
  /// Only the file's tensors named "<prefix>..." are considered, the prefix stripped
  /// ("model." reads a checkpoint's weights).
  std::string prefix;
  /// Strict: every parameter must be in the file and every considered tensor must be a
  /// parameter. Not strict: parameters the file lacks keep their values (and stay
  /// uninitialised unless they were initialised before), tensors the module lacks are
  /// ignored; both are listed in the result.
  bool strict = true;
};

struct LoadResult {
  std::map<std::string, std::string> metadata;  ///< the file's metadata, less the seal
  std::vector<std::string> missing;             ///< parameters the file lacked (not strict only)
  std::vector<std::string> unexpected;  ///< considered tensors the module lacks (not strict)
};

/// Loads the parameters of `module` from `path` and marks them initialised. Throws
/// core::FileFormatError naming the file and the tensor when the file cannot be read or parsed,
/// when a tensor has another shape or dtype than its parameter, and (strict) when a
/// parameter is missing or the file holds a tensor the module lacks. Nothing is changed
/// unless every check passes.
LoadResult load_module(Module& module, const std::filesystem::path& path,
                       const LoadOptions& options = {});

/// Where a training run stands besides its weights and optimiser.
struct TrainingProgress {
  std::uint64_t seed = 0;     ///< the run's seed
  std::int64_t epoch = 0;     ///< data cursor: the epoch of the next batch
  std::int64_t position = 0;  ///< and its position in that epoch's order of rows
};

/// The checkpoint's format name and version, as its metadata records them.
inline constexpr const char* kCheckpointFormat = "ropes-checkpoint";
/// 2: sealed (version 1 files, unsealed, still load).
inline constexpr int kCheckpointFormatVersion = 2;
inline constexpr const char* kCheckpointMetadataKey = "ropes.checkpoint";

/// Writes a training state (see the file comment). `adam`'s parameters need not be all of
/// `module`'s (a frozen part), but they are saved by the optimiser's names. Throws
/// std::invalid_argument when `metadata` uses the key "ropes.checkpoint" or "ropes.sha256",
/// core::FileFormatError naming the file when it cannot be written. Removes temporaries of this
/// file left by killed processes. Cost: builds the file in memory (weights + 2 moments) before
/// writing.
void save_checkpoint(const std::filesystem::path& path, const Module& module, const Adam& adam,
                     const LrSchedule& schedule, const TrainingProgress& progress,
                     const std::map<std::string, std::string>& metadata = {});

struct LoadedCheckpoint {
  LrSchedule schedule;  ///< as saved: the resumed run continues its curve at step
  std::int64_t step;    ///< optimiser steps taken (Adam::steps(), the schedule position)
  TrainingProgress progress;
  std::map<std::string, std::string> metadata;  ///< the caller's entries
};

/// Restores a training state into `module` (its weights, strictly) and `adam` (moments, per
/// parameter update counts, step count and hyperparameters, the rate included). Throws
/// core::FileFormatError naming the file and, where one is to blame, the tensor or field: not a
/// checkpoint (no "ropes.checkpoint" metadata), another format version, a truncated or
/// corrupt file, a seal that does not match (or none in a version 2 file), a missing, extra or
/// mis-shaped weight or optimiser tensor (a checkpoint of another architecture), a malformed
/// schedule or cursor. Nothing is changed unless every check passes.
LoadedCheckpoint load_checkpoint(const std::filesystem::path& path, Module& module, Adam& adam);

}  // namespace ropes::nn
