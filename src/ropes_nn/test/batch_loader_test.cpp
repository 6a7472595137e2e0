// BatchLoader and core::DatasetReader::read_rows_at: gathered rows, seeded epochs independent of
// the thread count and of reading ahead, regime filtering, resuming at a cursor, and
// refusals that name the column, row or value.
#include "ropes_nn/batch_loader.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "ropes_core/npy.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::nn {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

const std::vector<core::ColumnSpec> kColumns = {
    {"images", core::DType::kU8, {2, 3, 3}},  // [rows, cams, H, W]
    {"angles", core::DType::kF32, {2}},
    {"regime", core::DType::kI32, {}},
    {"anchor", core::DType::kI64, {}},
};
constexpr std::int64_t kRows = 103;  // shards of 40, 40, 23 rows

std::uint8_t pixel(std::int64_t row, int k) {
  return static_cast<std::uint8_t>((row * 7 + k * 3) % 256);
}

// a dataset whose every value says which row it is
class BatchLoaderTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("ropes_loader_" + std::to_string(::getpid())));
    const std::int64_t shard_rows[] = {40, 40, 23};
    std::int64_t first = 0;
    for (int s = 0; s < 3; ++s) {
      const std::int64_t n = shard_rows[s];
      std::vector<std::uint8_t> images;
      std::vector<float> angles;
      std::vector<std::int32_t> regime;
      std::vector<std::int64_t> anchor;
      for (std::int64_t r = first; r < first + n; ++r) {
        for (int k = 0; k < 18; ++k)
          images.push_back(pixel(r, k));
        angles.push_back(static_cast<float>(r));
        angles.push_back(-0.5f * static_cast<float>(r));
        regime.push_back(static_cast<std::int32_t>(r % 5));
        anchor.push_back(r / 5);
      }
      core::write_dataset_shard(*dir_, s, kColumns,
                                {core::make_npy_array(core::DType::kU8, {n, 2, 3, 3}, images),
                                 core::make_npy_array(core::DType::kF32, {n, 2}, angles),
                                 core::make_npy_array(core::DType::kI32, {n}, regime),
                                 core::make_npy_array(core::DType::kI64, {n}, anchor)});
      first += n;
    }
    core::write_dataset_manifest(*dir_, kColumns, 3, R"({"regimes": ["a", "b", "c", "d", "e"]})");
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static fs::path* dir_;
};
fs::path* BatchLoaderTest::dir_ = nullptr;

BatchLoaderOptions options_for(std::uint64_t seed, bool prefetch) {
  BatchLoaderOptions o;
  o.columns = {"images", "angles"};
  o.raw_columns = {"regime"};
  o.batch_size = 16;
  o.seed = seed;
  o.prefetch = prefetch;
  return o;
}

// the rows and the image values of `count` batches
std::vector<std::vector<float>> draw(BatchLoader& loader, int count) {
  std::vector<std::vector<float>> out;
  for (int i = 0; i < count; ++i) {
    const Batch b = loader.next();
    out.emplace_back(b.rows.begin(), b.rows.end());
    out.push_back(b.tensor("images").to_vector());
    out.push_back(b.tensor("angles").to_vector());
  }
  return out;
}

TEST_F(BatchLoaderTest, GathersRowsByIndexAcrossShardsInTheOrderGiven) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  const std::vector<std::int64_t> rows = {102, 0, 39, 40, 41, 79, 80, 7, 7, 100};
  const core::NpyArray gathered = reader.read_rows_at("images", rows);
  EXPECT_EQ(gathered.shape, (std::vector<std::int64_t>{10, 2, 3, 3}));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const core::NpyArray one = reader.read_rows("images", rows[i], 1);
    EXPECT_TRUE(std::equal(one.data.begin(), one.data.end(), gathered.data.begin() + 18 * i))
        << "row " << rows[i];
  }
  EXPECT_EQ(core::npy_values<std::int64_t>(reader.read_rows_at("anchor", {99, 5})),
            (std::vector<std::int64_t>{19, 1}));
  EXPECT_TRUE(reader.read_rows_at("anchor", {}).data.empty());
  try {
    reader.read_rows_at("images", {3, 103});
    ADD_FAILURE() << "read past the end";
  } catch (const std::out_of_range& e) {
    EXPECT_CONTAINS(e.what(), "rows[1] = 103 of column 'images' lies outside the dataset's 103");
  }
  EXPECT_THROW(reader.read_rows_at("colour", {1}), std::out_of_range);
}

