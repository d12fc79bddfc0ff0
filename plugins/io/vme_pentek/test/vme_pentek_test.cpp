// io.vme_pentek against the board emulator on a shared file (the same register protocol a
// real board speaks through a UIO window): a DAC -> ADC loopback round-trips values within
// one code, the safe values reach the outputs on a fault and on deactivate, and the three
// board faults are detected within the configured timeout: the board stops
// answering, an error bit is set, a conversion never completes. Plus no allocation per cycle,
// configuration errors that name the field, and a moved register map (`register_map`) used by
// both sides.
#include "emulator.hpp"
#include "regmap.hpp"
#include "vme_pentek.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "lode/hal/analog.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace {

using lode::StepStatus;
using lode::testing::BlockHarness;
using lode::vme::PentekEmulator;

const lode::Elements kCommand = {{"fx", "N"}, {"fy", "N"}};

struct WindowFile {
  WindowFile() : path((std::filesystem::temp_directory_path() / ("lode-vme-test-" + std::to_string(getpid()))).string()) {}
  ~WindowFile() { std::remove(path.c_str()); }
  std::string path;
};

using lode::vme::Layout;
const std::string kShuffledMap = LODE_SOURCE_DIR "/plugins/io/vme_pentek/test/shuffled.regmap";

/// Two ADC channels in volts, two DAC channels in newtons (10 N/V amplifier), 0 N safe.
std::string board_params(const std::string& device, double timeout_us = 20000.0, const std::string& register_map = "") {
  return "device: " + device + "\noffset: 0x200\nconversion_timeout_us: " + std::to_string(timeout_us) +
         (register_map.empty() ? std::string() : "\nregister_map: " + register_map) +
         "\nadc:\n  - {name: a1, bits: 16, span_v: [-10, 10]}\n  - {name: b1, bits: 16, span_v: [-10, 10]}\n"
         "dac:\n  - {name: fx, bits: 16, span_v: [-10, 10], gain: 10.0, unit: N, safe_value: 0.0}\n"
         "  - {name: fy, bits: 16, span_v: [-10, 10], gain: 10.0, unit: N, safe_value: 5.0}\n";
}

/// The emulator's front end: each ADC channel converts what DAC channel i outputs (a cable
/// from each DAC output to the ADC input of the same index).
void loopback(const std::vector<std::uint32_t>& dac, std::vector<std::uint32_t>& adc) {
  for (std::size_t i = 0; i < adc.size(); ++i) adc[i] = i < dac.size() ? dac[i] : 0;
}

/// The board configured with `register_map` ("" = built-in), the emulator with `layout`.
struct Rig {
  explicit Rig(double timeout_us = 20000.0, const std::string& register_map = "",
               const Layout& layout = Layout::default_layout())
      : h("io.vme_pentek", board_params(file.path, timeout_us, register_map), 1000.0) {
    auto e = PentekEmulator::create(file.path, 0x200, layout, 4, 2, loopback);
    if (!e) {
      ADD_FAILURE() << e.error();
      return;
    }
    emulator = std::move(*e);
    emulator->start();
    h.feed("command", kCommand);
    const auto configured = h.configure();
    if (!configured) {
      ADD_FAILURE() << h.diagnostics();
      return;
    }
    const auto activated = h.activate();
    if (!activated) {
      ADD_FAILURE() << activated.message();
      return;
    }
    ok = true;
  }
  lode::plugins::VmePentekBoard& board() { return dynamic_cast<lode::plugins::VmePentekBoard&>(h.block()); }
  WindowFile file;
  std::unique_ptr<PentekEmulator> emulator;
  BlockHarness h;
  bool ok = false;
};

double code_value(std::uint32_t raw) {
  lode::hal::AnalogChannel c;
  c.name = "x";
  c.gain = 10.0;
  c.unit = "N";
  return lode::hal::AnalogConversion(c).code_to_value(raw);
}

TEST(VmePentek, LoopbackRoundTripsWithinOneCodeAndSamplesTheLastCycle) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  const double lsb_v = 20.0 / 65536.0;
  for (int k = 0; k < 200; ++k) {
    const double fx = 40.0 * std::sin(0.05 * k), fy = -12.5;
    rig.h.input("command")[0] = fx;
    rig.h.input("command")[1] = fy;
    ASSERT_EQ(rig.h.step(), StepStatus::ok) << rig.h.block().fault_reason();
    if (k > 0) {
      // The sample of cycle k converts the DAC values written at the end of cycle k-1.
      const double expected_v = 40.0 * std::sin(0.05 * (k - 1)) / 10.0;
      EXPECT_NEAR(rig.h.output("signals")[0], expected_v, 0.5 * lsb_v + 1e-12) << "cycle " << k;
      EXPECT_NEAR(rig.h.output("signals")[1], -1.25, 0.5 * lsb_v + 1e-12);
      EXPECT_EQ(rig.h.output("counts")[0], std::round(rig.h.output("signals")[0] / lsb_v));
    }
    ASSERT_EQ(rig.h.write(), StepStatus::ok) << rig.h.block().fault_reason();
  }
  EXPECT_GE(rig.emulator->conversions(), 200u);
  EXPECT_EQ(rig.board().dac_clips(), 0u);
}

