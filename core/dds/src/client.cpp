// The client side's lifetime: its participant (with a publisher for commands and a
// subscriber for everything else), the `lode/signals` reader it keeps from the start, and
// the order of teardown. What it does with them is in client_discovery.cpp,
// client_subscriptions.cpp and client_commands.cpp (client_impl.hpp has the class).
#include <unistd.h>

#include "client_impl.hpp"

namespace lode::dds {

namespace client_detail {

ClientImpl::ClientImpl(std::string name) : name_(std::move(name)) {
  // Wire ids unique across runs: a reply left in a transient-local history by an earlier
  // client with the same name can never be taken for ours.
  next_id_ = (static_cast<std::uint64_t>(Clock::now().time_since_epoch().count()) << 16) ^
             static_cast<std::uint64_t>(getpid());
}

ClientImpl::~ClientImpl() {
  {
    std::lock_guard lock(replies_mutex_);
    closing_ = true;
  }
  if (info_gate_) {
    std::lock_guard lock(info_gate_->mutex);
    info_gate_->closed = true;
  }
  if (replies_gate_) {  // every command channel's reply listener
    std::lock_guard lock(replies_gate_->mutex);
    replies_gate_->closed = true;
  }
  delete_participant(participant_);
}

Status ClientImpl::open(const ParticipantOptions& options) {
  transport_ = options.transport.kind;
  auto created = create_participant(options, &participants_);
  if (!created) return created.status();
  participant_ = *created;
  if (Status s = detail::register_types(participant_); !s) return s;
  publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (publisher_ == nullptr || subscriber_ == nullptr) {
    return Status::error("dds client: could not create the DDS publisher/subscriber");
  }
  fdds::Topic* topic = find_or_create_topic(detail::kSignalsTopic, detail::type_name_signal_info());
  if (topic == nullptr) return Status::error("dds client: could not create topic lode/signals");
  info_gate_ = std::make_shared<Gate>();
  info_listener_ = std::make_unique<InfoListener>(
      info_gate_, [this](fdds::DataReader* r) { take_info(r); },
      [this](const fdds::InstanceHandle_t& writer) { forget_writer(writer); });
  info_reader_ = subscriber_->create_datareader(
      topic, detail::reader_qos(Durability::transient_local, 1, detail::kSignalInfoInstances),
      info_listener_.get(), fdds::StatusMask::data_available() << fdds::StatusMask::subscription_matched());
  if (info_reader_ == nullptr) return Status::error("dds client: could not create the reader of lode/signals");
  replies_gate_ = std::make_shared<Gate>();
  return Status::ok();
}

std::uint64_t ClientImpl::malformed_samples() const { return detail::malformed_samples(participant_); }

fdds::Topic* ClientImpl::find_or_create_topic(const std::string& name, const char* type) {
  std::lock_guard lock(topics_mutex_);
  if (auto* existing = participant_->lookup_topicdescription(name)) {
    return dynamic_cast<fdds::Topic*>(existing);
  }
  return participant_->create_topic(name, type, fdds::TOPIC_QOS_DEFAULT);
}

}  // namespace client_detail

Expected<std::unique_ptr<Client>> Client::create(const ParticipantOptions& options) {
  ParticipantOptions named = options;
  if (named.name.empty()) named.name = options_from_environment("").name;
  named.client = true;
  auto client = std::make_unique<client_detail::ClientImpl>(named.name);
  if (Status s = client->open(named); !s) return s;
  return std::unique_ptr<Client>(std::move(client));
}

}  // namespace lode::dds
