#include "superdyna/inference/onnx_model.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "superdyna/inference/model_files.h"
#include "superdyna/inference/tensor_spec.h"
#include "support/test_support.h"

namespace superdyna::inference {
namespace {

using test::expectError;

/// The XFeat contract (as XFeatExtractor states it), written out here.
ModelSignature xfeatSignature() {
  ModelSignature s;
  s.inputs.push_back({"",
                      {DimSpec::dynamic("batch"), DimSpec::fixed(3, "channels"),
                       DimSpec::multipleOf(32, "height"), DimSpec::multipleOf(32, "width")},
                      ElementType::kFloat32});
  for (const auto& [name, channels] : std::vector<std::pair<std::string, int>>{
           {"descriptors", 64}, {"keypoint_logits", 65}, {"reliability", 1}}) {
    s.outputs.push_back({name,
                         {DimSpec::dynamic("batch"), DimSpec::fixed(channels, "channels"),
                          DimSpec::dynamic(), DimSpec::dynamic()},
                         ElementType::kFloat32});
  }
  return s;
}

TEST(TensorSpec, DimensionsAcceptFixedDynamicAndMultiples) {
  EXPECT_TRUE(DimSpec::fixed(3).accepts(3));
  EXPECT_FALSE(DimSpec::fixed(3).accepts(1));
  EXPECT_TRUE(DimSpec::dynamic().accepts(7));
  EXPECT_FALSE(DimSpec::dynamic().accepts(0));
  EXPECT_TRUE(DimSpec::multipleOf(32).accepts(480));
  EXPECT_FALSE(DimSpec::multipleOf(32).accepts(488));
  EXPECT_EQ(DimSpec::multipleOf(32).describe(), "a multiple of 32");
}

TEST(TensorSpec, MismatchNamesTheDimensionRankAndType) {
  const TensorSpec spec{"image",
                        {DimSpec::dynamic("batch"), DimSpec::fixed(1, "channels"),
                         DimSpec::multipleOf(8, "height"), DimSpec::multipleOf(8, "width")},
                        ElementType::kFloat32};
  TensorInfo rgb{"image", {-1, 3, -1, -1}, {"batch", "", "h", "w"}, ElementType::kFloat32};
  ASSERT_TRUE(mismatch(spec, rgb).has_value());
  EXPECT_EQ(*mismatch(spec, rgb), "dimension 1 (channels) is 3, expected 1");

  TensorInfo fixed_bad{"image", {1, 1, 100, 64}, {}, ElementType::kFloat32};
  EXPECT_EQ(*mismatch(spec, fixed_bad), "dimension 2 (height) is 100, expected a multiple of 8");

  TensorInfo rank3{"image", {1, 64, 64}, {}, ElementType::kFloat32};
  EXPECT_NE(mismatch(spec, rank3)->find("rank is 3"), std::string::npos);

  TensorInfo bytes{"image", {1, 1, 64, 64}, {}, ElementType::kUInt8};
  EXPECT_EQ(*mismatch(spec, bytes), "element type is uint8, expected float32");

  TensorInfo good{"image", {1, 1, -1, -1}, {}, ElementType::kFloat32};
  EXPECT_FALSE(mismatch(spec, good).has_value());

  EXPECT_FALSE(shapeMismatch(spec, {1, 1, 480, 752}).has_value());
  EXPECT_EQ(*shapeMismatch(spec, {1, 1, 484, 752}),
            "shape [1, 1, 484, 752]: dimension 2 (height) is 484, expected a multiple of 8");
}

TEST(ModelFiles, MissingModelListsWhereItLookedAndHowToGetOne) {
  test::ScratchDir dir("model_files");
  test::ScopedEnv env(kModelDirVariable, dir.path().string());
  expectError([] { findModel("no_such_model.onnx"); },
              {"no_such_model.onnx", dir.path().string(), "models", "SUPERDYNA_MODEL_DIR",
               "docs/concepts/learned-features.md"});
  ASSERT_GE(modelSearchDirs().size(), 2u);
  EXPECT_EQ(modelSearchDirs()[0], dir.path());
}

TEST(ModelFiles, FindsAModelInTheEnvironmentFolderAndTakesPathsAsGiven) {
  test::ScratchDir dir("model_files");
  test::writeFile(dir / "tiny.onnx", "x");
  test::ScopedEnv env(kModelDirVariable, dir.path().string());
  EXPECT_EQ(findModel("tiny.onnx"), dir / "tiny.onnx");
  EXPECT_EQ(findModel((dir / "tiny.onnx").string()), dir / "tiny.onnx");
  expectError([&] { findModel((dir / "other.onnx").string()); },
              {(dir / "other.onnx").string(), "not found"});
}

TEST(OnnxModel, MissingOrCorruptFileGivesInputErrorNamingIt) {
  test::ScratchDir dir("onnx_model");
  expectError([&] { OnnxModel((dir / "absent.onnx"), xfeatSignature()); },
              {"absent.onnx", "not found"});
  test::writeFile(dir / "garbage.onnx", "this is not a protobuf");
  expectError([&] { OnnxModel((dir / "garbage.onnx"), xfeatSignature()); },
              {"garbage.onnx", "cannot load the ONNX model"});
  OnnxModelOptions options;
  options.intra_op_threads = 0;
  expectError<OptionError>([&] { OnnxModel((dir / "garbage.onnx"), xfeatSignature(), options); },
                           {"intra_op_threads"});
}

TEST(OnnxModel, LoadsXFeatDescribesItAndRunsWithTiming) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  OnnxModel model(xfeat, xfeatSignature());
  ASSERT_EQ(model.modelInputs().size(), 1u);
  EXPECT_EQ(model.modelInputs()[0].describe(), "'input' [batch, 3, height, width] float32");
  EXPECT_EQ(model.modelOutputs().size(), 3u);
  EXPECT_FALSE(model.metadata("superdyna.size_multiple").has_value());

