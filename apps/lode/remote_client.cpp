#include "remote_client.hpp"

#include <unistd.h>

#include <cmath>
#include <functional>
#include <cstdio>
#include <sstream>
#include <thread>

#include "analysis.hpp"
#include "local_control.hpp"

namespace lode::cli {

namespace {

using Clock = std::chrono::steady_clock;

/// Participant options: environment first, then the command line.
dds::ParticipantOptions participant_options(const Args& args, const std::string& role) {
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  auto o = dds::options_from_environment("lode-" + role + "-" + std::to_string(getpid()) + "@" + host);
  if (args.has("--name")) o.name = args.option("--name");
  if (args.has("--domain")) o.domain = static_cast<int>(args.integer("--domain", 0));
  // The parser accepted only the names transport_kind_from knows.
  if (args.has("--transport")) o.transport.kind = *transport_kind_from(args.option("--transport"));
  if (args.has("--peers")) o.transport.initial_peers = split_list(args.option("--peers"));
  if (args.has("--interfaces")) o.transport.interfaces = split_list(args.option("--interfaces"));
  return o;
}

/// The pipeline a command goes to: --pipeline, "pipeline/..." in the target, or the only
/// one publishing. While none has been heard of, `came_up_locally` is asked every 100 ms: when
/// it says a pipeline is now reachable on this host, the search ends there (nullopt, nothing
/// printed). Otherwise it says why there is none and sets `refusal` to the exit code: 1 when
/// no pipeline is live (as `lode echo` and `lode topics` say it), 2 when several are and the
/// command names none (the user must choose).
std::optional<std::string> target_pipeline(const Args& args, dds::Client& client, std::string& target, int& refusal,
                                           const std::function<bool()>& came_up_locally) {
  if (args.has("--pipeline")) return args.option("--pipeline");
  const auto slash = target.find('/');
  if (slash != std::string::npos) {
    std::string p = target.substr(0, slash);
    target = target.substr(slash + 1);
    return p;
  }
  // Discovery is gradual: the first pipeline heard of is not the only one live until no other
  // has appeared for a while. Take the set once this client has listened for 2.5 s (every
  // lodestone participant announces itself each second, so each live pipeline has had two
  // chances to be heard) and the set has held still for 2 s (a loaded host can take over a
  // second to process an announcement). A command never goes to the one that answered first.
  const auto listening_since = Clock::now();
  const auto deadline = listening_since + wait_option(args, 3.0);
  auto pipelines = client.pipelines(milliseconds(0));
  while (pipelines.empty() && Clock::now() < deadline) {
    if (came_up_locally && came_up_locally()) return std::nullopt;
    std::this_thread::sleep_for(milliseconds(100));
    pipelines = client.pipelines(milliseconds(0));
  }
  for (auto settled = Clock::now();
       !pipelines.empty() && (Clock::now() - settled < std::chrono::seconds(2) ||
                              Clock::now() - listening_since < std::chrono::milliseconds(2500));) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto now_live = client.pipelines(std::chrono::milliseconds(0));
    if (now_live != pipelines) {
      pipelines = std::move(now_live);
      settled = Clock::now();
    }
  }
  if (pipelines.size() == 1) return pipelines[0];
  if (pipelines.empty() && came_up_locally && came_up_locally()) return std::nullopt;  // one last look
  if (pipelines.empty()) {
    std::fprintf(stderr, "lode: no pipeline is publishing on this domain (give --pipeline NAME, check --domain/--transport)\n");
    refusal = kExitFault;
  } else {
    refusal = kExitConfig;
    std::fprintf(stderr, "lode: several pipelines are live; give --pipeline NAME (or NAME/BLOCK...):");
    for (const auto& p : pipelines) std::fprintf(stderr, " %s", p.c_str());
    std::fprintf(stderr, "\n");
  }
  return std::nullopt;
}

/// The same text whichever way the reply came (local socket or DDS).
int print_reply(const ControlRequest& request, const ControlReply& reply) {
  if (!reply.value.empty() && request.kind == "list") std::printf("%s", reply.value.c_str());
  std::printf("%s: %s\n", reply.ok ? "ok" : "error", reply.message.c_str());
  return reply.ok ? kExitOk : kExitFault;
}

milliseconds reply_timeout(const Args& args) {
  return milliseconds(std::llround(args.number("--timeout", 5.0) * 1e3));
}

std::uint64_t new_request_id() { return static_cast<std::uint64_t>(Clock::now().time_since_epoch().count()); }

/// How much longer than --timeout a reply may take: the shadow period of a swap, at the rate
/// `ask` (a status request over the command's own route) reports; 10 ms a cycle if it says
/// none (a pipeline of an older version).
milliseconds shadow_allowance(std::uint64_t shadow_cycles,
                              const std::function<Expected<ControlReply>(const ControlRequest&)>& ask) {
  if (shadow_cycles == 0) return milliseconds(0);
  ControlRequest status;
  status.kind = "status";
  status.id = new_request_id();
  double rate_hz = 0.0;
  if (auto reply = ask(status); reply && reply->ok) rate_hz = std::strtod(reply->value.c_str(), nullptr);
  const double seconds = static_cast<double>(shadow_cycles) / (rate_hz > 0.0 ? rate_hz : 100.0);
  return milliseconds(std::llround(seconds * 1e3)) + milliseconds(1000);
}

int send(const Args& args, dds::Client& client, const std::string& pipeline, ControlRequest request,
         std::uint64_t shadow_cycles) {
  const milliseconds allowance = shadow_allowance(shadow_cycles, [&](const ControlRequest& status) {
    return client.command(pipeline, status, reply_timeout(args));
  });
  request.id = new_request_id();
  auto reply = client.command(pipeline, request, reply_timeout(args) + allowance);
  if (!reply) {
    std::fprintf(stderr, "lode: %s\n", reply.error().c_str());
    return kExitFault;
  }
  return print_reply(request, *reply);
}

/// The local command socket of `pipeline` (or of the one pipeline on this host when none is
/// named), polled until `wait` has passed. nullopt when there is none; `refusal` is set (and
/// the reason printed) when the command must not go on: several pipelines and none named, or
/// --local (`force_local`) and none came up.
std::optional<std::string> find_local_socket(const std::optional<std::string>& pipeline, bool force_local,
                                             milliseconds wait, int& refusal) {
  const auto deadline = Clock::now() + wait;
  for (;;) {
    if (pipeline) {
      const std::string path = local_control_socket(*pipeline);
      if (probe_local_socket(path)) return path;
    } else {
      const auto live = live_local_pipelines();
      if (live.size() == 1) return live[0].path;
      if (live.size() > 1) {
        std::fprintf(stderr, "lode: several pipelines run on this host; give --pipeline NAME (or NAME/...), or --dds for a remote one:");
        for (const auto& p : live) std::fprintf(stderr, " %s (pid %d)", p.pipeline.c_str(), static_cast<int>(p.pid));
        std::fprintf(stderr, "\n");
        refusal = kExitConfig;  // refuse to guess
        return std::nullopt;
      }
    }
    if (Clock::now() >= deadline) break;
    std::this_thread::sleep_for(milliseconds(100));
  }
  if (!force_local) return std::nullopt;
  // --local: even a dead or missing socket, so the error says what is wrong with it.
  if (pipeline) return local_control_socket(*pipeline);
  std::fprintf(stderr, "lode: no pipeline runs on this host with a local command socket (looked in %s)\n",
               local_control_dir().c_str());
  refusal = kExitFault;
  return std::nullopt;
}

int send_local(const std::string& role, const std::string& socket, ControlRequest request, const Args& args,
               std::uint64_t shadow_cycles) {
  const milliseconds allowance = shadow_allowance(shadow_cycles, [&](const ControlRequest& status) {
    return local_send(socket, status, reply_timeout(args));
  });
  request.id = new_request_id();
  if (request.kind == "record_start" && !request.name.empty() && request.name[0] != '/') {
    // Same host: a relative file means relative to the caller, not to the runner's cwd.
    char cwd[4096];
    if (getcwd(cwd, sizeof cwd)) request.name = std::string(cwd) + "/" + request.name;
  }
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  request.client = "lode-" + role + "-" + std::to_string(getpid()) + "@" + host;
  auto reply = local_send(socket, request, reply_timeout(args) + allowance);
  if (!reply) {
    std::fprintf(stderr, "lode: %s\n", reply.error().c_str());
    return kExitFault;
  }
  return print_reply(request, *reply);
}

}  // namespace

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::unique_ptr<dds::Client> make_client(const Args& args, const std::string& role) {
  auto client = dds::Client::create(participant_options(args, role));
  if (!client) {
    std::fprintf(stderr, "lode: %s\n", client.error().c_str());
    return nullptr;
  }
  return std::move(*client);
}

