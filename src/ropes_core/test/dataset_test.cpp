#include "ropes_core/dataset.hpp"
#include "ropes_core/child_process.hpp"
#include "ropes_core/npy.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "ropes_core/sha256.hpp"

namespace ropes::core {
namespace {

namespace fs = std::filesystem;

const std::vector<ColumnSpec> kColumns = {
    {"images", DType::kU8, {2, 4, 4}},  // [rows, cams, H, W]
    {"angles", DType::kF32, {7}},       // [rows, 7]
    {"regime", DType::kI32, {}},        // [rows]
    {"anchor", DType::kI64, {}},        // [rows]
};
const std::vector<std::int64_t> kShardRows = {5, 3, 4};  // 12 rows; shards start at 0, 5, 8
constexpr std::int64_t kRows = 12;

// the arrays of global rows [first, first + rows), one per column of kColumns; every value is
// exact in float64, so sums compare exactly with numpy's
std::vector<NpyArray> make_rows(std::int64_t first, std::int64_t rows) {
  std::vector<std::uint8_t> images;
  std::vector<float> angles;
  std::vector<std::int32_t> regime;
  std::vector<std::int64_t> anchor;
  for (std::int64_t r = first; r < first + rows; ++r) {
    for (int k = 0; k < 32; ++k)
      images.push_back(static_cast<std::uint8_t>((r * 37 + k * 5ll) % 251));
    for (int j = 0; j < 7; ++j)
      angles.push_back(0.25f * static_cast<float>(r) - 0.5f * static_cast<float>(j));
    regime.push_back(static_cast<std::int32_t>(r % 3) - 1);
    anchor.push_back(r * 1000000007ll - 5);
  }
  return {make_npy_array(DType::kU8, {rows, 2, 4, 4}, images),
          make_npy_array(DType::kF32, {rows, 7}, angles),
          make_npy_array(DType::kI32, {rows}, regime), make_npy_array(DType::kI64, {rows}, anchor)};
}

std::string file_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

template <typename F>
std::string file_error_of(F f) {
  try {
    f();
  } catch (const FileFormatError& e) {
    return e.what();
  }
  return "(no FileFormatError)";
}

template <typename F>
std::string invalid_argument_of(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument)";
}

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "'" << (text) << "'"

// each test in a directory of its own, removed afterwards
class DatasetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ropes_dataset_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // the three shards and the manifest
  void write_dataset(const fs::path& dir) {
    std::int64_t first = 0;
    for (std::size_t s = 0; s < kShardRows.size(); ++s) {
      write_dataset_shard(dir, static_cast<int>(s), kColumns, make_rows(first, kShardRows[s]));
      first += kShardRows[s];
    }
    write_dataset_manifest(dir, kColumns, 3, R"({"seed": 7, "robot": "none"})");
  }

  fs::path shard_file(const std::string& column, int shard) const {
    char stem[16];
    std::snprintf(stem, sizeof(stem), "%05d", shard);
    return dir_ / "shards" / (column + "-" + stem + ".npy");
  }

  fs::path dir_;
};

TEST_F(DatasetTest, RoundTripsThreeShards) {
  write_dataset(dir_);
  DatasetReader reader = DatasetReader::open(dir_);
  EXPECT_EQ(reader.rows(), kRows);
  EXPECT_EQ(reader.shard_count(), 3);
  EXPECT_EQ(reader.columns(), kColumns);
  EXPECT_EQ(reader.column("angles").row_shape, (std::vector<std::int64_t>{7}));
  EXPECT_EQ(reader.metadata_json(), R"({"robot":"none","seed":7})");
  const std::vector<NpyArray> expected = make_rows(0, kRows);
  for (std::size_t c = 0; c < kColumns.size(); ++c) {
    const NpyArray all = reader.read_rows(kColumns[c].name, 0, kRows);
    EXPECT_EQ(all.dtype, expected[c].dtype) << kColumns[c].name;
    EXPECT_EQ(all.shape, expected[c].shape) << kColumns[c].name;
    EXPECT_EQ(all.data, expected[c].data) << kColumns[c].name;
  }
  reader.verify();
  // the layout of the file comment, and no temporary files left behind
  EXPECT_TRUE(fs::exists(dir_ / "shards" / "00002.json"));
  EXPECT_TRUE(fs::exists(shard_file("images", 2)));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "shards"), fs::directory_iterator()),
            3 * 5);
  // a moved reader keeps its open files
  DatasetReader moved = std::move(reader);
  EXPECT_EQ(moved.read_rows("regime", 11, 1).data, make_rows(11, 1)[2].data);
}

