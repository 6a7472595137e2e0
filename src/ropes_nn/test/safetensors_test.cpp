#include "ropes_nn/safetensors.hpp"
#include "ropes_core/child_process.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "ropes_core/philox.hpp"
#include "ropes_nn/checkpoint.hpp"
#include "ropes_nn/layers.hpp"

namespace ropes::nn {
namespace {

namespace fs = std::filesystem;

fs::path scratch_dir(const std::string& leaf) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_st_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / leaf;
}

std::vector<std::uint8_t> file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// a small CNN with named parameters: "0.weight", "1.block.norm1.scale", ...
std::shared_ptr<Sequential> seeded_net(std::uint64_t seed) {
  auto net = std::make_shared<Sequential>();
  net->add(std::make_shared<Conv2d>(1, 4, 3, 2));
  auto inner = std::make_shared<Sequential>();
  inner->add(std::make_shared<ResBlockGN>(4, 2), "block");
  net->add(inner);
  net->add(std::make_shared<ConvTranspose2d>(4, 1, 4, 2));
  net->initialize(seed);
  return net;
}

TEST(Safetensors, ModuleRoundTripIsBitIdentical) {
  const auto saved = seeded_net(1);
  const fs::path path = scratch_dir("net.safetensors");
  save_module(*saved, path, {{"arch", "small_net"}, {"seed", "1"}});
  const auto loaded = seeded_net(2);  // other values, same names and shapes
  const auto metadata = load_module(*loaded, path).metadata;
  EXPECT_EQ(metadata.at("arch"), "small_net");
  const auto a = saved->named_parameters();
  const auto b = loaded->named_parameters();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].first, b[i].first);
    EXPECT_EQ(std::memcmp(a[i].second.data(), b[i].second.data(),
                          static_cast<std::size_t>(a[i].second.numel()) * 4),
              0)
        << a[i].first;
  }
  EXPECT_EQ(a[0].first, "0.weight");
  EXPECT_EQ(a[2].first, "1.block.norm1.scale");
  fs::remove_all(path.parent_path());
}

