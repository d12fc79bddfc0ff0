#include "plant_parameters.hpp"

#include <algorithm>
#include <vector>

namespace lode::plugins::plants {

void read_numbers_into(Params& params, std::string_view key, std::span<double> values) {
  const std::vector<double> read =
      params.numbers(key, std::vector<double>(values.begin(), values.end()), values.size());
  std::copy_n(read.begin(), std::min(read.size(), values.size()), values.begin());
}

void read_initial_condition(Params& params, std::span<double> pose, std::span<double> rates) {
  read_numbers_into(params, "initial", pose);
  read_numbers_into(params, "initial_velocity", rates);
}

void describe_initial_condition(Json& out, std::span<const double> pose, std::span<const double> rates) {
  out["initial"] = std::vector<double>(pose.begin(), pose.end());
  out["initial_velocity"] = std::vector<double>(rates.begin(), rates.end());
}

void write_initial_state(std::span<const double> pose, std::span<const double> rates, double* x) noexcept {
  std::copy(pose.begin(), pose.end(), x);
  std::copy(rates.begin(), rates.end(), x + pose.size());
}

}  // namespace lode::plugins::plants