  model.warmUp({{1, 3, 64, 96}});
  EXPECT_EQ(model.runCount(), 0);
  EXPECT_EQ(model.lastRunMs(), 0.0);

  std::vector<float> input(3 * 64 * 96);
  for (std::size_t i = 0; i < input.size(); ++i)
    input[i] = static_cast<float>(i % 97) / 97.0f;
  const auto out = model.run({{input.data(), {1, 3, 64, 96}}});
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].shape, (std::vector<std::int64_t>{1, 64, 8, 12}));
  EXPECT_EQ(out[1].shape, (std::vector<std::int64_t>{1, 65, 8, 12}));
  EXPECT_EQ(out[2].shape, (std::vector<std::int64_t>{1, 1, 8, 12}));
  EXPECT_EQ(model.runCount(), 1);
  EXPECT_GT(model.lastRunMs(), 0.0);
  EXPECT_DOUBLE_EQ(model.meanRunMs(), model.lastRunMs());
  // Reliability is a sigmoid output.
  for (const float r : out[2].data) {
    EXPECT_GT(r, 0.0f);
    EXPECT_LT(r, 1.0f);
  }
  // Same input, same output (deterministic on a fixed thread count).
  const auto again = model.run({{input.data(), {1, 3, 64, 96}}});
  EXPECT_EQ(again[1].data, out[1].data);
  EXPECT_EQ(model.runCount(), 2);
}

