// The register-map parser (regmap.hpp): the shipped map is the built-in default; every kind of
// mistake gives "FILE:LINE: FIELD: message" naming the line and the register, bit or field;
// a map with the registers moved around parses to exactly those offsets.
#include "regmap.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace {

using lode::vme::Layout;

// The default map, one directive per line so the expected line numbers below can be read off.
const std::string kBase = R"(window 0x400
register BOARD_ID 0x000 ro value 0x61020000 mask 0xffff0000
register CONTROL 0x004 rw
register STATUS 0x008 ro
register CHANNELS 0x00c ro
register TRIGGER 0x010 rw
register DAC_LOAD 0x014 rw
register RESET_ERRORS 0x018 wo
register ADC_DATA 0x100 ro count 64 stride 4
register DAC_DATA 0x200 rw count 64 stride 4
bit CONTROL.ENABLE 0
bit CONTROL.EXT_TRIGGER 2
bit STATUS.DONE 0
bit STATUS.BUSY 1
bit STATUS.ERR_OVERRUN 8
bit STATUS.ERR_ADC 9
bit STATUS.ERR_DAC 10
bit STATUS.ERR_BUS 11
field STATUS.SEQUENCE 16..31
field CHANNELS.ADC 0..7
field CHANNELS.DAC 8..15
)";

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  if (pos == std::string::npos) throw std::runtime_error("test bug: '" + from + "' not in the base map");
  return s.replace(pos, from.size(), to);
}

TEST(Regmap, TheShippedFileIsTheDefaultLayout) {
  const auto layout = lode::vme::load_layout(LODE_SOURCE_DIR "/plugins/io/vme_pentek/pentek6102_dvme622.regmap");
  ASSERT_TRUE(layout) << layout.error();
  EXPECT_TRUE(*layout == Layout::default_layout());
  // Spot checks against the board's documentation (README.md), so the default itself is pinned.
  const Layout d = Layout::default_layout();
  EXPECT_EQ(d.window, 0x400u);
  EXPECT_EQ(d.status, 0x008u);
  EXPECT_EQ(d.dac_data.at(63), 0x2fcu);
  EXPECT_EQ(d.error_mask(), 0xf00u);
  EXPECT_EQ(d.sequence.get(0x12340001u), 0x1234u);
  EXPECT_EQ(d.sequence.put(0x10001u), 0x00010000u);  // the counter wraps within its field
}

TEST(Regmap, TheBaseTextAndItsWrittenFormParseToTheDefault) {
  const auto base = lode::vme::parse_layout(kBase, "t.regmap");
  ASSERT_TRUE(base) << base.error();
  EXPECT_TRUE(*base == Layout::default_layout());
  const auto again = lode::vme::parse_layout(lode::vme::to_text(Layout::default_layout()), "written");
  ASSERT_TRUE(again) << again.error();
  EXPECT_TRUE(*again == Layout::default_layout());
}

TEST(Regmap, CommentsBlankLinesCrlfAndDeclarationOrderDoNotMatter) {
  // Bits before their register, CRLF line ends, comments everywhere.
  std::string text = "# a board\r\n\r\n";
  const std::string bits = kBase.substr(kBase.find("bit CONTROL.ENABLE"));
  const std::string regs = kBase.substr(0, kBase.find("bit CONTROL.ENABLE"));
  for (const std::string& part : {bits, regs}) {
    std::size_t start = 0;
    while (start < part.size()) {
      const std::size_t end = part.find('\n', start);
      text += part.substr(start, end - start) + "   # why\r\n";
      start = end + 1;
    }
  }
  const auto layout = lode::vme::parse_layout(text, "crlf.regmap");
  ASSERT_TRUE(layout) << layout.error();
  EXPECT_TRUE(*layout == Layout::default_layout());
}

TEST(Regmap, AShuffledMapParsesToItsOffsetsAndInterleavedArraysDoNotOverlap) {
  const auto layout = lode::vme::load_layout(LODE_SOURCE_DIR "/plugins/io/vme_pentek/test/shuffled.regmap");
  ASSERT_TRUE(layout) << layout.error();
  EXPECT_EQ(layout->window, 0x800u);
  EXPECT_EQ(layout->board_id, 0x7fcu);
  EXPECT_EQ(layout->status, 0x100u);
  EXPECT_EQ(layout->dac_data.at(1), 0x008u);
  EXPECT_EQ(layout->adc_data.at(1), 0x00cu);
  EXPECT_EQ(layout->enable, 1u << 31);
  EXPECT_EQ(layout->sequence.mask(), 0xff00u);
  EXPECT_EQ(layout->dac_channels.put(3), 3u << 24);
}