TEST_F(DatasetTest, MetadataIsGivenParsedAndAMissingFieldIsNamed) {
  write_dataset(dir_);
  const DatasetReader reader = DatasetReader::open(dir_);
  EXPECT_EQ(reader.metadata().at("seed").get<int>(), 7);
  EXPECT_EQ(reader.metadata_at("/robot").get<std::string>(), "none");
  // a dataset written before a field existed opens; the reader that needs the field says so
  EXPECT_CONTAINS(file_error_of([&] {
                    reader.metadata_at("/regimes/1/joint", "written by an older generator");
                  }),
                  (dir_ / "manifest.json").string() +
                      ": metadata has no /regimes/1/joint (written by an older generator)");
  EXPECT_CONTAINS(file_error_of([&] { reader.metadata_at("/seed/x"); }), "metadata has no /seed/x");
  EXPECT_THROW(reader.metadata_at("regimes"), std::invalid_argument);
}

TEST_F(DatasetTest, RandomAccessAcrossShardBoundariesMatchesTheWrittenRows) {
  write_dataset(dir_);
  const DatasetReader reader = DatasetReader::open(dir_);
  for (std::int64_t first = 0; first <= kRows; ++first) {
    for (std::int64_t count = 0; first + count <= kRows; ++count) {
      const std::vector<NpyArray> expected = make_rows(first, count);
      for (std::size_t c = 0; c < kColumns.size(); ++c) {
        const NpyArray got = reader.read_rows(kColumns[c].name, first, count);
        ASSERT_EQ(got.shape, expected[c].shape) << first << " " << count;
        ASSERT_EQ(got.data, expected[c].data) << kColumns[c].name << " " << first << " " << count;
      }
    }
  }
  // into a caller's buffer
  std::vector<float> angles(std::size_t{4} * 7);
  reader.read_rows("angles", 4, 4, angles.data());  // rows 4 | 5 6 7 | (shards 0, 1)
  EXPECT_EQ(angles[0], 1.0f);
  EXPECT_EQ(angles[27], 0.25f * 7 - 0.5f * 6);
}

// one reader shared by threads: pread keeps no file position, so reads do not interfere
TEST_F(DatasetTest, ThreadsShareOneReader) {
  write_dataset(dir_);
  const DatasetReader reader = DatasetReader::open(dir_);
  const std::vector<NpyArray> expected = make_rows(0, kRows);
  std::vector<int> mismatches(4, 0);
  std::vector<std::thread> threads;
  threads.reserve(4);
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 200; ++i) {
        const std::int64_t first = (t * 5 + i * 7) % kRows;
        const std::int64_t count = std::min<std::int64_t>(1 + i % 6, kRows - first);
        const NpyArray got = reader.read_rows("images", first, count);
        if (std::memcmp(got.data.data(), expected[0].data.data() + first * 32, got.data.size()) !=
            0)
          ++mismatches[static_cast<std::size_t>(t)];
      }
    });
  }
  for (std::thread& thread : threads)
    thread.join();
  EXPECT_EQ(mismatches, std::vector<int>(4, 0));
}