TEST(OnnxModel, RunInPlaceViewsTheSameOutputsRunCopies) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  OnnxModel model(xfeat, xfeatSignature());
  std::vector<float> input(3 * 64 * 96);
  for (std::size_t i = 0; i < input.size(); ++i)
    input[i] = static_cast<float>(i % 89) / 89.0f;
  const auto copied = model.run({{input.data(), {1, 3, 64, 96}}});
  const auto viewed = model.runInPlace({{input.data(), {1, 3, 64, 96}}});
  ASSERT_EQ(viewed.size(), copied.size());
  for (std::size_t k = 0; k < viewed.size(); ++k) {
    EXPECT_EQ(viewed[k].shape, copied[k].shape);
    const std::vector<float> values(viewed[k].data, viewed[k].data + copied[k].data.size());
    EXPECT_EQ(values, copied[k].data) << "output " << k;
  }
  EXPECT_EQ(model.runCount(), 2);
  // A wrong input is refused as by run().
  EXPECT_THROW(model.runInPlace({{input.data(), {1, 3, 60, 96}}}), InputError);
}

TEST(OnnxModel, RejectsInputShapesOutsideTheContract) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  OnnxModel model(xfeat, xfeatSignature());
  std::vector<float> input(3 * 72 * 96, 0.0f);
  expectError(
      [&] {
        model.run({{input.data(), {1, 3, 72, 96}}});
      },
      {"xfeat.onnx", "input 'input'", "dimension 2 (height) is 72", "expected a multiple of 32"});
  expectError(
      [&] {
        model.run({{input.data(), {1, 1, 64, 96}}});
      },
      {"xfeat.onnx", "dimension 1 (channels) is 1, expected 3"});
  expectError([&] { model.run({{input.data(), {3, 64, 96}}}); }, {"rank 3, expected 4"});
  expectError([&] { model.run({}); }, {"got 0 input tensor(s), the model takes 1"});
  EXPECT_EQ(model.runCount(), 0);
}

TEST(OnnxModel, AWrongModelFailsItsContractWithAClearMessage) {
  SUPERDYNA_REQUIRE_SHARED(yolox, "models/yolox_nano.onnx");
  // A detector given as XFeat: its input fits ([1,3,416,416]), its outputs do not.
  expectError([&] { OnnxModel(yolox, xfeatSignature()); },
              {"yolox_nano.onnx", "output 'descriptors' missing", "'output' [1, 3549, 85]"});

  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  // XFeat given as a single-channel network.
  ModelSignature gray = xfeatSignature();
  gray.inputs[0].dims[1] = DimSpec::fixed(1, "channels");
  expectError([&] { OnnxModel(xfeat, gray); },
              {"xfeat.onnx", "input 'input'", "dimension 1 (channels) is 3, expected 1"});
  // An output of the wrong channel count.
  ModelSignature wide = xfeatSignature();
  wide.outputs[0].dims[1] = DimSpec::fixed(256, "channels");
  expectError([&] { OnnxModel(xfeat, wide); },
              {"xfeat.onnx", "output 'descriptors'", "dimension 1 (channels) is 64, expected 256"});
  // A signature with two inputs for a one-input model.
  ModelSignature two = xfeatSignature();
  two.inputs.push_back(two.inputs[0]);
  expectError([&] { OnnxModel(xfeat, two); }, {"xfeat.onnx", "the model has 1 input(s)"});
}

TEST(OnnxModel, FixedSizeModelDeclaresItsSizeAndRejectsOthers) {
  SUPERDYNA_REQUIRE_SHARED(fixed, "models/xfeat_640x640_opset12.onnx");
  ModelSignature s = xfeatSignature();
  // This export names its outputs differently; position-free matching is by name only.
  s.outputs = {
      {"output", {DimSpec::dynamic(), DimSpec::fixed(64), DimSpec::dynamic(), DimSpec::dynamic()}}};
  OnnxModel model(fixed, s);
  EXPECT_EQ(model.modelInputs()[0].dims, (std::vector<std::int64_t>{1, 3, 640, 640}));
  std::vector<float> input(3 * 64 * 64, 0.0f);
  expectError(
      [&] {
        model.run({{input.data(), {1, 3, 64, 64}}});
      },
      {"xfeat_640x640_opset12.onnx", "inference failed"});
}

}  // namespace
}  // namespace superdyna::inference
