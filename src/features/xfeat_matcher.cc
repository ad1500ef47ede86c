#include "superdyna/features/xfeat_matcher.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "superdyna/core/error.h"

namespace superdyna::features {

std::vector<FloatMatch> matchFloatMutualNN(const cv::Mat& query, const cv::Mat& train,
                                           double ratio) {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw OptionError("ratio", fmt::format("must be in (0, 1], got {}", ratio));
  }
  if (query.empty() || train.empty()) return {};
  if (query.type() != CV_32FC1 || train.type() != CV_32FC1 || query.cols != train.cols) {
    throw InputError(
        fmt::format("float matching needs CV_32FC1 descriptors of equal length, got "
                    "{} columns of type {} and {} of type {}",
                    query.cols, query.type(), train.cols, train.type()));
  }
  // Squared distances |q|^2 + |t|^2 - 2 q.t, all pairs at once.
  cv::Mat dot;
  cv::gemm(query, train, 1.0, cv::noArray(), 0.0, dot, cv::GEMM_2_T);
  cv::Mat q2, t2;
  cv::reduce(query.mul(query), q2, 1, cv::REDUCE_SUM);
  cv::reduce(train.mul(train), t2, 1, cv::REDUCE_SUM);
  const int nq = query.rows, nt = train.rows;
  cv::Mat d2(nq, nt, CV_32FC1);
  for (int i = 0; i < nq; ++i) {
    const float* row = dot.ptr<float>(i);
    float* out = d2.ptr<float>(i);
    for (int j = 0; j < nt; ++j) {
      out[j] = std::max(0.0f, q2.at<float>(i) + t2.at<float>(j) - 2.0f * row[j]);
    }
  }

  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::vector<int> best_query_of_train(static_cast<std::size_t>(nt), -1);
  std::vector<float> best_d2_of_train(static_cast<std::size_t>(nt), kInf);
  for (int i = 0; i < nq; ++i) {
    const float* row = d2.ptr<float>(i);
    for (int j = 0; j < nt; ++j) {
      if (row[j] < best_d2_of_train[static_cast<std::size_t>(j)]) {
        best_d2_of_train[static_cast<std::size_t>(j)] = row[j];
        best_query_of_train[static_cast<std::size_t>(j)] = i;
      }
    }
  }
  const double ratio2 = ratio * ratio;
  std::vector<FloatMatch> matches;
  for (int i = 0; i < nq; ++i) {
    const float* row = d2.ptr<float>(i);
    int best = -1;
    float best_d2 = kInf, second_d2 = kInf;
    for (int j = 0; j < nt; ++j) {
      if (row[j] < best_d2) {
        second_d2 = best_d2;
        best_d2 = row[j];
        best = j;
      } else if (row[j] < second_d2) {
        second_d2 = row[j];
      }
    }
    if (best < 0 || best_query_of_train[static_cast<std::size_t>(best)] != i) continue;
    if (ratio < 1.0 && !(best_d2 < ratio2 * second_d2)) continue;
    matches.push_back({i, best, std::sqrt(best_d2)});
  }
  return matches;
}

std::vector<FloatMatch> matchFloatMutualNN(const FeatureSet& query, const FeatureSet& train,
                                           double ratio) {
  if (query.descriptor_type != DescriptorType::kFloat ||
      train.descriptor_type != DescriptorType::kFloat) {
    throw InputError(fmt::format("float matching needs float descriptors, got {} and {}",
                                 toString(query.descriptor_type), toString(train.descriptor_type)));
  }
  return matchFloatMutualNN(query.descriptors, train.descriptors, ratio);
}

}  // namespace superdyna::features
