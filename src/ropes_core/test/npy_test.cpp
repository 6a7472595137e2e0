#include "ropes_core/npy.hpp"
#include "ropes_core/child_process.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_core/plain_name.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "ropes_core/philox.hpp"

namespace ropes::core {
namespace {

namespace fs = std::filesystem;

// fixtures written by numpy 1.24 (test/make_npy_fixtures.py): the witness for both directions
const fs::path kFixtures = ROPES_CORE_TEST_FIXTURES;

std::vector<std::uint8_t> file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// one array per fixture, built here from the same formulas the script uses
std::vector<std::pair<std::string, NpyArray>> expected_arrays() {
  std::vector<float> f32(24);
  for (int i = 0; i < 24; ++i)
    f32[i] = (static_cast<float>(i) - 11.5f) / 4.0f;
  return {
      {"u8_2x3.npy", make_npy_array<std::uint8_t>(DType::kU8, {2, 3}, {0, 40, 80, 120, 160, 200})},
      {"i32_4.npy", make_npy_array<std::int32_t>(DType::kI32, {4}, {-2, -1, 0, 2147483647})},
      {"i64_2x2.npy",
       make_npy_array<std::int64_t>(DType::kI64, {2, 2}, {-(1ll << 40), 1, 2, 1ll << 62})},
      {"f32_2x3x4.npy", make_npy_array<float>(DType::kF32, {2, 3, 4}, f32)},
      {"f64_scalar.npy", make_npy_array<double>(DType::kF64, {}, {M_PI})},
      {"f32_0.npy", make_npy_array<float>(DType::kF32, {0}, {})},
  };
}

TEST(NpyGolden, ReadsWhatNumpyWrote) {
  for (const auto& [name, expected] : expected_arrays()) {
    const NpyArray a = read_npy(kFixtures / name);
    EXPECT_EQ(a.dtype, expected.dtype) << name;
    EXPECT_EQ(a.shape, expected.shape) << name;
    EXPECT_EQ(a.data, expected.data) << name;
  }
  EXPECT_EQ(npy_values<double>(read_npy(kFixtures / "f64_scalar.npy"))[0], M_PI);
}

TEST(NpyGolden, WritesTheBytesNumpyWrites) {
  for (const auto& [name, expected] : expected_arrays()) {
    EXPECT_EQ(serialize_npy(expected), file_bytes(kFixtures / name)) << name;
  }
}

TEST(Npy, RoundTripsThroughAFileAndLeavesNoTemporary) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_npy_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const auto& [name, expected] : expected_arrays()) {
    write_npy(dir / name, expected);
    const NpyArray back = read_npy(dir / name);
    EXPECT_EQ(back.shape, expected.shape);
    EXPECT_EQ(back.data, expected.data);
    const NpyHeader header = read_npy_header(dir / name);
    EXPECT_EQ(header.data_offset % 64, 0u);
    EXPECT_EQ(header.data_bytes, expected.data.size());
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 6);
  fs::remove_all(dir);
}

// A symbolic link where the temporary or the file goes is never written through: its target
// keeps its bytes, the file is written, and no link or temporary is left
TEST(Npy, WritingNeverFollowsALinkAtTheTemporaryOrTheFile) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_npy_link_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "out");
  const fs::path target = dir / "outside.txt";
  std::ofstream(target) << "not yours";
  const std::uint8_t bytes[] = {1, 2, 3};
  const fs::path file = dir / "out" / "a.npy";
  fs::create_symlink(target, file.string() + ".tmp." + std::to_string(::getpid()));
  write_file_atomically(file, bytes, sizeof bytes);
  EXPECT_EQ(file_bytes(file), std::vector<std::uint8_t>({1, 2, 3}));
  const fs::path link = dir / "out" / "b.npy";
  fs::create_symlink(target, link);
  write_file_atomically(link, bytes, sizeof bytes);
  EXPECT_FALSE(fs::is_symlink(link));
  EXPECT_EQ(file_bytes(link), std::vector<std::uint8_t>({1, 2, 3}));
  std::ifstream in(target);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "not yours");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "out"), fs::directory_iterator()), 2);
  fs::remove_all(dir);
}

std::string text_file_error(const fs::path& path, std::uint64_t limit) {
  try {
    read_text_file(path, limit);
  } catch (const FileFormatError& e) {
    return e.what();
  }
  return "no error";
}