TEST(VmePentek, OutOfRangeCommandsAreClippedAndCounted) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  rig.h.input("command")[0] = 250.0;  // 25 V on a +-10 V DAC
  rig.h.input("command")[1] = 0.0;
  ASSERT_EQ(rig.h.step(), StepStatus::ok);
  ASSERT_EQ(rig.h.write(), StepStatus::ok);
  ASSERT_EQ(rig.h.step(), StepStatus::ok);
  EXPECT_NEAR(rig.h.output("signals")[0], 10.0 - 20.0 / 65536.0, 1e-12);
  EXPECT_EQ(rig.board().dac_clips(), 1u);
}

/// Runs cycles until the board faults; returns the reason and the time the failing cycle took.
struct Trip {
  std::string reason;
  double detect_ms = 0.0;
};
Trip run_until_fault(Rig& rig, int max_cycles = 100) {
  for (int k = 0; k < max_cycles; ++k) {
    rig.h.input("command")[0] = 20.0;
    rig.h.input("command")[1] = 20.0;
    const auto t0 = std::chrono::steady_clock::now();
    const StepStatus s = rig.h.step();
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (s != StepStatus::ok) {
      rig.h.board().drive_safe();  // what the pipeline does on a fault
      return {rig.h.block().fault_reason(), ms};
    }
    if (rig.h.write() != StepStatus::ok) return {rig.h.block().fault_reason(), 0.0};
  }
  return {"", 0.0};
}

/// After a fault and drive_safe(), the board latches the safe codes (fx 0 N, fy 5 N).
void expect_outputs_safe(Rig& rig) {
  rig.emulator->set_fault(PentekEmulator::Fault::none);
  for (int i = 0; i < 500 && rig.emulator->latched_dac().size() == 2 &&
                  !(code_value(rig.emulator->latched_dac()[0]) == 0.0 && std::abs(code_value(rig.emulator->latched_dac()[1]) - 5.0) < 10.0 * 20.0 / 65536.0);
       ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const auto dac = rig.emulator->latched_dac();
  ASSERT_EQ(dac.size(), 2u);
  EXPECT_EQ(code_value(dac[0]), 0.0);
  EXPECT_NEAR(code_value(dac[1]), 5.0, 10.0 * 20.0 / 65536.0);
}

TEST(VmePentekFaults, ABoardThatStopsAnsweringIsDetectedWithinTheTimeoutAndOutputsGoSafe) {
  Rig rig(20000.0);  // 20 ms: generous, the emulator thread shares a loaded machine
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(run_until_fault(rig, 20).reason, "");  // healthy first
  rig.emulator->set_fault(PentekEmulator::Fault::silent);
  const Trip trip = run_until_fault(rig);
  std::printf("silent board: '%s' after %.2f ms (timeout 20 ms)\n", trip.reason.c_str(), trip.detect_ms);
  EXPECT_EQ(trip.reason, "the board did not take the trigger within conversion_timeout_us (not answering)");
  EXPECT_GE(trip.detect_ms, 20.0);
  expect_outputs_safe(rig);
}

TEST(VmePentekFaults, ASilentBoardTripsTheTriggerTimeoutWhenNoDacLoadIsPending) {
  Rig rig(20000.0);
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.h.step(), StepStatus::ok);  // a conversion, no write() after it
  rig.emulator->set_fault(PentekEmulator::Fault::silent);
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(rig.h.step(), StepStatus::fault);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("trigger not taken: '%s' after %.2f ms (timeout 20 ms)\n", rig.h.block().fault_reason(), ms);
  EXPECT_NE(std::string(rig.h.block().fault_reason()).find("did not take the trigger"), std::string::npos);
  EXPECT_GE(ms, 20.0);
  EXPECT_LT(ms, 500.0);  // loose: a shared machine may preempt the test thread
  rig.h.board().drive_safe();
  expect_outputs_safe(rig);
}

