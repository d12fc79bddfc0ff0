#include "hall_polynomial.hpp"

#include <cmath>
#include <string>
#include <vector>

#include "lode/sdk/text.hpp"

namespace lode::plugins::hall {

Conversion read_conversion(Params& params) {
  Conversion c = Conversion::paper();
  const std::vector<double> coil = params.numbers("coil_polynomial_v", kPaperCoilPolynomial);
  const std::vector<double> distance = params.numbers("distance_polynomial_mm", kPaperDistancePolynomial);
  const std::vector<double> range =
      params.numbers("compensated_range_v", {kPaperCompensatedMinV, kPaperCompensatedMaxV}, 2);
  if (coil.empty() || coil.size() > kMaxCoefficients) {
    params.fail("coil_polynomial_v", "expected 1 to " + std::to_string(kMaxCoefficients) +
                                         " coefficients (descending powers of the coil voltage), got " +
                                         std::to_string(coil.size()));
  }
  if (distance.size() < 2 || distance.size() > kMaxCoefficients) {
    params.fail("distance_polynomial_mm", "expected 2 to " + std::to_string(kMaxCoefficients) +
                                              " coefficients (descending powers of C_H), got " +
                                              std::to_string(distance.size()));
  }
  for (double v : coil) {
    if (!std::isfinite(v)) params.fail("coil_polynomial_v", "coefficients must be finite");
  }
  for (double v : distance) {
    if (!std::isfinite(v)) params.fail("distance_polynomial_mm", "coefficients must be finite");
  }
  if (range.size() == 2 && !(range[0] < range[1])) {
    params.fail("compensated_range_v", "expected [min, max] with min < max, got [" + number_text(range[0]) +
                                           ", " + number_text(range[1]) + "]");
  }
  if (!params.ok()) return c;
  c.coil_v = Polynomial::from(coil);
  c.distance_mm = Polynomial::from(distance);
  c.compensated_min_v = range[0];
  c.compensated_max_v = range[1];
  // The conversion and its inverse need a one-to-one M_H: decreasing over the whole range.
  const double worst_slope = c.max_distance_slope();
  if (!(worst_slope < 0.0)) {
    params.fail("distance_polynomial_mm",
                "M_H must decrease strictly over compensated_range_v [" + number_text(range[0]) + ", " +
                    number_text(range[1]) + "] V (eq. 16 does on [0, 0.8] V); its largest slope there is " +
                    number_text(worst_slope) + " mm/V: narrow the range");
  }
  return c;
}

}  // namespace lode::plugins::hall
