// The static Hall-to-distance conversion of Sensors 2016, 16, 1504 (eqs. 14-16), shared by
// sensor.hall_gap (the forward model the simulator and the estimators use) and
// estimator.hall_direct (the paper's "direct measurement").
//
// Part of the sensor family's library (lode_sensor_common), which both plugins link, so that
// they evaluate one set of equations. The evaluation (Polynomial, Conversion) is RT-safe (no
// allocation, no throw); read_conversion() runs at configure time.
//
//   d_hall(v, v_hall) = M_H(C_H(v, v_hall))                                      (eq. 14)
//   C_H = v_hall - (1.299e-6 v^2 + 9.05e-5 v + 2.544)                            (eq. 15, read
//         with a bracket: the Hall output minus its quiescent level and the
//         coil-induced part; read literally C_H would be ~5 V and eq. 16 absurd)
//   M_H(C) = -563.9 C^5 + 1351.6 C^4 - 1284.2 C^3 + 633.1 C^2 - 183.9 C + 46.9   (eq. 16, mm)
//
// M_H decreases monotonically on C_H in [0, 0.8] V (46.9 mm down to 16.29 mm, slope between
// -183.9 and -7.07 mm/V); above it falls away steeply (11.83 mm at 0.9 V), outside the
// 15-45 mm FEM range where the characteristic was fitted. C_H is clamped to [0, 0.8] V.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/params.hpp"

namespace lode::plugins::hall {

inline constexpr std::size_t kMaxCoefficients = 9;  // polynomials up to degree 8

/// A polynomial in descending powers, fixed capacity (evaluated on the RT thread).
struct Polynomial {
  std::array<double, kMaxCoefficients> c{};
  std::size_t size = 0;

  static Polynomial from(const std::vector<double>& descending) {
    Polynomial p;
    p.size = std::min(descending.size(), kMaxCoefficients);
    for (std::size_t i = 0; i < p.size; ++i) p.c[i] = descending[i];
    return p;
  }
  [[nodiscard]] std::vector<double> coefficients() const { return {c.begin(), c.begin() + static_cast<std::ptrdiff_t>(size)}; }

  /// Horner.
  [[nodiscard]] double value(double x) const noexcept {
    double r = 0.0;
    for (std::size_t i = 0; i < size; ++i) r = r * x + c[i];
    return r;
  }
  [[nodiscard]] double slope(double x) const noexcept {
    double r = 0.0;
    for (std::size_t i = 0; i + 1 < size; ++i) r = r * x + c[i] * static_cast<double>(size - 1 - i);
    return r;
  }
};

/// eq. 15 coefficients [V/V^2, V/V, V] and eq. 16 coefficients [mm/V^5 ... mm], as printed.
inline const std::vector<double> kPaperCoilPolynomial{1.299e-6, 9.05e-5, 2.544};
inline const std::vector<double> kPaperDistancePolynomial{-563.9, 1351.6, -1284.2, 633.1, -183.9, 46.9};
inline constexpr double kPaperCompensatedMinV = 0.0;
inline constexpr double kPaperCompensatedMaxV = 0.8;

struct Conversion {
  Polynomial coil_v;       ///< quiescent level + coil-induced Hall voltage vs coil voltage v (eq. 15)
  Polynomial distance_mm;  ///< M_H: distance [mm] vs compensated Hall voltage C_H [V] (eq. 16)
  double compensated_min_v = kPaperCompensatedMinV;  ///< valid C_H range, M_H decreasing on it
  double compensated_max_v = kPaperCompensatedMaxV;

  static Conversion paper() {
    Conversion c;
    c.coil_v = Polynomial::from(kPaperCoilPolynomial);
    c.distance_mm = Polynomial::from(kPaperDistancePolynomial);
    return c;
  }

  /// C_H of eq. 15 (bracketed reading), not clamped.
  [[nodiscard]] double compensated_v(double hall_v, double coil_v_applied) const noexcept {
    return hall_v - coil_v.value(coil_v_applied);
  }
  [[nodiscard]] double clamp_compensated(double c_h) const noexcept {
    return std::clamp(c_h, compensated_min_v, compensated_max_v);
  }
  /// Distance range the conversion can report [mm]: M_H(max) .. M_H(min).
  [[nodiscard]] double nearest_mm() const noexcept { return distance_mm.value(compensated_max_v); }
  [[nodiscard]] double farthest_mm() const noexcept { return distance_mm.value(compensated_min_v); }

  /// eq. 14: the direct distance [m] from the Hall voltage and the coil voltage, with C_H
  /// clamped to the valid range; `clamped` tells whether the clamp acted.
  [[nodiscard]] double direct_gap_m(double hall_v, double coil_v_applied, bool& clamped) const noexcept {
    const double c_h = compensated_v(hall_v, coil_v_applied);
    const double used = clamp_compensated(c_h);
    clamped = used != c_h;
    return 1e-3 * distance_mm.value(used);
  }

  /// Inverse of M_H on the valid range: the C_H [V] at which M_H = distance_mm, clamped to
  /// the range ends outside [nearest_mm, farthest_mm]. Safeguarded Newton (bisection when a
  /// Newton step leaves the bracket); M_H must be strictly decreasing on the range, which
  /// validate_monotonic() checks at configure time.
  [[nodiscard]] double compensated_for_distance(double distance) const noexcept {
    return compensated_for_distance(distance, nearest_mm(), farthest_mm());
  }
  /// The same with nearest_mm() and farthest_mm() given (a model that keeps them).
  [[nodiscard]] double compensated_for_distance(double distance, double nearest, double farthest) const noexcept {
    double lo = compensated_min_v;  // M_H(lo) = farthest
    double hi = compensated_max_v;  // M_H(hi) = nearest
    if (!(distance < farthest)) return lo;
    if (!(distance > nearest)) return hi;
    double c = 0.5 * (lo + hi);
    for (int iteration = 0; iteration < 100; ++iteration) {
      const double residual = distance_mm.value(c) - distance;
      if (residual > 0.0) lo = c; else hi = c;  // decreasing: too far means C_H too small
      const double slope = distance_mm.slope(c);
      double next = slope < 0.0 ? c - residual / slope : 0.5 * (lo + hi);
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      if (std::abs(next - c) <= 1e-15 || hi - lo <= 1e-15) return next;
      c = next;
    }
    return c;
  }

  /// The largest slope dM_H/dC_H over the valid range, sampled at `samples` points
  /// (negative: strictly decreasing there).
  [[nodiscard]] double max_distance_slope(int samples = 4001) const {
    double worst = -INFINITY;
    for (int k = 0; k < samples; ++k) {
      const double c = compensated_min_v + (compensated_max_v - compensated_min_v) * k / (samples - 1);
      worst = std::max(worst, distance_mm.slope(c));
    }
    return worst;
  }
};

/// The parameter keys both plugins use for the conversion (configure time):
///   coil_polynomial_v      eq. 15 in descending powers of the coil voltage [V/V^n]
///   distance_polynomial_mm eq. 16 in descending powers of C_H [mm/V^n]
///   compensated_range_v    [min, max] of C_H where eq. 16 is valid and decreasing
/// Every problem is recorded on `params`; the result is usable only if params.ok().
Conversion read_conversion(Params& params);

}  // namespace lode::plugins::hall