TEST(VmePentekFaults, AnErrorBitIsAFaultNamingIt) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(run_until_fault(rig, 20).reason, "");
  rig.emulator->set_fault(PentekEmulator::Fault::error_bits, Layout::default_layout().err_adc);
  const Trip trip = run_until_fault(rig);
  EXPECT_EQ(trip.reason, "board error bit: ADC fault");
  EXPECT_NE(rig.board().last_status() & Layout::default_layout().err_adc, 0u);
  expect_outputs_safe(rig);
}

TEST(VmePentekFaults, AConversionThatNeverCompletesTimesOut) {
  Rig rig(20000.0);
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(run_until_fault(rig, 20).reason, "");
  rig.emulator->set_fault(PentekEmulator::Fault::never_complete);
  const Trip trip = run_until_fault(rig);
  std::printf("never completes: '%s' after %.2f ms (timeout 20 ms)\n", trip.reason.c_str(), trip.detect_ms);
  EXPECT_EQ(trip.reason, "conversion did not complete within conversion_timeout_us (BUSY)");
  EXPECT_GE(trip.detect_ms, 20.0);
  expect_outputs_safe(rig);
}

TEST(VmePentekFaults, ABusErrorReadsAllOnes) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(run_until_fault(rig, 20).reason, "");
  rig.emulator->set_fault(PentekEmulator::Fault::no_answer);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // the emulator thread applies it
  rig.h.input("command")[0] = 0.0;
  const StepStatus s = rig.h.step();
  ASSERT_EQ(s, StepStatus::fault);
  EXPECT_NE(std::string(rig.h.block().fault_reason()).find("VME bus error"), std::string::npos)
      << rig.h.block().fault_reason();
}

TEST(VmePentek, DeactivateDrivesTheOutputsSafe) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(run_until_fault(rig, 20).reason, "");
  rig.h.deactivate();
  expect_outputs_safe(rig);
}

TEST(VmePentek, ACycleAllocatesNothing) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  LODE_REQUIRE_ALLOCATION_COUNTING();
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 500; ++k) {
    rig.h.input("command")[0] = 0.01 * k;
    ASSERT_EQ(rig.h.step(), StepStatus::ok);
    ASSERT_EQ(rig.h.write(), StepStatus::ok);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

TEST(VmePentek, ActivationRefusesAMissingWindowOrAnotherBoard) {
  WindowFile file;
  {
    BlockHarness h("io.vme_pentek", board_params(file.path), 1000.0);
    h.feed("command", kCommand);
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    const auto st = h.activate();
    ASSERT_FALSE(st);
    EXPECT_NE(st.message().find(file.path + " @ 0x200"), std::string::npos) << st.message();
  }
  ASSERT_TRUE(lode::hal::RegisterWindow::create_file(file.path, 0x200 + Layout::default_layout().window));
  {
    BlockHarness h("io.vme_pentek", board_params(file.path), 1000.0);
    h.feed("command", kCommand);
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    const auto st = h.activate();  // an all-zero window: no board id
    ASSERT_FALSE(st);
    EXPECT_NE(st.message().find("BOARD_ID 0x0 is not a Pentek-like 6102 pair"), std::string::npos) << st.message();
  }
}

TEST(VmePentekRegisterMap, DriverAndEmulatorOnAShuffledMapExchangeData) {
  const auto layout = lode::vme::load_layout(kShuffledMap);
  ASSERT_TRUE(layout) << layout.error();
  ASSERT_NE(layout->dac_data.offset, Layout::default_layout().dac_data.offset);  // the test means something
  Rig rig(20000.0, kShuffledMap, *layout);
  ASSERT_TRUE(rig.ok);
  const double lsb_v = 20.0 / 65536.0;
  for (int k = 0; k < 300; ++k) {  // more conversions than the map's 8-bit SEQUENCE counts: it wraps
    rig.h.input("command")[0] = 30.0 * std::sin(0.07 * k);
    rig.h.input("command")[1] = 7.5;
    ASSERT_EQ(rig.h.step(), StepStatus::ok) << rig.h.block().fault_reason();
    if (k > 0) {
      EXPECT_NEAR(rig.h.output("signals")[0], 3.0 * std::sin(0.07 * (k - 1)), 0.5 * lsb_v + 1e-12) << "cycle " << k;
      EXPECT_NEAR(rig.h.output("signals")[1], 0.75, 0.5 * lsb_v + 1e-12);
    }
    ASSERT_EQ(rig.h.write(), StepStatus::ok) << rig.h.block().fault_reason();
  }
  EXPECT_GE(rig.emulator->conversions(), 300u);
  // The codes are where the shuffled map puts DAC_DATA (interleaved with ADC_DATA), and the
  // default map's DAC_DATA place is outside this 0x800-byte window's data entirely.
  rig.h.step();
  auto window = lode::hal::RegisterWindow::open(rig.file.path, 0x200, layout->window);
  ASSERT_TRUE(window) << window.error();
  const auto latched = rig.emulator->latched_dac();
  ASSERT_EQ(latched.size(), 2u);
  EXPECT_EQ(window->read32(layout->dac_data.at(0)), latched[0]);
  EXPECT_EQ(window->read32(layout->dac_data.at(1)), latched[1]);
  EXPECT_NEAR(code_value(latched[1]), 7.5, 10.0 * lsb_v);
  EXPECT_EQ(window->read32(layout->board_id) & layout->board_id_mask, layout->board_id_value);
}

TEST(VmePentekRegisterMap, ADriverOnAnotherMapThanTheBoardRefusesToStart) {
  // The board (emulator) on the default map, the driver on the shuffled one: BOARD_ID is not
  // where the driver looks, so activation refuses rather than exchanging garbage.
  WindowFile file;
  // A file long enough for the shuffled map's larger window, so the mapping itself succeeds.
  ASSERT_TRUE(lode::hal::RegisterWindow::create_file(file.path, 0x200 + 0x800));
  auto e = PentekEmulator::create(file.path, 0x200, Layout::default_layout(), 4, 2, loopback);
  ASSERT_TRUE(e) << e.error();
  BlockHarness h("io.vme_pentek", board_params(file.path, 20000.0, kShuffledMap), 1000.0);
  h.feed("command", kCommand);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const auto st = h.activate();
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find("is not a Pentek-like 6102 pair"), std::string::npos) << st.message();
}