TEST_F(BatchLoaderTest, SameSeedGivesTheSameBatchesForAnyThreadCountWithOrWithoutPrefetch) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  const int saved = num_threads();
  set_num_threads(1);
  BatchLoader plain(reader, options_for(5, false));
  const auto a = draw(plain, 20);  // more than two epochs of 7 batches
  set_num_threads(2);
  BatchLoader ahead(reader, options_for(5, true));
  const auto b = draw(ahead, 20);
  set_num_threads(saved);
  EXPECT_EQ(a, b);
  BatchLoader other(reader, options_for(6, true));
  EXPECT_NE(draw(other, 20), a);
}

TEST_F(BatchLoaderTest, EachEpochIsASeededPermutationOfTheRows) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  BatchLoader loader(reader, options_for(3, true));
  EXPECT_EQ(loader.batches_per_epoch(), 7);  // 6 of 16 and one of 7
  std::vector<std::vector<std::int64_t>> epochs(2);
  for (int e = 0; e < 2; ++e) {
    for (int i = 0; i < 7; ++i) {
      const Batch b = loader.next();
      EXPECT_EQ(b.cursor.epoch, e);
      EXPECT_EQ(b.index, i);
      EXPECT_EQ(b.size(), i < 6 ? 16 : 7);
      epochs[static_cast<std::size_t>(e)].insert(epochs[static_cast<std::size_t>(e)].end(),
                                                 b.rows.begin(), b.rows.end());
    }
    // the order is core::shuffled_indices' permutation of the rows
    EXPECT_EQ(epochs[static_cast<std::size_t>(e)],
              core::shuffled_indices(kRows, 3, static_cast<std::uint64_t>(e)));
    std::vector<std::int64_t> sorted = epochs[static_cast<std::size_t>(e)];
    std::sort(sorted.begin(), sorted.end());
    for (std::int64_t r = 0; r < kRows; ++r)
      ASSERT_EQ(sorted[static_cast<std::size_t>(r)], r);
  }
  EXPECT_NE(epochs[0], epochs[1]);
  EXPECT_EQ(loader.cursor(), (DataCursor{2, 0}));
  // without shuffling: dataset order
  BatchLoaderOptions in_order = options_for(3, false);
  in_order.shuffle = false;
  BatchLoader sequential(reader, in_order);
  EXPECT_EQ(sequential.next().rows.front(), 0);
  EXPECT_EQ(sequential.next().rows.front(), 16);
}

TEST_F(BatchLoaderTest, ImagesBecomeFloatsInUnitRangeAndRawColumnsStayAsStored) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  BatchLoader loader(reader, options_for(1, true));
  const Batch b = loader.next();
  const Tensor& images = b.tensor("images");
  EXPECT_EQ(images.shape(), (Shape{16, 2, 3, 3}));
  EXPECT_EQ(b.tensor("angles").shape(), (Shape{16, 2}));
  for (std::int64_t i = 0; i < 16; ++i) {
    const std::int64_t row = b.rows[static_cast<std::size_t>(i)];
    for (int k = 0; k < 18; ++k)
      ASSERT_EQ(images.data()[i * 18 + k], static_cast<float>(pixel(row, k)) / 255.0f);
    EXPECT_EQ(b.tensor("angles").data()[2 * i], static_cast<float>(row));
    EXPECT_EQ(core::npy_values<std::int32_t>(b.array("regime"))[static_cast<std::size_t>(i)],
              row % 5);
  }
  EXPECT_THROW(b.tensor("regime"), std::out_of_range);
  EXPECT_THROW(b.array("images"), std::out_of_range);
}

TEST_F(BatchLoaderTest, FiltersRowsByAColumnAndByAList) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  BatchLoaderOptions o = options_for(2, true);
  o.filter_column = "regime";
  o.filter_values = {2};
  BatchLoader regime2(reader, o);
  EXPECT_EQ(regime2.rows().size(), 21u);  // 2, 7, ..., 102
  std::set<std::int64_t> seen;
  for (int i = 0; i < regime2.batches_per_epoch(); ++i) {
    const Batch b = regime2.next();
    for (std::int64_t r : b.rows) {
      EXPECT_EQ(r % 5, 2);
      seen.insert(r);
    }
    for (std::int32_t regime : core::npy_values<std::int32_t>(b.array("regime")))
      EXPECT_EQ(regime, 2);
  }
  EXPECT_EQ(seen.size(), 21u);
  // a list of rows (say, the anchors held out), then the filter on it
  o.rows = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 100, 101, 102};
  o.filter_values = {2, 3};
  BatchLoader split(reader, o);
  EXPECT_EQ(split.rows(), (std::vector<std::int64_t>{2, 3, 7, 8, 102}));
}

