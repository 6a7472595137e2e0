#include "ropes_nn/lr_schedule.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "ropes_core/json_text.hpp"

namespace ropes::nn {

namespace {

using Json = nlohmann::json;
constexpr double kPi = 3.14159265358979323846;

std::string number(double v) {
  return Json(v).dump();
}

// std::invalid_argument "<where>.<field> is <value>; expected <what>" unless ok
void require(bool ok, const std::string& where, const char* field, const std::string& value,
             const char* expected) {
  if (!ok) {
    throw std::invalid_argument(where + "." + field + " is " + value + "; expected " + expected);
  }
}

void check_rate(double lr, const std::string& where, const char* field) {
  require(lr > 0 && std::isfinite(lr), where, field, number(lr), "a finite rate > 0");
}

void check_length(std::int64_t steps, std::int64_t minimum, const std::string& where,
                  const char* field) {
  require(steps >= minimum, where, field, std::to_string(steps),
          minimum == 1 ? "a length >= 1" : "a length >= 2");
}

// value + (start - value) (1 + cos(pi p)) / 2: from start at p = 0 to end at p = 1
double cosine_between(double start, double end, double p) {
  return end + (start - end) / 2.0 * (std::cos(kPi * p) + 1.0);
}

const Json& field_of(const Json& j, const char* name, const std::string& where) {
  const auto it = j.find(name);
  if (it == j.end())
    throw std::invalid_argument(where + ": no field '" + name + "'");
  return *it;
}

double schedule_number(const Json& j, const char* name, const std::string& where) {
  const Json& v = field_of(j, name, where);
  if (!v.is_number()) {
    throw std::invalid_argument(where + "." + name + " is a JSON " + v.type_name() +
                                "; expected a number");
  }
  return v.get<double>();
}

std::int64_t schedule_count(const Json& j, const char* name, const std::string& where) {
  const Json& v = field_of(j, name, where);
  if (!v.is_number_integer()) {
    throw std::invalid_argument(where + "." + name + " is " + core::describe(v) +
                                "; expected an integer");
  }
  return v.get<std::int64_t>();
}

}  // namespace

LrSchedule LrSchedule::constant(double lr) {
  check_rate(lr, "lr_schedule", "lr");
  LrSchedule s;
  s.kind_ = Kind::kConstant;
  s.lr_ = lr;
  return s;
}

LrSchedule LrSchedule::linear_warmup(double lr, std::int64_t warmup_steps) {
  check_rate(lr, "lr_schedule", "lr");
  check_length(warmup_steps, 1, "lr_schedule", "warmup_steps");
  LrSchedule s;
  s.kind_ = Kind::kLinearWarmup;
  s.lr_ = lr;
  s.warmup_steps_ = warmup_steps;
  return s;
}

LrSchedule LrSchedule::cosine(double lr, std::int64_t total_steps, double final_lr,
                              std::int64_t warmup_steps) {
  const std::string where = "lr_schedule";
  check_rate(lr, where, "lr");
  require(final_lr >= 0 && final_lr <= lr, where, "final_lr", number(final_lr),
          "a rate in [0, lr]");
  check_length(total_steps, 1, where, "total_steps");
  require(warmup_steps >= 0 && warmup_steps < total_steps, where, "warmup_steps",
          std::to_string(warmup_steps), "0 <= warmup_steps < total_steps");
  LrSchedule s;
  s.kind_ = Kind::kCosine;
  s.lr_ = lr;
  s.final_lr_ = final_lr;
  s.total_steps_ = total_steps;
  s.warmup_steps_ = warmup_steps;
  return s;
}

LrSchedule LrSchedule::one_cycle(double max_lr, std::int64_t total_steps, double pct_start,
                                 double div_factor, double final_div_factor) {
  const std::string where = "lr_schedule";
  check_rate(max_lr, where, "lr");
  check_length(total_steps, 2, where, "total_steps");
  require(pct_start > 0 && pct_start < 1, where, "pct_start", number(pct_start),
          "a fraction in (0, 1)");
  require(div_factor > 0 && std::isfinite(div_factor), where, "div_factor", number(div_factor),
          "a finite factor > 0");
  require(final_div_factor > 0 && std::isfinite(final_div_factor), where, "final_div_factor",
          number(final_div_factor), "a finite factor > 0");
  LrSchedule s;
  s.kind_ = Kind::kOneCycle;
  s.lr_ = max_lr;
  s.total_steps_ = total_steps;
  s.pct_start_ = pct_start;
  s.div_factor_ = div_factor;
  s.final_div_factor_ = final_div_factor;
  return s;
}

double LrSchedule::rate(std::int64_t step) const {
  if (step < 0) {
    throw std::invalid_argument("LrSchedule::rate: step " + std::to_string(step) +
                                "; expected >= 0");
  }
  const auto t = static_cast<double>(step);
  switch (kind_) {
    case Kind::kConstant:
      return lr_;
    case Kind::kLinearWarmup:
      return step < warmup_steps_ ? lr_ * (t + 1.0) / static_cast<double>(warmup_steps_) : lr_;
    case Kind::kCosine: {
      if (step < warmup_steps_)
        return lr_ * (t + 1.0) / static_cast<double>(warmup_steps_);
      if (step >= total_steps_)
        return final_lr_;
      const double p = (t - static_cast<double>(warmup_steps_)) /
                       static_cast<double>(total_steps_ - warmup_steps_);
      return cosine_between(lr_, final_lr_, p);
    }
    case Kind::kOneCycle: {
      // PyTorch's two phases: [0, up_end] rising, (up_end, total - 1] falling
      const double initial = lr_ / div_factor_;
      const double minimum = initial / final_div_factor_;
      const double up_end = pct_start_ * static_cast<double>(total_steps_) - 1.0;
      const double down_end = static_cast<double>(total_steps_) - 1.0;
      if (t <= up_end)
        return cosine_between(initial, lr_, up_end > 0 ? t / up_end : 1.0);
      const double p = std::min(1.0, (t - up_end) / (down_end - up_end));
      return cosine_between(lr_, minimum, p);
    }
  }
  return lr_;
}

const char* LrSchedule::kind_name() const {
  switch (kind_) {
    case Kind::kConstant:
      return "constant";
    case Kind::kLinearWarmup:
      return "linear_warmup";
    case Kind::kCosine:
      return "cosine";
    case Kind::kOneCycle:
      return "one_cycle";
  }
  return "?";
}

std::string LrSchedule::to_json() const {
  Json j = {{"kind", kind_name()}, {"lr", lr_}};
  switch (kind_) {
    case Kind::kConstant:
      break;
    case Kind::kLinearWarmup:
      j["warmup_steps"] = warmup_steps_;
      break;
    case Kind::kCosine:
      j["final_lr"] = final_lr_;
      j["total_steps"] = total_steps_;
      j["warmup_steps"] = warmup_steps_;
      break;
    case Kind::kOneCycle:
      j["total_steps"] = total_steps_;
      j["pct_start"] = pct_start_;
      j["div_factor"] = div_factor_;
      j["final_div_factor"] = final_div_factor_;
      break;
  }
  return j.dump();
}

LrSchedule LrSchedule::from_json(const std::string& text, const std::string& where) {
  Json j;
  const std::string problem = core::parse_json(text, &j);
  if (!problem.empty())
    throw std::invalid_argument(where + " " + problem);
  if (!j.is_object())
    throw std::invalid_argument(where + " is " + core::describe(j) + "; expected an object");
  const Json& kind = field_of(j, "kind", where);
  const std::string name = kind.is_string() ? kind.get<std::string>() : "";
  // the factories' checks, with `where` in their messages
  try {
    // fields read in a fixed order, so the first one missing is the one named
    if (name == "constant")
      return constant(schedule_number(j, "lr", where));
    if (name == "linear_warmup") {
      const double lr = schedule_number(j, "lr", where);
      return linear_warmup(lr, schedule_count(j, "warmup_steps", where));
    }
    if (name == "cosine") {
      const double lr = schedule_number(j, "lr", where);
      const std::int64_t total = schedule_count(j, "total_steps", where);
      const double final_lr = schedule_number(j, "final_lr", where);
      return cosine(lr, total, final_lr, schedule_count(j, "warmup_steps", where));
    }
    if (name == "one_cycle") {
      const double lr = schedule_number(j, "lr", where);
      const std::int64_t total = schedule_count(j, "total_steps", where);
      const double pct = schedule_number(j, "pct_start", where);
      const double div = schedule_number(j, "div_factor", where);
      return one_cycle(lr, total, pct, div, schedule_number(j, "final_div_factor", where));
    }
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    const std::string generic = "lr_schedule";
    if (where != generic && message.compare(0, generic.size(), generic) == 0)
      throw std::invalid_argument(where + message.substr(generic.size()));
    throw;
  }
  throw std::invalid_argument(where + ".kind is " + core::describe(kind) +
                              "; expected \"constant\", \"linear_warmup\", \"cosine\" or "
                              "\"one_cycle\"");
}

bool LrSchedule::operator==(const LrSchedule& o) const {
  return kind_ == o.kind_ && lr_ == o.lr_ && final_lr_ == o.final_lr_ &&
         warmup_steps_ == o.warmup_steps_ && total_steps_ == o.total_steps_ &&
         pct_start_ == o.pct_start_ && div_factor_ == o.div_factor_ &&
         final_div_factor_ == o.final_div_factor_;
}

}  // namespace ropes::nn
