// libFuzzer target: the register-map parser on arbitrary bytes. Beyond "no crash, no
// sanitizer report": an error names the file; a map that parses has every register aligned
// and inside the window, no two registers sharing a word, the bits of each register distinct,
// and written back as text it parses to the same layout.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "regmap.hpp"

namespace {

using lode::vme::Layout;

void require(bool condition) {
  if (!condition) std::abort();
}

void check_invariants(const Layout& l) {
  require(l.window >= 4 && l.window <= lode::vme::kMaxWindow && l.window % 4 == 0);
  std::vector<bool> used(l.window / 4, false);
  auto claim = [&](std::size_t offset) {
    require(offset % 4 == 0 && offset + 4 <= l.window);
    require(!used[offset / 4]);
    used[offset / 4] = true;
  };
  for (const std::size_t reg : {l.board_id, l.control, l.status, l.channels, l.trigger, l.dac_load, l.reset_errors})
    claim(reg);
  for (const auto* a : {&l.adc_data, &l.dac_data}) {
    require(a->count >= 1 && a->stride >= 4 && a->stride % 4 == 0);
    for (std::size_t i = 0; i < a->count; ++i) claim(a->at(i));
  }
  require((l.board_id_value & ~l.board_id_mask) == 0);
  auto one_bit = [](std::uint32_t m) { return m != 0 && (m & (m - 1)) == 0; };
  auto field_ok = [](const lode::vme::BitField& f) { return f.lo <= f.hi && f.hi <= 31 && f.mask() != 0; };
  require(one_bit(l.enable) && one_bit(l.ext_trigger) && (l.enable & l.ext_trigger) == 0);
  std::uint32_t status = 0;
  for (const std::uint32_t b : {l.done, l.busy, l.err_overrun, l.err_adc, l.err_dac, l.err_bus}) {
    require(one_bit(b) && (status & b) == 0);
    status |= b;
  }
  require(field_ok(l.sequence) && (status & l.sequence.mask()) == 0);
  require(field_ok(l.adc_channels) && field_ok(l.dac_channels) && (l.adc_channels.mask() & l.dac_channels.mask()) == 0);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto layout = lode::vme::parse_layout(text, "fuzz.regmap");
  if (!layout) {
    require(layout.error().rfind("fuzz.regmap:", 0) == 0);
    return 0;
  }
  check_invariants(*layout);
  const auto again = lode::vme::parse_layout(lode::vme::to_text(*layout), "round-trip");
  require(again.has_value() && *again == *layout);
  return 0;
}
