#include "replay.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "analysis.hpp"
#include "cli.hpp"
#include "log_drain.hpp"
#include "run_services.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/record/hdf5_recorder.hpp"
#include "lode/scheduler.hpp"

namespace lode::cli {

namespace {

namespace fs = std::filesystem;

/// What `lode replay` was asked (the command line declares and checks the options).
struct ReplayArgs {
  std::string recording;
  std::vector<std::string> configs;
  std::vector<std::string> estimates;
  std::string output, report, reference;
  bool quiet = false;
};

ReplayArgs replay_args(const Args& args) {
  ReplayArgs a;
  a.recording = args.positional.empty() ? "" : args.positional.front();
  if (auto it = args.lists.find("--config"); it != args.lists.end()) a.configs = it->second;
  if (auto it = args.lists.find("--estimate"); it != args.lists.end()) a.estimates = it->second;
  a.output = args.option("--output");
  a.report = args.option("--report");
  a.reference = args.option("--reference");
  a.quiet = args.has_flag("--quiet");
  return a;
}

// ---- statistics helpers ------------------------------------------------------------------

/// Regularized lower incomplete gamma P(a, x): series for x < a + 1, Lentz continued
/// fraction otherwise (Numerical Recipes, 3rd ed., §6.2).
double gamma_p(double a, double x) {
  if (x <= 0) return 0.0;
  const double log_front = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 1000; ++n) {
      term *= x / (a + n);
      sum += term;
      if (std::abs(term) < std::abs(sum) * 1e-15) break;
    }
    return sum * std::exp(log_front);
  }
  double b = x + 1.0 - a, c = 1e300, d = 1.0 / b, h = d;
  for (int n = 1; n < 1000; ++n) {
    const double an = -n * (n - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < 1e-300) d = 1e-300;
    c = b + an / c;
    if (std::abs(c) < 1e-300) c = 1e-300;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-15) break;
  }
  return 1.0 - std::exp(log_front) * h;
}

