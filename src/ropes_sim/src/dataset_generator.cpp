#include "ropes_sim/dataset_generator.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <mutex>
#include <thread>

#include "dataset_setup.hpp"
#include "json_config.hpp"
#include "ropes_core/dataset.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/npy.hpp"
#include "ropes_core/sha256.hpp"
#include "ropes_sim/intervention_sampler.hpp"
#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/renderer.hpp"

#ifndef ROPES_SIM_VERSION
#define ROPES_SIM_VERSION "unknown"
#endif

namespace ropes::sim {

namespace {

using Json = nlohmann::json;
namespace fs = std::filesystem;
using detail::Setup;

// a thread with its own Kinematics and Renderer (an OSMesa context stays on its thread)
struct Worker {
  Kinematics kinematics;
  Renderer renderer;
  Worker(const RobotModel& model, std::shared_ptr<const Scene> scene, int width, int height)
      : kinematics(model), renderer(std::move(scene), width, height) {}
};

// runs a job on every worker at once and waits for all of them
class WorkerPool {
 public:
  WorkerPool(int threads, const RobotModel& model, const std::shared_ptr<const Scene>& scene,
             int width, int height) {
    std::vector<std::exception_ptr> setup_errors(static_cast<std::size_t>(threads));
    for (int t = 0; t < threads; ++t) {
      threads_.emplace_back([this, t, &model, scene, width, height, &setup_errors] {
        std::unique_ptr<Worker> worker;
        try {
          worker = std::make_unique<Worker>(model, scene, width, height);
        } catch (...) {
          setup_errors[static_cast<std::size_t>(t)] = std::current_exception();
        }
        loop(t, worker.get());
      });
    }
    run([](int, Worker*) {});  // waits until every worker is set up
    for (auto& e : setup_errors)
      if (e) {
        shutdown();
        std::rethrow_exception(e);
      }
  }
  ~WorkerPool() { shutdown(); }
  int size() const { return static_cast<int>(threads_.size()); }

  // job(t, worker) on every thread t; rethrows the first exception
  void run(const std::function<void(int, Worker*)>& job) {
    std::unique_lock<std::mutex> lock(mutex_);
    job_ = &job;
    error_ = nullptr;
    running_ = size();
    ++generation_;
    wake_.notify_all();
    done_.wait(lock, [this] { return running_ == 0; });
    job_ = nullptr;
    if (error_)
      std::rethrow_exception(error_);
  }

 private:
  void loop(int t, Worker* worker) {
    std::uint64_t seen = 0;
    for (;;) {
      const std::function<void(int, Worker*)>* job = nullptr;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_)
          return;
        seen = generation_;
        job = job_;
      }
      std::exception_ptr error;
      try {
        if (worker)
          (*job)(t, worker);
      } catch (...) {
        error = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(mutex_);
      if (error && !error_)
        error_ = error;
      if (--running_ == 0)
        done_.notify_all();
    }
  }
  void shutdown() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
      wake_.notify_all();
    }
    for (auto& th : threads_)
      if (th.joinable())
        th.join();
  }

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(int, Worker*)>* job_ = nullptr;
  std::exception_ptr error_;
  int running_ = 0;
  std::uint64_t generation_ = 0;
  bool stop_ = false;
};

std::string short_dump(const Json& v) {
  std::string text = v.dump();
  return text.size() > 60 ? text.substr(0, 57) + "..." : text;
}

