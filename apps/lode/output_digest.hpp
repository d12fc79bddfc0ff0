// The output digest: one 64-bit hash over the bit patterns of every output of every cycle, in
// the pipeline's signal order, that proves two runs (or a run and its replay) bit-identical.
// New runs hash with XXH3-64 (libxxhash): one streaming update per cycle over the outputs'
// contiguous storage, ~30 ns for kawato_planar's 384 bytes. Recordings made before it carry a
// byte-wise FNV-1a digest and no algorithm attribute; a replay of one computes FNV-1a again,
// so old recordings keep verifying.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/telemetry.hpp"

namespace lode::cli {

enum class DigestAlgorithm { xxh3_64, fnv1a_64 };

/// The recording attribute and summary field that name the digest's algorithm.
inline constexpr const char* kDigestAlgorithmKey = "output_digest_algorithm";
/// What a recording without kDigestAlgorithmKey was digested with.
inline constexpr DigestAlgorithm kLegacyDigestAlgorithm = DigestAlgorithm::fnv1a_64;

/// "xxh3-64" or "fnv1a-64": the value of kDigestAlgorithmKey.
[[nodiscard]] const char* digest_algorithm_name(DigestAlgorithm algorithm);
/// The algorithm a recording's kDigestAlgorithmKey names ("" for a recording without one:
/// kLegacyDigestAlgorithm); nullopt for a name this build does not know.
[[nodiscard]] std::optional<DigestAlgorithm> digest_algorithm_named(const std::string& name);

/// FNV-1a (64-bit) continued over `size` bytes. Byte at a time, ~1 ns per byte: only for
/// replaying recordings that were digested with it.
[[nodiscard]] std::uint64_t fnv1a_64(std::uint64_t hash, const void* data, std::size_t size) noexcept;
inline constexpr std::uint64_t kFnv1a64Offset = 0xcbf29ce484222325ULL;

/// The digest as a scheduler hook: after_cycle() hashes the cycle's outputs. RT-safe: the
/// hash state and (when the outputs are not one contiguous block) the copy buffer are made
/// in the constructor; a cycle only reads the outputs and updates the state.
class OutputDigest final : public CycleHook {
 public:
  OutputDigest(const std::vector<SignalRef>& signals, DigestAlgorithm algorithm);
  ~OutputDigest() override;
  OutputDigest(const OutputDigest&) = delete;
  OutputDigest& operator=(const OutputDigest&) = delete;

  void after_cycle(const Tick& tick) noexcept override;
  /// Back to the state before the first cycle.
  void reset() noexcept;
  [[nodiscard]] std::uint64_t value() const noexcept;
  /// value() as 16 lower-case hex digits (the summary's and the recording's output_digest).
  [[nodiscard]] std::string text() const;
  [[nodiscard]] DigestAlgorithm algorithm() const noexcept { return algorithm_; }
  /// Bytes hashed per cycle.
  [[nodiscard]] std::size_t cycle_bytes() const noexcept { return cycle_bytes_; }

 private:
  struct XxhState;
  DigestAlgorithm algorithm_;
  SignalSpans spans_;
  // Every output in one block of memory (the pipeline's arena): hashed in place. Otherwise
  // each cycle's outputs are gathered into gather_ first (a copy per run of adjacent
  // signals), so the update is still one call.
  const unsigned char* contiguous_ = nullptr;
  std::size_t cycle_bytes_ = 0;
  std::vector<double> gather_;
  std::unique_ptr<XxhState> xxh_;
  std::uint64_t fnv_ = kFnv1a64Offset;
};

}  // namespace lode::cli