TEST_F(DatasetTest, ReadingOutsideTheRowsOrAnUnknownColumnThrows) {
  write_dataset(dir_);
  const DatasetReader reader = DatasetReader::open(dir_);
  const std::int64_t max = std::numeric_limits<std::int64_t>::max();
  for (const auto& [first, count] : std::vector<std::pair<std::int64_t, std::int64_t>>{
           {-1, 1}, {12, 1}, {10, 3}, {0, 13}, {0, -1}, {1, max}, {max, 1}}) {
    try {
      reader.read_rows("angles", first, count);
      ADD_FAILURE() << "no exception for " << first << ", " << count;
    } catch (const std::out_of_range& e) {
      EXPECT_CONTAINS(e.what(), "outside the dataset's 12 rows");
    }
  }
  try {
    reader.read_rows("angels", 0, 1);
    ADD_FAILURE() << "no exception";
  } catch (const std::out_of_range& e) {
    EXPECT_CONTAINS(e.what(), "no column 'angels'");
    EXPECT_CONTAINS(e.what(), "it has images, angles, regime, anchor");
  }
  EXPECT_THROW(reader.column("labels"), std::out_of_range);
}

TEST_F(DatasetTest, OpenRefusesATruncatedShardFile) {
  write_dataset(dir_);
  const fs::path file = shard_file("images", 1);
  fs::resize_file(file, fs::file_size(file) - 10);
  const std::string error = file_error_of([&] { DatasetReader::open(dir_); });
  EXPECT_CONTAINS(error, file.string() + ": holds");
  EXPECT_CONTAINS(error, "(truncated?)");
}

TEST_F(DatasetTest, OpenRefusesAnotherFormatVersion) {
  write_dataset(dir_);
  const fs::path manifest = dir_ / "manifest.json";
  std::string text = file_text(manifest);
  const std::size_t at = text.find("\"format_version\": 1");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 19, "\"format_version\": 2");
  write_text(manifest, text);
  EXPECT_CONTAINS(file_error_of([&] { DatasetReader::open(dir_); }),
                  manifest.string() + ": format_version is 2; expected 1");
}

TEST_F(DatasetTest, OpenRefusesMalformedManifests) {
  write_dataset(dir_);
  const fs::path manifest = dir_ / "manifest.json";
  const std::string good = file_text(manifest);
  const auto error_with = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    write_text(manifest, text);
    return file_error_of([&] { DatasetReader::open(dir_); });
  };
  EXPECT_CONTAINS(error_with("\"rows\": 12", "\"rows\": 13"), "rows is 13; the shards hold 12");
  EXPECT_CONTAINS(error_with("\"ropes-dataset\"", "\"other\""), "format is \"other\"");
  EXPECT_CONTAINS(error_with("\"dtype\": \"f32\"", "\"dtype\": \"f16\""),
                  "columns[1].dtype is \"f16\"; expected u8, i32, i64, f32 or f64");
  EXPECT_CONTAINS(error_with("shards/angles-00001.npy", "../angles-00001.npy"),
                  "shards[1].files.angles.path is \"../angles-00001.npy\"; expected "
                  "\"shards/angles-00001.npy\"");
  EXPECT_CONTAINS(error_with("{", "["), manifest.string() + ": is not JSON");
  EXPECT_CONTAINS(
      error_with("\"metadata\": {",
                 "\"metadata\": {\"deep\": " + std::string(100, '[') + std::string(100, ']') + ","),
      manifest.string() + ": nests deeper than 64 levels");
}

TEST_F(DatasetTest, OpenOfADirectoryWithoutManifestSaysNoCompleteDataset) {
  write_dataset(dir_);
  fs::remove(dir_ / "manifest.json");
  const std::string error = file_error_of([&] { DatasetReader::open(dir_); });
  EXPECT_CONTAINS(error, dir_.string() + ": holds no complete dataset");
  EXPECT_CONTAINS(error, (dir_ / "manifest.json").string() + " missing");
}

