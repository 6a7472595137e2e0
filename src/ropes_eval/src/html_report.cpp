#include "ropes_eval/html_report.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/run_directory.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "json_file.hpp"
#include "png.hpp"
#include "ropes_eval/occlusion.hpp"
#include "ropes_eval/supervised.hpp"
#include "text_format.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;
using detail::fmt;

namespace {

// scatter points in blue; curves in colours that are neither blue nor the heat map's orange
// (test/report_screenshot_check.py tells the plots apart by them)
const char* const kInk = "#1f5fa8";
const char* const kSeries[] = {"#d1495b", "#2e933c", "#00798c", "#8c564b",
                               "#c71585", "#808000", "#5a5a5a", "#b03060"};

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

// about five round tick values covering [lo, hi]
std::vector<double> ticks(double lo, double hi) {
  const double span = hi - lo;
  if (!(span > 0))
    return {lo};
  const double raw = span / 5, mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double step = raw / mag < 1.5   ? mag
                      : raw / mag < 3.5 ? 2 * mag
                      : raw / mag < 7.5 ? 5 * mag
                                        : 10 * mag;
  // by index, at most a dozen: a span of a few ulps must not loop on v += step
  std::vector<double> t;
  const double first = std::ceil(lo / step);
  for (int i = 0; i < 12; ++i) {
    const double v = (first + i) * step;
    if (v > hi + 1e-9 * span)
      break;
    t.push_back(std::fabs(v) < 1e-12 * span ? 0.0 : v);
  }
  return t;
}

std::string tick_label(double v) {
  char b[32];
  if (v != 0 && (std::fabs(v) < 1e-3 || std::fabs(v) >= 1e6))
    std::snprintf(b, sizeof b, "%.0e", v);
  else
    std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// a plot frame: data ranges mapped into a w x h box inside margins, axes, ticks and labels
struct Frame {
  double x0, x1, y0, y1;  // data ranges
  bool log_y = false, log_x = false;
  int w = 300, h = 240, left = 52, right = 12, top = 26, bottom = 40;
  double px(double x) const {
    if (log_x)
      return left + (std::log10(x) - std::log10(x0)) / (std::log10(x1) - std::log10(x0)) * w;
    return left + (x - x0) / (x1 - x0) * w;
  }
  double py(double y) const {
    const double v = log_y ? std::log10(y) : y;
    const double a = log_y ? std::log10(y0) : y0, b = log_y ? std::log10(y1) : y1;
    return top + h - (v - a) / (b - a) * h;
  }
  std::string open(const std::string& title, const std::string& xlabel, const std::string& ylabel,
                   const std::string& css_class) const {
    std::ostringstream s;
    const int W = left + w + right, H = top + h + bottom;
    s << "<svg class=\"" << css_class << "\" xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W
      << "\" height=\"" << H << "\" viewBox=\"0 0 " << W << " " << H << "\">"
      << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << w << "\" height=\"" << h
      << "\" fill=\"#fff\" stroke=\"#333\"/>"
      << "<text x=\"" << left + w / 2 << "\" y=\"16\" text-anchor=\"middle\" font-size=\"12\">"
      << escape(title) << "</text>"
      << "<text x=\"" << left + w / 2 << "\" y=\"" << H - 6
      << "\" text-anchor=\"middle\" font-size=\"11\">" << escape(xlabel) << "</text>"
      << "<text transform=\"translate(12," << top + h / 2
      << ") rotate(-90)\" text-anchor=\"middle\" font-size=\"11\">" << escape(ylabel) << "</text>";
    std::vector<double> xt;
    if (log_x) {
      for (double d = std::pow(10.0, std::floor(std::log10(x0))); d <= x1 * 1.001; d *= 10)
        for (double m : {1.0, 2.0, 5.0})
          if (m * d >= x0 * 0.999 && m * d <= x1 * 1.001)
            xt.push_back(m * d);
    } else {
      xt = ticks(x0, x1);
    }
    for (double t : xt)
      s << "<line x1=\"" << num(px(t)) << "\" x2=\"" << num(px(t)) << "\" y1=\"" << top + h
        << "\" y2=\"" << top + h + 4 << "\" stroke=\"#333\"/><text x=\"" << num(px(t)) << "\" y=\""
        << top + h + 15 << "\" text-anchor=\"middle\" font-size=\"10\">" << tick_label(t)
        << "</text>";
    std::vector<double> yt;
    if (log_y) {
      // decades; 2 and 5 between them when the range spans under two decades
      const bool fine = std::log10(y1) - std::log10(y0) < 2;
      for (double e = std::floor(std::log10(y0)); e <= std::ceil(std::log10(y1)); e += 1)
        for (double m : {1.0, 2.0, 5.0}) {
          const double t = m * std::pow(10.0, e);
          if ((m == 1.0 || fine) && t >= y0 * 0.999 && t <= y1 * 1.001)
            yt.push_back(t);
        }
    } else {
      yt = ticks(y0, y1);
    }
    for (double t : yt)
      s << "<line x1=\"" << left - 4 << "\" x2=\"" << left << "\" y1=\"" << num(py(t)) << "\" y2=\""
        << num(py(t)) << "\" stroke=\"#333\"/><text x=\"" << left - 6 << "\" y=\"" << num(py(t) + 3)
        << "\" text-anchor=\"end\" font-size=\"10\">" << tick_label(t) << "</text>";
    return s.str();
  }
};

// ROPES' estimate against the true angle on one suite's best repeat (the paper's scatter
// figures), the identity dashed
std::string scatter(const std::vector<double>& truth, const std::vector<double>& estimate,
                    const std::string& title) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const std::vector<double>* v : {&truth, &estimate})
    for (double x : *v)
      if (std::isfinite(x)) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
  // a range of (almost) one value gets a unit around it
  if (!(hi - lo > 1e-9 * std::max({1.0, std::fabs(lo), std::fabs(hi)}))) {
    lo -= 1;
    hi += 1;
  }
  const double pad = 0.04 * (hi - lo);
  Frame f{lo - pad, hi + pad, lo - pad, hi + pad};
  f.w = f.h = 240;
  std::ostringstream s;
  s << f.open(title, "true angle (rad)", "estimate (rad)", "plot scatter");
  s << "<line x1=\"" << num(f.px(lo)) << "\" y1=\"" << num(f.py(lo)) << "\" x2=\"" << num(f.px(hi))
    << "\" y2=\"" << num(f.py(hi)) << "\" stroke=\"#999\" stroke-dasharray=\"4 3\"/>";
  for (std::size_t i = 0; i < truth.size() && i < estimate.size(); ++i)
    if (std::isfinite(truth[i]) && std::isfinite(estimate[i]))
      s << "<circle cx=\"" << num(f.px(truth[i])) << "\" cy=\"" << num(f.py(estimate[i]))
        << "\" r=\"1.8\" fill=\"" << kInk << "\" fill-opacity=\"0.55\"/>";
  s << "</svg>";
  return s.str();
}

