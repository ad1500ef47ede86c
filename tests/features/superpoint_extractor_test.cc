#include "superdyna/features/superpoint_extractor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <opencv2/imgproc.hpp>

#include "learned_test_image.h"
#include "superdyna/core/error.h"
#include "superdyna/features/stereo_matcher.h"
#include "superdyna/features/xfeat_matcher.h"
#include "superdyna/inference/model_files.h"
#include "superdyna/io/euroc_dataset.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

namespace fs = std::filesystem;
using test::expectError;

constexpr const char* kPython = "/usr/bin/python3";

/// Runs scripts/make_superpoint_from_xfeat.py with `arguments`; false when Debian's python3-onnx
/// is missing (the caller skips).
bool havePythonOnnx() {
  return std::system((std::string(kPython) + " -c 'import onnx' >/dev/null 2>&1").c_str()) == 0;
}

void makeModel(const std::string& arguments) {
  const std::string command = std::string(kPython) + " " + SUPERDYNA_SOURCE_DIR +
                              "/scripts/make_superpoint_from_xfeat.py " + arguments + " >/dev/null";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
}

#define SUPERDYNA_REQUIRE_PYTHON_ONNX()                                                      \
  if (!havePythonOnnx()) {                                                                   \
    GTEST_SKIP() << "Debian's python3-onnx is not installed (apt-get install python3-onnx)"; \
  }

using test::syntheticImage;

// ------------------------------------------------------------------------------------------------
// A plain reference of SuperPoint's decoding, written out step by step from the description in
// superpoint_extractor.h and MagicLeap's demo, independent of keypoint_decoding.cc.

struct ReferenceOptions {
  float threshold = 0.015f;
  int nms_radius = 4;
  int border = 4;
  int top_k = 1200;
  int grid = 0;
};

struct ReferenceKeypoint {
  int x = 0, y = 0;
  float score = 0.0f;
  std::vector<float> descriptor;
};