struct Case {
  const char* name;
  std::string text;
  std::string expect;  ///< one whole line of the error
};

TEST(Regmap, EachMistakeNamesTheFileLineAndField) {
  const std::vector<Case> cases = {
      {"unknown directive", replace(kBase, "bit STATUS.BUSY 1", "bitt STATUS.BUSY 1"),
       "t.regmap:14: 'bitt': unknown directive (window, register, bit, field)"},
      {"bad number", replace(kBase, "STATUS 0x008", "STATUS 0x00g"),
       "t.regmap:4: register STATUS: bad offset '0x00g' (decimal or 0x hex, at most 0xffffffff)"},
      {"number beyond 32 bits", replace(kBase, "value 0x61020000", "value 0x161020000"),
       "t.regmap:2: register BOARD_ID: bad value '0x161020000' (decimal or 0x hex, at most 0xffffffff)"},
      {"duplicate register", kBase + "register STATUS 0x020 ro\n",
       "t.regmap:22: register STATUS: duplicate name (first on line 4)"},
      {"duplicate bit", kBase + "bit STATUS.DONE 3\n", "t.regmap:22: bit STATUS.DONE: duplicate name (first on line 13)"},
      {"overlapping registers", replace(kBase, "CHANNELS 0x00c", "CHANNELS 0x008"),
       "t.regmap:5: register CHANNELS: overlaps register STATUS (line 4) at 0x8"},
      {"overlapping arrays", replace(kBase, "0x100 ro count 64", "0x100 ro count 65"),
       "t.regmap:10: register DAC_DATA: overlaps register ADC_DATA (line 9) at 0x200"},
      {"unaligned offset", replace(kBase, "STATUS 0x008", "STATUS 0x009"),
       "t.regmap:4: register STATUS: offset 0x9 is not a multiple of 4 (32-bit registers)"},
      {"unaligned stride", replace(kBase, "0x200 rw count 64 stride 4", "0x200 rw count 64 stride 6"),
       "t.regmap:10: register DAC_DATA: stride 6 is not a multiple of 4 (at least 4)"},
      {"register outside the window", replace(kBase, "STATUS 0x008", "STATUS 0x400"),
       "t.regmap:4: register STATUS: offset 0x400 is outside the window (0x400 bytes)"},
      {"array outside the window", replace(kBase, "0x200 rw count 64 stride 4", "0x200 rw count 64 stride 16"),
       "t.regmap:10: register DAC_DATA: array 0x200 + 16 * 64 ends at 0x5f4, outside the window (0x400 bytes)"},
      {"bit above 31", replace(kBase, "STATUS.ERR_BUS 11", "STATUS.ERR_BUS 32"),
       "t.regmap:18: bit STATUS.ERR_BUS: bit 32 not within 0 ... 31 (32-bit registers)"},
      {"field lo > hi", replace(kBase, "16..31", "31..16"),
       "t.regmap:19: field STATUS.SEQUENCE: low bit 31 above high bit 16"},
      {"bit on an unknown register", kBase + "bit STATE.READY 3\n", "t.regmap:22: bit STATE.READY: unknown register STATE"},
      {"two bits in one place", replace(kBase, "STATUS.BUSY 1", "STATUS.BUSY 0"),
       "t.regmap:14: bit STATUS.BUSY: bit 0 is also bit STATUS.DONE (line 13)"},
      {"a field over a bit", replace(kBase, "16..31", "11..31"),
       "t.regmap:19: field STATUS.SEQUENCE: bit 11 is also bit STATUS.ERR_BUS (line 18)"},
      {"missing register", replace(kBase, "register RESET_ERRORS 0x018 wo\n", ""),
       "t.regmap:20: register RESET_ERRORS: missing (io.vme_pentek needs it)"},
      {"missing bit", replace(kBase, "bit STATUS.ERR_DAC 10\n", ""),
       "t.regmap:20: bit STATUS.ERR_DAC: missing (io.vme_pentek needs it)"},
      {"missing window", replace(kBase, "window 0x400\n", ""),
       "t.regmap:20: window: missing (window SIZE: the bytes the host maps)"},
      {"unknown access mode", replace(kBase, "CONTROL 0x004 rw", "CONTROL 0x004 rx"),
       "t.regmap:3: register CONTROL: access 'rx' is not ro, wo or rw"},
      {"doorbell not readable", replace(kBase, "TRIGGER 0x010 rw", "TRIGGER 0x010 wo"),
       "t.regmap:6: register TRIGGER: access wo, but the host writes and reads it (rw)"},
      {"written register read only", replace(kBase, "DAC_DATA 0x200 rw", "DAC_DATA 0x200 ro"),
       "t.regmap:10: register DAC_DATA: access ro, but the host writes it (wo or rw)"},
      {"read register write only", replace(kBase, "STATUS 0x008 ro", "STATUS 0x008 wo"),
       "t.regmap:4: register STATUS: access wo, but the host reads it (ro or rw)"},
      {"board id without value", replace(kBase, "ro value 0x61020000 mask 0xffff0000", "ro"),
       "t.regmap:2: register BOARD_ID: needs `value V [mask M]`: the id the host checks"},
      {"value outside mask", replace(kBase, "value 0x61020000", "value 0x61020001"),
       "t.regmap:2: register BOARD_ID: value 0x61020001 has bits outside mask 0xffff0000"},
      {"data not an array", replace(kBase, "0x100 ro count 64 stride 4", "0x100 ro"),
       "t.regmap:9: register ADC_DATA: must be an array (count N [stride S]: one register per channel)"},
      {"a field where a bit is needed", replace(kBase, "bit STATUS.DONE 0", "field STATUS.DONE 4..5"),
       "t.regmap:13: bit STATUS.DONE: must be a single bit, not 4..5"},
      {"window not a multiple of 4", replace(kBase, "window 0x400", "window 0x402"),
       "t.regmap:1: window: size 0x402 must be a multiple of 4 within 4 ... 0x10000"},
      {"unknown attribute", replace(kBase, "count 64 stride 4\nbit", "count 64 strides 4\nbit"),
       "t.regmap:10: register DAC_DATA: unknown attribute 'strides' (value, mask, count, stride)"},
      {"bad name", kBase + "register 9LIVES 0x20 ro\n", "t.regmap:22: register '9LIVES': bad name (letters, digits, _)"},
  };
  for (const auto& c : cases) {
    const auto layout = lode::vme::parse_layout(c.text, "t.regmap");
    ASSERT_FALSE(layout) << c.name;
    // Whole lines: the message is exactly one of the reported problems.
    const std::string lines = "\n" + layout.error() + "\n";
    EXPECT_NE(lines.find("\n" + c.expect + "\n"), std::string::npos) << c.name << ":\n" << layout.error();
  }
}