// the first leaf in which two metadata objects differ, as "/config/rig/cameras/0/target/2:
// -0.6 now, 30 there", for the message
std::string first_difference(const Json& ours, const Json& theirs, const std::string& path = "") {
  if (ours.is_object() && theirs.is_object()) {
    for (const auto& [key, value] : ours.items()) {
      if (!theirs.contains(key))
        return path + "/" + key + " (missing there)";
      if (theirs[key] != value)
        return first_difference(value, theirs[key], path + "/" + key);
    }
    for (const auto& [key, value] : theirs.items())
      if (!ours.contains(key))
        return path + "/" + key + " (only there)";
  } else if (ours.is_array() && theirs.is_array() && ours.size() == theirs.size()) {
    for (std::size_t i = 0; i < ours.size(); ++i)
      if (ours[i] != theirs[i])
        return first_difference(ours[i], theirs[i], path + "/" + std::to_string(i));
  }
  return path + ": " + short_dump(ours) + " now, " + short_dump(theirs) + " there";
}

// a dataset (or its unfinished start) of a sim_dataset_version before 3, which read the
// paper's TN(mean, x) as a standard deviation: refused with why and what to do, so that it is
// neither resumed nor mistaken for a mere change of config
void refuse_old_reading(const fs::path& dir, const fs::path& file, const Json& meta) {
  if (!meta.is_object() || !meta.contains("sim_dataset_version"))
    return;
  const Json& v = meta["sim_dataset_version"];
  if (v.is_number_integer() && v.get<std::int64_t>() >= kFirstVarianceReadingVersion)
    return;
  if (!v.is_number_integer())
    throw std::runtime_error(
        file.string() + ": sim_dataset_version is a " + std::string(v.type_name()) +
        ", expected an integer: not a dataset of this ropes-generate; remove " + dir.string() +
        " and generate it again, or choose another --out");
  const std::string version = std::to_string(v.get<std::int64_t>());
  throw std::runtime_error(
      file.string() + ": sim_dataset_version " + version +
      ", made when ropes-generate read the paper's TN(mean, x) as a standard deviation; the "
      "paper's x is a variance (sim_dataset_version " +
      std::to_string(kFirstVarianceReadingVersion) +
      " on), so it is not the paper's dataset: remove " + dir.string() +
      " and generate it again, or choose another --out");
}

// checks that `dir` is empty, new, or holds this dataset; returns true when it is complete
bool prepare_directory(const fs::path& dir, const std::string& metadata) {
  const Json ours = Json::parse(metadata);
  const fs::path manifest = dir / "manifest.json", generation = dir / kGenerationFile;
  core::remove_stale_temporaries(dir);
  core::remove_stale_temporaries(dir / "shards");
  if (fs::exists(manifest)) {
    const Json theirs = core::read_json_file(manifest);
    const Json& meta = theirs.contains("metadata") ? theirs["metadata"] : Json();
    refuse_old_reading(dir, manifest, meta);
    if (meta != ours)
      throw std::runtime_error(dir.string() + " holds a different dataset (manifest.json: " +
                               first_difference(ours, meta) +
                               "); choose another --out or remove it");
    return true;
  }
  if (fs::exists(generation)) {
    const Json theirs = core::read_json_file(generation);
    refuse_old_reading(dir, generation, theirs);
    if (theirs != ours)
      throw std::runtime_error(
          dir.string() + " holds an unfinished different dataset (" + std::string(kGenerationFile) +
          ": " + first_difference(ours, theirs) + "); choose another --out or remove it");
    return false;
  }
  if (fs::exists(dir)) {
    if (!fs::is_directory(dir))
      throw std::runtime_error(dir.string() + " exists and is not a directory");
    if (!fs::is_empty(dir))
      throw std::runtime_error(dir.string() +
                               " is not empty and holds no ropes dataset (no manifest.json or " +
                               kGenerationFile + "); choose an empty or new directory");
  }
  fs::create_directories(dir);
  const std::string text = ours.dump(2) + "\n";
  core::write_text_file_atomically(generation, text);
  return false;
}