struct Series {
  std::string name;
  std::vector<double> x, y;
};

// lines of (x, y) series with a legend; log y for losses
std::string line_plot(const std::vector<Series>& series, const std::string& title,
                      const std::string& xlabel, const std::string& ylabel, bool log_y,
                      const std::string& css_class, bool log_x = false) {
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const Series& s : series)
    for (std::size_t i = 0; i < s.x.size(); ++i)
      if (std::isfinite(s.y[i]) && (!log_y || s.y[i] > 0) && (!log_x || s.x[i] > 0)) {
        x0 = std::min(x0, s.x[i]);
        x1 = std::max(x1, s.x[i]);
        y0 = std::min(y0, s.y[i]);
        y1 = std::max(y1, s.y[i]);
      }
  const auto flat = [](double a, double b) {
    return !(b - a > 1e-9 * std::max({1.0, std::fabs(a), std::fabs(b)}));
  };
  if (flat(x0, x1)) {
    x0 = log_x ? x0 / 2 : x0 - 1;
    x1 = log_x ? x1 * 2 : x1 + 1;
  }
  if (flat(y0, y1) && !log_y) {
    y0 -= 1;
    y1 += 1;
  } else if (log_y && !(y1 > y0 * (1 + 1e-9))) {
    y0 /= 2;
    y1 *= 2;
  }
  if (!log_y) {
    const double pad = 0.05 * (y1 - y0);
    y0 -= pad;
    y1 += pad;
  }
  Frame f{x0, x1, y0, y1, log_y, log_x};
  f.w = 360;
  std::ostringstream s;
  s << f.open(title, xlabel, ylabel, css_class);
  for (std::size_t k = 0; k < series.size(); ++k) {
    const char* color = kSeries[k % (sizeof kSeries / sizeof kSeries[0])];
    std::string points;
    for (std::size_t i = 0; i < series[k].x.size(); ++i)
      if (std::isfinite(series[k].y[i]) && (!log_y || series[k].y[i] > 0))
        points += num(f.px(series[k].x[i])) + "," + num(f.py(series[k].y[i])) + " ";
    s << "<polyline fill=\"none\" stroke=\"" << color << "\" stroke-width=\"1.6\" points=\""
      << points << "\"/>";
    if (series[k].x.size() <= 12)
      for (std::size_t i = 0; i < series[k].x.size(); ++i)
        if (std::isfinite(series[k].y[i]) && (!log_y || series[k].y[i] > 0))
          s << "<circle cx=\"" << num(f.px(series[k].x[i])) << "\" cy=\""
            << num(f.py(series[k].y[i])) << "\" r=\"3\" fill=\"" << color << "\"/>";
    s << "<rect x=\"" << f.left + f.w - 118 << "\" y=\"" << f.top + 6 + 14 * k
      << "\" width=\"10\" height=\"3\" fill=\"" << color << "\"/><text x=\"" << f.left + f.w - 104
      << "\" y=\"" << f.top + 10 + 14 * k << "\" font-size=\"10\">" << escape(series[k].name)
      << "</text>";
  }
  s << "</svg>";
  return s.str();
}

