#include "estimator/per_axis.hpp"

#include <utility>

namespace lode::plugins::estimator {

std::vector<double> per_axis(Params& params, std::string_view key, std::vector<double> values, std::size_t axes) {
  return params.one_or_each(key, std::move(values), axes, "measured axis");
}

}  // namespace lode::plugins::estimator