// renders the rows of anchors [first, last) into the shard's columns
void render_anchors(const Setup& s, const DatasetConfig& config, std::uint64_t seed,
                    std::int64_t first, std::int64_t last, int thread, int threads, Worker* w,
                    std::vector<core::NpyArray>* data) {
  const std::size_t image_bytes = static_cast<std::size_t>(s.width) * s.height;
  for (std::int64_t a = first + thread; a < last; a += threads) {
    const auto samples = s.sampler.sample_anchor(seed, static_cast<std::uint64_t>(a));
    for (int r = 0; r < s.regimes; ++r) {
      const std::size_t row = static_cast<std::size_t>((a - first) * s.regimes + r);
      const std::vector<double>& q = samples[static_cast<std::size_t>(r)];
      w->kinematics.set_positions(s.coordinates(q));
      const auto X_BL = w->kinematics.link_poses();
      for (int c = 0; c < s.cameras; ++c)
        w->renderer.render(X_BL, config.rig.cameras[static_cast<std::size_t>(c)],
                           (*data)[0].data.data() + (row * s.cameras + c) * image_bytes);
      for (int j = 0; j < s.joints; ++j) {
        const float angle = static_cast<float>(q[static_cast<std::size_t>(j)]);
        std::memcpy((*data)[1].data.data() + (row * s.joints + j) * 4, &angle, 4);
      }
      const std::int32_t regime = r;
      const std::int64_t anchor = a;
      std::memcpy((*data)[2].data.data() + row * 4, &regime, 4);
      std::memcpy((*data)[3].data.data() + row * 8, &anchor, 8);
    }
  }
}

void check_cameras_see_robot(const Setup& s, const DatasetConfig& config, std::uint64_t seed,
                             Worker* w) {
  w->kinematics.set_positions(s.coordinates(s.sampler.sample_anchor(seed, 0)[0]));
  const auto X_BL = w->kinematics.link_poses();
  const int minimum = std::max(4, s.width * s.height / 1000);
  for (std::size_t c = 0; c < config.rig.cameras.size(); ++c) {
    const Camera& cam = config.rig.cameras[c];
    const int seen = w->renderer.robot_pixels(X_BL, cam);
    if (seen < minimum) {
      const Eigen::Vector3d t = cam.target;
      throw ConfigError(config.file.string() + ": rig camera '" + cam.name + "' (target [" +
                        std::to_string(t.x()) + ", " + std::to_string(t.y()) + ", " +
                        std::to_string(t.z()) + "], distance " + std::to_string(cam.distance) +
                        ", yaw " + std::to_string(cam.yaw_deg) + ", pitch " +
                        std::to_string(cam.pitch_deg) + ", fov " + std::to_string(cam.fov_y_deg) +
                        ") sees " + std::to_string(seen) +
                        " pixels of the robot in anchor 0's observational pose; expected at "
                        "least " +
                        std::to_string(minimum) + ": the camera looks at nothing");
    }
  }
}

// the dataset's metadata: everything its bytes depend on, the GL implementation included
std::string metadata_of(const Setup& s, const DatasetConfig& config, std::uint64_t seed,
                        const std::string& gl) {
  const Json distribution = detail::read_config_object(config.distribution, "distribution config");
  Json cameras = Json::array();
  for (const Camera& c : config.rig.cameras)
    cameras.push_back(c.name);
  // each regime parsed, so that no reader parses "do(panda_joint2)=1"
  Json regimes = Json::array();
  for (std::size_t r = 0; r < s.sampler.regimes().size(); ++r) {
    const InterventionSampler::Regime& regime = s.sampler.regimes()[r];
    const bool observational = regime.joint < 0;
    regimes.push_back(
        {{"name", s.sampler.regime_names()[r]},
         {"joint", observational ? Json() : Json(s.sampler.joint_names()[regime.joint])},
         {"joint_index", observational ? Json() : Json(regime.joint)},
         {"intervention", observational ? Json() : Json(regime.intervention)}});
  }
  const Json meta{{"generator", "ropes-generate"},
                  {"ropes_sim_version", ROPES_SIM_VERSION},
                  {"sim_dataset_version", kSimDatasetVersion},
                  {"config", Json::parse(config.to_json())},
                  {"distribution", distribution},
                  {"robot",
                   {{"name", s.model.name()},
                    {"file", config.robot.filename().string()},
                    {"sha256", core::sha256_file(config.robot)}}},
                  {"renderer", gl},
                  {"seed", seed},
                  {"anchors", config.anchors},
                  {"samples_per_anchor", s.regimes},
                  {"samples", config.anchors * s.regimes},
                  {"images", config.anchors * s.regimes * s.cameras},
                  {"image", {{"width", s.width}, {"height", s.height}}},
                  {"cameras", cameras},
                  {"joint_names", s.sampler.joint_names()},
                  {"regime_names", s.sampler.regime_names()},
                  {"regimes", regimes},
                  {"shards", config.shard_count()}};
  return meta.dump();
}