std::vector<ReferenceKeypoint> referenceDecode(const cv::Mat& gray, inference::OnnxModel& model,
                                               const ReferenceOptions& options) {
  // Pad right and bottom to multiples of 8 by reflection, scale to [0, 1].
  const int W = (gray.cols + 7) / 8 * 8, H = (gray.rows + 7) / 8 * 8;
  cv::Mat padded;
  cv::copyMakeBorder(gray, padded, 0, H - gray.rows, 0, W - gray.cols, cv::BORDER_REFLECT_101);
  std::vector<float> input(static_cast<std::size_t>(W * H));
  for (int y = 0; y < H; ++y) {
    for (int x = 0; x < W; ++x)
      input[y * W + x] = padded.at<std::uint8_t>(y, x) / 255.0f;
  }
  const auto out = model.run({{input.data(), {1, 1, H, W}}});
  const auto& semi = out[0];
  const auto& desc = out[1];
  const int Hc = H / 8, Wc = W / 8, D = static_cast<int>(desc.dim(1));
  auto semi_at = [&](int c, int i, int j) { return semi.data[(c * Hc + i) * Wc + j]; };
  auto desc_at = [&](int c, int i, int j) { return desc.data[(c * Hc + i) * Wc + j]; };

  // Softmax over the 65 channels of each cell (float, max subtracted); channel k of cell (i, j)
  // is pixel (8 j + k % 8, 8 i + k / 8); the dustbin (k = 64) is dropped.
  std::vector<float> heat(static_cast<std::size_t>(W * H));
  for (int i = 0; i < Hc; ++i) {
    for (int j = 0; j < Wc; ++j) {
      float m = semi_at(0, i, j);
      for (int k = 1; k < 65; ++k)
        m = std::max(m, semi_at(k, i, j));
      float e[65];
      float sum = 0.0f;
      for (int k = 0; k < 65; ++k) {
        e[k] = std::exp(semi_at(k, i, j) - m);
        sum += e[k];
      }
      for (int k = 0; k < 64; ++k)
        heat[(8 * i + k / 8) * W + 8 * j + k % 8] = e[k] / sum;
    }
  }
  // Candidates: heat >= threshold inside the original image.
  std::vector<ReferenceKeypoint> candidates;
  for (int y = 0; y < gray.rows; ++y) {
    for (int x = 0; x < gray.cols; ++x) {
      if (heat[y * W + x] >= options.threshold) candidates.push_back({x, y, heat[y * W + x], {}});
    }
  }
  auto by_score = [](const ReferenceKeypoint& a, const ReferenceKeypoint& b) {
    if (a.score != b.score) return a.score > b.score;
    return a.y != b.y ? a.y < b.y : a.x < b.x;
  };
  std::sort(candidates.begin(), candidates.end(), by_score);
  // MagicLeap's NMS: a grid holding 1 at every candidate; in score order, a candidate still
  // marked 1 is kept (-1) and zeroes its (2r+1)^2 square.
  const int r = options.nms_radius;
  std::vector<int> grid(static_cast<std::size_t>((W + 2 * r) * (H + 2 * r)), 0);
  auto cell = [&](int x, int y) -> int& { return grid[(y + r) * (W + 2 * r) + x + r]; };
  for (const auto& c : candidates)
    cell(c.x, c.y) = 1;
  std::vector<ReferenceKeypoint> kept;
  for (const auto& c : candidates) {
    if (cell(c.x, c.y) != 1) continue;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx)
        cell(c.x + dx, c.y + dy) = 0;
    }
    cell(c.x, c.y) = -1;
    kept.push_back(c);
  }
  // Border removal.
  std::vector<ReferenceKeypoint> inside;
  for (const auto& k : kept) {
    const int b = options.border;
    if (k.x >= b && k.x < gray.cols - b && k.y >= b && k.y < gray.rows - b) inside.push_back(k);
  }
  // Top-K, optionally by rank within grid cells first.
  if (static_cast<int>(inside.size()) > options.top_k) {
    if (options.grid > 0) {
      std::map<std::pair<int, int>, int> seen;
      std::vector<std::pair<int, ReferenceKeypoint>> ranked;
      for (const auto& k : inside) {
        ranked.push_back({seen[{k.x / options.grid, k.y / options.grid}]++, k});
      }
      std::sort(ranked.begin(), ranked.end(), [&](const auto& a, const auto& b) {
        return a.first != b.first ? a.first < b.first : by_score(a.second, b.second);
      });
      inside.clear();
      for (int i = 0; i < options.top_k; ++i)
        inside.push_back(ranked[i].second);
      std::sort(inside.begin(), inside.end(), by_score);
    } else {
      inside.resize(static_cast<std::size_t>(options.top_k));
    }
  }
  // Descriptors: bilinear at u = (x + 0.5) / 8 - 0.5 (clamped to the map), unit length.
  for (auto& k : inside) {
    const double u = std::clamp((k.x + 0.5) / 8.0 - 0.5, 0.0, Wc - 1.0);
    const double v = std::clamp((k.y + 0.5) / 8.0 - 0.5, 0.0, Hc - 1.0);
    const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
    const int u1 = std::min(u0 + 1, Wc - 1), v1 = std::min(v0 + 1, Hc - 1);
    const double a = u - u0, b = v - v0;
    double norm = 0.0;
    std::vector<double> d(static_cast<std::size_t>(D));
    for (int c = 0; c < D; ++c) {
      d[c] = (1 - a) * (1 - b) * desc_at(c, v0, u0) + a * (1 - b) * desc_at(c, v0, u1) +
             (1 - a) * b * desc_at(c, v1, u0) + a * b * desc_at(c, v1, u1);
      norm += d[c] * d[c];
    }
    for (int c = 0; c < D; ++c)
      k.descriptor.push_back(static_cast<float>(d[c] / std::sqrt(norm)));
  }
  return inside;
}

