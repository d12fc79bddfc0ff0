#include "command_line.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <iostream>
#include <memory>

#include "lode/plugin.hpp"
#include "lode/plugin_loader.hpp"

namespace lode::cli {
namespace {

constexpr const char* kFooter =
    "exit codes: 0 success, 1 runtime fault, 2 invalid configuration or usage\n"
    "plugin search path: $LODE_PLUGIN_PATH, <exe>/../lib/lodestone/plugins, install and build folders";

/// An integer in [min, max], written as digits (no fraction, no exponent).
CLI::Validator integer_in(long long min, long long max) {
  return CLI::Validator(
      [min, max](std::string& text) -> std::string {
        long long value = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
        if (text.empty() || error != std::errc() || end != text.data() + text.size())
          return "'" + text + "' is not an integer";
        if (value < min || value > max)
          return "'" + text + "' is outside [" + std::to_string(min) + ", " + std::to_string(max) + "]";
        return {};
      },
      "INT in [" + std::to_string(min) + ", " + std::to_string(max) + "]");
}

/// A finite number in [min, max].
CLI::Validator number_in(double min, double max) {
  return CLI::Validator(
      [min, max](std::string& text) -> std::string {
        double value = 0.0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
        if (text.empty() || error != std::errc() || end != text.data() + text.size())
          return "'" + text + "' is not a number";
        if (!(value >= min && value <= max)) {
          char range[64];
          std::snprintf(range, sizeof range, "[%g, %g]", min, max);
          return "'" + text + "' is outside " + range;
        }
        return {};
      },
      "");
}

/// Declares options on one command; each writes what it received into `args`, the one
/// structure the commands read. (The callbacks hold `args`, never the Declare, which is gone
/// by the time they run.)
class Declare {
 public:
  Declare(CLI::App* app, Args& args) : app_(app), args_(args) {}

  CLI::Option* text(const std::string& name, const std::string& value_name, const std::string& description) {
    return app_
        ->add_option_function<std::string>(
            name, [&args = args_, name](const std::string& value) { args.options[name] = value; }, description)
        ->type_name(value_name);
  }
  CLI::Option* integer(const std::string& name, const std::string& value_name, const std::string& description,
                       long long min, long long max) {
    return text(name, value_name, description)->check(integer_in(min, max));
  }
  CLI::Option* number(const std::string& name, const std::string& value_name, const std::string& description,
                      double min, double max) {
    return text(name, value_name, description)->check(number_in(min, max));
  }
  CLI::Option* choice(const std::string& name, const std::vector<std::string>& choices,
                      const std::string& description) {
    std::string names;
    for (const auto& c : choices) names += (names.empty() ? "" : "|") + c;
    return text(name, names, description)->check(CLI::IsMember(choices));
  }
  CLI::Option* flag(const std::string& name, const std::string& description) {
    return app_->add_flag_callback(name, [&args = args_, name] { args.flags.push_back(name); }, description);
  }
  /// Positional arguments, `min` to `max` of them, in order.
  CLI::Option* positional(const std::string& name, const std::string& description, int min, int max) {
    auto* o = app_->add_option_function<std::vector<std::string>>(
        name, [&args = args_](const std::vector<std::string>& values) { args.positional = values; }, description);
    o->expected(min, max);
    if (min > 0) o->required();
    return o;
  }

  /// Where a remote command finds its participants.
  void dds_options() {
    auto* group = app_->add_option_group("DDS", "where the pipelines are (default: LODE_DDS_* environment)");
    Declare g(group, args_);
    g.integer("--domain", "N", "DDS domain id", 0, 232);
    g.choice("--transport", {"loopback", "shm", "udp_loopback", "network"}, "DDS transport");
    g.text("--peers", "A,B", "unicast discovery peers (host or host:port)");
    g.text("--interfaces", "A,B", "network interfaces to use");
    g.text("--name", "NAME", "this participant's name (what allow_participants matches)");
  }
  /// set, swap and record --remote-*: the local socket of a pipeline on this host, else DDS.
  void command_route_options() {
    flag("--local", "only the local socket of a pipeline running on this host");
    flag("--dds", "only DDS (even when the pipeline runs on this host)");
    text("--pipeline", "NAME", "the pipeline to command when several run");
    number("--timeout", "S", "how long to wait for the reply (default 5)", 0.01, 600);
    number("--wait", "S", "how long to wait for the pipeline to appear (default 3)", 0, 3600);
  }

