// lode replay RECORDING: the recording's raw inputs through the recorded configuration
// (checked bit for bit against the recording) and through every --config, at full speed on
// the simulated clock, then one comparison report. Exit 0 when the replay is bit-identical
// and nothing faulted, 1 otherwise, 2 for an unusable recording or configuration.
#include "replay.hpp"

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>

#include "commands.hpp"
#include "estimator_signals.hpp"
#include "plot.hpp"
#include "log_drain.hpp"
#include "lode/event_log.hpp"
#include "lode/host_memory.hpp"
#include "memory_check.hpp"
#include "run_services.hpp"

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

/// The recording being replayed.
struct Source {
  std::string path;  ///< as the user gave it (for messages)
  std::string absolute;
  /// Its attributes, events and raw series (the io blocks' inputs), read once: the io.replay
  /// blocks of every configuration play back this same copy (record::read_recording_shared)
  /// while it is held here. The other series are read one at a time for the comparison.
  std::shared_ptr<const record::Recording> recording;
  std::size_t rows = 0;  ///< cycles to replay
  /// The recorded cycle numbers of those rows, when they skip some (the periods the recording's
  /// real-time loop skipped after overruns); empty when they are 0, 1, 2, ...
  std::vector<std::uint64_t> cycles;
  std::uint64_t skipped = 0;  ///< cycle numbers missing between the first row and the last
  DigestAlgorithm digest = kLegacyDigestAlgorithm;  ///< what its output_digest was computed with

  [[nodiscard]] std::string text(const std::string& key) const {
    auto it = recording->text_attributes.find(key);
    return it == recording->text_attributes.end() ? "" : it->second;
  }
  [[nodiscard]] std::optional<double> number(const std::string& key) const {
    auto it = recording->number_attributes.find(key);
    if (it == recording->number_attributes.end()) return std::nullopt;
    return it->second;
  }
};

/// Reads the recording and checks that it can be replayed; prints why not.
std::optional<Source> open_recording(const std::string& path) {
  Source s;
  s.path = path;
  std::error_code ec;
  s.absolute = fs::absolute(path, ec).lexically_normal().string();
  auto rec = record::read_recording_shared(s.absolute, record::SeriesSelection::raw());
  // Without raw series (a recording of another pipeline's outputs alone) the cycles to run
  // come from the series there are.
  if (rec && (*rec)->series.empty()) rec = record::read_recording_shared(s.absolute);
  if (!rec) {
    std::fprintf(stderr, "lode: replay: %s\n", rec.error().c_str());
    return std::nullopt;
  }
  s.recording = std::move(*rec);
  if (s.text("config").empty()) {
    std::fprintf(stderr, "lode: replay: %s has no `config` attribute (not written by `lode run --record`)\n",
                 path.c_str());
    return std::nullopt;
  }
  // The replay digests with the recording's algorithm, so that the two digests compare.
  const auto algorithm = digest_algorithm_named(s.text(kDigestAlgorithmKey));
  if (!algorithm) {
    std::fprintf(stderr,
                 "lode: replay: %s: attribute %s: '%s' is not a digest this lode computes (xxh3-64, fnv1a-64)\n",
                 path.c_str(), kDigestAlgorithmKey, s.text(kDigestAlgorithmKey).c_str());
    return std::nullopt;
  }
  s.digest = *algorithm;
  // The number of cycles to run: the rows of the raw series (every one is checked for
  // gaps by io.replay), else of any series.
  std::uint64_t first_cycle = 0;
  const record::SeriesData* played = nullptr;
  for (const auto& series : s.recording->series) {
    if (series.rows() == 0) continue;
    if (s.rows == 0 || series.info.kind == "raw") {
      s.rows = series.rows();
      first_cycle = series.cycle.front();
      played = &series;
      if (series.info.kind == "raw") break;
    }
  }
  if (played && played->info.kind == "raw" && played->cycle.back() + 1 > first_cycle + s.rows) {
    s.cycles.assign(played->cycle.begin(), played->cycle.end());
    s.skipped = played->cycle.back() + 1 - first_cycle - s.rows;
  }
  if (s.rows == 0) {
    std::fprintf(stderr, "lode: replay: %s holds no samples\n", path.c_str());
    return std::nullopt;
  }
  if (first_cycle != 0) {
    std::fprintf(stderr,
                 "lode: replay: %s starts at cycle %llu (recorded from mid-run): a replay starts from cycle 0, "
                 "with every estimator in its initial state; record from the start (lode run --record)\n",
                 path.c_str(), static_cast<unsigned long long>(first_cycle));
    return std::nullopt;
  }
  return s;
}

