// Internal: the records of a loaded pipeline (roles, instances, families of a primary and
// its shadows), shared by the pipeline and, through the roles API (roles.hpp), the hot swap.
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
#include <memory>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/board.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/tunables.hpp"

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
  /// Its configuration was refused (or configure() threw), or not tried because a block it
  /// reads from failed: what it or its readers would say next is a consequence, not reported.
  bool failed = false;

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

  /// Whether the primary's step needs more than the call: a health monitor, a step budget
  /// (timed), shadows, or a hot-swap candidate warming beside it.
  [[nodiscard]] bool watched() const noexcept {
    return health.enabled || health.step_budget_ns > 0 || !shadows.empty() || warming != nullptr;
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

}  // namespace lode
