#include "command_line.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <iostream>
#include <memory>

#include "lode/sdk/plugin.hpp"
#include "lode/nearest_name.hpp"
#include "lode/plugin_loader.hpp"

namespace lode::cli {
namespace {

constexpr const char* kFooter =
    "exit codes: 0 success, 1 runtime fault, 2 invalid configuration or usage\n"
    "plugin search path: $LODE_PLUGIN_PATH, then the installed and the build tree's plugin folders beside the program (lode --version lists them)";

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

}  // namespace

CLI::Option* Declare::text(const std::string& name, const std::string& value_name, const std::string& description) {
  return app_
      ->add_option_function<std::string>(
          name, [&args = args_, name](const std::string& value) { args.options[name] = value; }, description)
      ->type_name(value_name);
}

CLI::Option* Declare::integer(const std::string& name, const std::string& value_name, const std::string& description,
                              long long min, long long max) {
  return text(name, value_name, description)->check(integer_in(min, max));
}

CLI::Option* Declare::number(const std::string& name, const std::string& value_name, const std::string& description,
                             double min, double max) {
  return text(name, value_name, description)->check(number_in(min, max));
}

CLI::Option* Declare::choice(const std::string& name, const std::vector<std::string>& choices,
                             const std::string& description) {
  std::string names;
  for (const auto& c : choices) names += (names.empty() ? "" : "|") + c;
  return text(name, names, description)->check(CLI::IsMember(choices));
}

CLI::Option* Declare::flag(const std::string& name, const std::string& description) {
  return app_->add_flag_callback(name, [&args = args_, name] { args.flags.push_back(name); }, description);
}

CLI::Option* Declare::list(const std::string& name, const std::string& value_name, const std::string& description) {
  return app_
      ->add_option_function<std::vector<std::string>>(
          name, [&args = args_, name](const std::vector<std::string>& v) { args.lists[name] = v; }, description)
      ->type_name(value_name)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

CLI::Option* Declare::positional(const std::string& name, const std::string& description, int min, int max) {
  auto* o = app_->add_option_function<std::vector<std::string>>(
      name,
      [&args = args_, name, max](const std::vector<std::string>& values) {
        if (values.size() > static_cast<std::size_t>(max))
          throw CLI::ValidationError(name, "at most " + std::to_string(max) + " are taken, " +
                                               std::to_string(values.size()) + " were given");
        args.positional = values;
      },
      description);
  // More than one: unbounded for the parser, so that the usage line reads "NAME ..." (a bounded
  // count prints as "NAME(1x)"); the callback enforces the bound.
  o->expected(min, max > 1 ? CLI::detail::expected_max_vector_size : max);
  if (min > 0) o->required();
  return o;
}

void Declare::dds_options() {
  auto* group = app_->add_option_group("DDS", "where the pipelines are (default: LODE_DDS_* environment)");
  Declare g(group, args_);
  g.integer("--domain", "N", "DDS domain id", 0, 232);
  g.choice("--transport", {"loopback", "shm", "udp_loopback", "network"}, "DDS transport");
  g.text("--peers", "A,B", "unicast discovery peers (host or host:port)");
  g.text("--interfaces", "A,B", "network interfaces to use");
  g.text("--name", "NAME", "this participant's name (what allow_participants matches)");
}

void Declare::command_route_options() {
  flag("--local", "only the local socket of a pipeline running on this host");
  flag("--dds", "only DDS (even when the pipeline runs on this host)");
  text("--pipeline", "NAME", "the pipeline to command when several run");
  number("--timeout", "S", "how long to wait for the reply (default 5)", 0.01, 600);
  number("--wait", "S", "how long to wait for the pipeline to appear (default 3)", 0, 3600);
}

namespace {

struct Tree {
  CLI::App app{"lode: run, check and inspect lodestone pipelines", "lode"};
  std::vector<std::pair<std::string, CLI::App*>> commands;
};

std::unique_ptr<Tree> build_tree(Args& args, const std::vector<Command>& commands) {
  auto tree = std::make_unique<Tree>();
  CLI::App& app = tree->app;
  app.footer(kFooter);
  app.require_subcommand(0, 1);
  app.add_flag("--bash-completion")->description("print a bash completion script")->group("");
  app.set_version_flag("--version",
                       std::string("lode ") + LODE_VERSION + ", plugin ABI " + std::to_string(kPluginAbiVersion));
  for (const auto& command : commands) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    sub->footer(kFooter);
    tree->commands.emplace_back(command.name, sub);
    Declare declare(sub, args);
    command.declare(declare);
  }
  return tree;
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
  return nearest_name(known, unknown.substr(0, unknown.find('=')));
}

}  // namespace

std::string bash_completion(const std::vector<Command>& commands) {
  Args ignored;
  const auto tree = build_tree(ignored, commands);
  std::string names;
  for (const auto& [name, app] : tree->commands) names += (names.empty() ? "" : " ") + name;
  std::string out =
      "# bash completion for lode, generated by `lode --bash-completion` from its own option\n"
      "# declarations.\n"
      "_lode() {\n"
      "  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]} cmd=${COMP_WORDS[1]}\n"
      "  if [ \"$COMP_CWORD\" -eq 1 ]; then\n"
      "    COMPREPLY=($(compgen -W \"" + names + " --help --version\" -- \"$cur\")); return\n"
      "  fi\n"
      "  case \"$cmd\" in\n";
  for (std::size_t c = 0; c < tree->commands.size(); ++c) {
    const auto& [name, app] = tree->commands[c];
    std::string options, choices, files;
    const auto visit = [&](const CLI::App* a) {
      for (const CLI::Option* o : a->get_options()) {
        for (const auto& n : o->get_lnames()) {
          if ((options + " ").find(" --" + n + " ") != std::string::npos) continue;  // --help of a group
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
    if (const std::string& words = commands[c].positional_words; !words.empty())
      out += "      local lode=${COMP_WORDS[0]} npos=0 w\n"
             "      for w in \"${COMP_WORDS[@]:2:COMP_CWORD-2}\"; do [[ $w == -* ]] || npos=$((npos + 1)); done\n"
             "      COMPREPLY=($(compgen -W \"$(" + words + ")\" -- \"$cur\"))\n";
    out += "      ;;\n";
  }
  out += "  esac\n}\ncomplete -o filenames -F _lode lode\n";
  return out;
}

int run_command_line(int argc, char** argv, const std::vector<Command>& commands) {
  Args args;
  const auto tree = build_tree(args, commands);
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
    // No command named, and the first word is not an option: a misspelt command (`lode runn
    // x.yaml` said "the following arguments were not expected: x.yaml runn").
    if (command.empty() && argc > 1 && argv[1][0] != '-' && hint.empty()) {
      std::vector<std::string> names;
      for (const auto& [name, sub] : tree->commands) names.push_back(name);
      message = std::string("unknown command '") + argv[1] + "'";
      const std::string near = nearest_in(names, argv[1]);
      if (!near.empty()) hint = " (did you mean " + near + "?)";
    }
    std::fprintf(stderr, "lode%s%s: %s%s\nsee: lode %s%s--help\n", command.empty() ? "" : " ", command.c_str(),
                 message.c_str(), hint.c_str(), command.c_str(), command.empty() ? "" : " ");
    return kExitConfig;
  }
  if (app.count("--bash-completion") > 0) {
    std::fputs(bash_completion(commands).c_str(), stdout);
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