// sizes the dataset container and the writer can hold
void check_sizes(const Setup& s, const DatasetConfig& config) {
  if (config.shard_count() > (1 << 24))
    throw ConfigError(config.file.string() + ": anchors " + std::to_string(config.anchors) +
                      " at anchors_per_shard " + std::to_string(config.anchors_per_shard) +
                      " make " + std::to_string(config.shard_count()) +
                      " shards; expected at most 16777216 (raise anchors_per_shard)");
  const double bytes =
      static_cast<double>(config.anchors_per_shard) * s.regimes * s.cameras * s.width * s.height;
  if (bytes > 2.0 * (1 << 30))
    throw ConfigError(config.file.string() + ": anchors_per_shard " +
                      std::to_string(config.anchors_per_shard) + " makes image shards of " +
                      std::to_string(bytes / (1 << 30)) +
                      " GiB; expected at most 2 GiB (lower anchors_per_shard)");
}

}  // namespace

std::vector<FramingReach> framing_reach(const DatasetConfig& config, std::uint64_t seed) {
  const Setup s(config);
  Kinematics kinematics(s.model);
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.translation() = SceneOptions().robot_base;  // where generate_dataset's Scene puts it
  std::vector<Eigen::Matrix4d> P;
  std::vector<FramingReach> out(static_cast<std::size_t>(s.cameras));
  for (int c = 0; c < s.cameras; ++c) {
    const Camera& cam = config.rig.cameras[static_cast<std::size_t>(c)];
    P.push_back(cam.projection(s.width, s.height) * cam.X_CW().matrix());
    out[static_cast<std::size_t>(c)].camera = cam.name;
    out[static_cast<std::size_t>(c)].reach = -1;
  }
  for (std::int64_t a = 0; a < config.anchors; ++a) {
    const auto samples = s.sampler.sample_anchor(seed, static_cast<std::uint64_t>(a));
    for (int r = 0; r < s.regimes; ++r) {
      const auto& q = samples[static_cast<std::size_t>(r)];
      kinematics.set_positions(s.coordinates(q));
      const auto X_BL = kinematics.link_poses();
      for (std::size_t l = 0; l < X_BL.size(); ++l) {
        const Eigen::Vector4d p = (X_WB * X_BL[l].translation()).homogeneous();
        for (int c = 0; c < s.cameras; ++c) {
          const Eigen::Vector4d clip = P[static_cast<std::size_t>(c)] * p;
          const bool behind = !(clip.w() > 0);
          const double x = behind ? std::nan("") : clip.x() / clip.w();
          const double y = behind ? std::nan("") : clip.y() / clip.w();
          const double reach =
              behind ? std::numeric_limits<double>::infinity() : std::max(std::abs(x), std::abs(y));
          FramingReach& f = out[static_cast<std::size_t>(c)];
          if (reach > f.reach) {
            f.reach = reach;
            f.beyond_pixels = behind ? std::numeric_limits<double>::infinity()
                                     : std::max((std::abs(x) - 1) * s.width / 2,
                                                (std::abs(y) - 1) * s.height / 2);
            f.x = x;
            f.y = y;
            f.link = s.model.links()[l].name;
            f.anchor = a;
            f.regime = s.sampler.regime_names()[static_cast<std::size_t>(r)];
            f.angles = q;
          }
        }
      }
    }
  }
  return out;
}

