// The trainer's stage 2 at the tiny preset's size: one LDR a joint, its held-out accuracy
// and the Bayes accuracy of its interventions recorded in run.json; and a run stopped inside
// the stage, in the second joint's LDR, that resumes to the bytes of a run never stopped
// (the finished joint is kept, the stopped one restarts).
#include <ropes_nn/checkpoint.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "ropes_crl/networks.hpp"
#include "trainer_stage_fixture.hpp"

namespace ropes::crl::test_support {
namespace {

namespace fs = std::filesystem;

using TrainerLdr = TrainerStage;

TEST_F(TrainerLdr, TrainsOneLdrAJointAndRecordsItAgainstBayes) {
  const fs::path run = train_to("run", 2, options_);
  const RunDirectory r = RunDirectory::open(run);
  EXPECT_FALSE(r.complete());
  EXPECT_FALSE(fs::exists(run / "ae2.a.safetensors"));
  for (const char* joint : kJoints) {
    EXPECT_TRUE(fs::exists(run / (std::string("ldr.") + joint + ".safetensors"))) << joint;
    const std::optional<LdrRecord> l = r.ldr(joint);
    ASSERT_TRUE(l.has_value()) << joint;
    EXPECT_GE(l->held_out_accuracy, 0.0);
    EXPECT_LE(l->held_out_accuracy, 1.0);
    // the two interventions (means -0.6 and 0.6, truncated to [-1.4, 1.4]) overlap a
    // little: Bayes is well above chance and below 1
    EXPECT_GT(l->bayes_accuracy, 0.7) << joint;
    EXPECT_LT(l->bayes_accuracy, 1.0) << joint;
    EXPECT_GE(l->epochs, 1);
    EXPECT_LE(l->epochs, 2);
  }
  std::size_t per_joint[2] = {0, 0};
  for (const nlohmann::json& rec : records(run, "ldr"))
    ++per_joint[rec["joint"] == kJoints[0] ? 0 : 1];
  EXPECT_EQ(per_joint[0], 2u);  // an epoch a record
  EXPECT_EQ(per_joint[1], 2u);
}

TEST_F(TrainerLdr, AStopInsideTheStageResumesToTheSameBytes) {
  const fs::path whole = train_to("whole", 2, options_);
  TrainOptions stopping = options_;
  stopping.on_metrics = [](const nlohmann::json& rec) {
    if (rec.value("stage", "") == "ldr" && rec.value("joint", "") == kJoints[1])
      throw std::runtime_error("stopped in the LDR of b");
  };
  EXPECT_THROW(train_to("stopped", 2, stopping), std::runtime_error);
  const fs::path run = dir_ / "stopped";
  EXPECT_TRUE(fs::exists(run / "ldr.a.safetensors"));
  EXPECT_FALSE(fs::exists(run / "ldr.b.safetensors"));
  train_to("stopped", 2, options_);
  for (const char* f : {"ae1.safetensors", "codes.npy", "ldr.a.safetensors", "ldr.b.safetensors"})
    EXPECT_EQ(file_bytes(run / f), file_bytes(whole / f)) << f << " differs after the resume";
  const RunDirectory a = RunDirectory::open(run), b = RunDirectory::open(whole);
  for (const char* joint : kJoints)
    EXPECT_EQ(a.ldr(joint)->held_out_accuracy, b.ldr(joint)->held_out_accuracy) << joint;
  // the stopped joint's records are written again, not twice
  EXPECT_EQ(records(run, "ldr").size(), records(whole, "ldr").size());
}

TEST_F(TrainerLdr, EachMemberOfAnEnsembleTrainsAsASingleLdrWould) {
  // one epoch (so that early stopping keeps the same epoch's weights in both runs), with the
  // pair loss so that both of a member's terms are checked
  config_.ldr_training.max_epochs = 1;
  config_.ldr_training.pair_loss.weight = 1.0;
  const fs::path single = train_to("single", 2, options_);
  config_.ldr.members = 2;
  const fs::path ensemble = train_to("ensemble", 2, options_);
  for (const char* joint : kJoints) {
    const std::string file = std::string("ldr.") + joint + ".safetensors";
    LdrSpec one = config_.ldr;
    one.members = 1;
    Ldr a(one), b(config_.ldr);
    nn::load_module(a, single / file);
    nn::load_module(b, ensemble / file);
    // member 0 has the single LDR's names and seed: its loss, alone, gives it the single LDR's
    // steps, to the bit (with 2 members the ensemble's mean over both members' terms, times 2,
    // only scales by powers of two); trained on the members' mean logit instead, it differs by
    // 0.002 (checked by hand)
    const auto pa = a.named_parameters(), pb = b.named_parameters();
    ASSERT_EQ(pb.size(), 2 * pa.size());
    double most = 0, moved = 0;
    for (std::size_t i = 0; i < pa.size(); ++i) {
      ASSERT_EQ(pa[i].first, pb[i].first);
      const std::vector<float> x = pa[i].second.to_vector(), y = pb[i].second.to_vector();
      for (std::size_t e = 0; e < x.size(); ++e)
        most = std::max(most, static_cast<double>(std::fabs(x[e] - y[e])));
    }
    // member 1 is trained too, from its own start: it differs from member 0
    for (std::size_t i = 0; i < pa.size(); ++i) {
      const std::vector<float> x = pb[i].second.to_vector(),
                               y = pb[pa.size() + i].second.to_vector();
      for (std::size_t e = 0; e < x.size(); ++e)
        moved = std::max(moved, static_cast<double>(std::fabs(x[e] - y[e])));
    }
    EXPECT_EQ(most, 0.0) << joint;
    EXPECT_GT(moved, 1e-2) << joint;
  }
  const RunDirectory r = RunDirectory::open(ensemble);
  EXPECT_TRUE(r.ldr(kJoints[0]).has_value());
}

// ldr.weight_average saves the average of the weights over the steps, which starts at the
// initial weights w0 and after step t mixes in the trained weights with d_t = min(decay,
// (1 + t) / (10 + t)). With one step (one batch an epoch, one epoch) the saved weights are
// d_0 w0 + (1 - d_0) w1, w1 the plain run's: decay 0.5 gives 0.1 w0 + 0.9 w1 and decay 0.05
// gives 0.05 w0 + 0.95 w1, which eliminating w0 is the midpoint of the first and w1. The
// witness is that algebra; a saved copy of the trained weights, or a decay without its warm-up
// (0.5 w0 + 0.5 w1), fails it.
TEST_F(TrainerLdr, TheWeightAverageIsSavedAndStartsFromTheInitialWeights) {
  config_.ldr_training.max_epochs = 1;
  config_.ldr_training.batch_size = 1 << 20;  // every training row in one batch: one step
  const fs::path plain = train_to("plain", 2, options_);
  config_.ldr_training.weight_average.decay = 0.5;
  const fs::path half = train_to("half", 2, options_);
  config_.ldr_training.weight_average.decay = 0.05;
  const fs::path twentieth = train_to("twentieth", 2, options_);
  for (const char* joint : kJoints) {
    const std::string file = std::string("ldr.") + joint + ".safetensors";
    Ldr w1(config_.ldr), a1(config_.ldr), a2(config_.ldr);
    nn::load_module(w1, plain / file);
    nn::load_module(a1, half / file);
    nn::load_module(a2, twentieth / file);
    const auto p1 = w1.named_parameters(), q1 = a1.named_parameters(), q2 = a2.named_parameters();
    ASSERT_EQ(p1.size(), q1.size());
    double worst = 0, moved = 0;
    for (std::size_t i = 0; i < p1.size(); ++i) {
      const std::vector<float> w = p1[i].second.to_vector(), x = q1[i].second.to_vector(),
                               y = q2[i].second.to_vector();
      for (std::size_t e = 0; e < w.size(); ++e) {
        const double expected = 0.5 * (static_cast<double>(x[e]) + static_cast<double>(w[e]));
        worst = std::max(
            worst, std::fabs(static_cast<double>(y[e]) - expected) / (1e-3 + std::fabs(expected)));
        moved = std::max(moved, static_cast<double>(std::fabs(x[e] - w[e])));
      }
    }
    EXPECT_LT(worst, 1e-5) << joint;
    EXPECT_GT(moved, 1e-4) << joint << ": the average saved the trained weights";
  }
}

// ldr.all_regimes: one classifier over the dataset's five regimes (the observational one and
// each joint's two interventions); each joint's LDR file holds its trunk and the difference of
// its two output columns (Networks.ARegimeClassifiersRatioIsTheDifferenceOfTwoOutputs checks
// that difference), and run.json and metrics.jsonl record each joint as before
TEST_F(TrainerLdr, OneClassifierOverEveryRegimeWritesEachJointsLdr) {
  config_.ldr_training.all_regimes.on = true;
  const fs::path run = train_to("run", 2, options_);
  Ldr a(config_.ldr), b(config_.ldr);
  nn::load_module(a, run / "ldr.a.safetensors");
  nn::load_module(b, run / "ldr.b.safetensors");
  const auto pa = a.named_parameters(), pb = b.named_parameters();
  ASSERT_EQ(pa.size(), pb.size());
  for (std::size_t i = 0; i < pa.size(); ++i) {
    if (pa[i].first.rfind("out.", 0) == 0)
      EXPECT_NE(pa[i].second.to_vector(), pb[i].second.to_vector()) << pa[i].first;
    else
      EXPECT_EQ(pa[i].second.to_vector(), pb[i].second.to_vector())
          << pa[i].first << ": the joints' LDRs do not share the trunk";
  }
  const RunDirectory r = RunDirectory::open(run);
  for (const char* joint : kJoints) {
    const std::optional<LdrRecord> l = r.ldr(joint);
    ASSERT_TRUE(l.has_value()) << joint;
    EXPECT_GE(l->held_out_accuracy, 0.0);
    EXPECT_LE(l->held_out_accuracy, 1.0);
    EXPECT_GT(l->bayes_accuracy, 0.7) << joint;
    EXPECT_GE(l->epochs, 1);
    EXPECT_LE(l->epochs, 2);
  }
  std::map<std::string, std::size_t> per;
  for (const nlohmann::json& rec : records(run, "ldr"))
    ++per[rec["joint"].get<std::string>()];
  EXPECT_EQ(per["all_regimes"], 2u);  // an epoch a record
  EXPECT_EQ(per[kJoints[0]], 2u);
  EXPECT_EQ(per[kJoints[1]], 2u);
  // a plain run's LDRs differ: the option is not ignored
  config_.ldr_training.all_regimes.on = false;
  const fs::path plain = train_to("plain", 2, options_);
  EXPECT_NE(file_bytes(plain / "ldr.a.safetensors"), file_bytes(run / "ldr.a.safetensors"));
}

// a stop inside the stage trains the classifier again from its start, to the bytes and the
// records of a run never stopped
TEST_F(TrainerLdr, AStopInsideTheAllRegimesStageResumesToTheSameBytes) {
  config_.ldr_training.all_regimes.on = true;
  config_.ldr_training.pair_loss.weight = 1.0;
  const fs::path whole = train_to("whole", 2, options_);
  TrainOptions stopping = options_;
  stopping.on_metrics = [](const nlohmann::json& rec) {
    if (rec.value("joint", "") == "all_regimes" && rec.value("epoch", 0) == 2)
      throw std::runtime_error("stopped in the second epoch");
  };
  EXPECT_THROW(train_to("stopped", 2, stopping), std::runtime_error);
  const fs::path run = dir_ / "stopped";
  EXPECT_FALSE(fs::exists(run / "ldr.a.safetensors"));
  train_to("stopped", 2, options_);
  for (const char* f : {"ldr.a.safetensors", "ldr.b.safetensors"})
    EXPECT_EQ(file_bytes(run / f), file_bytes(whole / f)) << f << " differs after the resume";
  EXPECT_EQ(records(run, "ldr").size(), records(whole, "ldr").size());
}

// label-free: on a dataset whose angles are noise, with the pair loss and the weight average
// too, the same bytes
TEST_F(TrainerLdr, OneClassifierOverEveryRegimeReadsNoAngle) {
  const fs::path noise = dir_ / "noise";
  write_two_bar_dataset(noise, config_.cameras, config_.image_size, true, true);
  ASSERT_NE(file_bytes(noise / "shards" / "angles-00000.npy"),
            file_bytes(data() / "shards" / "angles-00000.npy"));
  config_.ldr_training.all_regimes.on = true;
  config_.ldr_training.pair_loss.weight = 1.0;
  config_.ldr_training.weight_average.decay = 0.9;
  const fs::path run = train_to("run", 2, options_);
  TrainOptions o = options_;
  o.last_stage = 2;
  train(config_, noise, dir_ / "noise_run", o);
  for (const char* f : {"ldr.a.safetensors", "ldr.b.safetensors"})
    EXPECT_EQ(file_bytes(dir_ / "noise_run" / f), file_bytes(run / f))
        << f << ": the angles reached the training";
}

}  // namespace
}  // namespace ropes::crl::test_support
