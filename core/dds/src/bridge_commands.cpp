// The telemetry bridge's command side: "lode-commands" takes commands in arrival order,
// checks the sender against telemetry.commands (participant name, host address), hands the
// allowed ones to the ControlService and writes the reply.
#include "bridge_impl.hpp"

namespace lode::dds::bridge_detail {

void Bridge::command_loop() {
  std::unique_lock wake_lock(wake_mutex_);
  while (true) {
    wake_.wait_for(wake_lock, std::chrono::milliseconds(100),
                   [this] { return stopped_ || commands_pending_; });
    if (stopped_) return;
    commands_pending_ = false;
    wake_lock.unlock();
    lode::msg::Command command;
    fdds::SampleInfo info;
    while (command_reader_->take_next_sample(&command, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) handle_command(command, info);
    }
    note_malformed_commands();
    wake_lock.lock();
  }
}

// Fast DDS drops a Command that does not decode before take() sees it; its type support
// counted it. A flood of them is summed into one event per look (at most 10 a second) and
// further limited by post_limited, so it cannot grow the event log without bound.
void Bridge::note_malformed_commands() {
  const std::uint64_t total = detail::malformed_samples(participant_, detail::type_name_command());
  const std::uint64_t before = commands_malformed_.exchange(total, std::memory_order_relaxed);
  if (total <= before) return;
  events_.post_limited(run_stats_.last_time_ns.load(std::memory_order_relaxed),
                       run_stats_.cycles.load(std::memory_order_relaxed), "command_malformed",
                       std::to_string(total - before) + " malformed command sample(s) dropped (" +
                           std::to_string(total) + " since start): the bytes on " +
                           pipeline_topic(pipeline_.name(), "command") +
                           " did not decode as lode::msg::Command (lode_msgs.idl, plain CDR)");
}

void Bridge::handle_command(const lode::msg::Command& command, const fdds::SampleInfo& info) {
  rtps::GuidPrefix_t sender = info.sample_identity.writer_guid().guidPrefix;
  if (sender == rtps::GuidPrefix_t::unknown()) sender = rtps::iHandle2GUID(info.publication_handle).guidPrefix;

  {
    // Another pipeline of this name would take the same command: neither may.
    std::unique_lock lock(peers_mutex_);
    if (namesakes_ > 0) {
      const std::string message = "refused: " + namesake_live() + " (" + namesake_text_ +
                                  ") and would take this command too; give one of them another `pipeline:` "
                                  "name or `telemetry.domain`";
      lock.unlock();
      refuse(command, message);
      return;
    }
  }
  const CommandAccess& access = spec_.commands;
  const bool open_to_all = access.allow_participants.empty() && access.allow_hosts.empty();
  // Discovery announces a participant before its endpoints match; the short wait only
  // covers the listener thread not having run yet.
  Peer peer;
  bool known = false;
  if (!open_to_all) {
    std::unique_lock lock(peers_mutex_);
    known = peers_changed_.wait_for(lock, std::chrono::milliseconds(500),
                                    [&] { return peers_.count(sender) > 0; });
    if (known) peer = peers_.at(sender);
  }
  const bool name_ok = access.allow_participants.empty() ||
                       (known && contains(access.allow_participants, peer.name));
  bool host_ok = access.allow_hosts.empty();
  for (const auto& host : peer.hosts) host_ok = host_ok || contains(access.allow_hosts, host);
  // A shared-memory peer is on this host: it is "127.0.0.1".
  host_ok = host_ok || (peer.shared_memory && contains(access.allow_hosts, "127.0.0.1"));

  if (!open_to_all && !(known && name_ok && host_ok)) {
    std::string fields;
    if (!name_ok) fields = "telemetry.commands.allow_participants";
    if (!host_ok) fields += std::string(fields.empty() ? "" : " and ") + "telemetry.commands.allow_hosts";
    refuse(command, known ? "refused: participant '" + peer.name + "' from hosts [" + peer.where() +
                                "] is not allowed to command this pipeline (see " + fields + ")"
                          : "refused: the sender (calling itself '" + command.client() +
                                "') was not discovered as a participant, so telemetry.commands.allow_* "
                                "cannot be checked");
    return;
  }

  // The discovered identity when access is checked, else what the sender declares.
  const ControlRequest request = detail::command_request(command, known ? peer.name : command.client());
  commands_accepted_.fetch_add(1, std::memory_order_relaxed);
  // A swap lasts as long as its shadow period (minutes): ControlService runs it on a worker,
  // so this thread goes on taking commands (a second swap meanwhile is refused by the hot-swap
  // service). stop() joins the workers before the writer goes away.
  control_->handle_async(request, [this, command](ControlReply reply) {
    reply.id = command.id();
    write_reply(command, reply);
  });
}

void Bridge::refuse(const lode::msg::Command& command, const std::string& message) {
  ControlReply reply;
  reply.id = command.id();
  reply.ok = false;
  reply.message = message;
  commands_refused_.fetch_add(1, std::memory_order_relaxed);
  events_.post_limited(run_stats_.last_time_ns.load(std::memory_order_relaxed),
                       run_stats_.cycles.load(std::memory_order_relaxed), "command_refused",
                       command.kind() + " " + command.block() + (command.name().empty() ? "" : "." + command.name()) +
                           ": " + message);
  write_reply(command, reply);
}

void Bridge::write_reply(const lode::msg::Command& command, const ControlReply& reply) {
  lode::msg::Reply r;
  r.client(command.client());
  r.id(command.id());
  r.ok(reply.ok);
  r.message(reply.message);
  r.value(reply.value);
  reply_writer_->write(&r);
}

}  // namespace lode::dds::bridge_detail