void check_framing(const DatasetConfig& config, std::uint64_t seed) {
  const InterventionSampler sampler = InterventionSampler::load(config.distribution);
  for (const FramingReach& f : framing_reach(config, seed)) {
    if (f.beyond_pixels <= kFramingTolerancePixels)
      continue;
    std::string angles;
    for (std::size_t j = 0; j < f.angles.size(); ++j) {
      char v[32];
      std::snprintf(v, sizeof v, " %.3f", f.angles[j]);
      angles += (j ? ", " : "") + sampler.joint_names()[j] + v;
    }
    char where[128];
    if (std::isfinite(f.reach))
      std::snprintf(where, sizeof where,
                    "lands at (%.3f, %.3f) in normalised image coordinates, %.1f px outside "
                    "the image",
                    f.x, f.y, f.beyond_pixels);
    else
      std::snprintf(where, sizeof where, "is behind the camera");
    throw ConfigError(config.file.string() + ": rig '" + config.rig.name + "' camera '" + f.camera +
                      "' loses link '" + f.link + "' from view: at anchor " +
                      std::to_string(f.anchor) + ", regime " + f.regime + " (" + angles +
                      ", seed " + std::to_string(seed) + ") its origin " + where +
                      "; move the camera back (distance), "
                      "widen fov_y_deg, aim target at the middle of the arm's sweep or narrow "
                      "the distribution (ropes-generate --preview-extremes shows the extremes)");
  }
}