// read_text_file: a 2 GiB file (sparse: no disk used) is refused by its size before it is
// read; a directory and a missing file are named
TEST(TextFile, RefusesAFileOverItsLimitBeforeReadingIt) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_text_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path big = dir / "big.json";
  std::ofstream(big) << "\"";
  fs::resize_file(big, std::uint64_t{2} << 30);
  EXPECT_EQ(text_file_error(big, kMaxJsonFileBytes),
            big.string() +
                ": holds 2147483648 bytes; expected at most 16777216 for a file of "
                "this kind");
  EXPECT_NE(text_file_error(dir, 100).find(dir.string() + ": is not a regular file"),
            std::string::npos);
  EXPECT_NE(text_file_error(dir / "none.json", 100).find(": cannot open: No such file"),
            std::string::npos);
  const fs::path small = dir / "small.json";
  std::ofstream(small) << "{\"a\": 1}";
  EXPECT_EQ(read_text_file(small, 8), "{\"a\": 1}");
  EXPECT_NE(text_file_error(small, 7).find("holds 8 bytes; expected at most 7"), std::string::npos);
  fs::remove_all(dir);
}

// the names tools make directories of: never a path
TEST(TextFile, PlainNamesAreNeverPaths) {
  for (const char* good : {"1c-tiny", "small-2c_causal", "a.b", "x"})
    EXPECT_TRUE(is_plain_name(good)) << good;
  for (const char* bad : {"", ".", "..", "../x", "/etc", "a/b", ".hidden", "a b", "a\\b"})
    EXPECT_FALSE(is_plain_name(bad)) << bad;
  EXPECT_TRUE(is_plain_name(std::string(128, 'a')));
  EXPECT_FALSE(is_plain_name(std::string(129, 'a')));
  EXPECT_FALSE(is_plain_name("abcd", 3));
}

// numpy itself opens what write_npy wrote, with the dtype and values of the fixture it made
TEST(NpyGolden, NumpyLoadsWhatWeWrite) {
  if (ropes::core::run_shell("/usr/bin/python3 -c 'import numpy' 2>/dev/null").rc != 0) {
    GTEST_SKIP() << "Debian's python3-numpy is not installed (ci/install-deps installs it)";
  }
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_npy_numpy_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const auto& [name, expected] : expected_arrays())
    write_npy(dir / name, expected);
  const std::string script =
      "import numpy as np, pathlib, sys\n"
      "ours, ref = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])\n"
      "for f in sorted(ref.glob('*.npy')):\n"
      "    a, b = np.load(ours / f.name), np.load(f)\n"
      "    assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), f.name\n"
      "print('numpy read', len(list(ref.glob('*.npy'))), 'files')\n";
  const std::string command =
      "/usr/bin/python3 -c \"" + script + "\" '" + dir.string() + "' '" + kFixtures.string() + "'";
  const ropes::core::ChildResult command_run = ropes::core::run_shell(command);
  EXPECT_EQ(command_run.rc, 0) << command << "\n" << command_run.output;
  fs::remove_all(dir);
}

std::string npy_error_of(const std::vector<std::uint8_t>& bytes) {
  try {
    parse_npy(bytes.data(), bytes.size(), "x.npy");
  } catch (const FileFormatError& e) {
    return e.what();
  }
  return "";
}

std::vector<std::uint8_t> with_header(const std::string& dict, std::size_t data_bytes,
                                      std::uint8_t major = 1) {
  std::vector<std::uint8_t> out = {0x93, 'N', 'U', 'M', 'P', 'Y', major, 0};
  const std::string text = dict + "\n";
  out.push_back(static_cast<std::uint8_t>(text.size()));
  out.push_back(static_cast<std::uint8_t>(text.size() >> 8));
  if (major != 1)
    out.insert(out.end(), {0, 0});
  out.insert(out.end(), text.begin(), text.end());
  out.resize(out.size() + data_bytes, 0);
  return out;
}