/// Expects the extractor's output to equal the reference: same keypoints in the same order,
/// same scores, descriptors within 1e-5.
void expectSameAsReference(const FeatureSet& features,
                           const std::vector<ReferenceKeypoint>& reference) {
  ASSERT_EQ(features.size(), reference.size());
  ASSERT_EQ(features.descriptors.rows, static_cast<int>(reference.size()));
  double worst = 0.0;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    const Keypoint& kp = features.keypoints[i];
    ASSERT_EQ(kp.pixel, Eigen::Vector2d(reference[i].x, reference[i].y)) << "keypoint " << i;
    ASSERT_EQ(kp.response, reference[i].score) << "keypoint " << i;
    ASSERT_EQ(features.descriptors.cols, static_cast<int>(reference[i].descriptor.size()));
    for (int c = 0; c < features.descriptors.cols; ++c) {
      worst = std::max(worst, static_cast<double>(
                                  std::abs(features.descriptors.at<float>(static_cast<int>(i), c) -
                                           reference[i].descriptor[static_cast<std::size_t>(c)])));
    }
  }
  EXPECT_LE(worst, 1e-5);
}

TEST(SuperPointExtractorTest, DecodingOfARandomWeightModelEqualsAPlainReference) {
  SUPERDYNA_REQUIRE_PYTHON_ONNX();
  test::ScratchDir dir("superpoint_random");
  makeModel("random --seed 3 --descriptor-size 256 --out " + (dir / "sp_random.onnx").string());
  SuperPointOptions options;
  options.model = (dir / "sp_random.onnx").string();
  inference::OnnxModel raw(options.model, SuperPointExtractor::signature(options));

  struct Case {
    const char* what;
    cv::Size size;
    ReferenceOptions reference;
  };
  const std::vector<Case> cases = {
      {"320x240, every keypoint", {320, 240}, {0.015f, 4, 4, 1000000, 0}},
      {"320x240, top 800", {320, 240}, {0.015f, 4, 4, 800, 0}},
      {"320x240, top 300 spread over 32 px cells", {320, 240}, {0.015f, 4, 4, 300, 32}},
      {"300x229 (padded to 304x232), top 500, radius 2, border 6",
       {300, 229},
       {0.015f, 2, 6, 500, 0}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const cv::Mat image = syntheticImage(c.size.width, c.size.height, 11);
    options.confidence_threshold = c.reference.threshold;
    options.nms_radius = c.reference.nms_radius;
    options.border = c.reference.border;
    options.max_keypoints = c.reference.top_k;
    options.grid_cell_px = c.reference.grid;
    SuperPointExtractor extractor(options);
    const FeatureSet features = extractor.extract(image);
    features.validate();
    const auto reference = referenceDecode(image, raw, c.reference);
    std::cout << c.what << ": " << features.size() << " keypoints, descriptors "
              << features.descriptorLength() << "-d\n";
    EXPECT_GT(features.size(), 100u);
    expectSameAsReference(features, reference);
  }
}

TEST(SuperPointExtractorTest, WrongOutputNamesAndOptionsAreRejected) {
  SUPERDYNA_REQUIRE_PYTHON_ONNX();
  test::ScratchDir dir("superpoint_contract");
  makeModel("random --seed 1 --descriptor-size 32 --out " + (dir / "sp.onnx").string());
  SuperPointOptions options;
  options.model = (dir / "sp.onnx").string();
  options.scores_output = "scores";
  expectError([&] { SuperPointExtractor{options}; },
              {"sp.onnx", "does not fit the SuperPoint contract", "output 'scores' missing",
               "'semi' [batch, 65, cells_y, cells_x]"});
  options.scores_output = "semi";
  options.size_multiple = 12;
  expectError<OptionError>([&] { SuperPointExtractor{options}; }, {"size_multiple"});
  options.size_multiple = 8;
  SuperPointExtractor extractor(options);
  EXPECT_EQ(extractor.sizeMultiple(), 8);
  EXPECT_EQ(extractor.extract(syntheticImage(64, 48, 2)).descriptorLength(), 32);
  expectError([&] { extractor.extract(cv::Mat(8, 8, CV_16UC1, cv::Scalar(0))); }, {"CV_8UC1"});
}

TEST(SuperPointExtractorTest, AModelOfAnotherContractIsRejectedWithAClearMessage) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  SuperPointOptions options;
  options.model = xfeat.string();
  expectError([&] { SuperPointExtractor{options}; },
              {"xfeat.onnx", "does not fit the SuperPoint contract", "output 'semi' missing"});
}