void report_malformed(const dds::Client& client, const char* command) {
  if (const std::uint64_t n = client.malformed_samples(); n > 0)
    std::fprintf(stderr, "lode %s: %llu malformed samples dropped (their bytes did not decode as lode_msgs.idl says: "
                 "a foreign or broken writer on the domain)\n", command, static_cast<unsigned long long>(n));
}

bool warn_namesakes(const dds::Client& client, const std::string& pipeline, const char* command) {
  const std::size_t live = client.namesakes(pipeline);
  if (live < 2) return false;
  std::fprintf(stderr,
               "lode %s: warning: %zu pipelines named '%s' are live on this domain (one configuration run on two "
               "rigs, or by two users): their samples arrive mixed on the same topics, and they refuse commands "
               "until one leaves\n",
               command, live, pipeline.c_str());
  return true;
}

milliseconds wait_option(const Args& args, double fallback_s) {
  return milliseconds(std::llround(args.number("--wait", fallback_s) * 1e3));
}

std::string unit_suffix(const std::string& unit) { return unit.empty() || unit == "1" ? "" : "[" + unit + "]"; }

std::string format_scaled(double v, const std::string& unit) {
  auto [scale, shown] = analysis::display_scale(unit, v);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%+12.4f %-6s", v * scale, shown.c_str());
  return buf;
}

