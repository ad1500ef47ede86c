#include "superdyna/eval/statistics.h"

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double mean(std::span<const double> values) {
  return std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

/// Sum of squared deviations from `center` (the numerator of both variance definitions).
double sumSquaredDeviations(std::span<const double> values, double center) {
  double sum = 0.0;
  for (double v : values)
    sum += (v - center) * (v - center);
  return sum;
}

}  // namespace

double median(std::span<const double> values) {
  if (values.empty()) throw InputError("cannot take the median of no values");
  std::vector<double> sorted(values.begin(), values.end());
  std::sort(sorted.begin(), sorted.end());
  const std::size_t mid = sorted.size() / 2;
  if (sorted.size() % 2 == 1) return sorted[mid];
  return 0.5 * (sorted[mid - 1] + sorted[mid]);
}

ErrorStatistics computeStatistics(std::span<const double> errors) {
  if (errors.empty()) throw InputError("cannot compute error statistics of no errors");
  ErrorStatistics stats;
  stats.count = errors.size();
  const double n = static_cast<double>(errors.size());
  stats.mean = mean(errors);
  stats.std = std::sqrt(sumSquaredDeviations(errors, stats.mean) / n);
  stats.rmse = std::sqrt(sumSquaredDeviations(errors, 0.0) / n);
  stats.median = median(errors);
  const auto [lo, hi] = std::minmax_element(errors.begin(), errors.end());
  stats.min = *lo;
  stats.max = *hi;
  return stats;
}

double sampleStandardDeviation(std::span<const double> values) {
  if (values.size() < 2) return kNaN;
  const double n = static_cast<double>(values.size());
  return std::sqrt(sumSquaredDeviations(values, mean(values)) / (n - 1.0));
}

double studentTQuantile(double confidence, int degrees_of_freedom) {
  if (!(confidence > 0.0 && confidence < 1.0)) {
    throw OptionError("confidence", "must be in (0, 1)");
  }
  if (degrees_of_freedom < 1) throw OptionError("degrees_of_freedom", "must be >= 1");
  const boost::math::students_t distribution(static_cast<double>(degrees_of_freedom));
  return boost::math::quantile(distribution, 0.5 * (1.0 + confidence));
}

double confidenceHalfWidth(std::span<const double> values, double confidence) {
  if (values.size() < 2) return kNaN;
  const int dof = static_cast<int>(values.size()) - 1;
  return studentTQuantile(confidence, dof) * sampleStandardDeviation(values) /
         std::sqrt(static_cast<double>(values.size()));
}

}  // namespace superdyna::eval