TEST_F(DatasetTest, OpenRefusesAForeignNpyOfTheSameSize) {
  write_dataset(dir_);
  // i32 [4, 7] has the header length and size of the f32 [4, 7] it replaces
  const fs::path file = shard_file("angles", 2);
  const std::uintmax_t size = fs::file_size(file);
  write_npy(file, make_npy_array(DType::kI32, {4, 7}, std::vector<std::int32_t>(28, 1)));
  ASSERT_EQ(fs::file_size(file), size);
  EXPECT_CONTAINS(file_error_of([&] { DatasetReader::open(dir_); }),
                  file.string() + ": dtype is i32; column 'angles' expects f32");
  // and one of another shape
  write_npy(file, make_npy_array(DType::kF32, {7, 4}, std::vector<float>(28, 1.0f)));
  EXPECT_CONTAINS(file_error_of([&] { DatasetReader::open(dir_); }),
                  file.string() + ": shape is [7, 4]; column 'angles' expects");
}

TEST_F(DatasetTest, VerifyCatchesOneFlippedByte) {
  write_dataset(dir_);
  const fs::path file = shard_file("regime", 0);
  const std::string recorded = sha256_file(file);
  {
    std::fstream f(file, std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(-1, std::ios::end);
    f.put(static_cast<char>(0x5a));
  }
  const DatasetReader reader = DatasetReader::open(dir_);  // sizes and headers are intact
  const std::string error = file_error_of([&] { reader.verify(); });
  EXPECT_CONTAINS(error, file.string() + ": sha256 is " + sha256_file(file) +
                             "; the manifest records " + recorded);
}

// dataset_shard_problem with check_sha256: a flipped byte in a committed shard is named,
// which dataset_shard_complete (sizes and headers only) does not see
TEST_F(DatasetTest, ShardProblemWithSha256FindsAFlippedByte) {
  write_dataset(dir_);
  EXPECT_EQ(dataset_shard_problem(dir_, 1, kColumns, "", true), "");
  const fs::path file = shard_file("angles", 1);
  {
    std::fstream f(file, std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(-3, std::ios::end);
    f.put(static_cast<char>(0x11));
  }
  EXPECT_TRUE(dataset_shard_complete(dir_, 1, kColumns));
  EXPECT_EQ(dataset_shard_problem(dir_, 1, kColumns), "");
  EXPECT_CONTAINS(dataset_shard_problem(dir_, 1, kColumns, "", true),
                  file.string() + ": sha256 is " + sha256_file(file) + "; the marker of shard 1");
  EXPECT_CONTAINS(dataset_shard_problem(dir_, 7, kColumns, "", true), "shard 7 is not complete");
}

// DIR/shards as a link to elsewhere: refused, nothing written there
TEST_F(DatasetTest, WritingAShardRefusesAShardsDirectoryThatIsALink) {
  const fs::path elsewhere = dir_.string() + "_elsewhere";
  fs::create_directories(elsewhere);
  fs::create_directories(dir_);
  fs::create_directory_symlink(elsewhere, dir_ / "shards");
  EXPECT_CONTAINS(file_error_of([&] { write_dataset_shard(dir_, 0, kColumns, make_rows(0, 2)); }),
                  (dir_ / "shards").string() + ": is a symbolic link");
  EXPECT_TRUE(fs::is_empty(elsewhere));
  fs::remove_all(elsewhere);
}

// a manifest whose files would not fit under the descriptor limit is refused before any
// file is opened, with the numbers and what to do
TEST_F(DatasetTest, OpenRefusesMoreFilesThanTheDescriptorLimitAllows) {
  write_dataset(dir_);
  rlimit saved{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &saved), 0);
  rlimit low = saved;
  low.rlim_cur = 40;  // below what the reader asks for: its files and 64 to spare
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  const std::string error = file_error_of([&] { DatasetReader::open(dir_); });
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &saved), 0);
  EXPECT_CONTAINS(error, (dir_ / "manifest.json").string() + ": lists 3 shards of " +
                             std::to_string(kColumns.size()) + " columns: ");
  EXPECT_CONTAINS(error, "over this process's limit of 40 file descriptors (raise it with");
  DatasetReader::open(dir_);  // under the usual limit it opens
}

