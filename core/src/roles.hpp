// Internal: roles and instances, the one API through which a hot swap changes a loaded
// pipeline. A role is a block name with output storage that other blocks, taps and topics
// read; an instance is a Block a plugin created. A swap builds a candidate instance with the
// loader's own code, checks it can stand in for the role, and installs it at a cycle boundary;
// a promotion exchanges the instances of a primary role and one of its shadow roles. The
// pipeline's other data (the YAML, the schedule, the health monitor's settings) stay behind
// this API.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "pipeline_records.hpp"

namespace lode::pipeline_detail {

class Roles {
 public:
  explicit Roles(Pipeline::Impl& pipeline) : pipeline_(pipeline) {}

  // Lookup (off the RT thread) ------------------------------------------------------------
  /// The role named `name`, or nullptr.
  [[nodiscard]] BlockEntry* find(const std::string& name) const;
  /// The family of a role that has one (`role.family >= 0`).
  [[nodiscard]] Family& family_of(const BlockEntry& role) const;
  /// Names of every role a swap may target (primaries and shadows).
  [[nodiscard]] std::vector<std::string> swappable() const;
  [[nodiscard]] Expected<LoadedPlugin> plugin(const std::string& name) const;
  /// Doubles of output storage (a snapshot of the outputs is laid out the same way).
  [[nodiscard]] std::size_t storage_size() const;
  /// Output storage, as the RT thread last wrote it (read it on the RT thread, or while none runs).
  [[nodiscard]] const double* storage() const;
  /// The output a wiring entry reads, or nullptr.
  [[nodiscard]] const DeclaredOutput* source_of(const InputWiring& wiring) const;

  // A candidate instance (off the RT thread) ----------------------------------------------
  /// Wires (`inputs`, or the incumbent's wiring when `inputs` is null), configures and
  /// resolves `candidate` with the loader's own code; problems go to `diagnostics`, located
  /// in "swap request". Inputs the candidate does not declare are dropped and named in
  /// `unused` ("input (source)").
  void configure_candidate(BlockEntry& candidate, const YAML::Node& inputs, const BlockEntry& incumbent,
                           Diagnostics& diagnostics, std::vector<std::string>& unused);
  /// The first input of `candidate` computed at or after `family`'s primary in the cycle (it
  /// would read a stale value in the primary's place), or nullptr.
  [[nodiscard]] const InputWiring* stale_input(const BlockEntry& candidate, const Family& family) const;
  /// Why `candidate` cannot take the place of `role` (every output, same size, compatible
  /// units), or empty. Synthetic outputs (a shadow's statistics) are the pipeline's own.
  [[nodiscard]] static std::string stand_in_problem(const BlockEntry& candidate, const BlockEntry& role);
  /// Storage and bindings for `candidate` in `family`: outputs to its staging storage (until
  /// installed), inputs to their sources.
  void bind_candidate(BlockEntry& candidate, const Family& family);

  // The exchange (RT thread; RT-safe, everything prepared before) -------------------------
  /// Puts `record` into `role` of `family`; returns the record that ran there.
  BlockEntry* install(Family& family, int role, BlockEntry& record) noexcept;
  /// Exchanges the instances of two roles of one family (a promotion).
  void exchange(Family& family, int role_a, int role_b) noexcept;
  /// Runs `candidate` beside `family`'s primary for `cycles` cycles before it is installed
  /// (nullptr: no candidate warms any more). The cycle watches the family meanwhile.
  void set_warming(Family& family, Block* candidate, std::uint32_t cycles) noexcept;

  // After the exchange (off the RT thread) ------------------------------------------------
  /// Binds `record`'s inputs into `storage`, laid out as the output storage (a snapshot).
  void bind_inputs_to(BlockEntry& record, const double* storage) const;
  /// Deactivates and releases an instance a swap replaced (the role keeps its storage).
  void retire(BlockEntry& record);
  /// Keeps an installed candidate alive for as long as the pipeline.
  void keep(std::unique_ptr<BlockEntry> record);

 private:
  Pipeline::Impl& pipeline_;
};

}  // namespace lode::pipeline_detail
