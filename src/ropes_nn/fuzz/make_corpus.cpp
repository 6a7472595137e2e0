// ropes_nn_fuzz_make_corpus DIR: writes the seed corpora of ropes_nn's checkpoint and
// safetensors harnesses and of ropes_core's dataset harness into DIR/<harness>/ (fuzz/corpus/
// of each package holds what it wrote; ropes_core's npy corpus is numpy's files from its
// test/fixtures). Run by hand when a format changes; the seeds
// of an older format stay (checkpoint/training_state.safetensors and weights.safetensors are
// format_version 1, unsealed; the *_sealed ones and safetensors/sealed.safetensors are what
// this writes now).
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz_module.hpp"
#include "ropes_core/dataset.hpp"
#include "ropes_core/fuzz_input.hpp"
#include "ropes_nn/checkpoint.hpp"
#include "ropes_nn/safetensors.hpp"

namespace fs = std::filesystem;
using namespace ropes::nn;
using namespace ropes::core;

namespace {

std::string slurp(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void put(const fs::path& file, const std::string& bytes) {
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << bytes;
  std::printf("%s (%zu bytes)\n", file.c_str(), bytes.size());
}

NpyArray f32(std::vector<std::int64_t> shape, std::vector<float> values) {
  NpyArray a;
  a.dtype = DType::kF32;
  a.shape = std::move(shape);
  a.data.resize(values.size() * sizeof(float));
  std::memcpy(a.data.data(), values.data(), a.data.size());
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const fs::path out = argv[1];
  const fs::path tmp = out / "tmp";
  fs::create_directories(tmp);

  // checkpoint: a whole training state, and a weights file
  auto net = ropes::nn::fuzz::fuzz_module();
  net->initialize(7);
  Adam adam(net->named_parameters());
  save_checkpoint(tmp / "c.safetensors", *net, adam, LrSchedule::cosine(1e-3, 100, 1e-5, 10),
                  {7, 2, 5}, {{"architecture", "fuzz"}});
  put(out / "checkpoint" / "training_state.safetensors", slurp(tmp / "c.safetensors"));
  save_module(*net, tmp / "w.safetensors", {{"stage", "ae1"}}, "model.");
  put(out / "checkpoint" / "weights.safetensors", slurp(tmp / "w.safetensors"));

  // safetensors: two tensors and metadata
  Safetensors file;
  file.tensors.push_back({"a", f32({2, 2}, {1, 2, 3, 4})});
  file.tensors.push_back({"b", f32({}, {0.5f})});
  file.metadata["key"] = "value";
  const std::vector<std::uint8_t> bytes = serialize_safetensors(file);
  put(out / "safetensors" / "two_tensors.safetensors", std::string(bytes.begin(), bytes.end()));

  // dataset: 3 rows of x f32 [2] and y u8 [], one shard
  const fs::path ds = tmp / "dataset";
  const std::vector<ColumnSpec> columns = {{"x", DType::kF32, {2}}, {"y", DType::kU8, {}}};
  NpyArray y;
  y.dtype = DType::kU8;
  y.shape = {3};
  y.data = {1, 2, 3};
  write_dataset_shard(ds, 0, columns, {f32({3, 2}, {0, 1, 2, 3, 4, 5}), y}, "fuzz");
  write_dataset_manifest(ds, columns, 1, R"({"robot": "none"})", "fuzz");
  put(out / "dataset" / "three_rows.txt",
      ropes::core::fuzz::join_sections({{"", slurp(ds / "manifest.json")},
                                        {"marker", slurp(ds / "shards" / "00000.json")},
                                        {"x", slurp(ds / "shards" / "x-00000.npy")},
                                        {"y", slurp(ds / "shards" / "y-00000.npy")}}));
  fs::remove_all(tmp);
  return 0;
}