TEST(SuperPointExtractorTest, SuperPointOptimizedTakesTheGrayImageInItsThreeColourChannels) {
  SUPERDYNA_REQUIRE_SHARED(model, "models/superpoint_optimized.onnx");
  SuperPointOptions options;
  options.model = model.string();
  SuperPointExtractor extractor(options);
  EXPECT_EQ(extractor.inputChannels(), 3);
  // The same texture shifted by (16, 8) px: the keypoints must move with it.
  const cv::Mat big = syntheticImage(400, 320, 7);
  const cv::Mat a = big(cv::Rect(16, 8, 352, 288)).clone();
  const cv::Mat b = big(cv::Rect(0, 0, 352, 288)).clone();
  const FeatureSet fa = extractor.extract(a), fb = extractor.extract(b);
  fa.validate();
  ASSERT_GT(fa.size(), 200u);
  EXPECT_EQ(fa.descriptorLength(), 256);
  for (int i = 0; i < fa.descriptors.rows; ++i)
    ASSERT_NEAR(cv::norm(fa.descriptors.row(i)), 1.0, 1e-4);
  std::size_t repeated = 0, inside = 0;
  for (const Keypoint& k : fa.keypoints) {
    const Eigen::Vector2d expected = k.pixel + Eigen::Vector2d(16.0, 8.0);
    if (expected.x() < 12 || expected.y() < 12 || expected.x() > 340 || expected.y() > 276)
      continue;
    ++inside;
    repeated += std::any_of(fb.keypoints.begin(), fb.keypoints.end(),
                            [&](const Keypoint& o) { return (o.pixel - expected).norm() <= 1.5; });
  }
  std::cout << "superpoint_optimized: " << fa.size() << " keypoints, " << repeated << " of "
            << inside << " found again 1.5 px from their shifted position\n";
  EXPECT_GT(static_cast<double>(repeated), 0.6 * static_cast<double>(inside));
}

TEST(SuperPointExtractorTest, ModelComposedFromXFeatKeepsXFeatsOutputs) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  SUPERDYNA_REQUIRE_PYTHON_ONNX();
  test::ScratchDir dir("superpoint_xfeat");
  const fs::path composed = dir / "superpoint_xfeat.onnx";
  makeModel("from-xfeat --xfeat " + xfeat.string() + " --out " + composed.string());

  SuperPointOptions options;
  options.model = composed.string();
  inference::OnnxModel as_superpoint(composed, SuperPointExtractor::signature(options));
  EXPECT_EQ(as_superpoint.metadata(SuperPointExtractor::kSizeMultipleKey), "32");
  inference::ModelSignature xfeat_signature;
  xfeat_signature.inputs = {
      {"",
       {inference::DimSpec::dynamic(), inference::DimSpec::fixed(3),
        inference::DimSpec::multipleOf(32), inference::DimSpec::multipleOf(32)}}};
  xfeat_signature.outputs = {{"keypoint_logits", std::vector<inference::DimSpec>(4)},
                             {"descriptors", std::vector<inference::DimSpec>(4)}};
  inference::OnnxModel original(xfeat, xfeat_signature);

  const cv::Mat image = syntheticImage(96, 64, 5);
  std::vector<float> gray(96 * 64), rgb;
  for (int i = 0; i < 96 * 64; ++i)
    gray[static_cast<std::size_t>(i)] = image.data[i] / 255.0f;
  for (int c = 0; c < 3; ++c)
    rgb.insert(rgb.end(), gray.begin(), gray.end());
  const auto sp = as_superpoint.run({{gray.data(), {1, 1, 64, 96}}});
  const auto xf = original.run({{rgb.data(), {1, 3, 64, 96}}});
  ASSERT_EQ(sp[0].shape, xf[0].shape);
  double semi_diff = 0.0, desc_diff = 0.0;
  for (std::size_t i = 0; i < sp[0].data.size(); ++i) {
    semi_diff = std::max(semi_diff, static_cast<double>(std::abs(sp[0].data[i] - xf[0].data[i])));
  }
  // desc = descriptors normalised per cell.
  const int cells = 8 * 12;
  for (int p = 0; p < cells; ++p) {
    double norm = 0.0;
    for (int c = 0; c < 64; ++c)
      norm += std::pow(xf[1].data[c * cells + p], 2);
    for (int c = 0; c < 64; ++c) {
      desc_diff = std::max(desc_diff, std::abs(sp[1].data[c * cells + p] -
                                               xf[1].data[c * cells + p] / std::sqrt(norm)));
    }
  }
  EXPECT_LE(semi_diff, 1e-5);
  EXPECT_LE(desc_diff, 1e-5);

  // The extractor reads the metadata and pads to 32 itself.
  SuperPointExtractor extractor(options);
  EXPECT_EQ(extractor.sizeMultiple(), 32);
  const FeatureSet features = extractor.extract(syntheticImage(40, 40, 6));
  EXPECT_EQ(features.descriptorLength(), 64);
}