/// One configuration to replay the inputs through, and where its outputs go.
struct Job {
  std::string label, text, output;
  bool recorded = false;
};

std::string without_h5(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  return (ext == ".h5" || ext == ".hdf5") ? path.substr(0, path.size() - ext.size()) : path;
}

/// The recorded configuration first, then every --config; nullopt when one cannot be read.
std::optional<std::vector<Job>> make_jobs(const ReplayArgs& a, const Source& source) {
  std::vector<Job> jobs;
  const std::string base = a.output.empty() ? without_h5(a.recording) + ".replay" : without_h5(a.output);
  Job recorded;
  recorded.label = source.text("config_file").empty() ? "recorded configuration" : source.text("config_file");
  recorded.text = source.text("config");
  recorded.recorded = true;
  recorded.output = a.output.empty() ? base + ".h5" : a.output;
  jobs.push_back(std::move(recorded));
  for (const auto& c : a.configs) {
    std::ifstream in(c);
    if (!in) {
      std::fprintf(stderr, "lode: replay: --config %s: cannot open the pipeline file\n", c.c_str());
      return std::nullopt;
    }
    std::stringstream ss;
    ss << in.rdbuf();
    jobs.push_back({c, ss.str(), base + "-" + fs::path(c).stem().string() + ".h5", false});
  }
  return jobs;
}

/// plugin name -> the file it was loaded from when the recording was made.
std::map<std::string, std::string> recorded_plugin_files(const Source& source) {
  std::map<std::string, std::string> files;
  if (const auto pj = source.text("lode_plugins"); !pj.empty()) {
    try {
      const YAML::Node n = YAML::Load(pj);  // JSON is YAML
      for (const auto& kv : n) files[kv.first.as<std::string>()] = kv.second.as<std::string>();
    } catch (const YAML::Exception&) {
    }
  }
  return files;
}

/// Where this replay cannot be the recorded run: another rate, other plugin files.
void note_differences(const Pipeline& p, const Job& job, const Source& source,
                      const std::map<std::string, std::string>& recorded_plugins, ConfigResult& cr) {
  if (job.recorded && std::abs(p.rate_hz() - source.number("rate_hz").value_or(p.rate_hz())) > 0)
    cr.notes.push_back("rate differs from the recording's");
  if (recorded_plugins.empty()) return;
  const Json d = p.describe();
  const Json* blocks = d.find("blocks");
  if (!blocks) return;
  for (const auto& [name, b] : blocks->members()) {
    const Json* plugin = b.find("plugin");
    const Json* file = b.find("plugin_file");
    if (!plugin || !file || plugin->as_string() == "io.replay") continue;
    auto it = recorded_plugins.find(plugin->as_string());
    if (it != recorded_plugins.end() && it->second != file->as_string())
      cr.notes.push_back("block " + name + ": plugin " + plugin->as_string() + " loaded from " + file->as_string() +
                         ", recorded with " + it->second);
  }
}

/// The signals captured every cycle: the estimators in order, then the reference (if any).
struct Tracked {
  std::vector<SignalRef> signals;
  std::vector<EstimatorStats> estimators;
  bool has_reference = false;
};

