#include "ropes_core/sha256.hpp"
#include "ropes_core/child_process.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "ropes_core/philox.hpp"

namespace ropes::core {
namespace {

namespace fs = std::filesystem;

std::string hex_of(const std::string& message) {
  return sha256_hex(message.data(), message.size());
}

std::vector<std::uint8_t> random_bytes(std::size_t n, std::uint64_t stream) {
  PhiloxStream rng(/*seed=*/2024, stream);
  std::vector<std::uint8_t> bytes(n);
  for (std::uint8_t& b : bytes)
    b = static_cast<std::uint8_t>(rng.next_u32());
  return bytes;
}

void write_bytes(const fs::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

// Witness: the example messages of FIPS 180-4 (NIST's "SHA256.pdf" and "SHA2_Additional.pdf"
// examples, and FIPS 180-2 appendix B.3 for one million 'a').
TEST(Sha256Golden, MatchesTheNistExampleVectors) {
  EXPECT_EQ(hex_of(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(hex_of("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(hex_of("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),  // 448 bits
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(
      hex_of("abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopq"
             "klmnopqrlmnopqrsmnopqrstnopqrstu"),  // 896 bits
      "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1");
  EXPECT_EQ(hex_of(std::string(1000000, 'a')),
            "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, PiecesOfAnySizeGiveTheOneShotDigest) {
  const std::vector<std::uint8_t> message = random_bytes(5000, 0);
  const std::string one_shot = sha256_hex(message.data(), message.size());
  // odd piece sizes that straddle block boundaries in every way
  for (std::size_t step : {1u, 3u, 7u, 55u, 63u, 65u, 127u, 1001u}) {
    Sha256 hash;
    for (std::size_t at = 0; at < message.size(); at += step)
      hash.update(message.data() + at, std::min(step, message.size() - at));
    EXPECT_EQ(sha256_hex(hash.finish()), one_shot) << "pieces of " << step;
  }
  // every split of a short message into two pieces, with an empty update between them
  for (std::size_t split = 0; split <= 200; ++split) {
    Sha256 hash;
    hash.update(message.data(), split);
    hash.update(nullptr, 0);
    hash.update(message.data() + split, 200 - split);
    EXPECT_EQ(sha256_hex(hash.finish()), sha256_hex(message.data(), 200)) << split;
  }
}

TEST(Sha256, FinishStartsTheNextMessage) {
  Sha256 hash;
  hash.update("abc", 3);
  const auto first = hash.finish();
  hash.update("abc", 3);
  EXPECT_EQ(hash.finish(), first);
  EXPECT_EQ(sha256_hex(hash.finish()), hex_of(""));
}

// Golden: sha256sum (GNU coreutils 9.1) printed this digest once for the 300000 bytes
// (i * 131 + 7) mod 256, written by Python when this test was made.
TEST(Sha256Golden, HashesAFileAsSha256sumDid) {
  std::vector<std::uint8_t> bytes(300000);
  for (std::size_t i = 0; i < bytes.size(); ++i)
    bytes[i] = static_cast<std::uint8_t>(i * 131 + 7);
  const fs::path path = fs::temp_directory_path() / ("ropes_sha256_" + std::to_string(::getpid()));
  write_bytes(path, bytes);
  EXPECT_EQ(sha256_file(path), "9b35fb1e0775edcc797a738ca665031e662abe1ad2d0c1e41a2900290b4c431c");
  fs::remove(path);
}

// Witness: Python's hashlib on files around the block and padding boundaries and one larger
// than sha256_file's 1 MiB chunk.
TEST(Sha256Golden, AgreesWithPythonHashlibOnFiles) {
  if (ropes::core::run_shell("/usr/bin/python3 -c 'import hashlib' 2>/dev/null").rc != 0)
    GTEST_SKIP() << "/usr/bin/python3 is not installed";
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_sha256_python_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<std::size_t> sizes = {0, 1, 55, 56, 57, 63, 64, 65, 119, 120, 1000, 3145745};
  std::string ours, args;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    const fs::path file = dir / std::to_string(i);
    write_bytes(file, random_bytes(sizes[i], i));
    ours += sha256_file(file) + "\n";
    args += " '" + file.string() + "'";
  }
  const fs::path out = dir / "python.txt";
  const std::string command =
      "/usr/bin/python3 -c \"import hashlib, sys\n"
      "for f in sys.argv[1:]: print(hashlib.sha256(open(f, 'rb').read()).hexdigest())\"" +
      args + " > '" + out.string() + "'";
  const ropes::core::ChildResult command_run = ropes::core::run_shell(command);
  ASSERT_EQ(command_run.rc, 0) << command << "\n" << command_run.output;
  std::ifstream in(out);
  const std::string python((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(ours, python);
  fs::remove_all(dir);
}

TEST(Sha256, FileThatCannotBeReadIsNamed) {
  try {
    sha256_file("/nonexistent/dir/data.npy");
    ADD_FAILURE() << "no exception";
  } catch (const FileFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/data.npy: cannot open"),
              std::string::npos)
        << e.what();
  }
  // a directory opens but cannot be read
  EXPECT_THROW(sha256_file(fs::temp_directory_path()), FileFormatError);
}

}  // namespace
}  // namespace ropes::core