int send_command(const Args& args, const std::string& role, std::string target,
                 const std::function<std::optional<ControlRequest>(const std::string&)>& make,
                 std::uint64_t shadow_cycles) {
  const bool force_local = args.has_flag("--local");
  const bool force_dds = args.has_flag("--dds");
  if (force_local && force_dds) {
    std::fprintf(stderr, "lode: --local and --dds exclude each other\n");
    return kExitConfig;
  }
  std::optional<std::string> pipeline;
  if (args.has("--pipeline")) {
    pipeline = args.option("--pipeline");
  } else if (const auto slash = target.find('/'); slash != std::string::npos) {
    pipeline = target.substr(0, slash);
    target = target.substr(slash + 1);
  }
  if (pipeline && pipeline->empty()) {
    std::fprintf(stderr, "lode: empty pipeline name\n");
    return kExitConfig;
  }
  auto request = make(target);
  if (!request) return kExitConfig;

  // The local socket first. --local waits up to --wait for one to come up (the pipeline may
  // still be loading); otherwise one look now, and one more if DDS finds no pipeline either.
  int refusal = 0;
  std::optional<std::string> socket;  // set: go local
  if (!force_dds) {
    const auto wait = force_local ? wait_option(args, 3.0) : milliseconds(0);
    socket = find_local_socket(pipeline, force_local, wait, refusal);
    if (refusal != 0) return refusal;
  }
  if (socket) return send_local(role, *socket, *request, args, shadow_cycles);
  auto client = make_client(args, role);
  if (!client) return kExitConfig;
  // Until one is heard of on DDS, a pipeline that comes up on this host meanwhile (one just
  // started, without telemetry) is commanded through its socket.
  std::optional<std::string> late;
  const auto came_up_locally = [&] {
    if (force_dds) return false;
    late = find_local_socket(pipeline, false, milliseconds(0), refusal);
    return late.has_value() || refusal != 0;
  };
  std::optional<std::string> target_name = pipeline;
  int not_found = kExitConfig;
  if (!target_name) target_name = target_pipeline(args, *client, target, not_found, came_up_locally);
  if (refusal != 0) return refusal;
  if (late) {
    client.reset();
    return send_local(role, *late, *request, args, shadow_cycles);
  }
  // None live, or several and none named: a command must never go to a guessed pipeline.
  if (!target_name) return not_found;
  return send(args, *client, *target_name, *request, shadow_cycles);
}

}  // namespace lode::cli
