// Analog channel descriptors and code conversions (hal/include/lode/hal/analog.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "lode/hal/analog.hpp"

namespace {

using lode::hal::AnalogChannel;
using lode::hal::AnalogConversion;
using lode::hal::Coding;

AnalogChannel bipolar16(Coding coding) {
  AnalogChannel c;
  c.name = "a1";
  c.bits = 16;
  c.span_min_v = -10.0;
  c.span_max_v = 10.0;
  c.coding = coding;
  return c;
}

TEST(AnalogConversion, TwosComplementCodesOfA16BitBipolarConverter) {
  const AnalogConversion conv(bipolar16(Coding::twos_complement));
  const double lsb = 20.0 / 65536.0;
  EXPECT_DOUBLE_EQ(conv.lsb_v(), lsb);
  EXPECT_DOUBLE_EQ(conv.code_to_value(0x0000), 0.0);
  EXPECT_DOUBLE_EQ(conv.code_to_value(0x0001), lsb);
  EXPECT_DOUBLE_EQ(conv.code_to_value(0xffff), -lsb);
  EXPECT_DOUBLE_EQ(conv.code_to_value(0x8000), -10.0);
  EXPECT_DOUBLE_EQ(conv.code_to_value(0x7fff), 10.0 - lsb);
  // Bits above the field are ignored (a 16-bit code in a 32-bit register).
  EXPECT_DOUBLE_EQ(conv.code_to_value(0xabcd0001), lsb);
}

TEST(AnalogConversion, OffsetBinaryAndUnipolarCodes) {
  const AnalogConversion offset(bipolar16(Coding::offset_binary));
  EXPECT_DOUBLE_EQ(offset.code_to_value(0x0000), -10.0);
  EXPECT_DOUBLE_EQ(offset.code_to_value(0x8000), 0.0);
  EXPECT_DOUBLE_EQ(offset.code_to_value(0xffff), 10.0 - 20.0 / 65536.0);
  AnalogChannel u = bipolar16(Coding::unipolar);
  u.bits = 12;
  u.span_min_v = 0.0;
  u.span_max_v = 5.0;
  const AnalogConversion unipolar(u);
  EXPECT_DOUBLE_EQ(unipolar.code_to_value(0), 0.0);
  EXPECT_DOUBLE_EQ(unipolar.code_to_value(4095), 5.0 - 5.0 / 4096.0);
}

TEST(AnalogConversion, EveryCodeRoundTripsThroughItsValue) {
  for (const Coding coding : {Coding::twos_complement, Coding::offset_binary}) {
    AnalogChannel c = bipolar16(coding);
    c.gain = 0.25;  // e.g. a 4 V/A current sense: value in A
    c.offset = 0.01;
    c.unit = "A";
    const AnalogConversion conv(c);
    for (std::uint32_t raw = 0; raw < 65536; ++raw) {
      bool clipped = false;
      ASSERT_EQ(conv.value_to_code(conv.code_to_value(raw), clipped), raw) << lode::hal::to_string(coding) << " " << raw;
      ASSERT_FALSE(clipped);
    }
  }
}

TEST(AnalogConversion, OutOfRangeAndNonFiniteValuesAreClippedOrMadeSafe) {
  AnalogChannel c = bipolar16(Coding::twos_complement);
  c.safe_value = 0.0;
  const AnalogConversion conv(c);
  bool clipped = false;
  EXPECT_EQ(conv.value_to_code(12.0, clipped), 0x7fffu);
  EXPECT_TRUE(clipped);
  clipped = false;
  EXPECT_EQ(conv.value_to_code(-12.0, clipped), 0x8000u);
  EXPECT_TRUE(clipped);
  clipped = false;
  EXPECT_EQ(conv.value_to_code(std::numeric_limits<double>::quiet_NaN(), clipped), conv.safe_code());
  EXPECT_TRUE(clipped);
  EXPECT_EQ(conv.safe_code(), 0x0000u);
  clipped = false;
  EXPECT_EQ(conv.value_to_code(0.5 * conv.lsb_v() * 0.99, clipped), 0x0000u);  // nearest code
  EXPECT_EQ(conv.value_to_code(0.5 * conv.lsb_v() * 1.01, clipped), 0x0001u);
  EXPECT_FALSE(clipped);
}

TEST(AnalogChannel, ValidationNamesTheChannelAndTheField) {
  struct Case {
    void (*edit)(AnalogChannel&);
    const char* expect;
  };
  const Case cases[] = {
      {[](AnalogChannel& c) { c.bits = 1; }, "channel 'a1': bits must be within 2 ... 32, got 1"},
      {[](AnalogChannel& c) { c.span_max_v = -20.0; }, "channel 'a1': span_v must be [min, max] with min < max"},
      {[](AnalogChannel& c) { c.gain = 0.0; }, "channel 'a1': gain must be finite and non-zero"},
      {[](AnalogChannel& c) { c.safe_value = 11.0; }, "channel 'a1': safe_value 11 V (11 V) is outside the converter's range"},
      {[](AnalogChannel& c) { c.coding = Coding::unipolar; }, "channel 'a1': a unipolar converter spans [0, max]"},
      {[](AnalogChannel& c) { c.name.clear(); }, "channel: name must not be empty"},
  };
  EXPECT_TRUE(lode::hal::validate(bipolar16(Coding::twos_complement)));
  for (const auto& k : cases) {
    AnalogChannel c = bipolar16(Coding::twos_complement);
    k.edit(c);
    const auto st = lode::hal::validate(c);
    ASSERT_FALSE(st) << k.expect;
    EXPECT_NE(st.message().find(k.expect), std::string::npos) << st.message();
  }
}

}  // namespace