/// monitor.estimate, each shadow's matching output, every --estimate, and the reference
/// (--reference, else monitor.truth); nullopt after printing why an output does not exist.
std::optional<Tracked> select_signals(const Pipeline& p, const ReplayArgs& a, const Job& job, ConfigResult& cr) {
  Tracked t;
  const auto& mon = p.monitor();
  auto add_estimator = [&](const SignalRef& s, const std::string& role) {
    for (const auto& e : t.estimators)
      if (e.signal == s.name()) return;
    EstimatorStats e;
    e.signal = s.name();
    e.block = s.block;
    e.plugin = p.plugin_of(s.block);
    e.role = role;
    t.estimators.push_back(std::move(e));
    t.signals.push_back(s);
  };
  for (const auto& e : estimator_signals(p, cr.notes)) add_estimator(e.signal, e.role);
  for (const auto& name : a.estimates) {
    auto s = p.signal(name);
    if (!s) {
      std::fprintf(stderr, "lode: replay: --estimate %s: %s has no such output (`lode describe` lists them)\n",
                   name.c_str(), job.label.c_str());
      return std::nullopt;
    }
    add_estimator(*s, "--estimate");
  }
  std::optional<SignalRef> reference = mon.truth;
  if (!a.reference.empty()) {
    reference = p.signal(a.reference);
    if (!reference) {
      std::fprintf(stderr, "lode: replay: --reference %s: %s has no such output\n", a.reference.c_str(),
                   job.label.c_str());
      return std::nullopt;
    }
  }
  if (reference) {
    cr.reference = reference->name();
    t.signals.push_back(*reference);
    t.has_reference = true;
  }
  return t;
}

/// The recorded configuration's replay against the recording, series by series and by the
/// output digest; prints the verdict. False when they differ.
bool check_bit_identical(const Source& source, const Job& job, ConfigResult& cr) {
  const auto compared = compare_recording_files(source.absolute, job.output);
  if (!compared) {
    std::printf("cannot compare the replay %s with the recording: %s\n", job.output.c_str(),
                compared.error().c_str());
    return false;
  }
  const BitCompare& cmp = *compared;
  const std::string recorded_digest = source.text("output_digest");
  for (const auto& s : cmp.only_in_one) cr.notes.push_back("not compared: " + s);
  const bool digest_ok = recorded_digest.empty() || recorded_digest == cr.digest;
  if (cmp.first_difference.empty() && digest_ok && cmp.series > 0) {
    std::printf("bit-identical: %zu series x %zu cycles, digest %s (%s)%s\n", cmp.series, cmp.cycles,
                cr.digest.c_str(), cr.digest_algorithm.c_str(),
                recorded_digest.empty() ? " (the recording has no digest to compare with)" : "");
    return true;
  }
  const char* with = source.absolute.c_str();
  if (!cmp.first_difference.empty()) {
    std::printf("NOT bit-identical with %s: first difference in %s\n", with, cmp.first_difference.c_str());
    for (const auto& line : cmp.largest_differences) std::printf("  %s\n", line.c_str());
  } else if (cmp.series == 0) {
    std::printf("NOT bit-identical with %s: no series in common\n", with);
  }
  if (!digest_ok)
    std::printf("NOT bit-identical with %s: output digest %s replayed, %s recorded (%s)\n", with, cr.digest.c_str(),
                recorded_digest.c_str(), cr.digest_algorithm.c_str());
  return false;
}

/// Everything one configuration's replay shares with the others.
struct ReplayContext {
  const ReplayArgs& args;
  const Source& source;
  PluginRegistry& registry;
  const std::map<std::string, std::string>& recorded_plugins;
};

/// One configuration loaded for its replay, with what it will compare.
struct Prepared {
  std::unique_ptr<Pipeline> pipeline;
  ConfigResult cr;
  Tracked tracked;
};

