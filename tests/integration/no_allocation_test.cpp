// The real-time contract, measured: no heap allocation in any step() of any shipped
// pipeline over 1e5 cycles. Every malloc-family call in the process is counted while the
// cycles run (operator new ends in malloc, Eigen's aligned allocation too), including
// calls made from the dlopen'ed plugins.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/control.hpp"
#include "lode/scheduler.hpp"
#include "lode/telemetry.hpp"
#include "lode/testing/allocation_counter.hpp"

namespace {

using lode::testing::allocation_count;

/// Keeps the compiler from eliding an allocation it can see is unused.
void escape(void* p) { asm volatile("" : : "g"(p) : "memory"); }

TEST(AllocationCounter, SeesAllocations) {
  // Guards the guard: the counter must see an ordinary allocation, or the test below
  // proves nothing.
  if (!lode::testing::allocation_counting_available())
    GTEST_SKIP() << "allocations are not counted in sanitizer builds";
  const auto before = allocation_count();
  auto* v = new std::vector<double>(100);
  escape(v);
  escape(v->data());
  const auto seen = allocation_count() - before;
  delete v;
  EXPECT_GE(seen, 2u);
  // Eigen's aligned heap buffers go through the malloc family, not operator new.
  const auto before_malloc = allocation_count();
  void* raw = std::malloc(64);
  escape(raw);
  EXPECT_EQ(allocation_count() - before_malloc, 1u);
  std::free(raw);
}

std::vector<std::string> shipped_pipelines() {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(LODE_SOURCE_DIR "/config"))
    if (e.path().extension() == ".yaml") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

class NoAllocation : public ::testing::TestWithParam<std::string> {};

TEST_P(NoAllocation, HundredThousandCyclesAllocateNothing) {
  {
    std::ifstream in(GetParam());
    std::stringstream buffer;
    buffer << in.rdbuf();
    const std::string text = buffer.str();
    if (text.find("plugin: io.vme_pentek") != std::string::npos)
      GTEST_SKIP() << "needs the board or lode-vme-emu: vme_closed_loop_test runs it, and io.vme_pentek's "
                      "own test checks that its cycle allocates nothing";
    if (text.find("plugin: io.socketcan_daq") != std::string::npos)
      GTEST_SKIP() << "needs a CAN interface and the module (can_qemu_test runs it), and io.socketcan_daq's "
                      "own test checks that its cycle allocates nothing";
  }
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_file(GetParam(), registry, diag);
  ASSERT_TRUE(p) << diag.format();
  ASSERT_TRUE(p->activate());
  // The tap the runner uses is part of the RT path too.
  std::vector<lode::SignalRef> signals = p->signals();
  lode::SignalTap tap(signals, 1024);
  std::vector<double> drained;
  drained.reserve(1024 * tap.stride());
  // So is the telemetry side: every output published at full rate (rings that fill up drop
  // and count, which must not allocate either), and the command mailbox checked each cycle.
  lode::TelemetrySpec spec = p->telemetry();
  spec.signals.clear();
  for (const auto& s : signals) spec.signals.push_back({s, 1, ""});
  spec.ring_records = 4096;
  lode::TelemetryTap telemetry(spec, p->rate_hz());
  lode::EventLog events;
  lode::ControlService control(*p, events);
  control.set_running(true);
  lode::Tick tick;
  tick.dt_s = 1.0 / p->rate_hz();
  std::size_t allocations = 0;
  std::uint64_t faults = 0;
  for (std::uint64_t k = 0; k < 100000; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    const auto before = allocation_count();
    control.before_cycle(tick);
    if (p->run_cycle(tick, true).status != lode::StepStatus::ok) ++faults;
    tap.capture(k, tick.time_ns);
    telemetry.after_cycle(tick);
    allocations += allocation_count() - before;
    if ((k & 511) == 511) {  // draining is the consumer's (non-RT) side: not counted
      drained.clear();
      tap.drain(drained);
      if ((k >> 14) % 2 == 0)  // half of the time nobody drains: the rings fill and drop
        for (auto& c : telemetry.channels()) {
          lode::SampleHeader h;
          while (c.ring->front(h)) c.ring->pop();
        }
    }
  }
  EXPECT_EQ(faults, 0u);
  EXPECT_EQ(allocations, 0u) << GetParam() << ": step() allocated";
  EXPECT_GT(telemetry.dropped(), 0u) << "the drop path of the telemetry rings was not exercised";
  p->deactivate();
}

INSTANTIATE_TEST_SUITE_P(ShippedPipelines, NoAllocation, ::testing::ValuesIn(shipped_pipelines()),
                         [](const auto& case_info) {
                           return std::filesystem::path(case_info.param).stem().string();
                         });

}  // namespace
