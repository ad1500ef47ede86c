#pragma once
// Summary statistics of error samples, computed the way evo and numpy do: the spread of the errors
// of one run is the population standard deviation (divide by n), while the spread of a metric over
// repeated runs is the sample standard deviation (divide by n - 1) with a Student-t interval.

#include <cstddef>
#include <span>

namespace superdyna::eval {

/// Statistics of a set of non-negative errors, all in the unit of the errors (m, deg, m/m, ...).
struct ErrorStatistics {
  double rmse = 0.0;    ///< sqrt(mean(e^2)).
  double mean = 0.0;    ///< Arithmetic mean.
  double median = 0.0;  ///< Middle value; mean of the two middle values for an even count.
  double std = 0.0;     ///< Population standard deviation (numpy.std, evo): divides by n.
  double min = 0.0;
  double max = 0.0;
  std::size_t count = 0;  ///< Number of errors.
};

/// Statistics of `errors`; throws InputError when `errors` is empty.
ErrorStatistics computeStatistics(std::span<const double> errors);

/// Median of `values` (mean of the two middle values for an even count); throws InputError when
/// empty.
double median(std::span<const double> values);

/// Sample standard deviation (divides by n - 1); NaN for fewer than two values.
double sampleStandardDeviation(std::span<const double> values);

/// Two-sided Student-t quantile t_{(1 + confidence) / 2, dof}, e.g. 2.776445105 for 0.95 and dof 4.
/// Throws OptionError unless dof >= 1 and 0 < confidence < 1.
double studentTQuantile(double confidence, int degrees_of_freedom);

/// Half-width of the two-sided confidence interval of the mean of `values`:
/// t_{(1 + confidence) / 2, n-1} * s / sqrt(n) with s the sample standard deviation.
/// NaN for fewer than two values (no spread can be estimated from one run).
double confidenceHalfWidth(std::span<const double> values, double confidence = 0.95);

}  // namespace superdyna::eval
