// lode plot RECORDING [REPLAY...] [-o report.html] [--png DIR]: one self-contained HTML
// report of a recording (lode run --record, lode record, lode replay), with the estimates of
// replays of it side by side; --png photographs each figure with headless Chromium.
//
// plot_data reads and arranges the recordings, plot_metrics computes the figures (reusing
// the run summary's RunAnalysis), plot_html writes the page.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "commands.hpp"
#include "plot.hpp"
#include "memory_check.hpp"
#include "plot_data.hpp"
#include "plot_html.hpp"
#include "plot_metrics.hpp"

extern char** environ;

namespace lode::cli {
namespace {

namespace fs = std::filesystem;

/// Chromium as Debian installs it, or $LODE_CHROMIUM.
std::string chromium_program() {
  if (const char* env = std::getenv("LODE_CHROMIUM"); env && *env) return env;
  for (const char* candidate : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"})
    if (::access(candidate, X_OK) == 0) return candidate;
  return "";
}

/// Starts `argv` with stdout and stderr discarded (Chromium reports GPU and D-Bus noise
/// there); returns its pid, or -1 when it could not be started.
pid_t spawn_quietly(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  return spawned == 0 ? pid : -1;
}

/// The exit status of `pid`, or -1 when it did not exit normally.
int wait_for(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// One PNG per figure: the page shows only the figure named in its #figure= fragment. Two
/// Chromiums at a time (each mostly waits on its own start-up), each with a fresh profile of
/// its own, since two cannot share (and lock) one.
int write_pngs(const fs::path& html, const std::vector<std::string>& figures, const fs::path& dir, bool quiet) {
  const std::string chromium = chromium_program();
  if (chromium.empty()) {
    std::fprintf(stderr, "lode: plot: --png needs Chromium (apt-get install chromium, or set LODE_CHROMIUM)\n");
    return kExitFault;
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  const std::string page = "file://" + fs::absolute(html).string() + "#figure=";
  struct Shot {
    pid_t pid;
    fs::path png, profile;
    std::string id;
  };
  std::vector<Shot> running;
  int failures = 0;
  const auto finish = [&](const Shot& shot) {
    const int status = wait_for(shot.pid);
    fs::remove_all(shot.profile, ec);
    if (status != 0 || !fs::exists(shot.png)) {
      std::fprintf(stderr, "lode: plot: Chromium could not photograph figure %s (exit %d)\n", shot.id.c_str(), status);
      ++failures;
    } else if (!quiet) {
      std::printf("  %s\n", shot.png.c_str());
    }
  };
  for (std::size_t i = 0; i < figures.size(); ++i) {
    if (running.size() == 2) {
      finish(running.front());
      running.erase(running.begin());
    }
    const std::string& id = figures[i];
    Shot shot{-1, fs::absolute(dir / (id + ".png")),
              fs::temp_directory_path() / ("lode-plot-" + std::to_string(::getpid()) + "-" + std::to_string(i)), id};
    fs::remove(shot.png, ec);
    shot.pid = spawn_quietly({chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                              "--no-first-run", "--user-data-dir=" + shot.profile.string(), "--window-size=1200,640",
                              "--virtual-time-budget=10000", "--screenshot=" + shot.png.string(), page + id});
    if (shot.pid < 0) {
      std::fprintf(stderr, "lode: plot: cannot start %s\n", chromium.c_str());
      ++failures;
      continue;
    }
    running.push_back(std::move(shot));
  }
  for (const auto& shot : running) finish(shot);
  return failures ? kExitFault : kExitOk;
}

}  // namespace

int write_plot_report(const std::vector<std::string>& recordings, const fs::path& output, bool quiet,
                      std::vector<std::string>* figures) {
  if constexpr (!LODE_PLOT_REPORTS) {
    std::fprintf(stderr, "lode: plot: built without its chart library (cd apps/lode/plot && npm ci, then rebuild)\n");
    return kExitFault;
  }
  const auto started = std::chrono::steady_clock::now();
  PluginRegistry registry;  // before the pipelines: their plugins' libraries outlive them
  std::vector<plot::LoadedRecording> loaded;
  std::uint64_t plotted = 0;
  for (const auto& path : recordings) {
    auto r = plot::open_recording(path, registry);
    auto bytes = r ? plot::plotted_bytes(*r) : Expected<std::uint64_t>(r.status());
    if (!bytes) {
      std::fprintf(stderr, "lode: plot: %s\n", bytes.error().c_str());
      return kExitConfig;
    }
    plotted += *bytes;
    loaded.push_back(std::move(*r));
  }
  // Measured on kawato_planar recordings of 300 s and 600 s: the peak grows by 3.06 times the
  // series it reads (held whole, and the arrays of its figures built from them), from about
  // 30 MB (the process and the pipeline's plugins, already in use here).
  if (!enough_memory("plot", recordings.size() == 1 ? recordings.front() : std::to_string(recordings.size()) + " recordings",
                     static_cast<std::uint64_t>(3.2 * static_cast<double>(plotted)),
                     "the series it plots are read whole"))
    return kExitFault;
  for (auto& l : loaded) {
    if (Status s = plot::read_plotted(l); !s) {
      std::fprintf(stderr, "lode: plot: %s\n", s.message().c_str());
      return kExitConfig;
    }
  }
  plot::ReportInput input;
  for (std::size_t i = 1; i < loaded.size(); ++i) {
    if (Status s = plot::check_replay_of(loaded.front(), loaded[i], input.notes); !s) {
      std::fprintf(stderr, "lode: plot: %s\n", s.message().c_str());
      return kExitConfig;
    }
  }
  std::vector<const plot::LoadedRecording*> files;
  std::vector<plot::SeriesRoles> roles;
  for (const auto& l : loaded) {
    files.push_back(&l);
    roles.push_back(plot::find_roles(l));
    input.notes.insert(input.notes.end(), l.notes.begin(), l.notes.end());
  }
  const plot::PlotSignals signals = plot::collect_axes(files, roles);
  input.notes.insert(input.notes.end(), signals.notes.begin(), signals.notes.end());
  if (signals.axes.empty()) {
    std::fprintf(stderr, "lode: plot: %s has no reference, truth or estimate to plot (roles: %s)\n",
                 loaded.front().path.c_str(), loaded.front().pipeline ? "monitor: section" : "by series name");
    return kExitConfig;
  }
  const auto errors = plot::estimation_errors(signals.axes);
  input.hold = plot::hold_window(roles.front(), signals.grid);
  const auto error_table = plot::estimator_errors(signals.axes, signals.grid, input.hold);
  const auto spectra = plot::hold_spectra(signals.axes, signals.grid, input.hold);
  input.summary = plot::run_summary(loaded.front(), input.notes);
  const std::string pipeline = loaded.front().text("pipeline");
  input.title = (pipeline.empty() ? std::string("recording") : pipeline) + " - " + loaded.front().label;
  input.files = files;
  input.signals = &signals;
  input.errors = &errors;
  input.error_table = &error_table;
  input.spectra = &spectra;
  const plot::Report report = plot::report_html(input);
  if (Status written = write_text_file(output, report.html); !written) {
    std::fprintf(stderr, "lode: plot: %s\n", written.message().c_str());
    return kExitFault;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  if (!quiet) {
    for (const auto& note : input.notes) std::printf("note: %s\n", note.c_str());
    std::printf("%s: %zu figures, %zu samples per curve, %.1f MB (%.1f MB of arrays) in %.2f s\n", output.c_str(),
                report.figures.size(), signals.grid.size(), static_cast<double>(report.html.size()) / 1e6,
                static_cast<double>(report.blob_bytes) / 1e6, seconds);
  }
  if (figures) *figures = report.figures;
  return kExitOk;
}

namespace {

int plot(const Args& args) {
  const bool quiet = args.has_flag("--quiet");
  const fs::path recording(args.positional.front());
  const fs::path output = args.has("-o,--output") ? fs::path(args.option("-o,--output"))
                                                  : recording.parent_path() / (recording.stem().string() + ".html");
  std::vector<std::string> figures;
  if (const int rc = write_plot_report(args.positional, output, quiet, &figures); rc != kExitOk) return rc;
  if (args.has("--png")) return write_pngs(output, figures, args.option("--png"), quiet);
  return kExitOk;
}

void declare(Declare& d) {
  d.positional("RECORDING", "a recording (lode run --record, lode record, lode replay); further recordings "
                            "(replays of it through other configurations) add their estimates", 1, 64);
  d.text("-o,--output", "REPORT.html", "where the report goes (default: RECORDING with .html)");
  d.text("--png", "DIR", "also write every figure as DIR/<figure>.png (headless Chromium)");
  d.flag("--quiet", "print nothing but errors");
}

}  // namespace

Command plot_command() {
  return {"plot",
          "one self-contained HTML report of a recording: signals, estimation errors, step responses, noise "
          "spectra, timing and events, zoomable; --png writes each figure as a PNG",
          declare, plot};
}

}  // namespace lode::cli
