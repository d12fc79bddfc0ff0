// The parameters of a ModelEstimator (estimator.ekf, estimator.ukf) on the Sensors 2016
// suspension, as their tests run it: the process model `plant` (plant.suspension), a
// measurement model and noise given by the test, x_0 = [26.5 mm, 0 m/s, the current that
// holds the benchmark's first gap] and P_0 = diag(1e-6, 1e-4, 1e-2).
#pragma once

#include <string>

#include "estimator/testing/yaml_numbers.hpp"

namespace lode::estimator_testing {

/// The gap measured through sensor.hall_gap (model `hall_distance`) with the benchmark's
/// noise: q per second (an intensity), r = 1.2e-7 m^2 (0.35 mm).
inline constexpr const char* kHallDistanceNoise =
    "measurement: hall_distance\nq: [5.6e-8, 1.7e-8, 7.71e-3]\nprocess_noise: per_second\nr: 1.2e-7\n";

/// `measurement_and_noise`: the YAML lines between process and initial_state (measurement,
/// q, process_noise, r), each ending in a newline.
inline std::string suspension_estimator(const std::string& measurement_and_noise, double initial_current,
                                        const std::string& process = "plant") {
  return "process: " + process + "\n" + measurement_and_noise + "initial_state: [0.0265, 0.0, " +
         exact(initial_current) + "]\np0: [1e-6, 1e-4, 1e-2]\n";
}

}  // namespace lode::estimator_testing