/// Loads one configuration for its replay (io blocks replaced by io.replay) and chooses what
/// it compares; nullopt after printing why it cannot be replayed.
std::optional<Prepared> prepare_one(const ReplayContext& ctx, const Job& job) {
  std::vector<std::string> replaced;
  std::string note;
  const std::string text = rewrite_for_replay(job.text, ctx.source.absolute, ctx.registry, replaced, note);
  const std::string label = job.label + " replaying " + ctx.source.path;
  Diagnostics diag;
  auto p = Pipeline::load_text(text, label, ctx.registry, diag);
  if (!p) {
    std::fputs(diag.format().c_str(), stderr);
    std::fprintf(stderr, "lode: replay: %zu problem%s in %s; nothing was replayed%s\n", diag.size(),
                 diag.size() == 1 ? "" : "s", label.c_str(), note.empty() ? "" : (" (" + note + ")").c_str());
    return std::nullopt;
  }
  // Another rate would step the blocks with another period over samples taken every recorded
  // period: each filter's model would be wrong by that ratio, and the comparison meaningless.
  const auto recorded_rate = ctx.source.number("rate_hz");
  if (!job.recorded && recorded_rate && p->rate_hz() != *recorded_rate) {
    std::fprintf(stderr,
                 "lode: replay: %s: rate_hz %g differs from the recording's %g Hz: its blocks would step the "
                 "recorded samples with another period; set rate_hz: %g; nothing was replayed\n",
                 job.label.c_str(), p->rate_hz(), *recorded_rate, *recorded_rate);
    return std::nullopt;
  }
  Prepared prepared;
  ConfigResult& cr = prepared.cr;
  cr.label = job.label;
  cr.recorded = job.recorded;
  cr.output = job.output;
  if (!note.empty()) cr.notes.push_back(note);
  if (replaced.empty()) cr.notes.push_back("no io block to replace: the configuration does not read the recording");
  note_differences(*p, job, ctx.source, ctx.recorded_plugins, cr);
  auto tracked = select_signals(*p, ctx.args, job, cr);
  if (!tracked) return std::nullopt;
  prepared.tracked = std::move(*tracked);
  prepared.pipeline = std::move(p);
  return prepared;
}