GenerateResult generate_dataset(const DatasetConfig& config, const GenerateOptions& options) {
  if (options.threads < 1 || options.threads > 256)
    throw std::invalid_argument("generate_dataset: threads is " + std::to_string(options.threads) +
                                "; expected 1..256");
  if (options.shard_count < 1 || options.shard_index < 0 ||
      options.shard_index >= options.shard_count)
    throw std::invalid_argument("generate_dataset: shard " + std::to_string(options.shard_index) +
                                "/" + std::to_string(options.shard_count) +
                                "; expected k/N with 0 <= k < N");
  // everything that can be wrong with the config is found before the directory is touched
  const Setup s(config);
  check_sizes(s, config);
  const auto scene = Scene::build(s.model);
  std::string gl;
  {
    Worker probe(s.model, scene, s.width, s.height);
    check_cameras_see_robot(s, config, options.seed, &probe);
    gl = probe.renderer.gl_description();
  }
  check_framing(config, options.seed);  // a camera that sees nothing is the clearer message
  const std::string metadata = metadata_of(s, config, options.seed, gl);
  const std::string id = core::sha256_hex(metadata.data(), metadata.size());
  const auto columns = s.columns();
  const int shards = static_cast<int>(config.shard_count());
  GenerateResult result;
  result.warnings = scene->warnings();
  if (prepare_directory(options.out, metadata)) {
    // finished before: its files must still be what the manifest records
    try {
      core::DatasetReader::open(options.out).verify();
    } catch (const core::FileFormatError& e) {
      throw std::runtime_error(std::string(e.what()) + "; remove " +
                               (options.out / "manifest.json").string() +
                               " and run again to redo the damaged shards");
    }
    result.complete = true;
    result.shards_skipped = shards;
    return result;
  }

  // the shards this run owns that are not done yet (a shard of another dataset is redone,
  // and so is one whose files no longer hash to its marker's SHA-256s)
  std::vector<int> todo;
  for (int shard = options.shard_index; shard < shards; shard += options.shard_count) {
    const std::string problem =
        core::dataset_shard_problem(options.out, shard, columns, id, /*check_sha256=*/true);
    if (problem.empty()) {
      ++result.shards_skipped;
    } else {
      if (problem.find("(the file changed after it was written)") != std::string::npos)
        result.warnings.push_back("shard " + std::to_string(shard) + " is redone: " + problem);
      todo.push_back(shard);
    }
  }

  if (!todo.empty()) {
    WorkerPool pool(options.threads, s.model, scene, s.width, s.height);
    int done = 0;
    for (const int shard : todo) {
      const auto start = std::chrono::steady_clock::now();
      const std::int64_t first = shard * config.anchors_per_shard;
      const std::int64_t last = std::min(config.anchors, first + config.anchors_per_shard);
      const std::int64_t rows = (last - first) * s.regimes;
      std::vector<core::NpyArray> data(columns.size());
      for (std::size_t c = 0; c < columns.size(); ++c) {
        data[c].dtype = columns[c].dtype;
        data[c].shape = {rows};
        data[c].shape.insert(data[c].shape.end(), columns[c].row_shape.begin(),
                             columns[c].row_shape.end());
        data[c].data.resize(static_cast<std::size_t>(data[c].element_count()) *
                            core::dtype_size(columns[c].dtype));
      }
      pool.run([&](int t, Worker* w) {
        render_anchors(s, config, options.seed, first, last, t, pool.size(), w, &data);
      });
      core::write_dataset_shard(options.out, shard, columns, data, id);
      ++done;
      const std::int64_t images = rows * s.cameras;
      result.images += images;
      ++result.shards_written;
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (options.progress) {
        options.progress(done, static_cast<int>(todo.size()),
                         "shard " + std::to_string(shard) + " (anchors " + std::to_string(first) +
                             ".." + std::to_string(last - 1) + "): " + std::to_string(images) +
                             " images, " + std::to_string(static_cast<int>(images / seconds)) +
                             " images/s");
      }
      if (options.keep_going && !options.keep_going())
        return result;
    }
  }

  // the manifest, once every shard (from any run) is there
  for (int shard = 0; shard < shards; ++shard)
    if (!core::dataset_shard_complete(options.out, shard, columns, id))
      return result;
  core::write_dataset_manifest(options.out, columns, shards, metadata, id);
  result.complete = true;
  return result;
}

namespace {

// one tile of a contact sheet: a configuration seen by one camera, labelled
struct Tile {
  int row = 0, column = 0, camera = 0;
  std::vector<double> q;  // the distribution's joints
  std::string label;
};

// renders the tiles into a grid (rows x columns) and writes it as a PNG
void write_sheet(const Setup& s, const DatasetConfig& config, Worker* w,
                 const std::vector<Tile>& tiles, int rows, int columns, int scale,
                 const std::filesystem::path& png) {
  const int tile_w = s.width * scale, tile_h = s.height * scale, label = 22, gap = 4;
  cv::Mat sheet(rows * (tile_h + label) + (rows + 1) * gap, columns * tile_w + (columns + 1) * gap,
                CV_8UC1, cv::Scalar(255));
  for (const Tile& t : tiles) {
    w->kinematics.set_positions(s.coordinates(t.q));
    const std::vector<std::uint8_t> image = w->renderer.render(
        w->kinematics.link_poses(), config.rig.cameras[static_cast<std::size_t>(t.camera)]);
    const cv::Mat tile(s.height, s.width, CV_8UC1, const_cast<std::uint8_t*>(image.data()));
    const int x = gap + t.column * (tile_w + gap), y = gap + t.row * (tile_h + label + gap);
    cv::resize(tile, sheet(cv::Rect(x, y + label, tile_w, tile_h)), cv::Size(tile_w, tile_h), 0, 0,
               cv::INTER_NEAREST);
    cv::putText(sheet, t.label, cv::Point(x + 2, y + label - 6), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0), 1, cv::LINE_AA);
  }
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".png", sheet, bytes))
    throw std::runtime_error(png.string() + ": OpenCV could not encode the PNG");
  core::write_file_atomically(png, bytes.data(), bytes.size());
}

