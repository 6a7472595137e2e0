// Checkpoints: a resumed run is byte-identical to an uninterrupted one (in process, and after
// a real SIGKILL of a training process); weights load alone; a file of another architecture,
// a truncated file or a foreign one is refused by name and changes nothing.
#include "ropes_nn/checkpoint.hpp"

#include "ropes_core/child_process.hpp"
#include "ropes_core/file_io.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "ropes_core/philox.hpp"
#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/safetensors.hpp"
#include "ropes_nn/train_step.hpp"

namespace ropes::nn {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

fs::path scratch(const std::string& leaf) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_ckpt_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / leaf;
}

std::vector<std::uint8_t> bytes_of(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::shared_ptr<Sequential> small_net(int width = 4) {
  auto net = std::make_shared<Sequential>();
  net->add(std::make_shared<Conv2d>(1, width, 3, 2), "conv");
  net->add(std::make_shared<ReLU>());
  net->add(std::make_shared<ConvTranspose2d>(width, 1, 4, 2), "up");
  net->initialize(3);
  return net;
}

// step `step` of a toy run: reconstruct a seeded batch, with a cosine schedule
void train(Sequential& net, Adam& adam, const LrSchedule& schedule, std::int64_t from,
           std::int64_t to) {
  for (std::int64_t step = from; step < to; ++step) {
    core::PhiloxStream rng(5, static_cast<std::uint64_t>(step));
    std::vector<float> v(8 * 64);
    for (float& x : v)
      x = rng.uniform_float();
    const Tensor x(Shape{8, 1, 8, 8}, v);
    StepOptions options;
    options.micro_batches = 2;
    options.schedule = &schedule;
    train_step(adam, mean_loss([&](std::size_t i) {
                 const Tensor xi = slice(x, 0, 4 * static_cast<std::int64_t>(i), 4 * (i + 1));
                 return mean(square(sub(net(xi), xi)), {1, 2, 3});
               }),
               options);
  }
}

TEST(Checkpoint, ResumedRunIsByteIdenticalToAnUninterruptedOne) {
  const LrSchedule schedule = LrSchedule::cosine(1e-2, 12, 1e-4, 3);
  auto whole = small_net();
  Adam adam_whole(whole->named_parameters(), AdamOptions{1e-2});
  train(*whole, adam_whole, schedule, 0, 12);
  const fs::path end_whole = scratch("whole.safetensors");
  save_checkpoint(end_whole, *whole, adam_whole, schedule, {9, 1, 4});

  auto first = small_net();
  Adam adam_first(first->named_parameters(), AdamOptions{1e-2});
  train(*first, adam_first, schedule, 0, 5);
  const fs::path middle = scratch("middle.safetensors");
  save_checkpoint(middle, *first, adam_first, schedule, {9, 0, 40}, {{"architecture", "small"}});

  // a fresh process would build the net from another seed and another schedule
  auto resumed = small_net();
  resumed->initialize(77);
  Adam adam_resumed(resumed->named_parameters(), AdamOptions{5.0, 0.5, 0.6, 1e-3});
  const LoadedCheckpoint c = load_checkpoint(middle, *resumed, adam_resumed);
  EXPECT_EQ(c.step, 5);
  EXPECT_EQ(adam_resumed.steps(), 5);
  EXPECT_EQ(c.schedule, schedule);
  EXPECT_EQ(c.progress.seed, 9u);
  EXPECT_EQ(c.progress.epoch, 0);
  EXPECT_EQ(c.progress.position, 40);
  EXPECT_EQ(c.metadata.at("architecture"), "small");
  EXPECT_EQ(c.metadata.count(kCheckpointMetadataKey), 0u);
  train(*resumed, adam_resumed, c.schedule, c.step, 12);
  const fs::path end_resumed = scratch("resumed.safetensors");
  save_checkpoint(end_resumed, *resumed, adam_resumed, schedule, {9, 1, 4});
  EXPECT_EQ(bytes_of(end_resumed), bytes_of(end_whole));
  fs::remove_all(end_whole.parent_path());
}

// runs `argv` with its stdout and stderr in a pipe; `on_line` sees each line and may kill
// the child; returns the wait status
int run_child(const std::vector<std::string>& argv,
              const std::function<void(core::ChildProcess&, const std::string&)>& on_line,
              std::string* output) {
  core::ChildOptions options;
  options.on_line = on_line;
  core::ChildProcess child(argv, options);
  child.wait();
  *output += child.output();
  return child.status();
}

// The headline: the README's training loop (examples/train_loop.cpp) killed with SIGKILL
// after a checkpoint and started again ends with the same bytes as an uninterrupted run.
TEST(Checkpoint, TrainingProcessKilledWithSigkillResumesToTheSameBytes) {
  const fs::path root = scratch("kill");
  const std::string binary = ROPES_NN_TRAIN_LOOP;
  const std::vector<std::string> flags = {"--steps", "2000",      "--checkpoint-every",
                                          "100",     "--threads", "2"};
  auto command = [&](const fs::path& dir) {
    std::vector<std::string> argv = {binary, dir.string()};
    argv.insert(argv.end(), flags.begin(), flags.end());
    return argv;
  };

  // uninterrupted
  std::string output;
  int status = run_child(command(root / "whole"), nullptr, &output);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;

  // killed right after its first checkpoint, while it trains on
  output.clear();
  status = run_child(
      command(root / "killed"),
      [](core::ChildProcess& child, const std::string& line) {
        if (line == "checkpoint 100\n")
          child.signal(SIGKILL);
      },
      &output);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << output;
  ASSERT_FALSE(fs::exists(root / "killed" / "weights.safetensors"))
      << "the run finished before the kill landed; the test proves nothing";
  ASSERT_TRUE(fs::exists(root / "killed" / "checkpoint.safetensors"));

  // started again: resumes from the checkpoint it left
  output.clear();
  status = run_child(command(root / "killed"), nullptr, &output);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
  long long resumed_at = -1;
  const std::size_t resumed = output.find("resumed at step ");
  ASSERT_NE(resumed, std::string::npos) << output;
  ASSERT_EQ(std::sscanf(output.c_str() + resumed, "resumed at step %lld", &resumed_at), 1)
      << output;
  EXPECT_GE(resumed_at, 100);
  EXPECT_LT(resumed_at, 2000);
  std::printf("killed after checkpoint 100, resumed at step %lld\n", resumed_at);

  for (const char* file : {"weights.safetensors", "checkpoint.safetensors"}) {
    const std::vector<std::uint8_t> a = bytes_of(root / "whole" / file);
    ASSERT_FALSE(a.empty()) << file;
    EXPECT_TRUE(a == bytes_of(root / "killed" / file)) << file << " differs after the resume";
  }
  fs::remove_all(root.parent_path());
}

TEST(Checkpoint, WeightsLoadAloneForInferenceWithThePrefix) {
  auto net = small_net();
  Adam adam(net->named_parameters(), AdamOptions{1e-3});
  const fs::path path = scratch("infer.safetensors");
  save_checkpoint(path, *net, adam, LrSchedule::constant(1e-3), {});
  Sequential inference;  // never initialised: a forward throws until the weights load
  inference.add(std::make_shared<Conv2d>(1, 4, 3, 2), "conv");
  inference.add(std::make_shared<ReLU>());
  inference.add(std::make_shared<ConvTranspose2d>(4, 1, 4, 2), "up");
  EXPECT_THROW(inference(Tensor::zeros(Shape{1, 1, 8, 8})), std::logic_error);
  const LoadResult r = load_module(inference, path, {"model."});
  EXPECT_TRUE(r.missing.empty());
  EXPECT_TRUE(r.unexpected.empty());
  EXPECT_TRUE(r.metadata.count(kCheckpointMetadataKey));
  const Tensor x = Tensor::ones(Shape{1, 1, 8, 8});
  EXPECT_EQ(inference(x).to_vector(), (*net)(x).to_vector());

  // without the prefix, strict loading says what to do
  Sequential other;
  other.add(std::make_shared<Conv2d>(1, 4, 3, 2), "conv");
  try {
    load_module(other, path);
    ADD_FAILURE() << "loaded a checkpoint's weights without the prefix";
  } catch (const core::FileFormatError& e) {
    EXPECT_CONTAINS(e.what(),
                    "has no tensor 'conv.weight' for parameter 'conv.weight' (the file "
                    "has 'model.conv.weight': load with the prefix \"model.\"?)");
  }
  // not strict: a part of the network, the rest listed
  const LoadResult part = load_module(other, path, {"model.", false});
  EXPECT_EQ(part.unexpected, (std::vector<std::string>{"up.weight", "up.bias"}));
  EXPECT_TRUE(part.missing.empty());
  EXPECT_TRUE(other.uninitialized_parameters().empty());
  fs::remove_all(path.parent_path());
}

TEST(Checkpoint, NonStrictLoadLeavesMissingParametersUninitialised) {
  Sequential conv_only;
  conv_only.add(std::make_shared<Conv2d>(1, 4, 3, 2), "conv");
  conv_only.initialize(1);
  const fs::path path = scratch("part.safetensors");
  save_module(conv_only, path);
  Sequential larger;
  larger.add(std::make_shared<Conv2d>(1, 4, 3, 2), "conv");
  larger.add(std::make_shared<ConvTranspose2d>(4, 1, 4, 2), "up");
  const LoadResult r = load_module(larger, path, {"", false});
  EXPECT_EQ(r.missing, (std::vector<std::string>{"up.weight", "up.bias"}));
  EXPECT_EQ(larger.uninitialized_parameters(), r.missing);
  try {
    larger(Tensor::zeros(Shape{1, 1, 8, 8}));
    ADD_FAILURE() << "a half-loaded module ran";
  } catch (const std::logic_error& e) {
    EXPECT_CONTAINS(e.what(), "parameter 'up.weight' was never initialised");
  }
  fs::remove_all(path.parent_path());
}

// another architecture, truncation, a weights file, a damaged state: named, nothing changed
TEST(Checkpoint, RefusesFilesThatDoNotMatchAndChangesNothing) {
  auto net = small_net();
  Adam adam(net->named_parameters(), AdamOptions{1e-3});
  train(*net, adam, LrSchedule::constant(1e-3), 0, 2);
  const fs::path good = scratch("good.safetensors");
  save_checkpoint(good, *net, adam, LrSchedule::constant(1e-3), {1, 0, 0});

  auto target = small_net();
  Adam target_adam(target->named_parameters(), AdamOptions{1e-3});
  const std::vector<float> weights = target->parameters()[0].to_vector();
  auto error_loading = [&](const fs::path& path, Sequential& module, Adam& optimizer) {
    try {
      load_checkpoint(path, module, optimizer);
    } catch (const core::FileFormatError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };

  // wider: every tensor mis-shaped; the first is named
  auto wide = small_net(6);
  Adam wide_adam(wide->named_parameters(), AdamOptions{1e-3});
  EXPECT_CONTAINS(error_loading(good, *wide, wide_adam),
                  good.string() +
                      ": tensor 'model.conv.weight' is f32 [4, 1, 3, 3]; parameter "
                      "'conv.weight' is f32 [6, 1, 3, 3]");
  // a module with a parameter the file lacks, and one without a parameter the file has
  Sequential more;
  more.add(std::make_shared<Conv2d>(1, 4, 3, 2), "conv");
  more.add(std::make_shared<ReLU>());
  more.add(std::make_shared<ConvTranspose2d>(4, 1, 4, 2), "up");
  more.add(std::make_shared<Conv2d>(1, 1, 1), "extra");
  Adam more_adam(more.named_parameters(), AdamOptions{1e-3});
  EXPECT_CONTAINS(error_loading(good, more, more_adam),
                  "has no tensor 'model.extra.weight' for parameter 'extra.weight'");
  Sequential fewer;
  fewer.add(std::make_shared<Conv2d>(1, 4, 3, 2), "conv");
  Adam fewer_adam(fewer.named_parameters(), AdamOptions{1e-3});
  EXPECT_CONTAINS(error_loading(good, fewer, fewer_adam),
                  "holds tensor 'model.up.weight', which the module does not have");
  // the optimiser over part of the module: its state for the rest is foreign
  Adam partial(std::vector<std::pair<std::string, Tensor>>{target->named_parameters()[0]},
               AdamOptions{1e-3});
  EXPECT_CONTAINS(error_loading(good, *target, partial),
                  "holds optimiser state 'optimizer.exp_avg.conv.bias' for a parameter the "
                  "optimiser does not have");

  // truncated anywhere
  const std::vector<std::uint8_t> bytes = bytes_of(good);
  const fs::path cut = scratch("cut.safetensors");
  for (std::size_t n :
       {std::size_t{0}, std::size_t{7}, std::size_t{100}, bytes.size() / 2, bytes.size() - 1}) {
    core::write_file_atomically(cut, bytes.data(), n);
    EXPECT_CONTAINS(error_loading(cut, *target, target_adam), cut.string() + ": ");
  }
  // a weights file is not a checkpoint
  const fs::path weights_only = scratch("weights.safetensors");
  save_module(*net, weights_only);
  EXPECT_CONTAINS(error_loading(weights_only, *target, target_adam),
                  "is not a training checkpoint (no \"ropes.checkpoint\" metadata); a weights "
                  "file loads with load_module");

  // a damaged training state, field by field
  // (each damaged copy is sealed anew, so that the field, not the seal, is what is refused)
  Safetensors file = read_safetensors(good);
  file.metadata.erase(kSafetensorsSealKey);
  auto with_state = [&](const std::string& json) {
    Safetensors f = file;
    f.metadata[kCheckpointMetadataKey] = json;
    const fs::path p = scratch("state.safetensors");
    write_safetensors(p, f, /*sealed=*/true);
    return error_loading(p, *target, target_adam);
  };
  const std::string state = file.metadata.at(kCheckpointMetadataKey);
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = state;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from << " in " << s;
    return s.replace(at, from.size(), to);
  };
  EXPECT_CONTAINS(with_state("{"), "metadata[\"ropes.checkpoint\"] is not JSON");
  // a version 2 checkpoint without its seal; a version 1 one (before seals) still loads
  const fs::path unsealed = scratch("unsealed.safetensors");
  write_safetensors(unsealed, file);
  EXPECT_CONTAINS(error_loading(unsealed, *target, target_adam),
                  unsealed.string() + ": has no seal (metadata 'ropes.sha256')");
  {
    Safetensors v1 = file;
    std::string& json = v1.metadata[kCheckpointMetadataKey];
    const auto at = json.find("\"format_version\":2");
    ASSERT_NE(at, std::string::npos) << json;
    json.replace(at, 18, "\"format_version\":1");
    write_safetensors(unsealed, v1);
    auto other = small_net();
    Adam other_adam(other->named_parameters(), AdamOptions{1e-3});
    EXPECT_EQ(error_loading(unsealed, *other, other_adam), "no error");
  }
  // one byte of the saved weights changed: refused by the seal
  {
    std::vector<std::uint8_t> damaged = bytes_of(good);
    damaged[damaged.size() - 40] ^= 0x10;
    core::write_file_atomically(unsealed, damaged.data(), damaged.size());
    EXPECT_CONTAINS(error_loading(unsealed, *target, target_adam), "; its seal records ");
  }
  EXPECT_CONTAINS(with_state(replaced("\"format_version\":2", "\"format_version\":3")),
                  "format_version is 3; expected 1 or 2");
  EXPECT_CONTAINS(with_state(replaced("\"epoch\":0", "\"epoch\":-3")),
                  "metadata[\"ropes.checkpoint\"].epoch is -3; expected an integer >= 0");
  EXPECT_CONTAINS(with_state(replaced("\"kind\":\"constant\",\"lr\":0.001",
                                      "\"kind\":\"constant\",\"lr\":-1.0")),
                  "metadata[\"ropes.checkpoint\"].schedule.lr is -1.0; expected a finite rate > 0");
  EXPECT_CONTAINS(with_state(replaced("\"beta1\":0.9", "\"beta1\":1.5")), ".adam: ");

  EXPECT_CONTAINS(with_state(replaced("\"seed\":1", "\"seed\":-1")),
                  "metadata[\"ropes.checkpoint\"].seed is -1; expected an integer >= 0");
  // tensors that belong to no part of the state
  Safetensors foreign = file;
  core::NpyArray extra;
  extra.dtype = core::DType::kF32;
  extra.data.resize(4);
  foreign.tensors.emplace_back("ema.conv.weight", extra);
  const fs::path foreign_path = scratch("foreign.safetensors");
  write_safetensors(foreign_path, foreign, /*sealed=*/true);
  EXPECT_CONTAINS(error_loading(foreign_path, *target, target_adam),
                  "holds tensor 'ema.conv.weight', which is neither model.* nor optimizer.*");
  // a parameter's update count beyond the checkpoint's step
  Safetensors counted = file;
  for (auto& [key, array] : counted.tensors) {
    if (key == "optimizer.step.conv.weight") {
      const std::int64_t too_many = 3;
      std::memcpy(array.data.data(), &too_many, sizeof(too_many));
    }
  }
  const fs::path counted_path = scratch("counted.safetensors");
  write_safetensors(counted_path, counted, /*sealed=*/true);
  EXPECT_CONTAINS(
      error_loading(counted_path, *target, target_adam),
      "tensor 'optimizer.step.conv.weight' is 3; expected 0..2 (the checkpoint's step)");
  // not strict still refuses a mis-shaped tensor
  auto wider = small_net(6);
  try {
    load_module(*wider, good, {"model.", false});
    ADD_FAILURE() << "a mis-shaped tensor loaded";
  } catch (const core::FileFormatError& e) {
    EXPECT_CONTAINS(e.what(), "tensor 'model.conv.weight' is f32 [4, 1, 3, 3]");
  }

  // after all of that, nothing changed
  EXPECT_EQ(target->parameters()[0].to_vector(), weights);
  EXPECT_EQ(target_adam.steps(), 0);
  EXPECT_EQ(target_adam.first_moment(0), std::vector<float>(target_adam.first_moment(0).size()));
  fs::remove_all(good.parent_path());
}

TEST(Checkpoint, SavingIsAtomicAndLeavesNoTemporaries) {
  auto net = small_net();
  Adam adam(net->named_parameters(), AdamOptions{1e-3});
  const fs::path path = scratch("atomic.safetensors");
  save_checkpoint(path, *net, adam, LrSchedule::constant(1e-3), {});
  const std::vector<std::uint8_t> before = bytes_of(path);
  // a temporary of a dead process (pid 2^22 + 1 is above Linux's pid_max default) goes
  const fs::path stale = path.string() + ".tmp.4194305";
  { std::ofstream(stale) << "half a checkpoint"; }
  // a failed save (metadata key reserved) leaves the old file as it was
  EXPECT_THROW(save_checkpoint(path, *net, adam, LrSchedule::constant(1e-3), {},
                               {{kCheckpointMetadataKey, "x"}}),
               std::invalid_argument);
  EXPECT_EQ(bytes_of(path), before);
  EXPECT_THROW(save_checkpoint(path, *net, adam, LrSchedule::constant(1e-3), {0, -1, 0}),
               std::invalid_argument);
  save_checkpoint(path, *net, adam, LrSchedule::constant(1e-3), {});
  EXPECT_FALSE(fs::exists(stale));
  for (const auto& entry : fs::directory_iterator(path.parent_path()))
    EXPECT_EQ(entry.path().string().find(".tmp."), std::string::npos) << entry.path();
  // a directory that cannot be written: core::FileFormatError naming the file
  EXPECT_THROW(
      save_checkpoint("/proc/ropes/none.safetensors", *net, adam, LrSchedule::constant(1e-3), {}),
      core::FileFormatError);
  fs::remove_all(path.parent_path());
}

}  // namespace
}  // namespace ropes::nn
