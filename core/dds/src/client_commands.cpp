// Commands: each pipeline gets one command writer and one transient-local reply reader for
// the client's lifetime. Ids on the wire are unique per client (time-seeded), so a reply
// left in a reply writer's history by an earlier client of the same name never matches;
// the reply handed back carries the caller's request.id.
#include <algorithm>

#include "client_impl.hpp"
#include "command_request.hpp"

namespace lode::dds::client_detail {

Expected<ControlReply> ClientImpl::command(const std::string& pipeline, ControlRequest request,
                                           std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  const std::string no_reply = "no reply within " + std::to_string(timeout.count()) +
                               " ms: is the pipeline running with telemetry.commands.enabled?";
  auto channel = command_channel(pipeline);
  if (!channel) return channel.status();
  // Wait until the pipeline's command reader and reply writer are matched: a command
  // written before that would reach nobody (volatile).
  const auto matched = [&] {
    fdds::PublicationMatchedStatus pub;
    fdds::SubscriptionMatchedStatus sub;
    return (*channel)->writer->get_publication_matched_status(pub) == ReturnCode_t::RETCODE_OK &&
           (*channel)->reader->get_subscription_matched_status(sub) == ReturnCode_t::RETCODE_OK &&
           pub.current_count > 0 && sub.current_count > 0;
  };
  while (!matched()) {
    if (Clock::now() >= deadline) {
      return Status::error(no_reply + " (no command reader on " + pipeline_topic(pipeline, "command") +
                           " was found)");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }

  std::uint64_t wire_id = 0;
  {
    std::lock_guard lock(replies_mutex_);
    wire_id = ++next_id_;
  }
  lode::msg::Command c = detail::command_message(request, name_, wire_id);
  if (!(*channel)->writer->write(&c)) {
    return Status::error("could not send the command to " + pipeline_topic(pipeline, "command"));
  }
  std::unique_lock lock(replies_mutex_);
  while (true) {
    auto it = std::find_if(replies_.begin(), replies_.end(),
                           [&](const lode::msg::Reply& r) { return r.id() == wire_id; });
    if (it != replies_.end()) {
      ControlReply reply;
      reply.id = request.id;
      reply.ok = it->ok();
      reply.message = it->message();
      reply.value = it->value();
      replies_.erase(it);
      return reply;
    }
    if (replies_changed_.wait_until(lock, deadline) == std::cv_status::timeout) {
      const bool arrived = std::any_of(replies_.begin(), replies_.end(),
                                       [&](const lode::msg::Reply& r) { return r.id() == wire_id; });
      if (!arrived) return Status::error(no_reply);
    }
  }
}

Expected<CommandChannel*> ClientImpl::command_channel(const std::string& pipeline) {
  std::lock_guard lock(commands_mutex_);
  if (auto it = commands_.find(pipeline); it != commands_.end()) return &it->second;
  const std::string command_name = pipeline_topic(pipeline, "command");
  const std::string reply_name = pipeline_topic(pipeline, "reply");
  fdds::Topic* command_topic = find_or_create_topic(command_name, detail::type_name_command());
  fdds::Topic* reply_topic = find_or_create_topic(reply_name, detail::type_name_reply());
  if (command_topic == nullptr || reply_topic == nullptr) {
    return Status::error("dds client: could not create topics " + command_name + " / " + reply_name);
  }
  CommandChannel channel;
  channel.listener = std::make_unique<TakeListener>(replies_gate_, [this](fdds::DataReader* r, Gate&) {
    lode::msg::Reply reply;
    fdds::SampleInfo info;
    while (r->take_next_sample(&reply, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data || reply.client() != name_) continue;
      std::lock_guard replies_lock(replies_mutex_);
      if (closing_) return;
      replies_.push_back(reply);
      if (replies_.size() > 256) replies_.pop_front();  // never collected: its command timed out
      replies_changed_.notify_all();
    }
  });
  channel.reader = subscriber_->create_datareader(
      reply_topic, detail::reader_qos(Durability::transient_local, detail::kReplyDepth),
      channel.listener.get(), fdds::StatusMask::data_available());
  channel.writer = publisher_->create_datawriter(
      command_topic, detail::keep_all_commands(detail::writer_qos(Durability::volatile_, 1), 2.0));
  if (channel.reader == nullptr || channel.writer == nullptr) {
    return Status::error("dds client: could not create the command writer / reply reader of '" + pipeline +
                         "'");
  }
  return &commands_.emplace(pipeline, std::move(channel)).first->second;
}

}  // namespace lode::dds::client_detail