/// Replays one prepared configuration into its ConfigResult; returns an exit code when the
/// replay cannot go on (nullopt: it ran, faulted or not).
std::optional<int> replay_one(const ReplayContext& ctx, const Job& job, Prepared& prepared, bool& mismatch,
                              bool& faulted) {
  Pipeline* const p = prepared.pipeline.get();
  ConfigResult& cr = prepared.cr;
  Tracked* const tracked = &prepared.tracked;
  EventLog events;
  LogDrain drain(events);
  SimulatedClock clock;
  Scheduler sched(*p, clock, events);
  // The cycles the recorded run ran, no more: the ticks (cycle number, time) each block sees
  // are then the recorded run's, and so are its outputs.
  if (!ctx.source.cycles.empty()) sched.follow_cycles(ctx.source.cycles);
  RunServiceOptions options;
  options.telemetry = false;
  options.local_control = false;  // a replay is not commanded
  options.simulated = true;
  options.record_path = job.output;
  options.record_source = "lode replay";
  options.record_rows = ctx.source.rows;  // the file is laid out for the whole replay at once
  options.digest = ctx.source.digest;
  auto services = RunServices::start(*p, sched, events, options);
  if (!services) {
    std::fprintf(stderr, "lode: replay: %s; nothing was replayed\n", services.error().c_str());
    return kExitFault;
  }
  const std::size_t rows = ctx.source.rows;
  CompareHook hook(tracked->signals, rows);
  for (const auto& e : tracked->estimators) {
    const auto* estimator = dynamic_cast<const EstimatorState*>(p->block(e.block));
    if (estimator && estimator->innovation_size() > 0) hook.track_nis(*p, e.block);
  }
  sched.add_hook(&hook);
  if (!ctx.args.quiet) std::fprintf(stderr, "lode: replaying %zu cycles through %s\n", rows, job.label.c_str());
  // The speed reported covers the cycles and writing the replay's file in full (closed), so
  // that writing it at the end rather than during the cycles cannot make a replay look faster.
  const auto started = std::chrono::steady_clock::now();
  const std::uint64_t cycle_bound = ctx.source.cycles.empty() ? rows : ctx.source.cycles.back() + 1;
  const auto outcome = execute_run(*p, sched, events, **services, cycle_bound,
                                   "replay of " + ctx.source.path + " through " + job.label,
                                   [&] { (*services)->on_idle(); }, [&] { drain.stop(); });
  if (!outcome) {
    std::fprintf(stderr, "lode: replay: %s: %s\n", job.label.c_str(), outcome.error().c_str());
    return kExitFault;
  }
  cr.cycles = sched.stats().executed.load();
  cr.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  // Real time: the stage time the replayed cycles cover (skipped periods included).
  cr.speed = cr.wall_s > 0 ? static_cast<double>(sched.stats().cycles.load()) / p->rate_hz() / cr.wall_s : 0.0;
  if (ctx.source.skipped > 0)
    cr.notes.push_back(std::to_string(ctx.source.skipped) +
                       " periods the recorded real-time loop skipped after overruns are skipped here too");
  cr.digest = (*services)->output_digest();
  cr.digest_algorithm = digest_algorithm_name((*services)->output_digest_algorithm());
  std::printf("%s: %llu cycles in %.3f s wall, %.0fx real time (%g Hz)\n", job.label.c_str(),
              static_cast<unsigned long long>(cr.cycles), cr.wall_s, cr.speed, p->rate_hz());
  if (outcome->faulted) {
    std::printf("%s: FAULT at cycle %llu: %s\n", job.label.c_str(), static_cast<unsigned long long>(cr.cycles),
                outcome->fault.c_str());
    faulted = true;
  }
  // The replay's own file: written in full, or removed (a disk that filled leaves one HDF5
  // cannot even open, which `lode plot` or a later comparison would trip over).
  std::string write_error;
  const Json services_summary = (*services)->summary();
  if (const Json* recordings = services_summary.find("recordings"))
    for (const Json& r : recordings->elements())
      if (const Json* error = r.find("error")) write_error = error->as_string();
  if (!write_error.empty()) {
    std::error_code ignored;
    fs::remove(job.output, ignored);
    std::printf("%s: the replay's file %s could not be written (%s); it was removed and nothing was compared\n",
                job.label.c_str(), job.output.c_str(), write_error.c_str());
    faulted = true;
  } else if (job.recorded && !check_bit_identical(ctx.source, job, cr)) {
    mismatch = true;
  }
  const int reference_index = tracked->has_reference ? static_cast<int>(tracked->signals.size()) - 1 : -1;
  estimator_statistics(hook, *p, reference_index, tracked->estimators, cr.notes);
  cr.estimators = std::move(tracked->estimators);
  return std::nullopt;
}

