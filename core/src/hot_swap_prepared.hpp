// Internal to hot swap: what a swap carries from its preparation (off the RT thread,
// hot_swap_prepare.cpp) through the exchange at a cycle boundary (RT) to its report
// (hot_swap.cpp).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "lode/hot_swap.hpp"
#include "lode/sdk/text.hpp"
#include "pipeline_records.hpp"

namespace lode {

namespace hot_swap_detail {

/// Figures in swap reports: three significant digits.
inline std::string number(double v) { return number_text(v, 3); }

inline std::string join(const std::vector<std::string>& items) {
  std::string s;
  for (const auto& i : items) s += (s.empty() ? "" : ", ") + i;
  return s;
}

/// "shadow_cycles=200; warm_start=false" (the `name` field of a swap command).
inline Status parse_options(const std::string& text, SwapRequest& r) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    auto end = text.find_first_of(";,", pos);
    if (end == std::string::npos) end = text.size();
    std::string item = text.substr(pos, end - pos);
    pos = end + 1;
    item.erase(0, item.find_first_not_of(' '));
    item.erase(item.find_last_not_of(' ') + 1);
    if (item.empty()) continue;
    const auto eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (key == "shadow_cycles") {
      char* e = nullptr;
      const long long n = std::strtoll(value.c_str(), &e, 10);
      if (value.empty() || *e != '\0' || n < 0 || n > 100000000)
        return Status::error("swap option shadow_cycles='" + value + "' must be an integer in 0..100000000");
      r.shadow_cycles = static_cast<std::uint32_t>(n);
    } else if (key == "warm_start") {
      if (value != "true" && value != "false")
        return Status::error("swap option warm_start='" + value + "' must be true or false");
      r.warm_start = value == "true";
    } else {
      return Status::error("unknown swap option '" + key + "' (shadow_cycles=N, warm_start=true|false)");
    }
  }
  return {};
}

}  // namespace hot_swap_detail

struct HotSwap::Prepared {
  using BlockEntry = pipeline_detail::BlockEntry;
  using Family = pipeline_detail::Family;
  enum class Kind { replace, promote } kind = Kind::replace;
  SwapReport report;
  Family* family = nullptr;
  int role = 0;                       // role index in the family
  BlockEntry* role_entry = nullptr;
  BlockEntry* expected = nullptr;     // the record live in the role when prepared
  std::unique_ptr<BlockEntry> record; // the newcomer (replace)
  int promote_slot = -1;              // promote: the shadow slot
  std::uint32_t shadow_cycles = 0;
  // Warm start: newcomer element j <- incumbent element map[j] (or absent).
  bool warm = false;
  std::vector<int> map;
  std::vector<std::uint8_t> present;
  std::vector<double> src_values, src_cov, dst_values, dst_cov;
  bool src_has_cov = false, dst_has_cov = false;
  // Filled on the RT thread.
  bool refused = false;
  const char* refusal = "";
  std::uint64_t cycle = 0;
  std::int64_t time_ns = 0;
  double dt_s = 0.0;
  std::int64_t cost_ns = 0;
  BlockEntry* retired = nullptr;
  std::vector<double> snapshot;       // arena-shaped: the spans below, at the end of the exchange cycle
  struct Span {
    std::size_t offset = 0, size = 0;
  };
  std::vector<Span> snapshot_spans;   // the retired instance's inputs and the role's first output
  std::int64_t prepared_at_ns = 0;
  bool prefetched = false;            // the RT thread has issued the prefetches (one cycle ahead)
};


}  // namespace lode
