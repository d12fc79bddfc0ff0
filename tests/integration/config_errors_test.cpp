// Table-driven: every kind of configuration mistake gives a message naming the file, the
// line and column and the field, and the pipeline does not load (exit code 2 from `lode`).
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <regex>
#include <string>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/testing/scratch_dir.hpp"

namespace {

const std::string kValid = R"(pipeline: errors
rate_hz: 800
models:
  platen: {plugin: plant.planar_stage}
  hall:
    plugin: sensor.halbach_hall
    sensors:
      - {name: A, x_m: 0.00635, y_m: 0.09525}
      - {name: B, x_m: -0.00635, y_m: -0.09525}
blocks:
  stage:
    plugin: io.sim
    plant: platen
    sensors: [hall]
    seed: 1
    inputs: {command: ctrl.out}
  ref:
    plugin: source.step
    names: [x, y, theta_z]
    units: [m, m, rad]
    steps: [{time_s: 0.1, value: [1.0e-4, 0.0, 0.0]}]
  ctrl:
    plugin: controller.discrete_tf
    axes:
      - {zeros_s: [-10.0], poles_s: [0.0, -1000.0], gain: 1.0e5, discretization: matched}
      - {zeros_s: [-10.0], poles_s: [0.0, -1000.0], gain: 1.0e5, discretization: matched}
      - {zeros_s: [-10.0], poles_s: [0.0, -1000.0], gain: 1.0e3, discretization: matched}
    output_units: [N, N, N*m]
    inputs: {measurement: stage.truth, reference: ref.out}
monitor:
  truth: stage.truth
)";

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  if (pos == std::string::npos) throw std::runtime_error("test bug: '" + from + "' not in base");
  return s.replace(pos, from.size(), to);
}

