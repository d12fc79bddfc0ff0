// What the client knows is live: the metadata of every signal (transient-local
// `lode/signals`, forgotten when its writer leaves or disposes it), the pipelines whose
// bridges it has discovered, and resolving a user's name for a signal against them.
#include <fastdds/rtps/participant/ParticipantDiscoveryInfo.h>

#include <algorithm>

#include "client_impl.hpp"
#include "local_delivery.hpp"

namespace lode::dds::client_detail {

namespace {

SignalMeta meta_from(const lode::msg::SignalInfo& info) {
  SignalMeta m;
  m.topic = info.topic();
  m.pipeline = info.pipeline();
  m.block = info.block();
  m.port = info.port();
  m.kind = info.kind();
  m.names = info.names();
  m.units = info.units();
  m.rate_hz = info.rate_hz();
  m.pipeline_rate_hz = info.pipeline_rate_hz();
  m.decimation = info.decimation();
  m.pose_size = info.pose_size();
  m.twist_size = info.twist_size();
  m.covariance_size = info.covariance_size();
  m.reliable = info.reliable();
  return m;
}

std::string topic_list(const std::vector<SignalMeta>& metas) {
  std::string out;
  for (const auto& m : metas) out += (out.empty() ? "" : ", ") + m.topic;
  return out.empty() ? "none" : out;
}

}  // namespace

void PipelineParticipants::on_participant_discovery(fdds::DomainParticipant*,
                                                    eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) {
  using Info = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
  if (const auto pipeline = pipeline_of_participant(info.info.m_participantName.to_string())) {
    std::lock_guard lock(mutex_);
    if (info.status == Info::REMOVED_PARTICIPANT || info.status == Info::DROPPED_PARTICIPANT)
      live_.erase(info.info.m_guid.guidPrefix);
    else
      live_[info.info.m_guid.guidPrefix] = {*pipeline, detail::announced_uid(info.info)};
  }
  detail::hold_reply_to_new_participant(info);
}

std::set<std::string> PipelineParticipants::pipelines() const {
  std::lock_guard lock(mutex_);
  std::set<std::string> out;
  for (const auto& [prefix, bridge] : live_) out.insert(bridge.pipeline);
  return out;
}

std::size_t PipelineParticipants::count(const std::string& pipeline) const {
  std::lock_guard lock(mutex_);
  return static_cast<std::size_t>(
      std::count_if(live_.begin(), live_.end(), [&](const auto& entry) { return entry.second.pipeline == pipeline; }));
}

bool PipelineParticipants::shared_memory_reaches_us(const std::string& pipeline,
                                                   const eprosima::fastrtps::rtps::GuidPrefix_t& own) const {
  std::lock_guard lock(mutex_);
  bool any = false;
  for (const auto& [prefix, bridge] : live_) {
    if (bridge.pipeline != pipeline) continue;
    if (!detail::shared_memory_reaches_us(own, prefix, bridge.uid)) return false;
    any = true;
  }
  return any;
}

std::vector<SignalMeta> ClientImpl::signals(std::chrono::milliseconds wait) {
  std::unique_lock lock(signals_mutex_);
  signals_changed_.wait_for(lock, wait, [this] { return !signals_.empty(); });
  std::vector<SignalMeta> out;
  for (const auto& [topic, meta] : signals_) out.push_back(meta);
  return out;
}

std::vector<std::string> ClientImpl::pipelines(std::chrono::milliseconds wait) {
  // Each running pipeline's bridge is a participant named after it, and has one SignalInfo
  // writer. Either tells us it is live. Once something is heard, wait (within `wait`) until
  // every matched SignalInfo writer has delivered its pipeline's description: the first
  // pipeline heard of is not the only one live just because its data came first.
  const auto deadline = Clock::now() + wait;
  const auto heard = [this] {
    std::set<std::string> names = participants_.pipelines();
    std::lock_guard lock(signals_mutex_);
    for (const auto& [topic, meta] : signals_) names.insert(meta.pipeline);
    return names;
  };
  std::set<std::string> names = heard();
  while (Clock::now() < deadline) {
    if (!names.empty()) {
      fdds::SubscriptionMatchedStatus matched;
      std::size_t described = 0;
      {
        std::lock_guard lock(signals_mutex_);
        std::set<std::string> with_info;
        for (const auto& [topic, meta] : signals_) with_info.insert(meta.pipeline);
        described = with_info.size();
      }
      if (info_reader_->get_subscription_matched_status(matched) != ReturnCode_t::RETCODE_OK ||
          static_cast<std::size_t>(matched.current_count) <= described)
        break;
    }
    std::unique_lock lock(signals_mutex_);
    signals_changed_.wait_for(lock, std::chrono::milliseconds(50));
    lock.unlock();
    names = heard();
  }
  return {names.begin(), names.end()};
}

Expected<SignalMeta> ClientImpl::resolve(const std::string& what, std::chrono::milliseconds wait) {
  const auto deadline = Clock::now() + wait;
  std::unique_lock lock(signals_mutex_);
  while (true) {
    std::vector<SignalMeta> candidates = match(what);
    if (candidates.size() == 1) return candidates.front();
    if (candidates.size() > 1) {
      return Status::error("'" + what + "' is ambiguous: " + topic_list(candidates) +
                           " (give the pipeline, e.g. 'pipeline/block.port')");
    }
    if (signals_changed_.wait_until(lock, deadline) == std::cv_status::timeout) {
      candidates = match(what);
      if (candidates.size() == 1) return candidates.front();
      std::vector<SignalMeta> live;
      for (const auto& [topic, meta] : signals_) live.push_back(meta);
      return Status::error("no live signal matches '" + what + "' (waited " +
                           std::to_string(wait.count()) + " ms); live topics: " + topic_list(live));
    }
  }
}

void ClientImpl::take_info(fdds::DataReader* reader) {
  lode::msg::SignalInfo info;
  fdds::SampleInfo sample_info;
  while (reader->take_next_sample(&info, &sample_info) == ReturnCode_t::RETCODE_OK) {
    std::lock_guard lock(signals_mutex_);
    if (sample_info.valid_data) {
      handles_[sample_info.instance_handle] = info.topic();
      writers_[info.topic()] = sample_info.publication_handle;
      signals_[info.topic()] = meta_from(info);
    } else if (sample_info.instance_state != fdds::ALIVE_INSTANCE_STATE) {
      // The pipeline is gone (its writer left or disposed the topic).
      if (auto it = handles_.find(sample_info.instance_handle); it != handles_.end()) {
        signals_.erase(it->second);
        writers_.erase(it->second);
        handles_.erase(it);
      }
    }
    signals_changed_.notify_all();
  }
}

void ClientImpl::forget_writer(const fdds::InstanceHandle_t& writer) {
  std::lock_guard lock(signals_mutex_);
  for (auto it = writers_.begin(); it != writers_.end();) {
    if (it->second == writer) {
      signals_.erase(it->first);
      it = writers_.erase(it);
    } else {
      ++it;
    }
  }
  signals_changed_.notify_all();
}

std::vector<SignalMeta> ClientImpl::match(const std::string& what) const {
  std::vector<SignalMeta> out;
  std::string pipeline, rest = what;
  if (what.rfind("lode/", 0) == 0) {
    if (auto it = signals_.find(what); it != signals_.end()) out.push_back(it->second);
    return out;
  }
  if (auto slash = what.find('/'); slash != std::string::npos) {
    pipeline = what.substr(0, slash);
    rest = what.substr(slash + 1);
  }
  std::string block, port;
  if (auto slash = rest.find('/'); slash != std::string::npos) {
    block = rest.substr(0, slash);
    port = rest.substr(slash + 1);
  } else if (auto dot = rest.rfind('.'); dot != std::string::npos) {
    block = rest.substr(0, dot);
    port = rest.substr(dot + 1);
  }
  for (const auto& [topic, meta] : signals_) {
    if (!pipeline.empty() && meta.pipeline != pipeline) continue;
    const bool hit = block.empty() ? (rest == "state" && meta.kind == "state")
                                   : (meta.kind == "signal" && meta.block == block && meta.port == port);
    if (hit) out.push_back(meta);
  }
  return out;
}

}  // namespace lode::dds::client_detail
