#pragma once
/// @file lr_schedule.hpp
/// LrSchedule: the learning rate as a function of the optimiser step — constant, linear
/// warm-up, cosine decay (with an optional warm-up) and one-cycle. A small value type: the
/// training step asks it for the rate of step t (train_step.hpp), and a checkpoint stores it
/// as JSON with the step count (checkpoint.hpp), so a resumed run continues the same curve.
///
/// `step` counts the updates already made: rate(0) is the rate of the first update. Past
/// the end of a finite schedule the last rate holds (PyTorch's cosine schedule would rise
/// again, its one-cycle schedule would throw).

#include <cstdint>
#include <string>

namespace ropes::nn {

class LrSchedule {
 public:
  enum class Kind { kConstant, kLinearWarmup, kCosine, kOneCycle };

  /// lr at every step. lr > 0.
  static LrSchedule constant(double lr);
  /// lr * (t + 1) / warmup_steps for t < warmup_steps, then lr (PyTorch's
  /// LinearLR(start_factor = 1 / warmup_steps, total_iters = warmup_steps - 1)).
  /// lr > 0, warmup_steps >= 1.
  static LrSchedule linear_warmup(double lr, std::int64_t warmup_steps);
  /// Linear warm-up over the first warmup_steps (as above; none when 0), then
  /// final_lr + (lr - final_lr) (1 + cos(pi (t - W) / (T - W))) / 2 up to t = T, then final_lr
  /// (with W = 0: PyTorch's CosineAnnealingLR(T_max = T, eta_min = final_lr) up to T).
  /// lr > 0, 0 <= final_lr <= lr, total_steps >= 1, 0 <= warmup_steps < total_steps.
  static LrSchedule cosine(double lr, std::int64_t total_steps, double final_lr = 0.0,
                           std::int64_t warmup_steps = 0);
  /// PyTorch's OneCycleLR (anneal_strategy "cos", two phases, cycle_momentum off): from
  /// max_lr / div_factor up to max_lr at t = pct_start * total_steps - 1, then down to
  /// max_lr / div_factor / final_div_factor at t = total_steps - 1, both by cosine.
  /// max_lr > 0, total_steps >= 2, 0 < pct_start < 1, div_factor > 0, final_div_factor > 0.
  static LrSchedule one_cycle(double max_lr, std::int64_t total_steps, double pct_start = 0.3,
                              double div_factor = 25.0, double final_div_factor = 1e4);

  /// The rate of update t (t >= 0, else std::invalid_argument).
  double rate(std::int64_t step) const;

  Kind kind() const { return kind_; }
  /// "constant", "linear_warmup", "cosine" or "one_cycle".
  const char* kind_name() const;

  /// The schedule as a JSON object, e.g. {"kind":"cosine","lr":0.001,"final_lr":0.0,
  /// "total_steps":1000,"warmup_steps":100}; doubles print so that they read back exactly.
  std::string to_json() const;
  /// Reads to_json's form. Throws std::invalid_argument naming `where`, the field, its value
  /// and what was expected (unknown kind, missing or mistyped field, a negative rate, a zero
  /// length...), with the same checks as the factory functions.
  static LrSchedule from_json(const std::string& text, const std::string& where = "lr_schedule");

  bool operator==(const LrSchedule& other) const;
  bool operator!=(const LrSchedule& other) const { return !(*this == other); }

 private:
  LrSchedule() = default;
  Kind kind_ = Kind::kConstant;
  double lr_ = 0;  // constant, warm-up and cosine: the peak; one-cycle: max_lr
  double final_lr_ = 0;
  std::int64_t warmup_steps_ = 0;
  std::int64_t total_steps_ = 0;
  double pct_start_ = 0.3, div_factor_ = 25.0, final_div_factor_ = 1e4;
};

}  // namespace ropes::nn
