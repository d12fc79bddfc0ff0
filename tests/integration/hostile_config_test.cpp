// Hostile or unlucky input to `lode check` and `lode run`: each case must end in a located
// configuration error (exit 2, the file named) within the time guard, never a crash, a hang,
// an out-of-memory or a pipeline that starts with a value it silently changed.
//
// Each case runs the real `lode` binary under `timeout`, so a stack overflow (exit 139), an
// abort (134), a hang (124) or an uncaught exception (exit 1, "internal error") all fail here.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <string>

#include "lode/sdk/testing/require.hpp"
#include "lode/sdk/testing/scratch_dir.hpp"

namespace {

/// A pipeline that loads (kawato_planar's blocks are not needed to reach the loader's checks:
/// every case below fails before or at the top level).
const std::string kValidHead = R"(pipeline: hostile
rate_hz: 800
blocks:
  ref:
    plugin: source.step
    names: [x]
    units: [m]
    steps: [{time_s: 0.1, value: [1.0e-4]}]
)";

struct Outcome {
  int exit_code = -1;
  std::string output;
  double seconds = 0.0;
};

/// Runs `lode ARGS` under a 60 s guard (a hang must not hang the suite); captures both streams.
Outcome run_lode(const std::string& args) {
  // A runtime directory of its own: a `lode run` here must not meet another run's sockets.
  static const std::string runtime = [] {
    const std::string dir = lode::testing::scratch_path("run");
    ::mkdir(dir.c_str(), 0700);
    return dir;
  }();
  const std::string cmd = "XDG_RUNTIME_DIR=" + runtime + " timeout -k 5 60 " + std::string(LODE_BINARY_DIR) +
                          "/apps/lode " + args + " </dev/null 2>&1";
  const auto start = std::chrono::steady_clock::now();
  FILE* pipe = popen(cmd.c_str(), "r");
  Outcome o;
  if (!pipe) return o;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe)) {
    if (o.output.size() < 64 * 1024) o.output += buf;  // a runaway message must not fill memory
  }
  const int status = pclose(pipe);
  o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return o;
}