TEST(Npy, RefusesForeignAndUnsupportedFilesByName) {
  const std::string ok = "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }";
  EXPECT_EQ(npy_error_of(with_header(ok, 8)), "");
  EXPECT_EQ(npy_error_of(with_header(ok, 8, 2)), "");  // version 2.0 layout
  EXPECT_NE(npy_error_of({'P', 'K', 3, 4, 0, 0, 0, 0, 0, 0}).find("x.npy: not a .npy file"),
            std::string::npos);
  EXPECT_NE(npy_error_of(with_header(ok, 8, 9)).find("version 9.0 is not supported"),
            std::string::npos);
  EXPECT_NE(
      npy_error_of(with_header(ok, 7)).find("holds 7 data bytes; the header's f32 (2,) needs 8"),
      std::string::npos);
  EXPECT_NE(npy_error_of(with_header(ok, 9)).find("holds 9 data bytes"), std::string::npos);
  EXPECT_NE(
      npy_error_of(with_header("{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }", 8))
          .find("dtype '>f4' is not supported"),
      std::string::npos);
  EXPECT_NE(
      npy_error_of(with_header("{'descr': '<c8', 'fortran_order': False, 'shape': (2,), }", 16))
          .find("dtype '<c8'"),
      std::string::npos);
  EXPECT_NE(npy_error_of(with_header("{'descr': '<f4', 'fortran_order': True, 'shape': (2,), }", 8))
                .find("fortran_order is True"),
            std::string::npos);
  EXPECT_NE(
      npy_error_of(with_header("{'descr': '<f4', 'fortran_order': False, 'shape': (-2,), }", 8))
          .find("expected non-negative integers"),
      std::string::npos);
  EXPECT_NE(npy_error_of(with_header("{'descr': '<f4', 'shape': (2,), }", 8)).find("lacks one of"),
            std::string::npos);
  // a shape whose byte count cannot be represented must not reach an allocation
  EXPECT_NE(npy_error_of(with_header("{'descr': '<f8', 'fortran_order': False, "
                                     "'shape': (4294967296, 4294967296, 16), }",
                                     0))
                .find("overflows 64 bits"),
            std::string::npos);
  // a header length beyond the limit
  std::vector<std::uint8_t> huge = {0x93, 'N', 'U', 'M', 'P', 'Y', 2, 0, 0, 0, 0, 0x10};
  EXPECT_NE(npy_error_of(huge).find("claims 268435456 bytes"), std::string::npos);
}

TEST(Npy, ReadNpyNamesAMissingFile) {
  try {
    read_npy("/nonexistent/dir/a.npy");
    ADD_FAILURE() << "no exception";
  } catch (const FileFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/a.npy: cannot open"), std::string::npos)
        << e.what();
  }
}

TEST(Npy, SerializeRefusesDataThatDoesNotMatchTheShape) {
  NpyArray a = make_npy_array<float>(DType::kF32, {2, 2}, {1, 2, 3});
  EXPECT_THROW(serialize_npy(a), std::invalid_argument);
}

// Fuzz: every truncation and many random corruptions of every fixture either parse or throw
// FileFormatError; nothing else (no crash, no bad_alloc, no other exception).
TEST(Npy, TruncatedAndCorruptedFilesGiveFileFormatErrorsOnly) {
  PhiloxStream rng(99, 0);
  int parsed = 0, refused = 0;
  for (const auto& entry : fs::directory_iterator(kFixtures)) {
    const std::vector<std::uint8_t> good = file_bytes(entry.path());
    for (std::size_t n = 0; n < good.size(); ++n) {
      EXPECT_THROW(parse_npy(good.data(), n, "cut.npy"), FileFormatError) << n;
    }
    for (int trial = 0; trial < 3000; ++trial) {
      std::vector<std::uint8_t> bad = good;
      const int flips = 1 + static_cast<int>(rng.next_u32() % 4);
      for (int f = 0; f < flips; ++f) {
        bad[rng.next_u32() % bad.size()] = static_cast<std::uint8_t>(rng.next_u32());
      }
      try {
        parse_npy(bad.data(), bad.size(), "bad.npy");
        ++parsed;
      } catch (const FileFormatError&) {
        ++refused;
      }
    }
  }
  EXPECT_GT(refused, 1000);
  EXPECT_GT(parsed, 100);  // flips in the data bytes are still valid files
}

TEST(Npy, TypedArraysRefuseAnElementTypeOfAnotherSize) {
  const NpyArray a = make_npy_array(DType::kI32, {2}, std::vector<std::int32_t>{7, -1});
  EXPECT_EQ(npy_values<std::int32_t>(a), (std::vector<std::int32_t>{7, -1}));
  EXPECT_THROW(make_npy_array(DType::kF64, {2}, std::vector<float>{1, 2}), std::invalid_argument);
  try {
    (void)npy_values<std::int64_t>(a);
    FAIL() << "read i32 elements as 8-byte values";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("from an array of i32"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ropes::core