struct Case {
  const char* name;
  std::function<std::string()> yaml;
  const char* message;  ///< must appear in the diagnostics
  const char* marker;   ///< the reported line must contain this text ("" = any line)
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

int line_of(const std::string& text, const std::string& marker) {
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    if (line.find(marker) != std::string::npos) return n;
  return -1;
}

const std::vector<Case>& cases() {
  static const std::vector<Case> c = {
      {"yaml_syntax_error", [] { return replace(kValid, "rate_hz: 800", "rate_hz: [800"); },
       "YAML syntax error", ""},
      {"unknown_plugin", [] { return replace(kValid, "plugin: source.step", "plugin: source.stepp"); },
       "no plugin named 'source.stepp'", "source.stepp"},
      {"missing_required_parameter", [] { return replace(kValid, "    output_units: [N, N, N*m]\n", ""); },
       "output_units", "plugin: controller.discrete_tf"},
      {"rate_not_a_number", [] { return replace(kValid, "rate_hz: 800", "rate_hz: fast"); },
       "rate_hz must be a number", "rate_hz: fast"},
      {"negative_rate", [] { return replace(kValid, "rate_hz: 800", "rate_hz: -5"); },
       "rate_hz must be a number in (0, 100000]", "rate_hz: -5"},
      {"unknown_parameter_typo", [] { return replace(kValid, "    seed: 1\n", "    seed: 1\n    noise_std: 1.0e-3\n"); },
       "unknown parameter 'noise_std' (did you mean 'noise_std_v'?)", "noise_std: 1.0e-3"},
      {"wrong_parameter_type", [] { return replace(kValid, "seed: 1", "seed: many"); },
       "expected an integer, got 'many'", "seed: many"},
      {"input_from_unknown_block", [] { return replace(kValid, "reference: ref.out", "reference: reff.out"); },
       "no block named 'reff'", "reff.out"},
      {"input_from_unknown_port", [] { return replace(kValid, "reference: ref.out", "reference: ref.outt"); },
       "has no output 'outt' (outputs: out)", "ref.outt"},
      {"malformed_port_reference", [] { return replace(kValid, "reference: ref.out", "reference: refout"); },
       "is not a `block.port` reference", "reference: refout"},
      {"wrong_port_size",
       [] {
         return replace(kValid, "    inputs: {command: ctrl.out}",
                        "    inputs: {command: two.out}\n  two: {plugin: source.step, names: [a, b], units: [N, N],"
                        " steps: [{time_s: 0.1, value: [1.0, 2.0]}]}");
       },
       "size mismatch: input 'command' of stage takes 3 elements", "command: two.out"},
      {"unit_mismatch", [] { return replace(kValid, "inputs: {command: ctrl.out}", "inputs: {command: ref.out}"); },
       "unit mismatch at element 0: ref.out.x is in 'm', input 'command.fx' expects 'N'", "command: ref.out"},
      {"cycle_between_blocks",
       [] {
         return replace(replace(kValid, "inputs: {measurement: stage.truth, reference: ref.out}",
                                "inputs: {measurement: stage.truth, reference: loop.out}"),
                        "monitor:",
                        "  loop:\n    plugin: controller.discrete_tf\n    axes: [{num_z: [1.0], den_z: [1.0]}, "
                        "{num_z: [1.0], den_z: [1.0]}, {num_z: [1.0], den_z: [1.0]}]\n    output_units: [m, m, rad]\n"
                        "    inputs: {measurement: ctrl.out}\nmonitor:");
       },
       "cycle among blocks", ""},
      {"required_input_not_connected", [] { return replace(kValid, "    inputs: {command: ctrl.out}\n", ""); },
       "required input 'command' is not connected", "  stage:"},
      {"unknown_input_name",
       [] { return replace(kValid, "reference: ref.out}", "reference: ref.out, feedforward: ref.out}"); },
       "has no input 'feedforward'", "feedforward"},
      {"duplicate_key", [] { return replace(kValid, "    seed: 1\n", "    seed: 1\n    seed: 2\n"); },
       "duplicate key 'seed'", "seed: 2"},
      {"unknown_model", [] { return replace(kValid, "plant: platen", "plant: platten"); },
       "no model named 'platten' in `models:` (models: hall, platen)", "plant: platten"},
      {"model_of_wrong_kind", [] { return replace(kValid, "plant: platen", "plant: hall"); },
       "model 'hall' is a sensor (sensor.halbach_hall), this parameter needs a plant model", "plant: hall"},
      {"block_plugin_as_model",
       [] { return replace(kValid, "platen: {plugin: plant.planar_stage}", "platen: {plugin: source.step}"); },
       "plugin source.step is a block, not a model", "platen: {plugin: source.step}"},
      {"model_plugin_as_block",
       [] { return replace(kValid, "monitor:", "  oops: {plugin: plant.planar_stage}\nmonitor:"); },
       "model: declare it under `models:`", "oops:"},
      {"invalid_choice", [] { return replace(kValid, "gain: 1.0e3, discretization: matched", "gain: 1.0e3, discretization: bilinear"); },
       "'bilinear' is not one of", "discretization: bilinear"},
      {"unknown_nested_parameter",
       [] { return replace(kValid, "gain: 1.0e3, discretization: matched}", "gain: 1.0e3, discretization: matched, pole_s: [1.0]}"); },
       "axes[2].pole_s: unknown parameter 'pole_s'", "pole_s: [1.0]"},
      {"unknown_top_level_key", [] { return replace(kValid, "monitor:", "blockz: {}\nmonitor:"); },
       "unknown top-level key 'blockz'", "blockz"},
      {"missing_pipeline_name", [] { return replace(kValid, "pipeline: errors\n", ""); },
       "missing pipeline name", ""},
      {"monitor_unknown_signal", [] { return replace(kValid, "truth: stage.truth\n", "truth: stage.truthy\n"); },
       "no output 'stage.truthy'", "truth: stage.truthy"},
      {"bad_model_parameter", [] { return replace(kValid, "{plugin: plant.planar_stage}", "{plugin: plant.planar_stage, mass_kg: -1}"); },
       "mass_kg", "mass_kg: -1"},
      {"bad_realtime_priority", [] { return replace(kValid, "rate_hz: 800\n", "rate_hz: 800\nrealtime: {priority: 150}\n"); },
       "SCHED_FIFO priority must be 0 (none) or 1..99", "priority: 150"},
      {"bad_realtime_spin", [] { return replace(kValid, "rate_hz: 800\n", "rate_hz: 800\nrealtime: {spin_us: -5}\n"); },
       "busy-wait before each deadline must be 0..1000000 us, got -5", "spin_us: -5"},
      // The telemetry: section is checked like the rest, before anything starts.
      {"telemetry_rate_not_a_divisor",
       [] { return kValid + std::string("telemetry: {rate_hz: 300, publish: [stage.truth]}\n"); },
       "rate 300 Hz does not divide the pipeline rate 800 Hz; nearest rates: 266.667 or 400 Hz", "rate_hz: 300"},
      {"telemetry_unknown_signal",
       [] { return kValid + std::string("telemetry:\n  publish: [stage.truth, ctrl.force]\n"); },
       "no output 'ctrl.force'", "publish: [stage.truth, ctrl.force]"},
      {"telemetry_bad_allow_host",
       [] { return kValid + std::string("telemetry:\n  commands: {enabled: true, allow_hosts: [lab-pc]}\n"); },
       "allow_hosts[0] 'lab-pc' is not an IPv4 address", "allow_hosts: [lab-pc]"},
      {"telemetry_network_settings_without_network",
       [] { return kValid + std::string("telemetry:\n  network: {interfaces: [10.0.0.5]}\n"); },
       "only apply with `transport: network`", "network: {interfaces"},
      {"telemetry_publisher_above_the_loop",
       [] {
         return replace(kValid, "rate_hz: 800\n", "rate_hz: 800\nrealtime: {priority: 40}\n") +
                std::string("telemetry: {priority: 40}\n");
       },
       "must be below realtime.priority (40): the RT thread must preempt the publisher", "telemetry: {priority: 40}"},
      {"telemetry_priority_out_of_range", [] { return kValid + std::string("telemetry: {priority: 99}\n"); },
       "must be in 0..98 (a SCHED_FIFO priority for the publisher thread", "priority: 99"},
      {"telemetry_missing_certificate",
       [] { return kValid + std::string("telemetry:\n  security: {ca_certificate: /nonexistent/ca.pem}\n"); },
       "cannot read '/nonexistent/ca.pem'", "security: {ca_certificate"},
  };
  return c;
}

class ConfigErrors : public ::testing::TestWithParam<Case> {};

TEST(ConfigErrorsBase, ValidBaseLoads) {
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(kValid, "base.yaml", registry, diag);
  EXPECT_TRUE(p) << diag.format();
}

TEST_P(ConfigErrors, LocatedMessageAndRefusal) {
  const Case& c = GetParam();
  const std::string yaml = c.yaml();
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(yaml, "bad.yaml", registry, diag);
  EXPECT_FALSE(p) << "a broken pipeline loaded";
  const std::string text = diag.format();
  EXPECT_NE(text.find(c.message), std::string::npos) << "expected \"" << c.message << "\" in:\n" << text;
  // Every diagnostic names file:line:column.
  const std::regex located(R"(^bad\.yaml:\d+:\d+: )");
  bool expected_line_found = std::string(c.marker).empty();
  const int want_line = std::string(c.marker).empty() ? -1 : line_of(yaml, c.marker);
  for (const auto& d : diag.items()) {
    EXPECT_TRUE(std::regex_search(d.format(), located)) << d.format();
    if (d.message.find(c.message) != std::string::npos || d.field.find(c.message) != std::string::npos ||
        d.format().find(c.message) != std::string::npos)
      expected_line_found = expected_line_found || d.where.line == want_line;
  }
  EXPECT_TRUE(expected_line_found) << "no diagnostic at line " << want_line << " ('" << c.marker << "'):\n" << text;
}

INSTANTIATE_TEST_SUITE_P(Table, ConfigErrors, ::testing::ValuesIn(cases()),
                         [](const auto& case_info) { return std::string(case_info.param.name); });

// One mistake is one problem: what the blocks reading from a block that failed, or every block
// at an invalid rate, would refuse next is its echo, not another mistake to fix.
TEST(ConfigErrorsEchoes, OneMistakeIsOneProblem) {
  const struct {
    const char* name;
    std::string yaml;
    const char* message;
  } mistakes[] = {
      {"a misspelt plugin that another block reads from",
       replace(kValid, "plugin: source.step", "plugin: source.stepp"),
       "no plugin named 'source.stepp' (did you mean 'source.step'?)"},
      {"a misspelt controller that the board reads from",
       replace(kValid, "plugin: controller.discrete_tf", "plugin: controller.discrete_tff"),
       "no plugin named 'controller.discrete_tff' (did you mean 'controller.discrete_tf'?)"},
      {"a controller whose configuration is refused", replace(kValid, "    output_units: [N, N, N*m]\n", ""),
       "blocks.ctrl.output_units: one SI unit per axis is required"},
      {"a rate with its unit", replace(kValid, "rate_hz: 800", "rate_hz: 800 Hz"),
       "rate_hz must be a number in (0, 100000], got '800 Hz' (the blocks are checked once it is valid"},
      // The mass is then not "must be > 0 kg, got 0", and the board that needs the plant is not
      // "plant model 'platen' is not available": both follow from the one mistake.
      {"a model's number with its unit", replace(kValid, "platen: {plugin: plant.planar_stage}",
                                                 "platen: {plugin: plant.planar_stage, mass_kg: 6.2 kg}"),
       "models.platen.mass_kg: expected a finite number, got '6.2 kg' (numbers are in SI units, written without "
       "the unit: 6.2 for 6.2 kg)"},
      {"a sensor position in millimetres", replace(kValid, "x_m: 0.00635, y_m: 0.09525", "x_m: 6.35mm, y_m: 0.09525"),
       "expected a finite number, got '6.35mm' (numbers are in SI units, written without the unit: 0.00635 for 6.35mm)"},
      {"a list element with its unit", replace(kValid, "value: [1.0e-4, 0.0, 0.0]", "value: [100 um, 0.0, 0.0]"),
       "value[0]: expected a finite number, got '100 um' (numbers are in SI units, written without the unit: 0.0001 "
       "for 100 um)"},
  };
  for (const auto& m : mistakes) {
    lode::PluginRegistry registry;
    lode::Diagnostics diag;
    EXPECT_FALSE(lode::Pipeline::load_text(m.yaml, "bad.yaml", registry, diag)) << m.name;
    const std::string text = diag.format();
    EXPECT_NE(text.find(m.message), std::string::npos) << m.name << ":\n" << text;
    EXPECT_EQ(diag.size(), 1u) << m.name << ":\n" << text;
  }
}

TEST(ConfigErrorsCli, LodeCheckExitsTwoWithLocation) {
  const std::string path = lode::testing::scratch_path("bad_config.yaml");
  {
    std::ofstream f(path);
    f << replace(kValid, "plant: platen", "plant: platten");
  }
  const std::string cmd = std::string(LODE_BINARY_DIR) + "/apps/lode check " + path + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string out;
  char buf[512];
  while (fgets(buf, sizeof buf, pipe)) out += buf;
  const int status = pclose(pipe);
  EXPECT_EQ(WEXITSTATUS(status), 2) << out;
  EXPECT_NE(out.find(path + ":13:12: blocks.stage.plant: no model named 'platten'"), std::string::npos) << out;
  EXPECT_NE(out.find("nothing was started"), std::string::npos) << out;
}

}  // namespace