// a matrix as a heat map: white 0 to orange at the largest |value|, each cell's value written.
// Rows may differ in length (run.json is read as it is): the map is as wide as the widest,
// a missing cell is drawn as a non-number (a ragged matrix read past a row's end before;
// found by ropes_eval's fuzz/run_dir).
std::string heat_map(const std::vector<std::vector<double>>& m,
                     const std::vector<std::string>& rows, const std::string& title) {
  const std::size_t r = m.size();
  std::size_t c = 0;
  for (const auto& row : m)
    c = std::max(c, row.size());
  const auto at = [&m](std::size_t i, std::size_t j) {
    return j < m[i].size() ? m[i][j] : std::numeric_limits<double>::quiet_NaN();
  };
  double top = 0;
  for (const auto& row : m)
    for (double v : row)
      top = std::max(top, std::isfinite(v) ? std::fabs(v) : 0.0);
  const int cell = 30, left = 110, head = 40;
  const int W = left + static_cast<int>(c) * cell + 10, H = head + static_cast<int>(r) * cell + 10;
  std::ostringstream s;
  s << "<svg class=\"plot heatmap\" xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W
    << "\" height=\"" << H << "\" viewBox=\"0 0 " << W << " " << H << "\"><text x=\"" << left
    << "\" y=\"14\" font-size=\"12\">" << escape(title) << "</text>";
  for (std::size_t j = 0; j < c; ++j)
    s << "<text x=\"" << left + static_cast<int>(j) * cell + cell / 2 << "\" y=\"" << head - 6
      << "\" text-anchor=\"middle\" font-size=\"9\">z" << j << "</text>";
  for (std::size_t i = 0; i < r; ++i) {
    s << "<text x=\"" << left - 6 << "\" y=\"" << head + static_cast<int>(i) * cell + cell / 2 + 4
      << "\" text-anchor=\"end\" font-size=\"10\">" << escape(i < rows.size() ? rows[i] : "")
      << "</text>";
    for (std::size_t j = 0; j < c; ++j) {
      const double v = std::isfinite(at(i, j)) ? std::fabs(at(i, j)) / (top > 0 ? top : 1) : 0;
      // white to orange rgb(230, 120, 20)
      const int red = static_cast<int>(255 - 25 * v), green = static_cast<int>(255 - 135 * v),
                blue = static_cast<int>(255 - 235 * v);
      s << "<rect x=\"" << left + static_cast<int>(j) * cell << "\" y=\""
        << head + static_cast<int>(i) * cell << "\" width=\"" << cell << "\" height=\"" << cell
        << "\" fill=\"rgb(" << red << "," << green << "," << blue
        << ")\" stroke=\"#fff\"/><text x=\"" << left + static_cast<int>(j) * cell + cell / 2
        << "\" y=\"" << head + static_cast<int>(i) * cell + cell / 2 + 3
        << "\" text-anchor=\"middle\" font-size=\"8\" fill=\"" << (v > 0.6 ? "#fff" : "#222")
        << "\">" << fmt(at(i, j), 2) << "</text>";
    }
  }
  s << "</svg>";
  return s.str();
}