/// Standard normal quantile (Acklam's rational approximation, |error| < 1.2e-9).
double normal_quantile(double p) {
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01,  -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  if (p < 0.02425) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p > 1 - 0.02425) return -normal_quantile(1 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

Json num(double v) { return std::isfinite(v) ? Json(v) : Json(); }

std::string with_unit(double v, const std::string& unit) {
  if (!std::isfinite(v)) return "n/a";
  auto [scale, shown] = analysis::display_scale(unit, std::abs(v));
  return fmt("%.4g", v * scale) + " " + shown;
}

// ---- per-cycle capture -------------------------------------------------------------------

/// Copies the compared signals and each estimator's NIS every cycle into storage sized
/// before the run (RT-safe: memcpy, the Block API's innovation(), arithmetic).
class CompareHook final : public CycleHook {
 public:
  struct Nis {
    Block* const* slot = nullptr;
    const Block* configured = nullptr;  ///< the instance whose innovation_size() sized `nu`
    std::vector<double> nu, s;
    std::vector<double> values;  ///< per cycle; NaN when innovation() returned false
  };
  CompareHook(std::vector<SignalRef> signals, std::size_t cycles) : signals_(std::move(signals)), capacity_(cycles) {
    time_s_.assign(cycles, 0.0);
    for (const auto& s : signals_) values_.emplace_back(cycles * s.size(), std::nan(""));
  }
  /// Track the NIS of `name` (called before the run; the block's innovation_size() > 0).
  void track_nis(const Pipeline& p, const std::string& name) {
    Nis n;
    n.slot = p.block_slot(name);
    n.configured = p.block(name);
    const std::size_t m = n.configured ? n.configured->innovation_size() : 0;
    n.nu.assign(m, 0.0);
    n.s.assign(m, 0.0);
    n.values.assign(capacity_, std::nan(""));
    nis_[name] = std::move(n);
  }
  void after_cycle(const Tick& tick) noexcept override {
    if (tick.cycle >= capacity_) return;
    const std::size_t k = tick.cycle;
    rows_ = std::max(rows_, k + 1);
    time_s_[k] = static_cast<double>(tick.time_ns) * 1e-9;
    for (std::size_t i = 0; i < signals_.size(); ++i)
      std::memcpy(values_[i].data() + k * signals_[i].size(), signals_[i].data, signals_[i].size() * sizeof(double));
    for (auto& [name, n] : nis_) {
      const Block* b = n.slot ? *n.slot : nullptr;
      // A block swapped in by the health monitor may have another innovation size: its
      // NIS is not counted (its size cannot be asked on this thread).
      if (!b || b != n.configured || n.nu.empty() || !b->innovation(n.nu.data(), n.s.data())) continue;
      double sum = 0.0;
      for (std::size_t i = 0; i < n.nu.size(); ++i) sum += n.nu[i] * n.nu[i] / n.s[i];
      n.values[k] = sum;
    }
  }
  [[nodiscard]] analysis::Series series(std::size_t i) const {
    analysis::Series s;
    s.elements = *signals_[i].elements;
    s.values.assign(values_[i].begin(), values_[i].begin() + static_cast<std::ptrdiff_t>(rows_ * signals_[i].size()));
    return s;
  }
  [[nodiscard]] std::vector<double> time_s() const { return {time_s_.begin(), time_s_.begin() + static_cast<std::ptrdiff_t>(rows_)}; }
  [[nodiscard]] const Nis* nis(const std::string& name) const {
    auto it = nis_.find(name);
    return it == nis_.end() ? nullptr : &it->second;
  }
  [[nodiscard]] std::size_t rows() const { return rows_; }

 private:
  std::vector<SignalRef> signals_;
  std::size_t capacity_;
  std::size_t rows_ = 0;
  std::vector<double> time_s_;
  std::vector<std::vector<double>> values_;
  std::map<std::string, Nis> nis_;
};

// ---- bit-exact comparison ----------------------------------------------------------------

struct BitCompare {
  std::size_t series = 0;
  std::size_t cycles = 0;
  std::string first_difference;  ///< empty when identical
  std::vector<std::string> only_in_one;
};

BitCompare compare_recordings(const record::Recording& recorded, const record::Recording& replayed) {
  BitCompare r;
  std::map<std::string, const record::SeriesData*> by_name;
  for (const auto& s : replayed.series) by_name[s.info.name] = &s;
  std::set<std::string> seen;
  for (const auto& a : recorded.series) {
    auto it = by_name.find(a.info.name);
    if (it == by_name.end()) {
      r.only_in_one.push_back(a.info.name + " (only in the recording)");
      continue;
    }
    seen.insert(a.info.name);
    const auto& b = *it->second;
    ++r.series;
    r.cycles = std::max(r.cycles, a.rows());
    if (!r.first_difference.empty()) continue;
    if (a.width() != b.width() || a.info.names != b.info.names) {
      r.first_difference = "series " + a.info.name + ": different elements";
      continue;
    }
    if (a.rows() != b.rows()) {
      r.first_difference = "series " + a.info.name + ": " + std::to_string(a.rows()) + " cycles recorded, " +
                           std::to_string(b.rows()) + " replayed";
      continue;
    }
    for (std::size_t k = 0; k < a.rows() && r.first_difference.empty(); ++k) {
      if (a.cycle[k] != b.cycle[k]) {
        r.first_difference = "series " + a.info.name + ": row " + std::to_string(k) + " is cycle " +
                             std::to_string(a.cycle[k]) + " recorded, " + std::to_string(b.cycle[k]) + " replayed";
        break;
      }
      const double* va = a.values.data() + k * a.width();
      const double* vb = b.values.data() + k * b.width();
      if (std::memcmp(va, vb, a.width() * sizeof(double)) == 0) continue;
      for (std::size_t i = 0; i < a.width(); ++i) {
        if (std::memcmp(va + i, vb + i, sizeof(double)) == 0) continue;
        char buf[320];
        std::snprintf(buf, sizeof buf, "series %s, cycle %llu, element %s: recorded %.17g, replayed %.17g",
                      a.info.name.c_str(), static_cast<unsigned long long>(a.cycle[k]), a.info.names[i].c_str(),
                      va[i], vb[i]);
        r.first_difference = buf;
        break;
      }
    }
  }
  for (const auto& s : replayed.series)
    if (!seen.count(s.info.name)) r.only_in_one.push_back(s.info.name + " (only in the replay)");
  return r;
}

// ---- one replayed configuration ----------------------------------------------------------

struct EstimatorStats {
  std::string signal;  ///< block.port
  std::string block;
  std::string plugin;
  std::string role;    ///< "monitor.estimate", "shadow of kf", "--estimate"
  struct Element {
    std::string name, unit;
    double bias = NAN, rms = NAN, max_abs = NAN, noise_std = NAN;
  };
  std::vector<Element> elements;
  std::size_t nis_channels = 0;
  std::size_t nis_cycles = 0;
  double nis_mean = NAN, nis_in_95 = NAN, nis_lo = NAN, nis_hi = NAN;
  double median_step_us = NAN;
};

struct ConfigResult {
  std::string label;        ///< what the user named (config file or "recorded configuration")
  bool recorded = false;
  std::string output;
  std::uint64_t cycles = 0;
  double wall_s = 0, speed = 0;
  std::string digest;
  std::string reference;    ///< "" when none
  std::vector<EstimatorStats> estimators;
  std::vector<std::string> notes;
};

std::string stem_of(const std::string& path) { return fs::path(path).stem().string(); }

std::string without_h5(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  return (ext == ".h5" || ext == ".hdf5") ? path.substr(0, path.size() - ext.size()) : path;
}

}  // namespace

