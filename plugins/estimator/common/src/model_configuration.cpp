#include "estimator/model_configuration.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "estimator/element_names.hpp"
#include "lode/sdk/text.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins::nonlinear {

using estimator::element_list;

bool pick_elements(const Elements& wanted, const Elements& source, std::vector<std::size_t>& index,
                   std::string& why) {
  index.clear();
  bool all_named = true;
  for (const Element& w : wanted) {
    const auto it = std::find_if(source.begin(), source.end(), [&](const Element& s) { return s.name == w.name; });
    if (it == source.end()) {
      all_named = false;
      break;
    }
    if (!units_compatible(it->unit, w.unit)) {
      why = "element '" + w.name + "' is in " + it->unit + ", expected " + w.unit;
      return false;
    }
    index.push_back(static_cast<std::size_t>(it - source.begin()));
  }
  if (all_named) return true;
  index.clear();
  if (source.size() != wanted.size()) {
    why = "needs " + element_list(wanted) + " (by name, or the same number of elements by position); the source has " +
          element_list(source);
    return false;
  }
  for (std::size_t i = 0; i < wanted.size(); ++i) {
    if (!units_compatible(source[i].unit, wanted[i].unit)) {
      why = "element " + std::to_string(i) + " ('" + source[i].name + "') is in " + source[i].unit + ", expected " +
            wanted[i].unit + " for '" + wanted[i].name + "'";
      return false;
    }
    index.push_back(i);
  }
  return true;
}

Eigen::MatrixXd covariance_from(Params& params, std::string_view key, const std::vector<double>& values,
                                std::size_t n, bool semidefinite) {
  Eigen::MatrixXd c = Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  const auto N = static_cast<Eigen::Index>(n);
  if (values.size() == 1) {
    c *= values[0];
  } else if (values.size() == n) {
    for (Eigen::Index i = 0; i < N; ++i) c(i, i) = values[static_cast<std::size_t>(i)];
  } else if (values.size() == n * n) {
    for (Eigen::Index i = 0; i < N; ++i)
      for (Eigen::Index j = 0; j < N; ++j) c(i, j) = values[static_cast<std::size_t>(i * N + j)];
  } else {
    params.fail(key, "expected 1, " + std::to_string(n) + " (diagonal) or " + std::to_string(n * n) +
                         " (row-major) numbers, got " + std::to_string(values.size()));
    return c;
  }
  if (!c.allFinite()) {
    params.fail(key, "must be finite");
    return c;
  }
  // Plain loops: Eigen's reductions on dynamic vectors trip g++ 12's -Wnull-dereference at -O2.
  double scale = std::numeric_limits<double>::min();
  double asymmetry = 0.0;
  for (Eigen::Index i = 0; i < N; ++i) {
    for (Eigen::Index j = 0; j < N; ++j) {
      scale = std::max(scale, std::abs(c(i, j)));
      asymmetry = std::max(asymmetry, std::abs(c(i, j) - c(j, i)));
    }
  }
  if (asymmetry > 1e-12 * scale) {
    params.fail(key, "must be symmetric");
    return c;
  }
  const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(c, Eigen::EigenvaluesOnly).eigenvalues();
  double smallest = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < eig.size(); ++i) smallest = std::min(smallest, eig(i));
  if (semidefinite ? smallest < -1e-12 * scale : !(smallest > 0.0)) {
    params.fail(key, std::string("must be positive ") + (semidefinite ? "semidefinite" : "definite") +
                         ", its smallest eigenvalue is " + number_text(smallest));
  }
  return c;
}

}  // namespace lode::plugins::nonlinear
