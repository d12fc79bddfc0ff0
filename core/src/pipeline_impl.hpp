// Internal: the loaded pipeline's data, shared by pipeline.cpp (loading, the cycle, the health
// monitor) and hot_swap.cpp (preparing replacements off the RT thread).
//
// Roles and instances. A BlockEntry is both a *role* (a name with output storage in
// the arena that other blocks, taps and topics read) and an *instance record* (a Block created
// from a plugin, with its declared ports). At load every role runs its own instance. A hot
// swap puts another record's instance into a role; a promotion or a health fallback exchanges
// the instances of a primary role and one of its shadow roles. `live` tells which record runs
// in a role; the RT thread only ever rewrites plain pointers (the op's or shadow slot's Block*,
// port bindings, `live`), all prepared off the RT thread.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "envelope.hpp"
#include "lode/pipeline.hpp"
#include "lode/sdk/board.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/spsc_ring.hpp"
#include "lode/telemetry.hpp"

namespace lode {
namespace pipeline_detail {

struct DeclaredOutput {
  std::string name;
  Elements elements;
  OutputPort* port = nullptr;
  std::size_t offset = 0;   // into the arena (roles) or into the record's staging storage
  bool synthetic = false;   // written by the pipeline (shadow statistics), not by the block
};

struct DeclaredInput {
  std::string name;
  Elements expected;
  bool required = true;
  InputPort* port = nullptr;
};

struct InputWiring {
  std::string input;       // input name on this block
  std::string source;      // "block.port" as written
  std::string src_block;
  std::string src_port;
  SourceLocation where;    // of the value
};

struct ModelSpec {
  std::string name;
  LoadedPlugin plugin;
  YAML::Node node;
  SourceLocation where;
};

/// Where each output of a record goes when it runs in a given role.
struct Binding {
  OutputPort* port = nullptr;
  double* data = nullptr;
  std::size_t size = 0;
};

struct BlockEntry {
  std::string name;
  std::string plugin_name;
  LoadedPlugin plugin;
  YAML::Node node;
  SourceLocation where;
  std::vector<InputWiring> wiring;
  std::unique_ptr<Block> block;
  // The optional interfaces of `block`, found once when it is created (nullptr: it has none).
  Board* board = nullptr;
  Tunables* tunables = nullptr;
  EstimatorState* estimator = nullptr;
  std::vector<DeclaredOutput> outputs;
  std::vector<DeclaredInput> inputs;
  bool configured = false;

  // Shadows and hot swap -------------------------------------------------------------
  std::string shadow_of;                 ///< `shadow_of:` (this role is a shadow of that block)
  SourceLocation shadow_where;
  std::uint32_t shadow_decimation = 1;   ///< `shadow_decimation:` (stepped every n-th cycle)
  int family = -1;                       ///< index into Impl::families (roles only)
  int family_role = -1;                  ///< 0 = the primary, 1.. = shadow slot + 1
  std::atomic<BlockEntry*> live{nullptr};  ///< roles: the record whose instance runs here
  std::vector<double> staging;           ///< this record's own output storage when out of its role
  std::vector<std::vector<Binding>> plans;  ///< per role of its family: where its outputs go
  std::vector<Binding> staging_plan;     ///< its outputs to `staging`
  StateLayout layout;                    ///< cached state_layout() (empty: no exportable state)
  bool candidate = false;                ///< created by a hot swap (owned by Impl::pool)