// what a preview needs: the config loaded, one renderer, the cameras checked
struct Preview {
  Setup s;
  std::shared_ptr<const Scene> scene;
  Worker w;
  Preview(const DatasetConfig& config, std::uint64_t seed, int scale)
      : s(config), scene(Scene::build(s.model)), w(s.model, scene, s.width, s.height) {
    if (scale < 1 || scale > 16)
      throw std::invalid_argument("preview scale is " + std::to_string(scale) + "; expected 1..16");
    check_cameras_see_robot(s, config, seed, &w);
  }
};

}  // namespace

void write_preview(const DatasetConfig& config, std::uint64_t seed, std::uint64_t anchor,
                   const std::filesystem::path& png, int scale) {
  Preview p(config, seed, scale);
  const Setup& s = p.s;
  const auto samples = s.sampler.sample_anchor(seed, anchor);
  std::vector<Tile> tiles;
  for (int c = 0; c < s.cameras; ++c) {
    for (int r = 0; r < s.regimes; ++r) {
      // short labels: "observational" or "yaw45 obs." (the camera), "do(joint2)=1"
      std::string text = s.sampler.regime_names()[static_cast<std::size_t>(r)];
      for (std::size_t at; (at = text.find("panda_joint")) != std::string::npos;)
        text.replace(at, 11, "joint");
      if (r == 0 && s.cameras > 1)
        text = config.rig.cameras[static_cast<std::size_t>(c)].name + " obs.";
      tiles.push_back({c, r, c, samples[static_cast<std::size_t>(r)], text});
    }
  }
  write_sheet(s, config, &p.w, tiles, s.cameras, s.regimes, scale, png);
}

void write_extremes_preview(const DatasetConfig& config, std::uint64_t seed,
                            const std::filesystem::path& png, int scale) {
  Preview p(config, seed, scale);
  const Setup& s = p.s;
  const Eigen::Isometry3d X_WB = p.scene->X_WB();
  // per camera, the samples whose link origins reach furthest left, right, up and down
  const char* const kSides[4] = {"left", "right", "top", "bottom"};
  std::vector<Tile> tiles;
  for (int c = 0; c < s.cameras; ++c) {
    const Camera& cam = config.rig.cameras[static_cast<std::size_t>(c)];
    const Eigen::Matrix4d P = cam.projection(s.width, s.height) * cam.X_CW().matrix();
    double best[4] = {0, 0, 0, 0};
    Tile extreme[4];
    for (std::int64_t a = 0; a < config.anchors; ++a) {
      const auto samples = s.sampler.sample_anchor(seed, static_cast<std::uint64_t>(a));
      for (int r = 0; r < s.regimes; ++r) {
        const auto& q = samples[static_cast<std::size_t>(r)];
        p.w.kinematics.set_positions(s.coordinates(q));
        for (const auto& X_BL : p.w.kinematics.link_poses()) {
          const Eigen::Vector4d clip = P * (X_WB * X_BL.translation()).homogeneous();
          const double x = clip.x() / clip.w(), y = clip.y() / clip.w();
          const double reach[4] = {-x, x, y, -y};
          for (int k = 0; k < 4; ++k) {
            if (reach[k] > best[k]) {
              best[k] = reach[k];
              char label[64];
              std::snprintf(label, sizeof label, "%s%s %.2f (a%lld)",
                            s.cameras > 1 ? (cam.name + " ").c_str() : "", kSides[k], reach[k],
                            static_cast<long long>(a));
              extreme[k] = {c, k, c, q, label};
            }
          }
        }
      }
    }
    for (const Tile& t : extreme)
      tiles.push_back(t);
  }
  write_sheet(s, config, &p.w, tiles, s.cameras, 4, scale, png);
}

}  // namespace ropes::sim