TEST(VmePentekRegisterMap, AnInvalidMapIsAConfigurationErrorNamingItsFileAndLine) {
  WindowFile file;
  const std::string map = file.path + ".regmap";
  {
    std::FILE* f = std::fopen(map.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("window 0x400\n# status moved off the end\nregister STATUS 0x402 ro\n", f);
    std::fclose(f);
  }
  BlockHarness h("io.vme_pentek", board_params(file.path, 20000.0, map), 1000.0);
  h.feed("command", kCommand);
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  EXPECT_NE(d.find("register_map: invalid register map:"), std::string::npos) << d;
  EXPECT_NE(d.find(map + ":3: register STATUS: offset 0x402 is not a multiple of 4"), std::string::npos) << d;
  EXPECT_NE(d.find(map + ":3: register TRIGGER: missing (io.vme_pentek needs it)"), std::string::npos) << d;
  std::remove(map.c_str());
  BlockHarness missing("io.vme_pentek", board_params(file.path, 20000.0, map), 1000.0);
  missing.feed("command", kCommand);
  EXPECT_FALSE(missing.configure());
  EXPECT_NE(missing.diagnostics().find(map + ": cannot read the register map"), std::string::npos)
      << missing.diagnostics();
}

TEST(VmePentekRegisterMap, MoreChannelsThanTheMapsArraysIsAConfigurationError) {
  // The shuffled map has 8 ADC_DATA registers.
  std::string params = "device: x\nregister_map: " + kShuffledMap + "\nadc:\n";
  for (int i = 0; i < 9; ++i) params += "  - {name: a" + std::to_string(i) + "}\n";
  BlockHarness h("io.vme_pentek", params, 1000.0);
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("at most 8 channels (ADC_DATA of the register map)"), std::string::npos)
      << h.diagnostics();
}

TEST(VmePentek, ConfigurationErrorsNameTheField) {
  WindowFile file;
  struct Case {
    std::string params, expect;
  };
  const std::vector<Case> cases = {
      {"device: x\nadc:\n  - {name: a1, bits: 40}\n", "bits must be within 2 ... 32, got 40"},
      {"device: x\nadc:\n  - {name: a1, span_v: [5, -5]}\n", "span_v must be [min, max] with min < max"},
      {"device: x\nadc:\n  - {name: a1}\ndac:\n  - {name: fx, safe_value: 20}\n", "safe_value 20 V (20 V) is outside"},
      {"device: x\ntrigger: sometimes\nadc:\n  - {name: a1}\n", "trigger"},
      {"device: x\nconversion_timeout_us: 0\nadc:\n  - {name: a1}\n", "conversion_timeout_us"},
  };
  for (const auto& c : cases) {
    BlockHarness h("io.vme_pentek", c.params, 1000.0);
    h.feed("command", {{"fx", "V"}});
    EXPECT_FALSE(h.configure()) << c.params;
    EXPECT_NE(h.diagnostics().find(c.expect), std::string::npos) << h.diagnostics();
  }
}

}  // namespace
