// Parameter shapes the plant plugins read, describe and start from in the same way.
//
// A plant whose state is a pose followed by its rates (plant.planar_stage, plant.maglev6,
// plant.rigid_body6) starts from the YAML keys `initial` (the pose) and `initial_velocity`
// (the rates), each a list of exactly as many numbers as the pose has, zero when absent.
//
// Threads: the readers and describe_initial_condition() on the loader thread;
// write_initial_state() is RT-safe (reset() calls it).
#pragma once

#include <span>
#include <string_view>

#include "lode/sdk/json.hpp"
#include "lode/sdk/params.hpp"

namespace lode::plugins::plants {

/// Reads `key` as a list of exactly values.size() numbers into `values`; when the key is
/// absent `values` keeps what it holds (the default). A wrong length is reported on the key.
void read_numbers_into(Params& params, std::string_view key, std::span<double> values);

/// `initial` into pose and `initial_velocity` into rates (same length), defaults kept.
void read_initial_condition(Params& params, std::span<double> pose, std::span<double> rates);

/// describe(): `initial` and `initial_velocity` as lists.
void describe_initial_condition(Json& out, std::span<const double> pose, std::span<const double> rates);

/// The state a reset() starts from: x = [pose, rates].
void write_initial_state(std::span<const double> pose, std::span<const double> rates, double* x) noexcept;

}  // namespace lode::plugins::plants
