// The comparison report of `lode replay`: one row per estimator and configuration.
#include <cstdio>

#include "replay.hpp"

namespace lode::cli {
namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

Json num(double v) { return std::isfinite(v) ? Json(v) : Json(); }

std::string with_unit(double v, const std::string& unit) {
  if (!std::isfinite(v)) return "n/a";
  auto [scale, shown] = analysis::display_scale(unit, std::abs(v));
  return fmt("%.4g", v * scale) + " " + shown;
}

}  // namespace

ReplayReport replay_report(const std::string& recording, const std::string& pipeline, std::size_t cycles,
                           double rate_hz, const std::vector<ConfigResult>& results, bool bit_identical,
                           bool faulted) {
  std::string reference_name;
  for (const auto& cr : results)
    if (reference_name.empty()) reference_name = cr.reference;
  std::string md;
  md += "# Replay of " + recording + "\n\n";
  md += "Pipeline `" + pipeline + "`, " + std::to_string(cycles) + " cycles at " +
        fmt("%g", rate_hz) + " Hz.\n";
  {
    // hold window of the first configuration (they normally share it)
    md += "Error statistics against the reference from the start of the hold window to the end; noise std = "
          "std of the error inside the hold window (`monitor.hold_s`); NIS = sum nu_i^2 / S_ii per cycle with "
          "its two-sided 95 % chi-square interval.\n\n";
  }
  md += "| configuration | estimator | reference | bias | RMS | max abs | noise std | NIS mean (expected) | NIS in 95 % | median step |\n";
  md += "|---|---|---|---|---|---|---|---|---|---|\n";
  Json jr = Json::object();
  jr["recording"] = recording;
  jr["pipeline"] = pipeline;
  jr["cycles"] = static_cast<std::uint64_t>(cycles);
  jr["rate_hz"] = rate_hz;
  Json all = Json::array();
  Json configs = Json::array();
  for (const auto& cr : results) {
    Json cj = Json::object();
    cj["config"] = cr.label;
    cj["recorded"] = cr.recorded;
    cj["output"] = cr.output;
    cj["cycles"] = cr.cycles;
    cj["wall_s"] = cr.wall_s;
    cj["speed_vs_realtime"] = cr.speed;
    cj["output_digest"] = cr.digest;
    cj["output_digest_algorithm"] = cr.digest_algorithm;
    cj["reference"] = cr.reference.empty() ? Json() : Json(cr.reference);
    Json notes = Json::array();
    for (const auto& n : cr.notes) notes.push(n);
    cj["notes"] = std::move(notes);
    configs.push(std::move(cj));
    for (const auto& e : cr.estimators) {
      auto join = [&](auto get) {
        std::string s;
        for (const auto& el : e.elements) s += (s.empty() ? "" : ", ") + el.name + " " + with_unit(get(el), el.unit);
        return s;
      };
      const std::string nis_mean =
          e.nis_channels ? (std::isfinite(e.nis_mean) ? fmt("%.3g", e.nis_mean) : std::string("n/a")) + " (" +
                               std::to_string(e.nis_channels) + ")"
                         : "n/a";
      const std::string nis_in = e.nis_channels && std::isfinite(e.nis_in_95) ? fmt("%.1f %%", 100.0 * e.nis_in_95) : "n/a";
      md += "| " + cr.label + (cr.recorded ? " (recorded)" : "") + " | " + e.signal + " (" + e.plugin + ") | " +
            (cr.reference.empty() ? "none" : cr.reference) + " | " +
            join([](const auto& el) { return el.bias; }) + " | " + join([](const auto& el) { return el.rms; }) +
            " | " + join([](const auto& el) { return el.max_abs; }) + " | " +
            join([](const auto& el) { return el.noise_std; }) + " | " + nis_mean + " | " + nis_in + " | " +
            (std::isfinite(e.median_step_us) ? fmt("%.2f us", e.median_step_us) : std::string("n/a")) + " |\n";
      Json ej = Json::object();
      ej["config"] = cr.label;
      ej["estimator"] = e.signal;
      ej["block"] = e.block;
      ej["plugin"] = e.plugin;
      ej["role"] = e.role;
      ej["reference"] = cr.reference.empty() ? Json() : Json(cr.reference);
      Json els = Json::object();
      for (const auto& el : e.elements) {
        Json x = Json::object();
        x["unit"] = el.unit;
        x["bias"] = num(el.bias);
        x["rms"] = num(el.rms);
        x["max_abs"] = num(el.max_abs);
        x["noise_std"] = num(el.noise_std);
        els[el.name] = std::move(x);
      }
      ej["elements"] = std::move(els);
      Json nis = Json::object();
      nis["channels"] = static_cast<std::uint64_t>(e.nis_channels);
      nis["cycles"] = static_cast<std::uint64_t>(e.nis_cycles);
      nis["mean"] = num(e.nis_mean);
      nis["expected"] = e.nis_channels ? Json(static_cast<double>(e.nis_channels)) : Json();
      nis["interval_95"] = e.nis_channels ? Json(std::vector<double>{e.nis_lo, e.nis_hi}) : Json();
      nis["fraction_in_95"] = num(e.nis_in_95);
      ej["nis"] = std::move(nis);
      ej["median_step_us"] = num(e.median_step_us);
      all.push(std::move(ej));
    }
  }
  if (reference_name.empty())
    md += "\nNo reference: neither --reference nor `monitor.truth`; bias, RMS and max are not available, noise std is "
          "the estimate's own std in the hold window.\n";
  for (const auto& cr : results)
    for (const auto& n : cr.notes) md += "\nNote (" + cr.label + "): " + n + "\n";
  jr["configurations"] = std::move(configs);
  jr["estimators"] = std::move(all);
  jr["bit_identical"] = bit_identical;
  jr["faulted"] = faulted;
  return {md, std::move(jr)};
}

}  // namespace lode::cli
