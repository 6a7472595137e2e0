#include "ropes_sim/intervention_sampler.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "json_config.hpp"

namespace ropes::sim {

namespace {

using Json = nlohmann::json;

using detail::fail;
using detail::number;

// {mean, variance | std, lower, upper}: the paper's TN_[a,b](mu, sigma^2) names a variance
// (paper line 472), so a distribution file states it as `variance`; `std` is read for users
// who think in standard deviations. Exactly one of the two.
TruncatedNormal truncated_normal(const Json& v, const std::string& file, const std::string& field) {
  if (!v.is_object())
    fail(file, field + " is not an object {mean, variance (or std), lower, upper}");
  for (const char* key : {"mean", "lower", "upper"}) {
    if (!v.contains(key))
      fail(file, field + " lacks '" + key + "'");
  }
  const bool has_variance = v.contains("variance"), has_std = v.contains("std");
  if (has_variance == has_std)
    fail(file, field +
                   (has_variance ? " gives both 'variance' and 'std'"
                                 : " gives neither 'variance' nor 'std'") +
                   "; expected exactly one (the paper's TN(mean, x) takes the variance x)");
  double sigma = 0;
  if (has_variance) {
    const double variance = number(v["variance"], file, field + ".variance");
    if (!(variance > 0) || !std::isfinite(variance)) {
      std::ostringstream text;
      text << variance;
      fail(file, field + ".variance is " + text.str() + "; expected a finite number > 0");
    }
    sigma = std::sqrt(variance);
  } else {
    sigma = number(v["std"], file, field + ".std");
  }
  try {
    return TruncatedNormal(number(v["mean"], file, field + ".mean"), sigma,
                           number(v["lower"], file, field + ".lower"),
                           number(v["upper"], file, field + ".upper"));
  } catch (const std::invalid_argument& e) {
    fail(file, field + ": " + e.what());
  }
}

}  // namespace

InterventionSampler InterventionSampler::load(const std::filesystem::path& path) {
  const std::string file = path.string();
  const Json config = detail::read_config_object(path, "distribution config");
  for (const char* key : {"name", "joints", "observational", "interventions"}) {
    if (!config.contains(key))
      fail(file, std::string("lacks the field '") + key + "'");
  }

  InterventionSampler s;
  s.name_ = config["name"].is_string() ? config["name"].get<std::string>() : "";
  const Json& joints = config["joints"];
  if (!joints.is_array() || joints.empty())
    fail(file, "joints is not a non-empty list of names");
  for (const Json& j : joints) {
    if (!j.is_string())
      fail(file, "joints holds a non-string");
    s.joints_.push_back(j.get<std::string>());
  }
  s.specs_.resize(s.joints_.size());
  const auto index_of = [&](const std::string& name, const std::string& field) {
    for (std::size_t i = 0; i < s.joints_.size(); ++i) {
      if (s.joints_[i] == name)
        return static_cast<int>(i);
    }
    fail(file, field + " names joint '" + name + "', which is not in joints");
  };

  if (config.contains("held")) {
    for (const auto& [name, value] : config["held"].items()) {
      s.specs_[static_cast<std::size_t>(index_of(name, "held"))].held =
          number(value, file, "held." + name);
    }
  }
  for (const auto& [name, value] : config["observational"].items()) {
    s.specs_[static_cast<std::size_t>(index_of(name, "observational"))].observational =
        truncated_normal(value, file, "observational." + name);
  }
  for (const auto& [name, value] : config["interventions"].items()) {
    const int j = index_of(name, "interventions");
    if (!value.is_array() || value.size() != 2) {
      fail(file, "interventions." + name + " must list two distributions");
    }
    for (std::size_t k = 0; k < 2; ++k) {
      s.specs_[static_cast<std::size_t>(j)].interventions.push_back(truncated_normal(
          value[k], file, "interventions." + name + "[" + std::to_string(k) + "]"));
    }
  }
  if (config.contains("sem")) {
    const Json& sem = config["sem"];
    if (!sem.contains("noise") || !sem.contains("parents"))
      fail(file, "sem needs noise and parents");
    s.sem_noise_ = truncated_normal(sem["noise"], file, "sem.noise");
    for (const auto& [child, parents] : sem["parents"].items()) {
      const int c = index_of(child, "sem.parents");
      for (const auto& [parent, weight] : parents.items()) {
        const int p = index_of(parent, "sem.parents." + child);
        if (p >= c) {
          fail(file, "sem.parents." + child + " has parent '" + parent +
                         "', which does not come before it in joints");
        }
        s.specs_[static_cast<std::size_t>(c)].parents.emplace_back(
            p, number(weight, file, "sem.parents." + child + "." + parent));
      }
    }
  }
  // every joint gets a value from somewhere
  for (std::size_t j = 0; j < s.specs_.size(); ++j) {
    const JointSpec& spec = s.specs_[j];
    if (!spec.held && !spec.observational && spec.parents.empty()) {
      fail(file,
           "joint '" + s.joints_[j] + "' is neither held, observational nor a child in the sem");
    }
  }
  s.regimes_.push_back("observational");
  s.regime_info_.push_back({-1, 0});
  for (std::size_t j = 0; j < s.specs_.size(); ++j) {
    if (s.specs_[j].interventions.empty())
      continue;
    s.intervened_.push_back(static_cast<int>(j));
    for (int k = 1; k <= 2; ++k) {
      s.regimes_.push_back("do(" + s.joints_[j] + ")=" + std::to_string(k));
      s.regime_info_.push_back({static_cast<int>(j), k});
    }
  }
  return s;
}

void InterventionSampler::draw_observational(core::PhiloxStream& rng, std::vector<double>* q,
                                             std::vector<double>* noise) const {
  q->assign(specs_.size(), 0.0);
  noise->assign(specs_.size(), 0.0);
  for (std::size_t j = 0; j < specs_.size(); ++j) {
    const JointSpec& spec = specs_[j];
    if (spec.held) {
      (*q)[j] = *spec.held;
      continue;
    }
    if (sem_noise_)
      (*noise)[j] = sem_noise_->sample(rng);
    double value = spec.observational ? spec.observational->sample(rng) : 0.0;
    for (const auto& [p, w] : spec.parents)
      value += w * (*q)[static_cast<std::size_t>(p)];
    (*q)[j] = value + (*noise)[j];
  }
}

void InterventionSampler::propagate(int changed, const std::vector<double>& noise,
                                    std::vector<double>* q) const {
  // joints are in topological order (parents come first), so one pass suffices
  std::vector<bool> moved(specs_.size(), false);
  moved[static_cast<std::size_t>(changed)] = true;
  for (std::size_t j = static_cast<std::size_t>(changed) + 1; j < specs_.size(); ++j) {
    const JointSpec& spec = specs_[j];
    bool depends = false;
    for (const auto& [p, w] : spec.parents)
      depends = depends || moved[static_cast<std::size_t>(p)];
    if (!depends)
      continue;
    double value = 0.0;
    for (const auto& [p, w] : spec.parents)
      value += w * (*q)[static_cast<std::size_t>(p)];
    (*q)[j] = value + noise[j];
    moved[j] = true;
  }
}

std::vector<std::vector<double>> InterventionSampler::sample_anchor(std::uint64_t seed,
                                                                    std::uint64_t anchor) const {
  core::PhiloxStream rng(seed, anchor);
  std::vector<double> base, noise;
  draw_observational(rng, &base, &noise);
  std::vector<std::vector<double>> samples = {base};
  for (int j : intervened_) {
    for (const TruncatedNormal& tn : specs_[static_cast<std::size_t>(j)].interventions) {
      std::vector<double> q = base;
      q[static_cast<std::size_t>(j)] = tn.sample(rng);
      propagate(j, noise, &q);
      samples.push_back(std::move(q));
    }
  }
  return samples;
}

const std::optional<TruncatedNormal>& InterventionSampler::observational(int j) const {
  return specs_.at(static_cast<std::size_t>(j)).observational;
}

const std::vector<TruncatedNormal>& InterventionSampler::interventions(int j) const {
  return specs_.at(static_cast<std::size_t>(j)).interventions;
}

double InterventionSampler::sem_weight(int child, int parent) const {
  for (const auto& [p, w] : specs_.at(static_cast<std::size_t>(child)).parents) {
    if (p == parent)
      return w;
  }
  return 0.0;
}

}  // namespace ropes::sim