TEST(SuperPointExtractorTest, ComposedModelOnEurocStereoAndTiming) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  SUPERDYNA_REQUIRE_SHARED(root, "data/euroc/V1_01_easy_micro");
  SUPERDYNA_REQUIRE_PYTHON_ONNX();
  test::ScratchDir dir("superpoint_xfeat_euroc");
  makeModel("from-xfeat --xfeat " + xfeat.string() + " --out " +
            (dir / "superpoint_xfeat.onnx").string());
  // Found by name through SUPERDYNA_MODEL_DIR, as users would.
  const test::ScopedEnv env(inference::kModelDirVariable, dir.path().string());
  SuperPointOptions options;
  options.model = "superpoint_xfeat.onnx";
  options.warmup_size = {752, 480};
  SuperPointExtractor extractor(options);

  const io::EurocDataset dataset = io::EurocDataset::open(root);
  const sensors::CameraCalibration& cam0 = dataset.cam0Calibration();
  const sensors::CameraCalibration& cam1 = *dataset.cam1Calibration();
  const StereoMatcher geometry(cam0, cam1);
  std::size_t frames = 0, keypoints = 0, matches = 0, inliers = 0;
  double total_ms = 0.0, network_ms = 0.0, min_ms = 1e9;
  for (std::size_t k = 0; k < dataset.stereoFrames().size(); k += 20, ++frames) {
    const auto& frame = dataset.stereoFrames()[k];
    const FeatureSet left = extractor.extract(io::loadImage(frame.cam0, cam0));
    total_ms += extractor.lastExtractMs();
    network_ms += extractor.lastInferenceMs();
    min_ms = std::min(min_ms, extractor.lastExtractMs());
    const FeatureSet right = extractor.extract(io::loadImage(frame.cam1, cam1));
    keypoints += left.size();
    for (const FloatMatch& m : matchFloatMutualNN(left, right, 0.9)) {
      const auto f0 = cam0.cameraModel().unproject(left.keypoints[m.query].pixel);
      const auto f1 = cam1.cameraModel().unproject(right.keypoints[m.train].pixel);
      ++matches;
      inliers += f0 && f1 && geometry.epipolarErrorPx(*f0, *f1) < 2.0;
    }
  }
  const double ratio = matches == 0 ? 0.0 : static_cast<double>(inliers) / matches;
  std::cout << "SuperPoint decoding of XFeat (composed model) on EuRoC V1_01, " << frames
            << " stereo frames: " << static_cast<double>(keypoints) / frames << " keypoints/frame, "
            << static_cast<double>(matches) / frames
            << " cam0-cam1 matches/frame (mutual NN, ratio 0.9), " << 100.0 * ratio
            << " % within 2 px of the epipolar curve\n"
            << "  752x480 (input 768x480), " << options.runtime.intra_op_threads
            << " threads: " << total_ms / frames << " ms per frame (min " << min_ms
            << "), of which network " << network_ms / frames << " ms\n";
  RecordProperty("superpoint_xfeat_ms_per_frame", std::to_string(total_ms / frames));
  EXPECT_GT(static_cast<double>(keypoints) / frames, 500.0);
  EXPECT_GT(ratio, 0.6);
}

}  // namespace
}  // namespace superdyna::features