TEST_F(DatasetTest, IncompleteShardsAreReportedAndRefusedByTheManifest) {
  std::int64_t first = 0;
  for (std::size_t s = 0; s < kShardRows.size(); ++s) {
    write_dataset_shard(dir_, static_cast<int>(s), kColumns, make_rows(first, kShardRows[s]));
    EXPECT_TRUE(dataset_shard_complete(dir_, static_cast<int>(s), kColumns));
    first += kShardRows[s];
  }
  EXPECT_FALSE(dataset_shard_complete(dir_, 3, kColumns));
  // other columns than the shard was written with
  std::vector<ColumnSpec> other = kColumns;
  other[1].row_shape = {6};
  EXPECT_FALSE(dataset_shard_complete(dir_, 0, other));
  other.pop_back();
  EXPECT_FALSE(dataset_shard_complete(dir_, 0, other));

  // a marker missing
  fs::remove(dir_ / "shards" / "00001.json");
  EXPECT_FALSE(dataset_shard_complete(dir_, 1, kColumns));
  const std::string missing_marker =
      file_error_of([&] { write_dataset_manifest(dir_, kColumns, 3, "{}"); });
  EXPECT_CONTAINS(missing_marker,
                  (dir_ / "shards" / "00001.json").string() + ": shard 1 is not complete");
  EXPECT_FALSE(fs::exists(dir_ / "manifest.json"));

  // rewritten, then a column file missing
  write_dataset_shard(dir_, 1, kColumns, make_rows(5, 3));
  EXPECT_TRUE(dataset_shard_complete(dir_, 1, kColumns));
  fs::remove(shard_file("anchor", 2));
  EXPECT_FALSE(dataset_shard_complete(dir_, 2, kColumns));
  const std::string missing_file =
      file_error_of([&] { write_dataset_manifest(dir_, kColumns, 3, "{}"); });
  EXPECT_CONTAINS(missing_file, shard_file("anchor", 2).string() + ": shard 2 is not complete");
  EXPECT_FALSE(fs::exists(dir_ / "manifest.json"));

  // a marker that does not parse
  write_dataset_shard(dir_, 2, kColumns, make_rows(8, 4));
  write_text(dir_ / "shards" / "00000.json", "{\"rows\": 5, \"files\": ");
  EXPECT_FALSE(dataset_shard_complete(dir_, 0, kColumns));
}

TEST_F(DatasetTest, ADatasetIdKeepsShardsOfAnotherDatasetOut) {
  write_dataset_shard(dir_, 0, kColumns, make_rows(0, 5), "dataset-a");
  write_dataset_shard(dir_, 1, kColumns, make_rows(5, 3), "dataset-b");  // copied in
  EXPECT_TRUE(dataset_shard_complete(dir_, 0, kColumns, "dataset-a"));
  EXPECT_FALSE(dataset_shard_complete(dir_, 1, kColumns, "dataset-a"));
  EXPECT_FALSE(dataset_shard_complete(dir_, 0, kColumns));  // an id is expected only if given
  const std::string mixed =
      file_error_of([&] { write_dataset_manifest(dir_, kColumns, 2, "{}", "dataset-a"); });
  EXPECT_CONTAINS(mixed, (dir_ / "shards" / "00001.json").string() +
                             ": shard 1 is not complete: the marker's dataset is \"dataset-b\"");
  EXPECT_FALSE(fs::exists(dir_ / "manifest.json"));
  write_dataset_shard(dir_, 1, kColumns, make_rows(5, 3), "dataset-a");
  write_dataset_manifest(dir_, kColumns, 2, "{}", "dataset-a");
  EXPECT_CONTAINS(file_text(dir_ / "manifest.json"), "\"dataset\": \"dataset-a\"");
  EXPECT_EQ(DatasetReader::open(dir_).rows(), 8);
}

