// Internal: the loaded pipeline (Pipeline::Impl), shared by the loader, the graph, configure,
// the cycle, the health monitor and describe. Hot swap does not see it: it works through the
// roles-and-instances API (roles.hpp).
#pragma once

#include <yaml-cpp/yaml.h>

#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "envelope.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/spsc_ring.hpp"
#include "lode/telemetry.hpp"
#include "pipeline_records.hpp"
#include "roles.hpp"

namespace lode {
struct Pipeline::Impl {
  using BlockEntry = pipeline_detail::BlockEntry;
  using ModelSpec = pipeline_detail::ModelSpec;
  using Family = pipeline_detail::Family;

  std::string name;
  std::string file;
  double rate_hz = 0.0;
  std::optional<double> duration_s;
  RealtimeSettings realtime;
  RecordSettings record_settings;
  MonitorSpec monitor;
  TelemetrySpec telemetry;
  std::string source_text;
  std::map<std::string, ModelSpec> models;
  std::vector<std::unique_ptr<BlockEntry>> blocks;  // file order (roles)
  std::vector<double> arena;
  std::vector<Op> ops;
  bool active = false;
  std::vector<Family> families;
  pipeline_detail::Envelope envelope;
  /// The op before which the envelope is checked: the first write phase (so an out-of-bounds
  /// command never reaches a board), or ops.size() to check after the last op.
  std::size_t envelope_at = 0;
  /// Some family is watched (Family::watched()): run_cycle takes the path that looks at each
  /// op's family. Kept by refresh_watched() wherever what it depends on changes (the load, a
  /// warming candidate of a hot swap, on the RT thread), so the common cycle reads one flag.
  bool watched = false;
  /// RT-safe (no allocation): recompute `watched` from the families.
  void refresh_watched() noexcept {
    bool any = false;
    for (const Family& f : families) any = any || f.watched();
    watched = any;
  }
  std::vector<std::unique_ptr<BlockEntry>> pool;  // hot-swap instances now running in a role
  std::deque<OutputPort> synthetic_ports;          // shadow statistics outputs

  // Health trips: RT producer, one non-RT consumer (take_health_trips).
  static constexpr std::size_t kTripCapacity = 64;
  SpscQueue<pipeline_detail::TripRecord> trips{kTripCapacity};
  std::uint64_t trips_lost_reported = 0;  ///< consumer side: drops already reported

  /// The roles-and-instances API (what hot swap uses).
  pipeline_detail::Roles roles{*this};

  std::deque<OutputPort> feed_ports;  // storage handles of the test pseudo-block "feed"
  PluginRegistry* registry = nullptr;
  Diagnostics* diag = nullptr;

  BlockEntry* find_block(const std::string& n) {
    for (auto& b : blocks)
      if (b->name == n) return b.get();
    return nullptr;
  }
  const BlockEntry* find_block(const std::string& n) const {
    for (const auto& b : blocks)
      if (b->name == n) return b.get();
    return nullptr;
  }

  void error(const SourceLocation& where, const std::string& field, const std::string& msg) {
    diag->add(where, field, msg);
  }

  bool parse_top(const YAML::Node& root);
  void parse_realtime(const YAML::Node& rt);
  void parse_record(const YAML::Node& node);
  void parse_envelope(const YAML::Node& node);
  void parse_models(const YAML::Node& models_node);
  void parse_blocks(const YAML::Node& blocks_node);
  /// A block's `inputs:` map into its wiring (the loader's and a hot swap's); problems are
  /// reported at `path`.inputs.NAME.
  void parse_wiring(const YAML::Node& inputs, const std::string& path, BlockEntry& e);
  std::vector<BlockEntry*> order_blocks();
  void configure_block(BlockEntry& entry);
  void check_documented(const LoadedPlugin& plugin, const Params& params, const std::string& path);
  void resolve_inputs();
  void resolve_inputs_of(BlockEntry& entry);
  void check_shadows(const std::vector<BlockEntry*>& order);
  void allocate_and_bind();
  void build_ops(const std::vector<BlockEntry*>& order);
  void build_families();
  void parse_monitor(const YAML::Node& m);
  void parse_telemetry(const YAML::Node& t);
  void parse_health(const YAML::Node& h);
  std::optional<SignalRef> signal(const std::string& ref) const;

  // Roles and instances.
  /// Bindings of `record`'s outputs into `role`'s storage (by port name, size and units);
  /// outputs the role does not have go to the record's staging storage.
  std::vector<pipeline_detail::Binding> plan_for(BlockEntry& record, const BlockEntry& role);
  /// Staging storage and plans for `record` as a member of `family`.
  void prepare_record(BlockEntry& record, const Family& family);
  /// Bind `record`'s inputs to the sources its wiring names, in `storage` laid out as the
  /// arena (the arena itself, or a snapshot of it).
  void bind_inputs(BlockEntry& record, const double* storage);
  /// RT: point the op (role 0) or the shadow slot at record's instance and its interfaces.
  void put_instance(Family& f, int role, BlockEntry& record) noexcept;
  /// RT: rebind ports and exchange instances of two roles of one family.
  void exchange_roles(Family& f, int role_a, int role_b) noexcept;
  /// RT: put `record` into `role` of `f`; the record that ran there goes to its staging.
  BlockEntry* install(Family& f, int role, BlockEntry& record) noexcept;
  /// RT: after the primary's step: shadows, warming candidate, health. Returns the status the
  /// cycle continues with; `reason` is set when the health monitor turns it into a fault.
  StepStatus after_primary(Family& f, const Tick& tick, StepStatus status, std::int64_t step_ns,
                           const char*& reason) noexcept;
  void push_trip(const pipeline_detail::TripRecord& t) noexcept;
  /// Every record with a live instance (roles that own theirs, and the pool).
  std::vector<BlockEntry*> instances();

  /// `needed` names the interface M in messages: "plant", "sensor" or "process".
  template <typename M>
  std::unique_ptr<M> make_model(Params& block_params, std::string_view key, const char* needed) {
    const std::string model_name = block_params.text(key);
    if (model_name.empty()) return nullptr;
    return make_model_named<M>(block_params, key, model_name, needed);
  }
  template <typename M>
  std::unique_ptr<M> make_model_named(Params& block_params, std::string_view key,
                                      const std::string& model_name, const char* needed);
};

}  // namespace lode