 private:
  CLI::App* app_;
  Args& args_;
};

struct Tree {
  CLI::App app{"lode: run, check and inspect lodestone pipelines", "lode"};
  std::vector<std::pair<std::string, CLI::App*>> commands;
};

std::unique_ptr<Tree> build_tree(Args& args) {
  auto tree = std::make_unique<Tree>();
  CLI::App& app = tree->app;
  app.footer(kFooter);
  app.require_subcommand(0, 1);
  app.add_flag("--bash-completion")->description("print a bash completion script")->group("");
  app.set_version_flag("--version",
                       std::string("lode ") + LODE_VERSION + ", plugin ABI " + std::to_string(kPluginAbiVersion));
  const auto command = [&](const std::string& name, const std::string& description) {
    CLI::App* sub = app.add_subcommand(name, description);
    sub->footer(kFooter);
    tree->commands.emplace_back(name, sub);
    return Declare(sub, args);
  };

  {
    auto d = command("run", "run a pipeline: live status line and a summary at the end; publishes the "
                            "YAML's telemetry: topics over Fast DDS; serves set/swap/record commands on "
                            "the local socket $XDG_RUNTIME_DIR/lode/PIPELINE.sock");
    d.positional("CONFIG", "the pipeline file", 1, 1);
    d.number("--duration", "S", "how long to run (default: the pipeline's duration_s, else until Ctrl-C)", 0, 1e9);
    d.choice("--clock", {"sim", "real"}, "the clock (default: the pipeline's realtime.clock, else sim)");
    d.text("--summary-json", "FILE", "write the summary as JSON");
    d.flag("--quiet", "no status line");
    d.text("--record", "FILE.h5", "record every output at full rate (HDF5)");
    d.integer("--domain", "N", "DDS domain of the telemetry (overrides LODE_DDS_DOMAIN, which overrides telemetry.domain)", 0, 232);
    d.flag("--no-telemetry", "do not publish over DDS");
    d.integer("--wait-subscribers", "N", "wait for N subscribers before starting", 0, 1000);
    d.number("--wait", "S", "how long --wait-subscribers waits (default 10)", 0, 3600);
    d.number("--speed", "X", "simulated clock: at most X times real time", 1e-6, 1e9);
    d.flag("--no-local-control", "do not serve commands on the local socket");
  }
  command("check", "validate a pipeline; every problem with file:line:column")
      .positional("CONFIG", "the pipeline file", 1, 1);
  command("describe", "the resolved pipeline as JSON, with every derived quantity")
      .positional("CONFIG", "the pipeline file", 1, 1);
  {
    auto d = command("plugins", "installed plugins with their parameters and ports");
    d.positional("NAME", "show this plugin only (e.g. filter.biquad)", 0, 1);
    d.flag("--json", "as JSON");
  }
  {
    auto d = command("replay", "run a recording's raw inputs (lode run --record) through the recorded "
                               "configuration (checked bit for bit) and other estimator sets at full speed; "
                               "writes OUT.h5 per configuration and a comparison report");
    d.positional("RECORDING", "a recording written by lode run --record", 1, 1);
    CLI::App* sub = tree->commands.back().second;
    sub->add_option_function<std::vector<std::string>>(
           "--config", [&args](const std::vector<std::string>& v) { args.lists["--config"] = v; },
           "another pipeline to replay the inputs through (repeatable)")
        ->type_name("OTHER.yaml")
        ->take_all()
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    sub->add_option_function<std::vector<std::string>>(
           "--estimate", [&args](const std::vector<std::string>& v) { args.lists["--estimate"] = v; },
           "another output to compare (repeatable)")
        ->type_name("BLOCK.PORT")
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    d.text("--output", "OUT.h5", "where the replayed outputs go (one file per configuration)");
    d.text("--report", "R.md|R.json", "write the comparison report");
    d.text("--reference", "BLOCK.PORT", "what the estimators are compared against (default monitor.truth)");
    d.flag("--quiet", "no progress");
  }
  {
    auto d = command("bench", "per-block and whole-cycle step cost (simulated clock)");
    d.positional("CONFIG", "the pipeline file", 1, 1);
    d.integer("--cycles", "N", "how many cycles (default 20000)", 1, 1000000000);
  }
  command("rtcheck", "how fit this host is for real-time runs, with advice");
  {
    auto d = command("topics", "the live lodestone topics with rates, element names and units");
    d.flag("--json", "as JSON");
    d.number("--wait", "S", "how long to listen (default 2)", 0, 3600);
    d.dds_options();
  }
  {
    auto d = command("echo", "live samples: one line per sample (cycle, time, values) or a table");
    d.positional("TOPIC", "a topic, BLOCK.PORT, state, events or timing", 1, 1);
    d.integer("--count", "N", "stop after N samples", 1, 1000000000000LL);
    d.number("--duration", "S", "stop after S seconds", 0, 1e9);
    d.flag("--table", "a table that updates in place");
    d.flag("--latency", "print the delivery latency of each sample");
    d.flag("--quiet", "no header line");
    d.text("--pipeline", "NAME", "the pipeline whose topic (or events, timing) to show when several run");
    d.number("--wait", "S", "how long to wait for the topic (default 3)", 0, 3600);
    d.dds_options();
  }
  {
    auto d = command("record", "record live topics and events to HDF5 (stops on Ctrl-C, --duration, or when "
                               "the pipelines stop); or ask a running pipeline to record on its own host");
    d.positional("FILE", "the HDF5 file to write", 0, 1);
    d.text("--topics", "A,B", "only these topics");
    d.number("--duration", "S", "stop after S seconds", 0, 1e9);
    d.text("--remote-start", "FILE", "ask the running pipeline to record every output into FILE on its host");
    d.flag("--remote-stop", "ask the running pipeline to stop recording");
    d.flag("--quiet", "no progress");
    d.command_route_options();
    d.dds_options();
  }
  {
    auto d = command("set", "change (or read) a runtime parameter of a running pipeline; the reply says "
                            "what happened");
    d.positional("TARGET", "[PIPELINE/]BLOCK.PARAM [VALUE], or with --list an optional BLOCK", 0, 2);
    d.flag("--list", "list the runtime parameters (of BLOCK)");
    d.command_route_options();
    d.dds_options();
  }
  {
    auto d = command("swap", "hot-swap an estimator of a running pipeline (state handed over at a cycle "
                             "boundary) or promote a shadow");
    d.positional("ARGS", "[PIPELINE/]BLOCK PLUGIN: the block and the plugin to swap in", 0, 2);
    d.text("--params", "'{k: v}'", "the new block's parameters (YAML flow map)");
    d.integer("--shadow-cycles", "N", "run the newcomer as a shadow for N cycles first", 0, 1000000000);
    d.flag("--cold", "no state handover");
    d.text("--promote", "SHADOW", "promote a shadow to the running estimator");
    d.command_route_options();
    d.dds_options();
  }
  return tree;
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::vector<std::string> long_names(const CLI::App* app) {
  std::vector<std::string> names;
  for (const CLI::Option* o : app->get_options()) {
    for (const auto& n : o->get_lnames()) names.push_back("--" + n);
  }
  for (const CLI::App* group : app->get_subcommands([](const CLI::App* s) { return s->get_name().empty(); })) {
    for (const auto& n : long_names(group)) names.push_back(n);
  }
  return names;
}

std::string nearest_in(const std::vector<std::string>& known, const std::string& unknown) {
  const std::string bare = unknown.substr(0, unknown.find('='));
  std::string best;
  std::size_t best_distance = std::max<std::size_t>(2, bare.size() / 3) + 1;
  for (const auto& name : known) {
    const std::size_t d = edit_distance(bare, name);
    if (d < best_distance) {
      best_distance = d;
      best = name;
    }
  }
  return best;
}

}  // namespace

std::string bash_completion() {
  Args ignored;
  const auto tree = build_tree(ignored);
  std::string commands;
  for (const auto& [name, app] : tree->commands) commands += (commands.empty() ? "" : " ") + name;
  std::string out =
      "# bash completion for lode, generated by `lode --bash-completion` from its own option\n"
      "# declarations.\n"
      "_lode() {\n"
      "  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]} cmd=${COMP_WORDS[1]}\n"
      "  if [ \"$COMP_CWORD\" -eq 1 ]; then\n"
      "    COMPREPLY=($(compgen -W \"" + commands + " --help --version\" -- \"$cur\")); return\n"
      "  fi\n"
      "  case \"$cmd\" in\n";
  for (const auto& [name, app] : tree->commands) {
    std::string options, choices, files;
    const auto visit = [&](const CLI::App* a) {
      for (const CLI::Option* o : a->get_options()) {
        for (const auto& n : o->get_lnames()) {
          options += " --" + n;
          // A choice's value name is its choices, "sim|real" (CLI11 appends ":{sim,real}").
          const std::string type = o->get_type_name().substr(0, o->get_type_name().find(':'));
          if (type.find('|') != std::string::npos && type.find('.') == std::string::npos) {
            std::string words = type;
            std::replace(words.begin(), words.end(), '|', ' ');
            choices += "      --" + n + ") COMPREPLY=($(compgen -W \"" + words + "\" -- \"$cur\")); return;;\n";
          }
        }
        if (o->get_positional()) {
          const std::string p = o->get_name();
          if (p == "CONFIG") files = "*.yaml";
          if (p == "RECORDING") files = "*.h5";
        }
      }
    };
    visit(app);
    for (const CLI::App* group : app->get_subcommands([](const CLI::App* g) { return g->get_name().empty(); }))
      visit(group);
    out += "    " + name + ")\n      case \"$prev\" in\n" + choices +
           "      --config) COMPREPLY=($(compgen -f -X '!*.yaml' -- \"$cur\")); return;;\n"
           "      esac\n"
           "      if [[ \"$cur\" == -* ]]; then COMPREPLY=($(compgen -W \"" +
           options + "\" -- \"$cur\")); return; fi\n";
    if (!files.empty())
      out += "      COMPREPLY=($(compgen -f -X '!" + files + "' -- \"$cur\") $(compgen -d -- \"$cur\"))\n";
    out += "      ;;\n";
  }
  out += "  esac\n}\ncomplete -o filenames -F _lode lode\n";
  return out;
}

int run_command_line(int argc, char** argv, const std::vector<CommandEntry>& commands) {
  Args args;
  const auto tree = build_tree(args);
  CLI::App& app = tree->app;
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e, std::cout, std::cerr);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e, std::cout, std::cerr);
  } catch (const CLI::CallForVersion& e) {
    std::printf("%s\nplugin search path:", app.version().c_str());
    for (const auto& dir : PluginRegistry::default_search_path()) std::printf(" %s", dir.c_str());
    std::printf("\n");
    return kExitOk;
  } catch (const CLI::ParseError& e) {
    // Which command was meant: the first argument that names one.
    std::string command;
    for (int i = 1; i < argc && command.empty(); ++i)
      for (const auto& [name, sub] : tree->commands)
        if (name == argv[i]) command = name;
    std::string message = e.what();
    std::string hint;
    // An option the command does not know explains the rest (a misspelt --duraton 1 also
    // leaves a stray positional "1"): name it first, with the nearest known option.
    std::vector<std::string> known;
    for (const auto& [name, sub] : tree->commands)
      if (name == command) known = long_names(sub);
    if (command.empty()) known = long_names(&app);
    known.push_back("--help");
    for (int i = 1; i < argc; ++i) {
      const std::string token = argv[i];
      if (token == "--") break;
      if (token.rfind("--", 0) != 0) continue;
      const std::string bare = token.substr(0, token.find('='));
      if (std::find(known.begin(), known.end(), bare) != known.end()) continue;
      message = "unknown option '" + bare + "'";
      const std::string near = nearest_in(known, bare);
      if (!near.empty()) hint = " (did you mean " + near + "?)";
      break;
    }
    std::fprintf(stderr, "lode%s%s: %s%s\nsee: lode %s%s--help\n", command.empty() ? "" : " ", command.c_str(),
                 message.c_str(), hint.c_str(), command.c_str(), command.empty() ? "" : " ");
    return kExitConfig;
  }
  if (app.count("--bash-completion") > 0) {
    std::fputs(bash_completion().c_str(), stdout);
    return kExitOk;
  }
  for (const auto& [name, sub] : tree->commands) {
    if (!sub->parsed()) continue;
    args.command = name;
    for (const auto& entry : commands)
      if (entry.name == name) return entry.run(args);
    std::fprintf(stderr, "lode: command '%s' is declared but has no implementation\n", name.c_str());
    return kExitFault;
  }
  // No command: the overview, on stderr (a usage error).
  std::cerr << app.help();
  return kExitConfig;
}

}  // namespace lode::cli