TEST(Regmap, EveryProblemIsReportedAtOnceUpToALimit) {
  const std::string text = replace(replace(replace(kBase, "STATUS 0x008", "STATUS 0x009"), "CONTROL 0x004 rw", "CONTROL 0x004 rx"),
                                   "STATUS.ERR_BUS 11", "STATUS.ERR_BUS 40");
  const auto layout = lode::vme::parse_layout(text, "t.regmap");
  ASSERT_FALSE(layout);
  EXPECT_NE(layout.error().find("t.regmap:3: register CONTROL"), std::string::npos) << layout.error();
  EXPECT_NE(layout.error().find("t.regmap:4: register STATUS"), std::string::npos) << layout.error();
  EXPECT_NE(layout.error().find("t.regmap:18: bit STATUS.ERR_BUS"), std::string::npos) << layout.error();
  std::string garbage;
  for (int i = 0; i < 100; ++i) garbage += "nonsense " + std::to_string(i) + "\n";
  const auto many = lode::vme::parse_layout(garbage, "g.regmap");
  ASSERT_FALSE(many);
  EXPECT_NE(many.error().find("more problems)"), std::string::npos) << many.error();
  EXPECT_LT(many.error().size(), 4000u);
}

TEST(Regmap, BinaryGarbageIsAnErrorNamingTheFile) {
  const std::string bytes("\x00\xff\x01register\x00 \x80\x80 0x\n\n\xfe window 0x", 30);
  const auto layout = lode::vme::parse_layout(bytes, "bin.regmap");
  ASSERT_FALSE(layout);
  EXPECT_EQ(layout.error().rfind("bin.regmap:", 0), 0u) << layout.error();
  EXPECT_EQ(layout.error().find('\0'), std::string::npos);  // made printable
}

TEST(Regmap, AMissingFileIsNamed) {
  const auto layout = lode::vme::load_layout("/nonexistent/board.regmap");
  ASSERT_FALSE(layout);
  EXPECT_NE(layout.error().find("/nonexistent/board.regmap: cannot read the register map"), std::string::npos)
      << layout.error();
}

}  // namespace
