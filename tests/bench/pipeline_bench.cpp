// Step cost of every operation of every shipped pipeline, and of its whole cycle.
//
//   ./build/tests/lode_pipeline_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//   ./build/tests/lode_pipeline_bench --benchmark_filter=kawato
//
// Each pipeline runs its real cycle; an operation's benchmark times only that operation
// (manual timing: PauseTiming() costs more than the cheaper blocks), the others run untimed
// so its inputs stay live.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"

namespace {

struct Loaded {
  lode::PluginRegistry registry;
  std::unique_ptr<lode::Pipeline> pipeline;
  lode::Tick tick;
  std::uint64_t cycle = 0;

  void advance() {
    tick.cycle = cycle++;
    tick.time_ns = static_cast<std::int64_t>(tick.cycle) * pipeline->period_ns();
  }
  void run_op(std::size_t i) {
    auto& op = pipeline->ops()[i];
    benchmark::DoNotOptimize(op.write_phase ? op.board->write(tick) : op.block->step(tick));
  }
};

std::vector<std::unique_ptr<Loaded>>& pipelines() {
  static std::vector<std::unique_ptr<Loaded>> all;
  return all;
}

void register_pipeline(const std::filesystem::path& file) {
  auto l = std::make_unique<Loaded>();
  lode::Diagnostics diag;
  l->pipeline = lode::Pipeline::load_file(file.string(), l->registry, diag);
  if (!l->pipeline || !l->pipeline->activate()) {
    std::fprintf(stderr, "skipping %s:\n%s", file.c_str(), diag.format().c_str());
    return;
  }
  l->tick.dt_s = 1.0 / l->pipeline->rate_hz();
  Loaded* p = l.get();
  const std::string name = file.stem().string();
  benchmark::RegisterBenchmark((name + "/whole_cycle").c_str(), [p](benchmark::State& state) {
    for (auto _ : state) {
      p->advance();
      benchmark::DoNotOptimize(p->pipeline->run_cycle(p->tick, false));
    }
  });
  const auto& ops = p->pipeline->ops();
  for (std::size_t index = 0; index < ops.size(); ++index) {
    benchmark::RegisterBenchmark((name + "/" + ops[index].label).c_str(), [p, index](benchmark::State& state) {
      const std::size_t n = p->pipeline->ops().size();
      for (auto _ : state) {
        p->advance();
        for (std::size_t i = 0; i < index; ++i) p->run_op(i);
        const auto t0 = std::chrono::steady_clock::now();
        p->run_op(index);
        const auto t1 = std::chrono::steady_clock::now();
        state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
        for (std::size_t i = index + 1; i < n; ++i) p->run_op(i);
      }
    })->UseManualTime();
  }
  pipelines().push_back(std::move(l));
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(LODE_SOURCE_DIR "/config"))
    if (e.path().extension() == ".yaml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) register_pipeline(f);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