double chi_square_quantile(double p, double k) {
  if (!(k > 0) || !(p > 0) || !(p < 1)) return NAN;
  // Wilson-Hilferty (1931) as the starting bracket, then bisection on the exact CDF
  // P(k/2, x/2): the approximation alone is off by ~15 % at the 2.5 % point for k = 3.
  const double z = normal_quantile(p);
  const double h = 2.0 / (9.0 * k);
  const double wh = k * std::pow(std::max(0.0, 1.0 - h + z * std::sqrt(h)), 3.0);
  double lo = 0.0, hi = std::max(4.0 * wh, k + 40.0 * std::sqrt(2.0 * k) + 10.0);
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (gamma_p(0.5 * k, 0.5 * mid) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

std::string rewrite_for_replay(const std::string& yaml, const std::string& recording, PluginRegistry& registry,
                               std::vector<std::string>& replaced, std::string& note) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception&) {
    return yaml;  // the loader reports the syntax error at its place
  }
  if (!root.IsMap() || !root["blocks"] || !root["blocks"].IsMap()) return yaml;
  const YAML::Node blocks = root["blocks"];

  // Lines of the text (without their '\n').
  std::vector<std::string> lines;
  {
    std::size_t start = 0;
    for (;;) {
      const auto nl = yaml.find('\n', start);
      lines.push_back(yaml.substr(start, nl == std::string::npos ? std::string::npos : nl - start));
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }
  std::vector<int> top_lines;
  for (const auto& kv : root) top_lines.push_back(kv.first.Mark().line);
  std::vector<int> block_lines;
  for (const auto& kv : blocks) block_lines.push_back(kv.first.Mark().line);

  struct Edit {
    int first = 0, end = 0;  // [first, end) lines
    std::string text;
  };
  std::vector<Edit> edits;
  bool whole = false;
  std::size_t index = 0;
  for (auto it = blocks.begin(); it != blocks.end(); ++it, ++index) {
    const std::string name = it->first.as<std::string>();
    const YAML::Node spec = it->second;
    if (!spec.IsMap() || !spec["plugin"] || !spec["plugin"].IsScalar()) continue;
    auto plugin = registry.find(spec["plugin"].Scalar());
    if (!plugin || plugin->descriptor->kind != PluginKind::io) continue;
    replaced.push_back(name);

    YAML::Emitter e;
    e << YAML::Flow << YAML::BeginMap;
    e << YAML::Key << "plugin" << YAML::Value << "io.replay";
    e << YAML::Key << "recording" << YAML::Value << YAML::DoubleQuoted << recording;
    e << YAML::Key << "block" << YAML::Value << name;
    if (spec["inputs"]) e << YAML::Key << "inputs" << YAML::Value << YAML::Flow << spec["inputs"];
    e << YAML::EndMap;

    const int first = it->first.Mark().line;
    int end = static_cast<int>(lines.size());
    if (index + 1 < block_lines.size()) {
      end = block_lines[index + 1];
    } else {
      for (const int t : top_lines)
        if (t > first) {
          end = t;
          break;
        }
    }
    // A flow-style `blocks:` puts several blocks on one line: no line-preserving edit.
    if (end <= first || first < 0 || static_cast<std::size_t>(first) >= lines.size()) whole = true;
    YAML::Emitter key;
    key << name;
    const std::string indent(static_cast<std::size_t>(std::max(0, it->first.Mark().column)), ' ');
    edits.push_back({first, end, indent + key.c_str() + ": " + e.c_str()});
  }
  if (edits.empty()) return yaml;

  if (whole) {
    YAML::Node copy = YAML::Clone(root);
    for (const auto& name : replaced) {
      YAML::Node spec = copy["blocks"][name];
      YAML::Node r;
      r["plugin"] = "io.replay";
      r["recording"] = recording;
      r["block"] = name;
      if (spec["inputs"]) r["inputs"] = spec["inputs"];
      copy["blocks"][name] = r;
    }
    YAML::Emitter e;
    e << copy;
    note = "the configuration was rewritten as a whole (flow-style blocks:): line numbers refer to the rewritten text";
    return std::string(e.c_str()) + "\n";
  }
  for (const auto& ed : edits) {
    lines[static_cast<std::size_t>(ed.first)] = ed.text;
    for (int l = ed.first + 1; l < ed.end; ++l) lines[static_cast<std::size_t>(l)].clear();
  }
  std::string out;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    out += lines[i];
    if (i + 1 < lines.size()) out += '\n';
  }
  return out;
}