TEST_F(DatasetTest, ManifestBytesAreTheSameWhenWrittenTwice) {
  write_dataset(dir_);
  const std::string first = file_text(dir_ / "manifest.json");
  // the same metadata in another order and spacing
  write_dataset_manifest(dir_, kColumns, 3, "{ \"robot\" : \"none\",\n \"seed\": 7 }");
  EXPECT_EQ(file_text(dir_ / "manifest.json"), first);
  // and a dataset written again elsewhere from the same inputs
  const fs::path again = dir_ / "again";
  write_dataset(again);
  EXPECT_EQ(file_text(again / "manifest.json"), first);
  EXPECT_EQ(first.back(), '\n');
  EXPECT_CONTAINS(first, "\n  \"format\": \"ropes-dataset\",\n  \"format_version\": 1,\n");
}

TEST_F(DatasetTest, WritersRefuseBadInputBeforeWritingAnything) {
  std::vector<NpyArray> data = make_rows(0, 3);
  data[1].dtype = DType::kI32;
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_shard(dir_, 0, kColumns, data); }),
                  "write_dataset_shard: column 'angles' has dtype i32; expected f32");
  data = make_rows(0, 3);
  data[0].shape = {3, 2, 16};
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_shard(dir_, 0, kColumns, data); }),
                  "column 'images' has shape [3, 2, 16]; expected [rows, row_shape...] = "
                  "[rows, 2, 4, 4]");
  data = make_rows(0, 3);
  data[3] = make_rows(0, 4)[3];
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_shard(dir_, 0, kColumns, data); }),
                  "column 'anchor' has 4 rows; expected 3, as column 'images' has");
  data = make_rows(0, 3);
  data.pop_back();
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_shard(dir_, 0, kColumns, data); }),
                  "3 arrays for 4 columns (images, angles, regime, anchor)");
  data = make_rows(0, 3);
  data[2].data.pop_back();
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_shard(dir_, 0, kColumns, data); }),
                  "column 'regime' holds 11 data bytes; its shape [3] needs 12");
  EXPECT_CONTAINS(
      invalid_argument_of([&] { write_dataset_shard(dir_, 0, kColumns, make_rows(0, 0)); }),
      "column 'images' has 0 rows; expected at least 1");
  std::vector<ColumnSpec> bad = kColumns;
  bad[0].name = "../images";
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_shard(dir_, 0, bad, make_rows(0, 3)); }),
                  "column name '../images' holds the character '/'");
  EXPECT_FALSE(fs::exists(dir_));

  write_dataset_shard(dir_, 0, kColumns, make_rows(0, 3));
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_manifest(dir_, kColumns, 1, "[1, 2]"); }),
                  "metadata_json is a JSON array; expected the text of a JSON object");
  EXPECT_CONTAINS(invalid_argument_of([&] { write_dataset_manifest(dir_, kColumns, 1, "{"); }),
                  "metadata_json is not JSON");
  EXPECT_THROW(write_dataset_manifest(dir_, kColumns, 0, "{}"), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "manifest.json"));
}

TEST(DatasetShuffle, IsADeterministicPermutationThatChangesWithEpochAndSeed) {
  for (std::int64_t n : {0, 1, 2, 10, 1000}) {
    std::vector<std::int64_t> order = shuffled_indices(n, 42, 0);
    EXPECT_EQ(order, shuffled_indices(n, 42, 0));
    std::sort(order.begin(), order.end());
    std::vector<std::int64_t> identity(static_cast<std::size_t>(n));
    std::iota(identity.begin(), identity.end(), 0);
    EXPECT_EQ(order, identity) << n;
  }
  EXPECT_NE(shuffled_indices(1000, 42, 0), shuffled_indices(1000, 42, 1));
  EXPECT_NE(shuffled_indices(1000, 42, 0), shuffled_indices(1000, 43, 0));
  EXPECT_THROW(shuffled_indices(-1, 42, 0), std::invalid_argument);
}

