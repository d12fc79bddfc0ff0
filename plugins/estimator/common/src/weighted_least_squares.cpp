#include "estimator/weighted_least_squares.hpp"

#include <string>

#include "lode/sdk/text.hpp"

namespace lode::plugins::estimator {

void check_channel_noise(Params& params, const std::vector<double>& noise_std_v, int channels) {
  if (noise_std_v.size() != 1 && static_cast<int>(noise_std_v.size()) != channels) {
    params.fail("noise_std_v", "needs one value or one per channel (" + std::to_string(channels) + "), got " +
                                   std::to_string(noise_std_v.size()));
  }
  for (double sigma : noise_std_v) {
    if (!(sigma > 0.0)) {
      params.fail("noise_std_v", "every channel noise std must be > 0 V, got " + number_text(sigma));
      break;
    }
  }
}

}  // namespace lode::plugins::estimator