int replay(const Args& args) {
  const ReplayArgs a = replay_args(args);
  {
    // A replay holds the recording's raw series (the inputs it plays back), the signals it
    // compares, every cycle (an allowance of 16 values a row), and for the bit-for-bit check
    // one series of the recording and the same of the replay at a time; plus what HDF5 and
    // the plugins take (measured: 186 MB at the peak for a 194 MB, 300 s kawato_planar
    // recording, against this estimate's 212 MB). An HTML report (lode plot of the recording
    // and each other configuration's replay) holds at most about 1.6 times those files more.
    const std::uint64_t bytes = files_bytes({a.recording});
    const auto raw = record::read_cost(a.recording, record::SeriesSelection::raw());
    const auto all = record::read_cost(a.recording, record::SeriesSelection::all());
    if (raw && all) {
      constexpr double kFixedBytes = 32.0 * 1024 * 1024;
      double needed = static_cast<double>(raw->bytes) + 2.0 * static_cast<double>(all->largest_series) +
                      static_cast<double>(all->rows) * 16 * sizeof(double) + kFixedBytes;
      if (fs::path(a.report).extension() == ".html")
        needed += 1.6 * static_cast<double>(bytes) * static_cast<double>(1 + a.configs.size());
      if (!enough_memory("replay", a.recording + " (" + format_bytes(bytes) + ")",
                         static_cast<std::uint64_t>(needed),
                         "a replay holds the recording's raw inputs and the signals it compares, and checks "
                         "its file against the recording one series at a time"))
        return kExitFault;
    }  // else open_recording() says why the file cannot be read
  }
  const auto source = open_recording(a.recording);
  if (!source) return kExitConfig;
  const auto jobs = make_jobs(a, *source);
  if (!jobs) return kExitConfig;
  PluginRegistry registry;  // declared before every pipeline: libraries outlive the blocks
  const auto recorded_plugins = recorded_plugin_files(*source);
  const ReplayContext ctx{a, *source, registry, recorded_plugins};
  // Every configuration is loaded and checked before the first is replayed: a mistake in the
  // last --config stops the command before it has spent time or written files.
  std::vector<Prepared> prepared;
  for (const auto& job : *jobs) {
    auto one = prepare_one(ctx, job);
    if (!one) return kExitConfig;
    prepared.push_back(std::move(*one));
  }
  bool mismatch = false, faulted = false;
  std::vector<ConfigResult> results;
  for (std::size_t i = 0; i < jobs->size(); ++i) {
    if (const auto rc = replay_one(ctx, (*jobs)[i], prepared[i], mismatch, faulted)) return *rc;
    results.push_back(std::move(prepared[i].cr));
    prepared[i].pipeline.reset();  // its blocks and memory, before the next one runs
  }

  const ReplayReport report = replay_report(a.recording, source->text("pipeline"), source->rows,
                                            source->number("rate_hz").value_or(0), results, !mismatch, faulted);
  if (!a.quiet) std::printf("\n%s", report.markdown.c_str());
  if (fs::path(a.report).extension() == ".html") {
    // The comparison as plots: the recording with every other configuration's replay beside it.
    std::vector<std::string> recordings{a.recording};
    for (const auto& cr : results)
      if (!cr.recorded && !cr.output.empty()) recordings.push_back(cr.output);
    const int rc = write_plot_report(recordings, a.report, a.quiet);
    if (rc != kExitOk) return rc;
  } else if (!a.report.empty()) {
    const bool json = fs::path(a.report).extension() == ".json";
    if (Status written = write_text_file(a.report, json ? report.json.dump() + "\n" : report.markdown); !written) {
      std::fprintf(stderr, "lode: replay: %s\n", written.message().c_str());
      return kExitFault;
    }
  }
  return (mismatch || faulted) ? kExitFault : kExitOk;
}

void declare(Declare& d) {
  d.positional("RECORDING", "a recording written by lode run --record", 1, 1);
  d.list("--config", "OTHER.yaml", "another pipeline to replay the inputs through (repeatable)");
  d.list("--estimate", "BLOCK.PORT", "another output to compare (repeatable)");
  d.text("--output", "OUT.h5", "where the replayed outputs go (one file per configuration)");
  d.text("--report", "R.md|R.json|R.html",
         "write the comparison report (.html: the plots of lode plot, every configuration beside the recording)");
  d.text("--reference", "BLOCK.PORT", "what the estimators are compared against (default monitor.truth)");
  d.flag("--quiet", "no progress");
}

}  // namespace

Command replay_command() {
  return {"replay",
          "run a recording's raw inputs (lode run --record) through the recorded configuration (checked bit for "
          "bit) and other estimator sets at full speed; writes OUT.h5 per configuration and a comparison report",
          declare, replay};
}

}  // namespace lode::cli