// the bounded draw is unbiased: the 6 orders of 3 elements come up equally often
TEST(DatasetShuffle, DrawsEveryOrderOfThreeEquallyOften) {
  std::map<std::vector<std::int64_t>, int> counts;
  const int epochs = 6000;
  for (int epoch = 0; epoch < epochs; ++epoch)
    ++counts[shuffled_indices(3, 9, static_cast<std::uint64_t>(epoch))];
  ASSERT_EQ(counts.size(), 6u);
  for (const auto& [order, count] : counts)
    EXPECT_NEAR(count, epochs / 6.0, 150.0);  // ~5 standard deviations
}

// Witness: numpy loads every shard file, and hashlib agrees with the manifest's sha256
TEST_F(DatasetTest, NumpyLoadsEveryShardFile) {
  if (ropes::core::run_shell("/usr/bin/python3 -c 'import numpy' 2>/dev/null").rc != 0)
    GTEST_SKIP() << "Debian's python3-numpy is not installed (ci/install-deps installs it)";
  write_dataset(dir_);
  // the sums of each column over all rows, as numpy computes them in float64
  const std::vector<NpyArray> all = make_rows(0, kRows);
  double images = 0, angles = 0, regime = 0, anchor = 0;
  for (std::uint8_t v : all[0].data)
    images += v;
  for (std::int64_t i = 0; i < kRows * 7; ++i) {
    float v = 0;
    std::memcpy(&v, all[1].data.data() + 4 * i, 4);
    angles += v;
  }
  for (std::int64_t i = 0; i < kRows; ++i) {
    std::int32_t r = 0;
    std::int64_t a = 0;
    std::memcpy(&r, all[2].data.data() + 4 * i, 4);
    std::memcpy(&a, all[3].data.data() + 8 * i, 8);
    regime += r;
    anchor += static_cast<double>(a);
  }
  char sums[256];
  std::snprintf(sums, sizeof(sums), "images=%.17g angles=%.17g regime=%.17g anchor=%.17g", images,
                angles, regime, anchor);
  const std::string script =
      "import hashlib, json, pathlib, sys\n"
      "import numpy as np\n"
      "d = pathlib.Path(sys.argv[1])\n"
      "want = dict(a.split('=') for a in sys.argv[2:])\n"
      "m = json.loads((d / 'manifest.json').read_text())\n"
      "assert m['format'] == 'ropes-dataset' and m['format_version'] == 1\n"
      "types = {'u8': 'uint8', 'i32': 'int32', 'i64': 'int64', 'f32': 'float32', 'f64': "
      "'float64'}\n"
      "total = {c['name']: 0.0 for c in m['columns']}\n"
      "for s in m['shards']:\n"
      "    for c in m['columns']:\n"
      "        f = s['files'][c['name']]\n"
      "        p = d / f['path']\n"
      "        raw = p.read_bytes()\n"
      "        assert len(raw) == f['bytes'], p\n"
      "        assert hashlib.sha256(raw).hexdigest() == f['sha256'], p\n"
      "        a = np.load(p)\n"
      "        assert a.dtype == np.dtype(types[c['dtype']]), (p, a.dtype)\n"
      "        assert list(a.shape) == [s['rows']] + c['row_shape'], (p, a.shape)\n"
      "        total[c['name']] += float(a.astype(np.float64).sum())\n"
      "assert sum(s['rows'] for s in m['shards']) == m['rows']\n"
      "for k, v in want.items():\n"
      "    assert total[k] == float(v), (k, total[k], v)\n"
      "print('numpy read', len(m['shards']) * len(m['columns']), 'shard files')\n";
  const std::string command =
      "/usr/bin/python3 -c \"" + script + "\" '" + dir_.string() + "' " + sums;
  const ropes::core::ChildResult command_run = ropes::core::run_shell(command);
  EXPECT_EQ(command_run.rc, 0) << command << "\n" << command_run.output;
}

}  // namespace
}  // namespace ropes::core
