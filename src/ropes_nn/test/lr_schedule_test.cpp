// LrSchedule: the rates of PyTorch's schedulers (the witness: test/fixtures/lr_schedules.json,
// written by test/make_lr_schedule_fixture.py with Debian's python3-torch 1.13), exact JSON
// round trips, and refusals that name the field.
#include "ropes_nn/lr_schedule.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>

namespace ropes::nn {
namespace {

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

using Json = nlohmann::json;

LrSchedule from_params(const std::string& name, const Json& p) {
  if (name == "linear_warmup")
    return LrSchedule::linear_warmup(p["lr"], p["warmup_steps"]);
  if (name.rfind("cosine", 0) == 0)
    return LrSchedule::cosine(p["lr"], p["total_steps"], p["final_lr"], p["warmup_steps"]);
  return LrSchedule::one_cycle(p["lr"], p["total_steps"], p["pct_start"], p["div_factor"],
                               p["final_div_factor"]);
}

TEST(LrScheduleGolden, RatesMatchPyTorchSchedulers) {
  std::ifstream in(std::string(ROPES_NN_TEST_FIXTURES) + "/lr_schedules.json");
  ASSERT_TRUE(in) << "fixture missing";
  const Json fixture = Json::parse(in);
  ASSERT_EQ(fixture["cases"].size(), 5u);
  for (const auto& [name, c] : fixture["cases"].items()) {
    const LrSchedule s = from_params(name, c["params"]);
    const Json& rates = c["rates"];
    for (std::size_t t = 0; t < rates.size(); ++t) {
      const double expected = rates[t];
      // PyTorch updates some rates recursively: equal to the closed form up to rounding
      EXPECT_NEAR(s.rate(static_cast<std::int64_t>(t)), expected, 1e-12 + 1e-9 * expected)
          << name << " step " << t;
    }
  }
}

TEST(LrSchedule, HoldsTheLastRatePastTheEnd) {
  const LrSchedule cosine = LrSchedule::cosine(1e-3, 10, 1e-5);
  EXPECT_DOUBLE_EQ(cosine.rate(0), 1e-3);
  EXPECT_DOUBLE_EQ(cosine.rate(10), 1e-5);
  EXPECT_DOUBLE_EQ(cosine.rate(1000), 1e-5);
  const LrSchedule cycle = LrSchedule::one_cycle(1e-2, 20);
  EXPECT_DOUBLE_EQ(cycle.rate(19), 1e-2 / 25 / 1e4);
  EXPECT_DOUBLE_EQ(cycle.rate(500), cycle.rate(19));
  EXPECT_DOUBLE_EQ(LrSchedule::linear_warmup(2e-3, 4).rate(400), 2e-3);
  EXPECT_DOUBLE_EQ(LrSchedule::constant(3e-4).rate(7), 3e-4);
  EXPECT_THROW(cosine.rate(-1), std::invalid_argument);
}

TEST(LrSchedule, JsonRoundTripIsExact) {
  for (const LrSchedule& s :
       {LrSchedule::constant(0.1 + 0.2), LrSchedule::linear_warmup(1.0 / 3.0, 7),
        LrSchedule::cosine(3e-3, 1000, 1e-7, 100), LrSchedule::one_cycle(7e-5, 123, 0.31, 17, 3)}) {
    const LrSchedule back = LrSchedule::from_json(s.to_json());
    EXPECT_EQ(back, s) << s.to_json();
    EXPECT_EQ(back.to_json(), s.to_json());
    for (std::int64_t t : {0, 1, 50, 99, 122, 999})
      EXPECT_EQ(back.rate(t), s.rate(t));
  }
  EXPECT_EQ(LrSchedule::cosine(1e-3, 10).to_json(),
            R"({"final_lr":0.0,"kind":"cosine","lr":0.001,"total_steps":10,"warmup_steps":0})");
}

TEST(LrSchedule, RefusesNegativeRatesZeroLengthsAndMalformedJsonByField) {
  auto error = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_CONTAINS(error([] { LrSchedule::constant(-1e-3); }),
                  "lr_schedule.lr is -0.001; expected a finite rate > 0");
  EXPECT_CONTAINS(error([] { LrSchedule::constant(0); }), "lr_schedule.lr is 0.0");
  EXPECT_CONTAINS(error([] { LrSchedule::linear_warmup(1e-3, 0); }),
                  "lr_schedule.warmup_steps is 0; expected a length >= 1");
  EXPECT_CONTAINS(error([] { LrSchedule::cosine(1e-3, 0); }),
                  "lr_schedule.total_steps is 0; expected a length >= 1");
  EXPECT_CONTAINS(error([] { LrSchedule::cosine(1e-3, 10, 2e-3); }),
                  "lr_schedule.final_lr is 0.002; expected a rate in [0, lr]");
  EXPECT_CONTAINS(error([] { LrSchedule::cosine(1e-3, 10, 0, 10); }),
                  "lr_schedule.warmup_steps is 10; expected 0 <= warmup_steps < total_steps");
  EXPECT_CONTAINS(error([] { LrSchedule::one_cycle(1e-3, 1); }),
                  "lr_schedule.total_steps is 1; expected a length >= 2");
  EXPECT_CONTAINS(error([] { LrSchedule::one_cycle(1e-3, 10, 1.0); }),
                  "lr_schedule.pct_start is 1.0; expected a fraction in (0, 1)");
  EXPECT_CONTAINS(error([] { LrSchedule::one_cycle(1e-3, 10, 0.3, 0); }),
                  "lr_schedule.div_factor is 0.0");
  EXPECT_CONTAINS(error([] { LrSchedule::from_json("{", "run.json/schedule"); }),
                  "run.json/schedule is not JSON");
  EXPECT_CONTAINS(error([] { LrSchedule::from_json("[1]", "cfg"); }),
                  "cfg is a JSON array; expected an object");
  EXPECT_CONTAINS(error([] { LrSchedule::from_json(R"({"kind":"step","lr":1})", "cfg"); }),
                  "cfg.kind is \"step\"; expected \"constant\", \"linear_warmup\", \"cosine\" or "
                  "\"one_cycle\"");
  EXPECT_CONTAINS(error([] { LrSchedule::from_json(R"({"kind":"cosine","lr":1e-3})", "cfg"); }),
                  "cfg: no field 'total_steps'");
  EXPECT_CONTAINS(
      error([] {
        LrSchedule::from_json(
            R"({"kind":"cosine","lr":-2,"total_steps":5,"final_lr":0,"warmup_steps":0})", "cfg");
      }),
      "cfg.lr is -2.0; expected a finite rate > 0");
  EXPECT_CONTAINS(error([] {
                    LrSchedule::from_json(R"({"kind":"linear_warmup","lr":1,"warmup_steps":2.5})",
                                          "cfg");
                  }),
                  "cfg.warmup_steps is 2.5; expected an integer");
}

}  // namespace
}  // namespace ropes::nn