std::string temp_path(const std::string& name) { return lode::testing::scratch_path(name); }

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = temp_path(name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

std::string billion_laughs() {
  // Nine levels of nine aliases each: 9^9 = 387 million leaves from about 1 KB of text.
  std::string s = "pipeline: laughs\nrate_hz: 800\nl0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n";
  for (int i = 1; i <= 9; ++i) {
    s += "l" + std::to_string(i) + ": &l" + std::to_string(i) + " [";
    for (int k = 0; k < 9; ++k) s += (k ? ", *l" : "*l") + std::to_string(i - 1);
    s += "]\n";
  }
  return s + "blocks: {ref: {plugin: source.step, names: [x], units: [m], value: *l9}}\n";
}

struct Case {
  const char* name;
  /// Makes the input and returns the arguments after `lode`.
  std::function<std::string()> args;
  const char* message;  ///< must appear in the output
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

const std::vector<Case>& cases() {
  static const std::vector<Case> c = {
      {"recursive_alias_check",
       [] { return "check " + write_file("alias.yaml", kValidHead + "a: &r [1, *r]\n"); },
       "recursive alias"},
      {"recursive_alias_run",
       [] { return "run " + write_file("alias_run.yaml", kValidHead + "a: &r [1, *r]\n") + " --quiet"; },
       "recursive alias"},
      {"recursive_alias_in_a_map",
       [] { return "check " + write_file("alias_map.yaml", kValidHead + "m: &m {self: *m}\n"); },
       "recursive alias"},
      {"billion_laughs", [] { return "check " + write_file("laughs.yaml", billion_laughs()); },
       "expands to more than"},
      {"oversized_flow_array",
       [] {
         std::string s = kValidHead + "big: [";
         while (s.size() < 3 * 1024 * 1024) s += "1.0,";
         return "check " + write_file("big.yaml", s + "0]\n");
       },
       "is larger than 1048576 bytes"},
      {"character_device", [] { return std::string("check /dev/zero"); }, "/dev/zero: is a character device"},
      {"directory", [] { return "check " + ::testing::TempDir(); }, "is a directory"},
      {"fifo_nobody_writes",
       [] {
         const std::string path = temp_path("fifo.yaml");
         ::unlink(path.c_str());
         if (::mkfifo(path.c_str(), 0600) != 0) return std::string("check /nonexistent-fifo");
         return "check " + path;
       },
       "is a FIFO"},
      {"sequence_as_key", [] { return "check " + write_file("seqkey.yaml", kValidHead + "? [a, b]\n: 1\n"); },
       "a key must be a plain scalar (a name), not a list"},
      {"map_as_key", [] { return "check " + write_file("mapkey.yaml", kValidHead + "{a: 1}: 2\n"); },
       "a key must be a plain scalar (a name), not a map"},
      {"nesting_past_the_parser_limit",
       [] { return "check " + write_file("deep.yaml", kValidHead + "deep: " + std::string(5000, '[') +
                                                           std::string(5000, ']') + "\n"); },
       "YAML syntax error"},
      {"nesting_past_the_loader_limit",
       [] { return "check " + write_file("deep100.yaml", kValidHead + "deep: " + std::string(100, '[') +
                                                              std::string(100, ']') + "\n"); },
       "nested deeper than 64 levels"},
      {"duration_below_one_cycle",
       [] { return "check " + write_file("tiny.yaml", "duration_s: 1.0e-300\n" + kValidHead); },
       "is shorter than one cycle"},
      {"run_duration_below_one_cycle",
       [] { return "run " + write_file("tiny_run.yaml", kValidHead) + " --duration 0.0005 --quiet"; },
       "is shorter than one cycle at 800 Hz"},
      {"priority_past_int",
       [] { return "check " + write_file("prio.yaml", kValidHead + "realtime: {priority: 4294967376}\n"); },
       "got 4294967376"},
      {"cpu_past_int",
       [] { return "check " + write_file("cpu.yaml", kValidHead + "realtime: {cpu: 4294967296}\n"); },
       "got 4294967296"},
      {"pipeline_name_with_path",
       [] {
         std::string s = kValidHead;
         s.replace(s.find("hostile"), 7, "lab/../../evil");
         return "check " + write_file("evil.yaml", s);
       },
       "may hold only letters, digits"},
      // Saved as Windows-1252: "µm" is the byte 0xB5; the error points at it (line 10, column
      // 10: after the head's 8 lines and a comment, inside `units: ["`), the character to retype.
      {"latin1_unit",
       [] { return "check " + write_file("latin1.yaml", kValidHead + "# stroke\nunits: [\"\xB5m\"]\n"); },
       "latin1.yaml:10:10: not UTF-8"},
      {"latin1_unit_names_the_byte",
       [] { return "check " + write_file("latin1_b.yaml", kValidHead + "units: [\"\xB5m\"]\n"); },
       "not UTF-8 text: byte 0xB5"},
      {"truncated_utf8_sequence_at_the_end",
       [] { return "run " + write_file("cut.yaml", kValidHead + "# \xCE") + " --quiet"; }, "not UTF-8 text: byte 0xCE"},
      {"pipeline_name_hidden_file",
       [] {
         std::string s = kValidHead;
         s.replace(s.find("hostile"), 7, ".hidden");
         return "check " + write_file("hidden.yaml", s);
       },
       "starts with '.'"},
  };
  return c;
}

class HostileConfig : public ::testing::TestWithParam<Case> {};

TEST_P(HostileConfig, LocatedErrorExitTwoNoCrashNoHang) {
  LODE_REQUIRE_PLUGINS("source.step");
  const Case& c = GetParam();
  const Outcome o = run_lode(c.args());
  EXPECT_EQ(o.exit_code, 2) << "exit " << o.exit_code << " after " << o.seconds << " s (124: hang, 134/139: crash)\n"
                            << o.output.substr(0, 2000);
  EXPECT_NE(o.output.find(c.message), std::string::npos)
      << "expected \"" << c.message << "\" in:\n" << o.output.substr(0, 2000);
  EXPECT_EQ(o.output.find("internal error"), std::string::npos) << o.output.substr(0, 2000);
  std::printf("%-32s exit %d in %.2f s\n", c.name, o.exit_code, o.seconds);
}

INSTANTIATE_TEST_SUITE_P(Table, HostileConfig, ::testing::ValuesIn(cases()),
                         [](const auto& case_info) { return std::string(case_info.param.name); });

TEST(HostileConfigBase, TheValidHeadChecksClean) {
  // Without this, every case above could pass for a reason that has nothing to do with it.
  LODE_REQUIRE_PLUGINS("source.step");
  const Outcome o = run_lode("check " + write_file("valid.yaml", kValidHead));
  EXPECT_EQ(o.exit_code, 0) << o.output;
}

}  // namespace