TEST_F(BatchLoaderTest, SeekToASavedCursorContinuesTheSameSequence) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  BatchLoader first(reader, options_for(9, true));
  draw(first, 3);
  const DataCursor saved = first.cursor();
  EXPECT_EQ(saved, (DataCursor{0, 48}));
  const auto rest = draw(first, 8);
  BatchLoader resumed(reader, options_for(9, true));
  resumed.next();  // read ahead for cursor 0, then dropped by the seek
  resumed.seek(saved);
  EXPECT_EQ(draw(resumed, 8), rest);
  EXPECT_THROW(resumed.seek({0, kRows}), std::invalid_argument);
  EXPECT_THROW(resumed.seek({-1, 0}), std::invalid_argument);
}

TEST_F(BatchLoaderTest, DropLastGivesOnlyFullBatches) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  BatchLoaderOptions o = options_for(4, true);
  o.drop_last = true;
  BatchLoader loader(reader, o);
  EXPECT_EQ(loader.batches_per_epoch(), 6);
  for (int i = 0; i < 13; ++i)
    EXPECT_EQ(loader.next().size(), 16);
  EXPECT_EQ(loader.cursor(), (DataCursor{2, 16}));
  EXPECT_THROW(loader.seek({0, 90}), std::invalid_argument);
}

TEST_F(BatchLoaderTest, RefusesColumnsRowsAndFiltersThatDoNotFit) {
  const core::DatasetReader reader = core::DatasetReader::open(*dir_);
  auto error = [&](BatchLoaderOptions o) {
    try {
      BatchLoader loader(reader, std::move(o));
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  BatchLoaderOptions o = options_for(1, true);
  o.columns = {"images", "colour"};
  EXPECT_CONTAINS(error(o), "no column 'colour'");
  o = options_for(1, true);
  o.raw_columns = {"images"};
  EXPECT_CONTAINS(error(o), "column 'images' is named twice");
  o = options_for(1, true);
  o.batch_size = 0;
  EXPECT_CONTAINS(error(o), "batch_size is 0; expected >= 1");
  o = options_for(1, true);
  o.rows = {5, 103};
  EXPECT_CONTAINS(error(o), "rows[1] is 103; the dataset");
  o = options_for(1, true);
  o.filter_column = "angles";
  o.filter_values = {1};
  EXPECT_CONTAINS(error(o), "filter_column 'angles' is f32");
  o.filter_column = "regime";
  o.filter_values = {};
  EXPECT_CONTAINS(error(o), "filter_column 'regime' given without filter_values");
  o.filter_values = {7, 9};
  EXPECT_CONTAINS(error(o), "has regime in {7, 9}; its values lie in 0..4");
  o = options_for(1, true);
  o.columns = {};
  o.raw_columns = {};
  EXPECT_CONTAINS(error(o), "no columns to read");
  o = options_for(1, true);
  o.drop_last = true;
  o.batch_size = 200;
  EXPECT_CONTAINS(error(o), "drop_last with 103 rows and batch_size 200 leaves no batch");
}

TEST(SplitRows, NearEqualContiguousParts) {
  auto sizes = [](std::int64_t n, std::int64_t max) {
    std::vector<std::int64_t> out;
    std::int64_t next = 0;
    for (const RowRange& r : split_rows(n, max)) {
      EXPECT_EQ(r.begin, next);
      next = r.end;
      out.push_back(r.size());
    }
    EXPECT_EQ(next, n);
    return out;
  };
  EXPECT_EQ(sizes(64, 16), (std::vector<std::int64_t>{16, 16, 16, 16}));
  EXPECT_EQ(sizes(10, 4), (std::vector<std::int64_t>{4, 3, 3}));
  EXPECT_EQ(sizes(3, 8), (std::vector<std::int64_t>{3}));
  EXPECT_TRUE(sizes(0, 8).empty());
  EXPECT_THROW(split_rows(4, 0), std::invalid_argument);
}

// a file cut short after the reader opened it: the error reaches next(), with the file's name
TEST(BatchLoader, ReadErrorsSurfaceInNextNamingTheFile) {
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_loader_cut_" + std::to_string(::getpid()));
  const std::vector<core::ColumnSpec> columns = {{"x", core::DType::kF32, {4}}};
  core::write_dataset_shard(
      dir, 0, columns,
      {core::make_npy_array(core::DType::kF32, {8, 4}, std::vector<float>(32, 1))});
  core::write_dataset_manifest(dir, columns, 1, "{}");
  const core::DatasetReader reader = core::DatasetReader::open(dir);
  fs::resize_file(dir / "shards" / "x-00000.npy", 100);
  for (bool prefetch : {false, true}) {
    BatchLoaderOptions o;
    o.columns = {"x"};
    o.batch_size = 8;
    o.prefetch = prefetch;
    BatchLoader loader(reader, o);
    try {
      loader.next();
      ADD_FAILURE() << "read a truncated file";
    } catch (const core::FileFormatError& e) {
      EXPECT_CONTAINS(e.what(), "x-00000.npy");
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ropes::nn