// Witness: tools/safetensors_io.py, a reader written from the published format with numpy
// only, lists the same names, dtypes, shapes and sums (and, when Debian's python3-torch is
// there, torch.from_numpy takes them as they are).
TEST(SafetensorsGolden, APythonReaderOfThePublishedFormatReadsWhatWeWrite) {
  if (ropes::core::run_shell("/usr/bin/python3 -c 'import numpy' 2>/dev/null").rc != 0) {
    GTEST_SKIP() << "Debian's python3-numpy is not installed";
  }
  const auto net = seeded_net(3);
  const fs::path path = scratch_dir("py.safetensors");
  save_module(*net, path, {{"note", "written by ropes_nn"}});
  // what the reader should print, computed here
  std::ostringstream expected;
  expected << "meta note=written by ropes_nn\n";
  expected << "meta ropes.sha256=" << read_safetensors(path).metadata.at(kSafetensorsSealKey)
           << "\n";
  auto params = net->named_parameters();
  std::sort(params.begin(), params.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  for (const auto& [name, t] : params) {
    double s = 0;
    for (std::int64_t i = 0; i < t.numel(); ++i)
      s += t.data()[i];
    char sum[64];
    std::snprintf(sum, sizeof sum, "%.9g", s);
    expected << name << " F32 [";
    for (int d = 0; d < t.rank(); ++d)
      expected << (d ? ", " : "") << t.shape()[d];
    expected << "] " << sum << "\n";
  }
  const fs::path listing = scratch_dir("listing.txt");
  const std::string command = "/usr/bin/python3 " + std::string(ROPES_NN_TOOLS) +
                              "/safetensors_io.py summary '" + path.string() + "' > '" +
                              listing.string() + "'";
  const ropes::core::ChildResult command_run = ropes::core::run_shell(command);
  ASSERT_EQ(command_run.rc, 0) << command << "\n" << command_run.output;
  std::ifstream in(listing);
  const std::string printed((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(printed, expected.str());

  // the values themselves: the reader saves each tensor with numpy.save (through
  // torch.from_numpy when python3-torch is there) and core::read_npy compares every bit
  const fs::path exported = scratch_dir("exported");
  fs::create_directories(exported);
  const std::string export_command = "/usr/bin/python3 " + std::string(ROPES_NN_TOOLS) +
                                     "/safetensors_io.py export '" + path.string() + "' '" +
                                     exported.string() + "' > /dev/null";
  const ropes::core::ChildResult export_command_run = ropes::core::run_shell(export_command);
  ASSERT_EQ(export_command_run.rc, 0) << export_command << "\n" << export_command_run.output;
  for (const auto& [name, t] : params) {
    const core::NpyArray a = core::read_npy(exported / (name + ".npy"));
    EXPECT_EQ(a.dtype, core::DType::kF32) << name;
    EXPECT_EQ(a.shape, t.shape().dims()) << name;
    ASSERT_EQ(a.data.size(), static_cast<std::size_t>(t.numel()) * 4) << name;
    EXPECT_EQ(std::memcmp(a.data.data(), t.data(), a.data.size()), 0) << name;
  }
  fs::remove_all(path.parent_path());
}

std::string parse_error(const std::vector<std::uint8_t>& bytes) {
  try {
    parse_safetensors(bytes.data(), bytes.size(), "m.safetensors");
  } catch (const core::FileFormatError& e) {
    return e.what();
  }
  return "";
}

std::vector<std::uint8_t> file_with(const std::string& json, std::size_t data_bytes) {
  std::vector<std::uint8_t> out;
  for (int i = 0; i < 8; ++i)
    out.push_back(static_cast<std::uint8_t>(json.size() >> (8 * i)));
  out.insert(out.end(), json.begin(), json.end());
  out.resize(out.size() + data_bytes, 0);
  return out;
}

TEST(Safetensors, RefusesMalformedFilesNamingTheProblem) {
  const std::string ok = R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})";
  EXPECT_EQ(parse_error(file_with(ok, 8)), "");
  EXPECT_NE(parse_error({1, 2, 3}).find("m.safetensors: shorter than"), std::string::npos);
  EXPECT_NE(parse_error(file_with(ok, 4)).find("tensors cover 8 bytes but the file holds 4"),
            std::string::npos);
  EXPECT_NE(parse_error(file_with("{not json", 0)).find("the header is not JSON"),
            std::string::npos);
  EXPECT_NE(parse_error(file_with("[1,2]", 0)).find("not a JSON object"), std::string::npos);
  EXPECT_NE(parse_error(file_with(R"({"a":{"dtype":"BF16","shape":[2],"data_offsets":[0,4]}})", 4))
                .find("has dtype \"BF16\""),
            std::string::npos);
  EXPECT_NE(parse_error(file_with(R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", 8))
                .find("tensor 'a' has data_offsets [0,8] for a F32 [3] tensor of 12 bytes"),
            std::string::npos);
  EXPECT_NE(parse_error(file_with(R"({"a":{"dtype":"U8","shape":[2],"data_offsets":[2,4]}})", 4))
                .find("starts at byte 2; expected 0"),
            std::string::npos);
  EXPECT_NE(parse_error(file_with(R"({"a":{"dtype":"U8","shape":[2]}})", 2)).find("lacks"),
            std::string::npos);
  EXPECT_NE(parse_error(file_with(R"({"__metadata__":{"k":1}})", 0)).find("is not a string"),
            std::string::npos);
  // hostile JSON: a shape nested 200000 deep (refused while parsing: destroying or dumping
  // it would recurse past the stack) and a number beyond double range (nlohmann throws
  // out_of_range, not parse_error)
  std::string deep = R"({"a":{"dtype":"F32","shape":)";
  deep += std::string(200000, '[') + std::string(200000, ']') + R"(,"data_offsets":[0,0]}})";
  EXPECT_NE(parse_error(file_with(deep, 0)).find("the header nests deeper than 64 levels"),
            std::string::npos);
  EXPECT_NE(parse_error(file_with(R"({"a":1e999})", 0)).find("the header is not JSON"),
            std::string::npos);
  // a header length far beyond the file or the limit is refused before any allocation
  std::vector<std::uint8_t> huge = {0, 0, 0, 0, 0, 0, 0, 0x7f};
  EXPECT_NE(parse_error(huge).find("exceeds the limit"), std::string::npos);
  std::vector<std::uint8_t> past = {0xff, 0, 0, 0, 0, 0, 0, 0, '{', '}'};
  EXPECT_NE(parse_error(past).find("runs past the end"), std::string::npos);
}

TEST(Safetensors, LoadModuleRefusesAMismatchAndChangesNothing) {
  const auto a = seeded_net(4);
  const fs::path path = scratch_dir("a.safetensors");
  save_module(*a, path);
  // a module with another layout: one shape differs
  Sequential other;
  other.add(std::make_shared<Conv2d>(1, 5, 3, 2));
  other.initialize(9);
  const std::vector<float> before = other.parameters()[0].to_vector();
  try {
    load_module(other, path);
    ADD_FAILURE() << "loaded a mismatched file";
  } catch (const core::FileFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("tensor '0.weight' is f32 [4, 1, 3, 3]; parameter "
                                         "'0.weight' is f32 [5, 1, 3, 3]"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(other.parameters()[0].to_vector(), before);
  fs::remove_all(path.parent_path());
}

// Fuzz: truncations and random corruptions parse or give core::FileFormatError, nothing else.
TEST(Safetensors, TruncatedAndCorruptedFilesGiveFileFormatErrorsOnly) {
  const auto net = seeded_net(5);
  const fs::path path = scratch_dir("f.safetensors");
  save_module(*net, path, {{"k", "v"}});
  const std::vector<std::uint8_t> good = file_bytes(path);
  for (std::size_t n = 0; n < good.size(); n += 7) {
    EXPECT_THROW(parse_safetensors(good.data(), n, "cut"), core::FileFormatError) << n;
  }
  core::PhiloxStream rng(7, 0);
  int refused = 0;
  const std::size_t header_end = 8 + (good[0] | (good[1] << 8) | (good[2] << 16));
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<std::uint8_t> bad = good;
    // mostly in the header, where the structure is
    const std::size_t span = trial % 4 == 0 ? bad.size() : header_end;
    bad[rng.next_u32() % span] = static_cast<std::uint8_t>(rng.next_u32());
    try {
      parse_safetensors(bad.data(), bad.size(), "bad");
    } catch (const core::FileFormatError&) {
      ++refused;
    }
  }
  EXPECT_GT(refused, 500);
  fs::remove_all(path.parent_path());
}

// A sealed file: the seal is the SHA-256 of the file with its 64 digits read as '0'
// (witness: coreutils' sha256sum of that image), and a change to any one byte of it, header
// or data, is refused, but for the seal's own key (an intact unsealed file then); the seal's
// entry cannot be set by hand.
TEST(Safetensors, ASealedFileIsRefusedWhenAnyByteChanged) {
  const auto net = seeded_net(9);
  const fs::path path = scratch_dir("sealed.safetensors");
  save_module(*net, path, {{"k", "v"}});
  const std::vector<std::uint8_t> good = file_bytes(path);
  const Safetensors parsed = parse_safetensors(good.data(), good.size(), "good");
  ASSERT_TRUE(is_sealed(parsed));
  const std::string seal = parsed.metadata.at(kSafetensorsSealKey);
  ASSERT_EQ(seal.size(), 64u);

  std::string image(good.begin(), good.end());
  const auto at = image.find(seal);
  ASSERT_NE(at, std::string::npos);
  image.replace(at, 64, std::string(64, '0'));
  const fs::path zeroed = scratch_dir("zeroed.bin");
  std::ofstream(zeroed, std::ios::binary) << image;
  const fs::path sum = scratch_dir("sum.txt");
  const std::string command = "sha256sum '" + zeroed.string() + "' > '" + sum.string() + "'";
  const ropes::core::ChildResult command_run = ropes::core::run_shell(command);
  ASSERT_EQ(command_run.rc, 0) << command << "\n" << command_run.output;
  std::ifstream sum_in(sum);
  std::string printed;
  sum_in >> printed;
  EXPECT_EQ(printed, seal);

  // every byte but those of the seal's own key: a change there leaves an unsealed file
  // whose tensors are intact (a checkpoint is refused then: it must be sealed)
  const std::size_t key_at = image.find(std::string("\"") + kSafetensorsSealKey + "\"") + 1;
  std::size_t refused = 0, by_seal = 0;
  for (std::size_t i = 0; i < good.size(); ++i) {
    std::vector<std::uint8_t> bad = good;
    bad[i] ^= 0x01;
    try {
      const Safetensors read = parse_safetensors(bad.data(), bad.size(), "bad");
      EXPECT_TRUE(i >= key_at && i < key_at + 12) << "byte " << i << " changed, not refused";
      EXPECT_FALSE(is_sealed(read));
      for (std::size_t t = 0; t < read.tensors.size(); ++t)
        EXPECT_EQ(read.tensors[t].second.data, parsed.tensors[t].second.data);
    } catch (const core::FileFormatError& e) {
      ++refused;
      by_seal += std::string(e.what()).find("(the file changed after it was written)") !=
                 std::string::npos;
    }
  }
  EXPECT_EQ(refused, good.size() - 12);
  EXPECT_GT(by_seal, good.size() / 2);  // the data bytes, and the header's numbers

  // the seal is the writer's: set by hand it is refused, an unsealed file still reads
  Safetensors f = parsed;
  EXPECT_THROW(serialize_safetensors(f, /*sealed=*/true), std::invalid_argument);
  f.metadata.erase(kSafetensorsSealKey);
  const std::vector<std::uint8_t> plain = serialize_safetensors(f);
  EXPECT_FALSE(is_sealed(parse_safetensors(plain.data(), plain.size(), "plain")));
  // a seal that is not 64 digits is named
  f.metadata[kSafetensorsSealKey] = "abc";
  const std::vector<std::uint8_t> short_seal = serialize_safetensors(f);
  EXPECT_NE(parse_error(short_seal).find("__metadata__['ropes.sha256'] is \"abc\"; expected 64"),
            std::string::npos)
      << parse_error(short_seal);
  fs::remove_all(path.parent_path());
}

}  // namespace
}  // namespace ropes::nn