std::string img(const ReportImage& image, int scale = 1) {
  return "<figure><img alt=\"" + escape(image.label) + "\" width=\"" +
         std::to_string(image.width * scale) + "\" height=\"" +
         std::to_string(image.height * scale) + "\" src=\"data:image/png;base64," +
         detail::base64(detail::grey_png(image.grey, image.width, image.height)) +
         "\"><figcaption>" + escape(image.label) + "</figcaption></figure>";
}

std::uint8_t to_byte(float v) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

}  // namespace

ReportImages collect_report_images(const fs::path& run_dir, const fs::path& data_dir,
                                   std::int64_t occlusion, std::uint64_t seed,
                                   std::int64_t samples) {
  ReportImages out;
  out.occlusion = occlusion;
  crl::Estimator estimator = crl::Estimator::load(run_dir);
  const std::int64_t cams = estimator.cameras(), side = estimator.image_size(), plane = side * side;
  const core::DatasetReader reader = core::DatasetReader::open(data_dir);
  if (reader.column("images").row_shape != std::vector<std::int64_t>{cams, side, side})
    throw std::invalid_argument((data_dir / "manifest.json").string() +
                                ": images of another shape than the run's");
  const nlohmann::json& regimes = reader.metadata_at("/regimes");
  const core::NpyArray regime = reader.read_rows("regime", 0, reader.rows());
  // the first observational rows; anchor 0's rows, one per regime, for the grid
  std::vector<std::int64_t> observational, anchor0;
  const core::NpyArray anchors = reader.read_rows("anchor", 0, reader.rows());
  for (std::int64_t r = 0; r < reader.rows(); ++r) {
    std::int32_t g;
    std::int64_t a;
    std::memcpy(&g, regime.data.data() + r * 4, 4);
    std::memcpy(&a, anchors.data.data() + r * 8, 8);
    if (a == 0)
      anchor0.push_back(r);
    if (g >= 0 && static_cast<std::size_t>(g) < regimes.size() && regimes[g].is_object() &&
        regimes[g].contains("joint") && regimes[g]["joint"].is_null() &&
        static_cast<std::int64_t>(observational.size()) < samples)
      observational.push_back(r);
  }
  auto image_of = [&](const std::uint8_t* p, const std::string& label) {
    ReportImage i;
    i.label = label;
    i.width = i.height = static_cast<int>(side);
    i.grey.assign(p, p + plane);
    return i;
  };
  if (!observational.empty() && occlusion > 0) {
    const core::NpyArray clean = reader.read_rows_at("images", observational);
    std::vector<std::uint8_t> occluded = clean.data;
    occlude(occluded, observational, cams, side, side, occlusion, seed);
    nn::Buffer x(occluded.size());
    for (std::size_t i = 0; i < x.size(); ++i)
      x[i] = static_cast<float>(occluded[i]) / 255.0f;
    const std::int64_t n = static_cast<std::int64_t>(observational.size());
    const nn::Tensor input(nn::Shape{n, cams, side, side}, std::move(x));
    const nn::Tensor ae1 = estimator.reconstruct(input);
    const nn::Tensor ae2 = estimator.reconstruct_through_ae2(input, 0);
    out.occlusion_columns = {"input", "occluded input (" + std::to_string(occlusion) + " px)",
                             "AE1 reconstruction",
                             "AE2 (" + estimator.joints()[0] + ") reconstruction, through AE1"};
    for (std::int64_t s = 0; s < n; ++s)
      for (std::int64_t c = 0; c < cams; ++c) {
        const std::int64_t at = (s * cams + c) * plane;
        std::vector<std::uint8_t> a(plane), b(plane);
        for (std::int64_t i = 0; i < plane; ++i) {
          a[i] = to_byte(ae1.data()[at + i]);
          b[i] = to_byte(ae2.data()[at + i]);
        }
        const std::string who = "row " + std::to_string(observational[s]) +
                                (cams > 1 ? ", camera " + std::to_string(c) : "");
        out.occlusion_rows.push_back({image_of(clean.data.data() + at, who),
                                      image_of(occluded.data() + at, "occluded"),
                                      image_of(a.data(), "AE1"), image_of(b.data(), "AE2 → AE1")});
      }
  }
  if (!anchor0.empty()) {
    const core::NpyArray grid = reader.read_rows_at("images", anchor0);
    out.intervention_rows.assign(static_cast<std::size_t>(cams), {});
    for (std::size_t k = 0; k < anchor0.size(); ++k) {
      std::int32_t g;
      std::memcpy(&g, regime.data.data() + anchor0[k] * 4, 4);
      const std::string name = g >= 0 && static_cast<std::size_t>(g) < regimes.size() &&
                                       regimes[g].is_object() && regimes[g].contains("name") &&
                                       regimes[g]["name"].is_string()
                                   ? regimes[g]["name"].get<std::string>()
                                   : std::to_string(g);
      out.regime_names.push_back(name);
      for (std::int64_t c = 0; c < cams; ++c)
        out.intervention_rows[static_cast<std::size_t>(c)].push_back(
            image_of(grid.data.data() + (static_cast<std::int64_t>(k) * cams + c) * plane, name));
    }
  }
  return out;
}

