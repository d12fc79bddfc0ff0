#include "estimator/per_axis.hpp"

#include <string>

namespace lode::plugins::estimator {

std::vector<double> per_axis(Params& params, std::string_view key, std::vector<double> values, std::size_t axes) {
  if (values.size() == 1 && axes > 1) values.assign(axes, values.front());
  if (values.size() != axes) {
    params.fail(key, "expected one number or " + std::to_string(axes) + " (one per measured axis), got " +
                         std::to_string(values.size()));
    values.resize(axes, values.empty() ? 0.0 : values.back());
  }
  return values;
}

}  // namespace lode::plugins::estimator