  bool is_io() const { return plugin.descriptor && plugin.descriptor->kind == PluginKind::io; }
  /// Takes the instance a plugin created and finds its optional interfaces.
  void adopt(std::unique_ptr<Block> instance) {
    block = std::move(instance);
    board = dynamic_cast<Board*>(block.get());
    tunables = dynamic_cast<Tunables*>(block.get());
    estimator = dynamic_cast<EstimatorState*>(block.get());
  }
  const DeclaredOutput* output(const std::string& port) const {
    for (const auto& o : outputs)
      if (o.name == port) return &o;
    return nullptr;
  }
};

/// A shadow role as the RT thread sees it.
struct ShadowSlot {
  Block* block = nullptr;      ///< instance running in the shadow role
  EstimatorState* estimator = nullptr;  ///< its estimator interface (nullptr: none)
  BlockEntry* role = nullptr;
  std::uint32_t decimation = 1;
  bool stepped_ok = false;     ///< stepped this cycle and returned ok
  std::uint64_t faults = 0;    ///< faults of the shadow (never stop the pipeline)
  // disagreement = this role's output - the primary role's output (same port), elementwise
  const double* mine = nullptr;
  const double* primary = nullptr;
  double* disagreement = nullptr;
  std::size_t disagreement_size = 0;
  double* nis = nullptr;       ///< synthetic output: sum nu^2 / S (NaN without innovation)
  std::vector<double> nu, s;   ///< innovation scratch (sized at load)
};

/// The health monitor of one primary role (`health:` section).
struct HealthSpec {
  bool enabled = false;
  bool non_finite = true;
  std::uint32_t covariance_every = 1;  ///< 0 = off
  std::uint32_t nis_window = 0;        ///< 0 = off
  double nis_threshold = 0.0;          ///< on the window mean
  std::int64_t step_budget_ns = 0;     ///< 0 = off
  std::uint32_t budget_cycles = 1;
  int fallback_slot = -1;              ///< shadow slot promoted on a trip; -1 = drive safe
};

/// A trip, from the RT thread to whoever posts events (fixed-size ring, wait-free).
struct TripRecord {
  std::uint64_t cycle = 0;
  std::int64_t time_ns = 0;
  int family = -1;
  const char* reason = "";
  int fallback_slot = -1;  ///< the slot that took over, -1 if outputs were driven safe
};

/// A primary role with its shadow roles and its health monitor.
struct Family {
  BlockEntry* primary = nullptr;
  std::vector<BlockEntry*> roles;   ///< [0] primary, [1 + j] shadow slot j
  std::size_t op = 0;               ///< the primary's op
  std::vector<ShadowSlot> shadows;
  HealthSpec health;
  bool fallback_used = false;       ///< one automatic fallback; the next trip drives safe

  // A hot-swap candidate warming up as a shadow before it takes over (hot_swap.cpp).
  Block* warming = nullptr;
  std::uint32_t warming_left = 0;

  // Health state (RT thread only).
  std::vector<double> nis_ring;
  std::size_t nis_pos = 0;
  std::uint32_t nis_count = 0;
  double nis_sum = 0.0;
  std::uint32_t over_budget = 0;
  std::vector<double> state_values, state_covariance;  ///< export buffers (layout of the live record)
  std::vector<double> nu, s;
  // Primary role storage ranges, for the finiteness test and the fallback's same-cycle copy.
  struct Range {
    double* primary = nullptr;
    const double* shadow = nullptr;  // per fallback; set when health is parsed
    std::size_t size = 0;
  };
  std::vector<Range> ranges;

  /// A new primary starts its own health statistics: after a fallback, a promotion, a swap
  /// into the primary role and at activation (or its first slow step would trip on the
  /// previous one's count). RT-safe.
  void restart_health() noexcept {
    nis_count = 0;
    nis_sum = 0.0;
    nis_pos = 0;
    over_budget = 0;
  }
};

/// Keys of a block that the pipeline reads (the rest are the plugin's parameters).
inline const std::vector<std::string> kPipelineBlockKeys = {"plugin", "inputs", "shadow_of", "shadow_decimation"};
/// Outputs the pipeline adds to every shadow role.
inline constexpr const char* kDisagreementPort = "disagreement";
inline constexpr const char* kNisPort = "nis";

/// "[x m, y m]" for messages.
inline std::string element_list(const Elements& e) {
  std::string s = "[";
  for (std::size_t i = 0; i < e.size(); ++i)
    s += (i ? ", " : "") + e[i].name + (e[i].unit.empty() ? "" : " " + e[i].unit);
  return s + "]";
}

/// Offset in the arena of an output that load-time validation guarantees to exist.
inline std::size_t output_offset(const BlockEntry& b, const std::string& port) {
  const DeclaredOutput* o = b.output(port);
  return o ? o->offset : 0;
}

}  // namespace pipeline_detail

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
  std::vector<std::unique_ptr<BlockEntry>> pool;  // hot-swap instances now running in a role
  std::deque<OutputPort> synthetic_ports;          // shadow statistics outputs

  // Health trips: RT producer, one non-RT consumer (take_health_trips).
  static constexpr std::size_t kTripCapacity = 64;
  SpscQueue<pipeline_detail::TripRecord> trips{kTripCapacity};
  std::uint64_t trips_lost_reported = 0;  ///< consumer side: drops already reported

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
  /// Why `candidate` cannot take the place of `role` (promotion, fallback, swap): it must
  /// provide every output of the role with the same number of elements and compatible units.
  /// Empty when it can. Synthetic outputs (a shadow's statistics) are the pipeline's own.
  static std::string stand_in_problem(const BlockEntry& candidate, const BlockEntry& role);
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
  /// Bind `record`'s inputs to the sources its wiring names (arena storage).
  void bind_inputs(BlockEntry& record);
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