std::string html_report(const EvaluationReport& report, const fs::path& run_dir,
                        const ReportImages& images) {
  std::ostringstream h;
  const std::string config = report.suites.empty() ? "" : report.suites[0].evaluation.config_name;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>ropes-eval: "
    << escape(config)
    << "</title><style>body{font-family:sans-serif;margin:24px;color:#222;max-width:1500px}"
       "h2{margin-top:32px;border-bottom:1px solid #ccc}table{border-collapse:collapse;"
       "font-size:13px}td,th{border:1px solid #ccc;padding:3px 7px;text-align:right}"
       "th:first-child,td:first-child{text-align:left}.row{display:flex;flex-wrap:wrap;"
       "gap:10px;align-items:flex-start}figure{margin:0 4px 6px 0;text-align:center;"
       "font-size:10px}img{image-rendering:pixelated;border:1px solid #ddd}.worse{color:#b00}"
       ".better{color:#070}</style></head><body>\n";
  h << "<h1>ropes-eval: " << escape(config) << "</h1>\n<p>Run <code>" << escape(run_dir.string())
    << "</code>. Each suite: the paper's protocol ("
    << (report.suites.empty() ? 0 : report.suites[0].evaluation.methods[0].repeats.size())
    << " repeats of "
    << (report.suites.empty() ? 0 : report.suites[0].evaluation.calibration_samples)
    << " calibration and " << (report.suites.empty() ? 0 : report.suites[0].evaluation.test_samples)
    << " test samples); numbers are mean ± std over the repeats, MSE in rad².</p>\n";

  // the suites' table: ROPES' MCC and MSE per joint, the paper's MSE beside where it has one
  h << "<h2>Suites</h2>\n<table class=\"suites\"><tr><th>suite</th><th>test set</th>";
  const std::vector<std::string> joints =
      report.suites.empty() ? std::vector<std::string>{} : report.suites[0].evaluation.joints;
  for (const std::string& j : joints)
    h << "<th>" << escape(j) << " MCC</th><th>MSE</th><th>paper MSE</th>";
  h << "</tr>\n";
  for (const SuiteResult& s : report.suites) {
    const MethodSummary& r = s.evaluation.methods[0];
    h << "<tr><td>" << escape(s.name) << "</td><td>" << escape(s.data_config) << "</td>";
    for (std::size_t k = 0; k < joints.size(); ++k) {
      const std::string patch = s.occlusion > 0 ? std::to_string(s.occlusion) : "none";
      const nlohmann::json::json_pointer p("/" + s.distribution + "/" + patch + "/" + joints[k]);
      double paper = std::numeric_limits<double>::quiet_NaN();
      if (report.paper_appendix.is_object() && report.paper_appendix.contains(p) &&
          report.paper_appendix[p].is_number())
        paper = report.paper_appendix[p].get<double>();
      else if (s.name == "id")
        paper = s.evaluation.paper_mse[k];
      const char* cls = !std::isfinite(paper) ? "" : r.mean.mse[k] > paper ? "worse" : "better";
      h << "<td>" << detail::plus_minus(r.mean.mcc[k], r.std.mcc[k]) << "</td><td class=\"" << cls
        << "\">" << detail::plus_minus(r.mean.mse[k], r.std.mse[k]) << "</td><td>" << fmt(paper)
        << "</td>";
    }
    h << "</tr>\n";
  }
  h << "</table>\n";
  for (const std::string& n : report.notes)
    h << "<p>Not run: " << escape(n) << "</p>\n";

  // scatter plots of each suite's best repeat
  h << "<h2>Estimate against ground truth (best repeat of each suite)</h2>\n";
  for (const SuiteResult& s : report.suites) {
    const RunEvaluation& ev = s.evaluation;
    const std::size_t b = static_cast<std::size_t>(ev.best_repeat);
    h << "<h3>" << escape(s.name) << "</h3><div class=\"row\">";
    for (std::size_t k = 0; k < ev.joints.size() && k < ev.scatter_truth.size(); ++k) {
      const MethodScores& best = ev.methods[0].repeats[b];
      h << scatter(ev.scatter_truth[k], ev.scatter_estimate[k],
                   ev.joints[k] + ": |r| " + fmt(best.mcc[k]) + ", MSE " + fmt(best.mse[k]));
    }
    h << "</div>\n";
  }

  // the occlusion figure
  if (!images.occlusion_rows.empty()) {
    h << "<h2>Occlusion</h2>\n<p>A white square of " << images.occlusion
      << " px at a seeded place in every camera image (the model never saw one in training). "
         "Columns: ";
    for (std::size_t i = 0; i < images.occlusion_columns.size(); ++i)
      h << (i ? "; " : "") << escape(images.occlusion_columns[i]);
    h << ".</p>\n";
    for (const auto& row : images.occlusion_rows) {
      h << "<div class=\"row occlusion\">";
      for (const ReportImage& i : row)
        h << img(i, 2);
      h << "</div>\n";
    }
  }
  // the occlusion diagnostics: which stage breaks (EvaluationReport::occlusion_markdown)
  const std::vector<OcclusionDiagnosticRow> diagnostic_rows = report.occlusion_rows();
  if (!diagnostic_rows.empty()) {
    h << "<h2>Occlusion diagnostics: which stage breaks</h2>\n<p>AE1's code shift: "
         "E|Y<sub>occluded</sub> − Y<sub>clean</sub>|² / E|Y<sub>clean</sub> − mean|² (0: the "
         "code does not move). Hiding: samples whose squares cover robot pixels, and the mean "
         "share of the robot's pixels covered.</p>\n<table class=\"occlusion-diagnostics\">"
         "<tr><th>suite</th><th>occluded cameras</th><th>AE1 code shift</th><th>samples whose "
         "squares hide the robot</th><th>robot pixels hidden</th></tr>\n";
    for (const OcclusionSummary& r : report.occlusion_summaries())
      h << "<tr><td>" << escape(r.suite) << "</td><td>" << escape(r.cameras) << "</td><td>"
        << fmt(r.code_shift) << "</td><td>" << fmt(r.share_hiding) << "</td><td>"
        << fmt(r.robot_hidden) << "</td></tr>\n";
    h << "</table>\n<p>MCC per joint: ropes (AE1, LDRs, AE2), ldr_logit (no AE2), "
         "lambda0_autoencoder (no sparsity term) and supervised_100% (every label, clean codes: "
         "what AE1's code still holds). Where ldr_logit holds and ropes falls, AE2 is fragile; "
         "where supervised_100% falls too, AE1's code is.</p>\n<table "
         "class=\"occlusion-diagnostics\"><tr><th>suite</th><th>method</th><th>test "
         "samples</th>";
    for (const std::string& j : joints)
      h << "<th>" << escape(j) << "</th>";
    h << "</tr>\n";
    for (const OcclusionDiagnosticRow& r : diagnostic_rows) {
      h << "<tr><td>" << escape(r.suite) << "</td><td>" << escape(r.method) << "</td><td>"
        << escape(r.samples) << "</td>";
      for (double v : r.mcc)
        h << "<td>" << fmt(v) << "</td>";
      h << "</tr>\n";
    }
    h << "</table>\n";
  }
  if (!images.intervention_rows.empty()) {
    h << "<h2>Interventions: one anchor in every regime</h2>\n";
    for (std::size_t c = 0; c < images.intervention_rows.size(); ++c) {
      h << "<div class=\"row interventions\">";
      for (const ReportImage& i : images.intervention_rows[c])
        h << img(i, 1);
      h << "</div>\n";
    }
  }

  // training curves
  h << "<h2>Training curves</h2>\n";
  std::map<std::string, std::map<std::string, Series>> curves;  // stage -> model -> series
  for (const std::string& line : detail::read_log_lines(run_dir / "metrics.jsonl")) {
    const nlohmann::json m = core::parse_json_or_discarded(line);
    if (!m.is_object() || !m.contains("stage") || !m["stage"].is_string())
      continue;
    const std::string stage = m["stage"].get<std::string>();
    // AE1 and AE2 log a loss by step; an LDR its held-out loss by epoch
    const bool by_step =
        m.contains("step") && m["step"].is_number() && m.contains("loss") && m["loss"].is_number();
    const bool by_epoch = m.contains("epoch") && m["epoch"].is_number() &&
                          m.contains("held_out_loss") && m["held_out_loss"].is_number();
    if (!by_step && !by_epoch)
      continue;
    std::string model = stage;
    for (const char* key : {"model", "joint"})
      if (m.contains(key) && m[key].is_string())
        model = m[key].get<std::string>();
    Series& s = curves[by_step ? stage : stage + " held-out"][model];
    s.name = model;
    s.x.push_back(m[by_step ? "step" : "epoch"].get<double>());
    s.y.push_back(m[by_step ? "loss" : "held_out_loss"].get<double>());
  }
  if (curves.empty())
    h << "<p>No training curves: metrics.jsonl is missing from the run directory or holds no "
         "losses.</p>\n";
  h << "<div class=\"row\">";
  for (const auto& [stage, models] : curves) {
    std::vector<Series> list;
    for (const auto& [name, s] : models)
      list.push_back(s);
    const bool epochs = stage.find("held-out") != std::string::npos;
    h << line_plot(list, stage + " loss", epochs ? "epoch" : "step", "loss", true, "plot curve");
  }
  h << "</div>\n";

  // sparsity matrices
  const std::vector<crl::SparsityMatrix> matrices =
      core::is_regular_file(run_dir / "run.json")
          ? crl::RunDirectory::open(run_dir).sparsity_matrices()
          : std::vector<crl::SparsityMatrix>();
  if (!matrices.empty()) {
    h << "<h2>Score sparsity: |score-difference Jacobian| per joint (rows) and latent "
         "(columns)</h2>\n<div class=\"row\">";
    for (const crl::SparsityMatrix& m : matrices)
      h << heat_map(m.rows, joints, "AE2 " + m.model);
    h << "</div>\n";
  }

  // the supervised baselines' label-efficiency curve on the id suite
  const SuiteResult* id = report.find("id");
  if (!report.supervised.empty() && id != nullptr) {
    h << "<h2>Label efficiency: a supervised encoder against ROPES (id suite)</h2>\n"
         "<p>MSE of the supervised encoder trained on a fraction of the training set's labels; "
         "the flat line is label-free ROPES (calibrated on "
      << id->evaluation.calibration_samples << " samples).</p><div class=\"row\">";
    for (std::size_t k = 0; k < joints.size(); ++k) {
      Series sup{"supervised", {}, {}}, ours{"ROPES (label-free)", {}, {}};
      for (const SupervisedInfo& p : report.supervised) {
        const std::string name = supervised_method_name(p.fraction);
        for (const MethodSummary& m : id->evaluation.methods)
          if (m.method == name) {
            sup.x.push_back(100.0 * p.fraction);
            sup.y.push_back(m.mean.mse[k]);
          }
      }
      if (!sup.x.empty()) {
        ours.x = {sup.x.front(), sup.x.back()};
        ours.y = {id->evaluation.methods[0].mean.mse[k], id->evaluation.methods[0].mean.mse[k]};
      }
      h << line_plot({sup, ours}, joints[k] + ": MSE by labelled fraction",
                     "labelled training samples (%)", "MSE (rad²)", true, "plot label-efficiency",
                     true);
    }
    h << "</div>\n";
  }
  h << "</body></html>\n";
  return h.str();
}

}  // namespace ropes::eval