int cmd_replay(const Args& args) {
  const ReplayArgs a = replay_args(args);
  std::error_code ec;
  const std::string recording = fs::absolute(a.recording, ec).lexically_normal().string();
  auto rec = record::read_recording(recording);
  if (!rec) {
    std::fprintf(stderr, "lode: replay: %s\n", rec.error().c_str());
    return kExitConfig;
  }
  auto text_attr = [&](const std::string& k) -> std::string {
    auto it = rec->text_attributes.find(k);
    return it == rec->text_attributes.end() ? "" : it->second;
  };
  auto number_attr = [&](const std::string& k) -> std::optional<double> {
    auto it = rec->number_attributes.find(k);
    if (it == rec->number_attributes.end()) return std::nullopt;
    return it->second;
  };
  const std::string recorded_config = text_attr("config");
  if (recorded_config.empty()) {
    std::fprintf(stderr, "lode: replay: %s has no `config` attribute (not written by `lode run --record`)\n",
                 a.recording.c_str());
    return kExitConfig;
  }
  // The number of cycles to run: the rows of the raw series (every one is checked for
  // gaps by io.replay), else of any series.
  std::size_t rows = 0;
  std::uint64_t first_cycle = 0;
  for (const auto& s : rec->series) {
    if (s.rows() == 0) continue;
    if (rows == 0 || s.info.kind == "raw") {
      rows = s.rows();
      first_cycle = s.cycle.front();
      if (s.info.kind == "raw") break;
    }
  }
  if (rows == 0) {
    std::fprintf(stderr, "lode: replay: %s holds no samples\n", a.recording.c_str());
    return kExitConfig;
  }
  if (first_cycle != 0) {
    std::fprintf(stderr,
                 "lode: replay: %s starts at cycle %llu (recorded from mid-run): a replay starts from cycle 0, "
                 "with every estimator in its initial state; record from the start (lode run --record)\n",
                 a.recording.c_str(), static_cast<unsigned long long>(first_cycle));
    return kExitConfig;
  }
  const std::string recorded_digest = text_attr("output_digest");

  struct Job {
    std::string label, text, output;
    bool recorded = false;
  };
  std::vector<Job> jobs;
  const std::string base = a.output.empty() ? without_h5(a.recording) + ".replay" : without_h5(a.output);
  {
    Job j;
    j.label = text_attr("config_file").empty() ? std::string("recorded configuration") : text_attr("config_file");
    j.text = recorded_config;
    j.recorded = true;
    j.output = a.output.empty() ? base + ".h5" : a.output;
    jobs.push_back(std::move(j));
  }
  for (const auto& c : a.configs) {
    std::ifstream in(c);
    if (!in) {
      std::fprintf(stderr, "lode: replay: --config %s: cannot open the pipeline file\n", c.c_str());
      return kExitConfig;
    }
    std::stringstream ss;
    ss << in.rdbuf();
    Job j;
    j.label = c;
    j.text = ss.str();
    j.output = (a.output.empty() ? base + "-" : base + "-") + stem_of(c) + ".h5";
    jobs.push_back(std::move(j));
  }

  PluginRegistry registry;  // declared before every pipeline: libraries outlive the blocks
  bool mismatch = false, faulted = false;
  std::vector<ConfigResult> results;
  std::string reference_name;

  // Recorded plugin files, to say when a replay loads different code.
  std::map<std::string, std::string> recorded_plugins;
  if (const auto pj = text_attr("lode_plugins"); !pj.empty()) {
    try {
      const YAML::Node n = YAML::Load(pj);  // JSON is YAML
      for (const auto& kv : n) recorded_plugins[kv.first.as<std::string>()] = kv.second.as<std::string>();
    } catch (const YAML::Exception&) {
    }
  }

  for (const auto& job : jobs) {
    std::vector<std::string> replaced;
    std::string note;
    const std::string text = rewrite_for_replay(job.text, recording, registry, replaced, note);
    const std::string label = job.label + " replaying " + a.recording;
    Diagnostics diag;
    auto p = Pipeline::load_text(text, label, registry, diag);
    if (!p) {
      std::fputs(diag.format().c_str(), stderr);
      std::fprintf(stderr, "lode: replay: %zu problem%s in %s; nothing was replayed%s\n", diag.size(),
                   diag.size() == 1 ? "" : "s", label.c_str(), note.empty() ? "" : (" (" + note + ")").c_str());
      return kExitConfig;
    }
    ConfigResult cr;
    cr.label = job.label;
    cr.recorded = job.recorded;
    cr.output = job.output;
    if (!note.empty()) cr.notes.push_back(note);
    if (replaced.empty()) cr.notes.push_back("no io block to replace: the configuration does not read the recording");
    if (job.recorded && std::abs(p->rate_hz() - number_attr("rate_hz").value_or(p->rate_hz())) > 0)
      cr.notes.push_back("rate differs from the recording's");
    if (!recorded_plugins.empty()) {
      const Json d = p->describe();
      if (const Json* bj = d.find("blocks"))
        for (const auto& [name, b] : bj->members()) {
          const Json* plugin = b.find("plugin");
          const Json* file = b.find("plugin_file");
          if (!plugin || !file || plugin->as_string() == "io.replay") continue;
          auto it = recorded_plugins.find(plugin->as_string());
          if (it != recorded_plugins.end() && it->second != file->as_string())
            cr.notes.push_back("block " + name + ": plugin " + plugin->as_string() + " loaded from " +
                               file->as_string() + ", recorded with " + it->second);
        }
    }

    // Estimators and reference of this configuration.
    const auto& mon = p->monitor();
    std::vector<SignalRef> tracked;
    std::vector<EstimatorStats> estimators;
    auto add_estimator = [&](const SignalRef& s, const std::string& role) {
      for (const auto& e : estimators)
        if (e.signal == s.name()) return;
      EstimatorStats e;
      e.signal = s.name();
      e.block = s.block;
      e.plugin = p->plugin_of(s.block);
      e.role = role;
      estimators.push_back(std::move(e));
      tracked.push_back(s);
    };
    if (mon.estimate) add_estimator(*mon.estimate, "monitor.estimate");
    for (const auto& sh : p->shadows()) {
      const std::string port = mon.estimate ? mon.estimate->port : "";
      auto s = port.empty() ? std::nullopt : p->signal(sh.name + "." + port);
      if (s) add_estimator(*s, "shadow of " + sh.primary);
      else cr.notes.push_back("shadow " + sh.name + " has no output '" + port + "' to compare");
    }
    for (const auto& ref : a.estimates) {
      auto s = p->signal(ref);
      if (!s) {
        std::fprintf(stderr, "lode: replay: --estimate %s: %s has no such output (`lode describe` lists them)\n",
                     ref.c_str(), job.label.c_str());
        return kExitConfig;
      }
      add_estimator(*s, "--estimate");
    }
    std::optional<SignalRef> reference;
    if (!a.reference.empty()) {
      reference = p->signal(a.reference);
      if (!reference) {
        std::fprintf(stderr, "lode: replay: --reference %s: %s has no such output\n", a.reference.c_str(),
                     job.label.c_str());
        return kExitConfig;
      }
    } else if (mon.truth) {
      reference = mon.truth;
    }
    if (reference) {
      cr.reference = reference->name();
      tracked.push_back(*reference);
    }

    EventLog events;
    LogDrain drain(events);
    SimulatedClock clock;
    Scheduler sched(*p, clock, events);
    RunServiceOptions options;
    options.telemetry = false;
    options.local_control = false;  // a replay is not commanded
    options.simulated = true;
    options.record_path = job.output;
    auto services = RunServices::start(*p, sched, events, options);
    if (!services) {
      std::fprintf(stderr, "lode: replay: %s; nothing was replayed\n", services.error().c_str());
      return kExitFault;
    }
    CompareHook hook(tracked, rows);
    for (const auto& e : estimators) {
      const Block* b = p->block(e.block);
      if (b && b->innovation_size() > 0) hook.track_nis(*p, e.block);
    }
    sched.add_hook(&hook);
    if (!a.quiet) std::fprintf(stderr, "lode: replaying %zu cycles through %s\n", rows, job.label.c_str());
    const auto outcome = execute_run(*p, sched, events, **services, rows,
                                     "replay of " + a.recording + " through " + job.label,
                                     [&] { (*services)->on_idle(); }, [&] { drain.stop(); });
    if (!outcome) {
      std::fprintf(stderr, "lode: replay: %s: %s\n", job.label.c_str(), outcome.error().c_str());
      return kExitFault;
    }
    const auto& result = *outcome;
    cr.cycles = sched.stats().cycles.load();
    cr.wall_s = result.wall_s;
    cr.speed = result.wall_s > 0 ? static_cast<double>(cr.cycles) / p->rate_hz() / result.wall_s : 0.0;
    cr.digest = (*services)->output_digest();
    std::printf("%s: %llu cycles in %.3f s wall, %.0fx real time (%g Hz)\n", job.label.c_str(),
                static_cast<unsigned long long>(cr.cycles), cr.wall_s, cr.speed, p->rate_hz());
    if (result.faulted) {
      std::printf("%s: FAULT at cycle %llu: %s\n", job.label.c_str(),
                  static_cast<unsigned long long>(sched.stats().cycles.load()), result.fault.c_str());
      faulted = true;
    }

    // Bit-exactness of the recorded configuration.
    if (job.recorded) {
      auto replayed = record::read_recording(job.output);
      if (!replayed) {
        std::printf("cannot read the replay %s: %s\n", job.output.c_str(), replayed.error().c_str());
        mismatch = true;
      } else {
        const auto cmp = compare_recordings(*rec, *replayed);
        const bool digest_ok = recorded_digest.empty() || recorded_digest == cr.digest;
        if (cmp.first_difference.empty() && digest_ok && cmp.series > 0) {
          std::printf("bit-identical: %zu series x %zu cycles, digest %s%s\n", cmp.series, cmp.cycles,
                      cr.digest.c_str(),
                      recorded_digest.empty() ? " (the recording has no digest to compare with)" : "");
        } else {
          mismatch = true;
          if (!cmp.first_difference.empty())
            std::printf("NOT bit-identical with %s: first difference in %s\n", recording.c_str(),
                        cmp.first_difference.c_str());
          else if (cmp.series == 0)
            std::printf("NOT bit-identical with %s: no series in common\n", recording.c_str());
          if (!digest_ok)
            std::printf("NOT bit-identical with %s: output digest %s replayed, %s recorded\n", recording.c_str(),
                        cr.digest.c_str(), recorded_digest.c_str());
        }
        for (const auto& s : cmp.only_in_one) cr.notes.push_back("not compared: " + s);
      }
    }

    // Statistics.
    using analysis::window_stats;
    const auto t = hook.time_s();
    double h0 = mon.hold_start_s, h1 = mon.hold_end_s;
    if (h1 <= h0) {
      h0 = 0.0;
      h1 = t.empty() ? 0.0 : t.back();
    }
    const double t_end = t.empty() ? 0.0 : t.back();
    std::optional<analysis::Series> ref_series;
    if (reference) ref_series = hook.series(tracked.size() - 1);
    for (std::size_t i = 0; i < estimators.size(); ++i) {
      auto& e = estimators[i];
      const auto est = hook.series(i);
      // The reference's element matching each estimate element: by name, else by position.
      std::vector<int> match(est.width(), -1);
      if (ref_series) {
        for (std::size_t k = 0; k < est.width(); ++k)
          for (std::size_t r = 0; r < ref_series->width(); ++r)
            if (ref_series->elements[r].name == est.elements[k].name) match[k] = static_cast<int>(r);
        if (std::all_of(match.begin(), match.end(), [](int m) { return m < 0; }) && est.width() == ref_series->width())
          for (std::size_t k = 0; k < est.width(); ++k) match[k] = static_cast<int>(k);
      }
      analysis::Series aligned;
      aligned.elements = est.elements;
      aligned.values.assign(est.values.size(), 0.0);
      if (ref_series)
        for (std::size_t r = 0; r < t.size(); ++r)
          for (std::size_t k = 0; k < est.width(); ++k)
            aligned.values[r * est.width() + k] =
                match[k] >= 0 ? ref_series->at(r, static_cast<std::size_t>(match[k])) : std::nan("");
      const auto err = ref_series ? window_stats(t, est, &aligned, h0, t_end) : std::vector<analysis::AxisStats>{};
      const auto hold = window_stats(t, est, ref_series ? &aligned : nullptr, h0, h1);
      for (std::size_t k = 0; k < est.width(); ++k) {
        EstimatorStats::Element el;
        el.name = est.elements[k].name;
        el.unit = est.elements[k].unit;
        if (ref_series && match[k] >= 0) {
          el.bias = err[k].mean;
          el.rms = err[k].rms;
          el.max_abs = err[k].max_abs;
          el.noise_std = hold[k].std;
        } else if (!ref_series) {
          el.noise_std = hold[k].std;  // the estimate's own scatter in the hold window
        }
        e.elements.push_back(el);
      }
      if (const auto* n = hook.nis(e.block); n && !n->nu.empty()) {
        e.nis_channels = n->nu.size();
        const double m = static_cast<double>(e.nis_channels);
        e.nis_lo = chi_square_quantile(0.025, m);
        e.nis_hi = chi_square_quantile(0.975, m);
        double sum = 0.0;
        std::size_t inside = 0;
        for (std::size_t k = 0; k < hook.rows(); ++k) {
          const double v = n->values[k];
          if (!std::isfinite(v)) continue;
          ++e.nis_cycles;
          sum += v;
          if (v >= e.nis_lo && v <= e.nis_hi) ++inside;
        }
        if (e.nis_cycles > 0) {
          e.nis_mean = sum / static_cast<double>(e.nis_cycles);
          e.nis_in_95 = static_cast<double>(inside) / static_cast<double>(e.nis_cycles);
        }
      }
      for (const auto& op : p->ops())
        if (op.label == e.block && op.exec_time && op.exec_time->count() > 0)
          e.median_step_us = static_cast<double>(op.exec_time->percentile(0.5)) * 1e-3;
      if (!std::isfinite(e.median_step_us) && e.role.rfind("shadow", 0) == 0)
        cr.notes.push_back("shadow " + e.block + " is stepped inside its primary's operation: no step time of its own");
    }
    cr.estimators = std::move(estimators);
    if (reference_name.empty()) reference_name = cr.reference;
    results.push_back(std::move(cr));
  }

  // ---- report ------------------------------------------------------------------------------
  std::string md;
  md += "# Replay of " + a.recording + "\n\n";
  md += "Pipeline `" + text_attr("pipeline") + "`, " + std::to_string(rows) + " cycles at " +
        fmt("%g", number_attr("rate_hz").value_or(0)) + " Hz.\n";
  {
    // hold window of the first configuration (they normally share it)
    md += "Error statistics against the reference from the start of the hold window to the end; noise std = "
          "std of the error inside the hold window (`monitor.hold_s`); NIS = sum nu_i^2 / S_ii per cycle with "
          "its two-sided 95 % chi-square interval.\n\n";
  }
  md += "| configuration | estimator | reference | bias | RMS | max abs | noise std | NIS mean (expected) | NIS in 95 % | median step |\n";
  md += "|---|---|---|---|---|---|---|---|---|---|\n";
  Json jr = Json::object();
  jr["recording"] = a.recording;
  jr["pipeline"] = text_attr("pipeline");
  jr["cycles"] = static_cast<std::uint64_t>(rows);
  jr["rate_hz"] = number_attr("rate_hz").value_or(0);
  Json all = Json::array();
  Json configs = Json::array();
  for (const auto& cr : results) {
    Json cj = Json::object();
    cj["config"] = cr.label;
    cj["recorded"] = cr.recorded;
    cj["output"] = cr.output;
    cj["cycles"] = cr.cycles;
    cj["wall_s"] = cr.wall_s;
    cj["speed_vs_realtime"] = cr.speed;
    cj["output_digest"] = cr.digest;
    cj["reference"] = cr.reference.empty() ? Json() : Json(cr.reference);
    Json notes = Json::array();
    for (const auto& n : cr.notes) notes.push(n);
    cj["notes"] = std::move(notes);
    configs.push(std::move(cj));
    for (const auto& e : cr.estimators) {
      auto join = [&](auto get) {
        std::string s;
        for (const auto& el : e.elements) s += (s.empty() ? "" : ", ") + el.name + " " + with_unit(get(el), el.unit);
        return s;
      };
      const std::string nis_mean =
          e.nis_channels ? (std::isfinite(e.nis_mean) ? fmt("%.3g", e.nis_mean) : std::string("n/a")) + " (" +
                               std::to_string(e.nis_channels) + ")"
                         : "n/a";
      const std::string nis_in = e.nis_channels && std::isfinite(e.nis_in_95) ? fmt("%.1f %%", 100.0 * e.nis_in_95) : "n/a";
      md += "| " + cr.label + (cr.recorded ? " (recorded)" : "") + " | " + e.signal + " (" + e.plugin + ") | " +
            (cr.reference.empty() ? "none" : cr.reference) + " | " +
            join([](const auto& el) { return el.bias; }) + " | " + join([](const auto& el) { return el.rms; }) +
            " | " + join([](const auto& el) { return el.max_abs; }) + " | " +
            join([](const auto& el) { return el.noise_std; }) + " | " + nis_mean + " | " + nis_in + " | " +
            (std::isfinite(e.median_step_us) ? fmt("%.2f us", e.median_step_us) : std::string("n/a")) + " |\n";
      Json ej = Json::object();
      ej["config"] = cr.label;
      ej["estimator"] = e.signal;
      ej["block"] = e.block;
      ej["plugin"] = e.plugin;
      ej["role"] = e.role;
      ej["reference"] = cr.reference.empty() ? Json() : Json(cr.reference);
      Json els = Json::object();
      for (const auto& el : e.elements) {
        Json x = Json::object();
        x["unit"] = el.unit;
        x["bias"] = num(el.bias);
        x["rms"] = num(el.rms);
        x["max_abs"] = num(el.max_abs);
        x["noise_std"] = num(el.noise_std);
        els[el.name] = std::move(x);
      }
      ej["elements"] = std::move(els);
      Json nis = Json::object();
      nis["channels"] = static_cast<std::uint64_t>(e.nis_channels);
      nis["cycles"] = static_cast<std::uint64_t>(e.nis_cycles);
      nis["mean"] = num(e.nis_mean);
      nis["expected"] = e.nis_channels ? Json(static_cast<double>(e.nis_channels)) : Json();
      nis["interval_95"] = e.nis_channels ? Json(std::vector<double>{e.nis_lo, e.nis_hi}) : Json();
      nis["fraction_in_95"] = num(e.nis_in_95);
      ej["nis"] = std::move(nis);
      ej["median_step_us"] = num(e.median_step_us);
      all.push(std::move(ej));
    }
  }
  if (reference_name.empty())
    md += "\nNo reference: neither --reference nor `monitor.truth`; bias, RMS and max are not available, noise std is "
          "the estimate's own std in the hold window.\n";
  for (const auto& cr : results)
    for (const auto& n : cr.notes) md += "\nNote (" + cr.label + "): " + n + "\n";
  jr["configurations"] = std::move(configs);
  jr["estimators"] = std::move(all);
  jr["bit_identical"] = !mismatch;
  jr["faulted"] = faulted;
  if (!a.quiet) std::printf("\n%s", md.c_str());
  if (!a.report.empty()) {
    std::ofstream f(a.report);
    if (!f) {
      std::fprintf(stderr, "lode: replay: cannot write %s\n", a.report.c_str());
      return kExitFault;
    }
    const bool json = fs::path(a.report).extension() == ".json";
    f << (json ? jr.dump() + "\n" : md);
  }
  return (mismatch || faulted) ? kExitFault : kExitOk;
}

}  // namespace lode::cli
