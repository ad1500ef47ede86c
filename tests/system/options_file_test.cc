// The options file writer against its reader: every key round-trips exactly, and a changed option
// changes the file.

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/system/system.h"
#include "support/test_support.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

/// Every key of the options file with a value other than its default (and valid). A key the
/// reader does not know fails the load; one missing here fails AllKeysRoundTripExactly.
constexpr const char* kNonDefaultOptions = R"(features:
  type: xfeat
  model: "models/x \"feat\": v2\\.onnx"
  max_keypoints: 900
  detection_threshold: 0.02
  nms_radius_px: 3
  grid_cell_px: 16
  input_scale: 0.75
  subpixel_radius_px: 2
  inference_threads: 2
  class_wise_matching: false
  parallel_extraction: false
orb:
  features: 1000
  scale_factor: 1.25
  levels: 6
  fast_threshold: 18
  min_fast_threshold: 6
  cell_size: 32
  edge_threshold: 21
  blur_sigma: 1.5
stereo:
  max_epipolar_error_px: 1.5
  max_distance: 60
  max_l2_distance: 0.8
  ratio: 0.85
  max_octave_difference: 2
  max_angle_difference_deg: 25
  min_depth_m: 0.2
  max_depth_m: 50
  refine_on_images: false
  refine_max_shift: 0.75
  check_search_px: 4.5
  check_ratio: 0.9
projection:
  radius_px: 12.5
  max_distance: 90
  max_l2_distance: 0.85
  ratio: 0.8
  min_octave_offset: -1
  max_octave_offset: 0
  radius_octave_scale: 1.2
  ratio_within_octave: true
  check_orientation: false
pose:
  rounds: 5
  iterations_per_round: 8
  robust_rounds: 2
  sigma0_px: 1.5
  chi2_mono: 7.814727903251178
  min_inliers: 12
tracker:
  wide_radius_px: 35
  min_projection_matches: 30
  refine_radius_px: 4
  min_inliers: 20
  local_keyframes: 8
  keyframe_tracked_ratio: 0.7
  keyframe_max_interval_s: 0.4
  keyframe_min_tracked: 120
  keyframe_min_interval_s: 0.1
  keyframe_weak_inliers: 60
  mono_wait_for_mapping: false
  mono_inertial_wait_for_keyframe_ba: false
  keyframe_min_stereo: 40
  close_depth_baselines: 35
  min_new_points: 250
  stereo_pose_observations: false
  imu_translation_prediction: false
  imu_rotation_prior_sigma_deg: 0.5
  imu_min_keyframe_interval_s: 0.2
  imu_weak_keyframes: false
  imu_bridge_s: 0.3
  relocalization_s: 2.5
  relocalization_candidates: 5
  imu_reanchor: false
  imu_max_gap_s: 0.2
  viewing_limits: false
  predict_octave: true
  reference_matching: false
  reference_max_distance: 60
  reference_max_l2_distance: 0.95
  reference_ratio: 0.75
  reference_ransac_threshold_px: 2.5
  reference_search_radius_px: 6
  reference_min_inliers: 40
  imu_prior_velocity_sigma: 0.1
  imu_prior_position_sigma_m: 0.01
  imu_prior_rotation_sigma_deg: 0.3
dynamic:
  mode: semantic-geometric
  min_pairs: 4
  skip_border_pairs: false
  max_tested_pairs: 12
  threshold_scale: 3.5
  min_threshold_px: 1.25
  fallback_threshold_px: 2.5
  min_background_pairs: 30
  moving_vote_share: 0.45
  min_votes: 3
  min_translation_m: 0.02
  stereo_reprojection: false
  refine_motion: false
  static_confirmations: 3
  clear_static_pairs: 5
  moving_confirmations: 3
  drop_unverified: false
  background_pairs_for_new_objects: false
  cull_points_by_instance: false
  background_radius_px: 25
  object_search_radius_px: 100
  match_ratio: 0.75
  max_pedestrian_speed_mps: 3.5
  max_vehicle_speed_mps: 50.0
  max_hamming: 60
  max_l2_distance: 0.9
  seed: 7
  baseline_frames: 1
  geometric: true
  geometric_cell_px: 64
  geometric_min_outliers: 5
  geometric_outlier_share: 0.6
  geometric_threshold_factor: 1.5
mono_init:
  min_features: 120
  min_matches: 90
  search_radius_px: 80
  max_distance: 45
  max_l2_distance: 0.85
  ratio: 0.85
  ransac_threshold_px: 2
  min_parallax_deg: 1.5
  min_triangulated: 60
  ambiguity_ratio: 0.7
  homography_score_ratio: 0.4
  max_reference_age_s: 1.5
  max_gyro_rotation_error_deg: 0.7
  gyro_bias_allowance_deg_s: 4
mapping:
  window_keyframes: 6
  fixed_observer_keyframes: 12
  iterations: 12
  chi2_outlier: 7.5
  cull_after_keyframes: 4
  min_observations: 3
  min_found_ratio: 0.3
  sigma0_px: 1.2
  triangulate: true
  triangulation_neighbours: 8
  triangulation_max_distance: 45
  triangulation_max_l2_distance: 0.8
  triangulation_ratio: 0.4
  triangulation_min_baseline_depth_ratio: 0.012345678901234567
  fusion: false
  fusion_neighbours: 7
  fusion_second_neighbours: 3
  fusion_radius_px: 2.5
  fusion_max_distance: 40
  fusion_max_l2_distance: 0.8
  fusion_stereo_check: false
  cull_keyframes: false
  cull_redundancy: 0.85
  cull_min_observers: 4
  cull_max_gap_s: 0.6
  cull_max_gap_inertial_s: 2.5
  cull_max_gap_old_s: 45
  cull_old_after_s: 20
  inertial: false
  inertial_init_min_keyframes: 12
  inertial_init_min_duration_s: 2.5
  refine_first_s: 4
  refine_second_s: 12
  full_ba_iterations: 15
  inertial_window_keyframes: 8
  inertial_fixed_covisible: 4
  inertial_iterations: 6
  inertial_free_anchor_velocity_below_s: 0.35
  global_ba_iterations: 7
semantics:
  segmenter: yolo
  dataset_format: color
  color_table: "rgb_ids.txt"
  movable_ids: "vehicle_ids_city_day.txt"
  id_png_folder: "detectron2/left"
  id_png_folder_right: "detectron2/right"
  id_png_classes: "detectron2/classes.csv"
  id_png_tracked_ids: true
  right_labels: left
  mask_dilate: 2
  mask_erode: 1
  error_false_objects_per_frame: 1.5
  error_false_object_frames: 4
  error_false_object_min_px: 30
  error_false_object_max_px: 120
  error_miss_rate: 0.1
  error_seed: 7
  every_n_frames: 3
  propagation_radius_px: 30
  propagation_max_hamming: 50
  propagation_max_l2: 0.7
  propagation_ratio: 0.7
  propagation_min_matches: 10
  propagation_min_instance_matches: 5
  yolo_model: "yolov8n-seg.onnx"
  yolo_input_size: 640
  yolo_score_threshold: 0.3
  yolo_nms_iou: 0.6
  yolo_mask_threshold: 0.4
  yolo_min_area_px: 50
  yolo_max_detections: 30
  yolo_inference_threads: 1
  maskrcnn_model: "maskrcnn_mobilenet.onnx"
  maskrcnn_score_threshold: 0.7
  maskrcnn_mask_threshold: 0.45
  maskrcnn_min_area_px: 60
  maskrcnn_max_detections: 40
  maskrcnn_inference_threads: 1
  sam_encoder_model: "sam_vit_b_encoder.onnx"
  sam_decoder_model: "sam_vit_b_decoder.onnx"
  sam_detector_model: "yolox_s.onnx"
  sam_detector_score_threshold: 0.4
  sam_nms_iou: 0.5
  sam_mask_threshold: -0.5
  sam_min_area_px: 80
  sam_max_detections: 12
  sam_inference_threads: 1
  pedestrian_labels: "person,rider"
  vehicle_labels: "car,truck"
  other_movable_labels: "dog"
loop:
  enabled: false
  database_neighbours: 3
  database_max_descriptors: 300
  database_max_hamming: 55
  database_min_similarity: 0.7
  database_hnsw_search: 24
  database_hold_s: 6
  database_max_culled_share: 0.4
  min_time_gap_s: 8
  min_score: 0.03
  group_keyframes: 8
  consistency: 2
  max_candidates: 2
  keyframes_between_loops: 4
  match_max_hamming: 45
  match_max_l2: 0.8
  match_ratio: 0.8
  ransac_iterations: 250
  ransac_min_inliers: 15
  ransac_seed: 9
  ransac_chi2: 7.5
  guided_radius_px: 6
  min_inliers: 50
  max_roll_pitch_deg: 1.5
  max_correction_deg: 25
  max_correction_path_share: 0.3
  min_correction_m: 0.25
  pose_graph_iterations: 15
  pose_graph_rotation_weight: 2
  strong_covisibility: 80
  fuse: false
pipeline:
  frame_queue: 3
  mapping_queue: 8
)";

/// "section.key" -> value text of an options file.
std::map<std::string, std::string> valuesOf(const std::string& text) {
  std::map<std::string, std::string> values;
  for (const auto& section : YAML::Load(text)) {
    for (const auto& key : section.second) {
      values[section.first.Scalar() + "." + key.first.Scalar()] = key.second.Scalar();
    }
  }
  return values;
}

SystemOptions reloaded(const SystemOptions& options, const fs::path& file) {
  writeSystemOptions(file, options);
  return loadSystemOptions(file);
}

TEST(OptionsFileWriter, AllKeysRoundTripExactly) {
  const test::ScratchDir dir("system_options_writer");
  test::writeFile(dir / "non_default.yaml", kNonDefaultOptions);
  SystemOptions options = loadSystemOptions(dir / "non_default.yaml");
  options.mode = SensorMode::kMonoInertial;
  options.deterministic = false;
  // Every key the writer writes was set above, to another value than its default.
  const std::map<std::string, std::string> defaults = valuesOf(formatSystemOptions({}));
  const std::map<std::string, std::string> written = valuesOf(formatSystemOptions(options));
  ASSERT_EQ(written.size(), defaults.size());
  EXPECT_EQ(written.size(), 252u);  // every key of the twelve sections
  for (const auto& [key, value] : written) {
    ASSERT_TRUE(defaults.contains(key)) << key;
    EXPECT_NE(value, defaults.at(key)) << key << " keeps its default";
  }
  EXPECT_EQ(written.at("features.model"), "models/x \"feat\": v2\\.onnx");
  EXPECT_EQ(written.at("pose.chi2_mono"), "7.814727903251178");

  const SystemOptions back = reloaded(options, dir / "written.yaml");
  // The mode and the pipeline come from the command line; the file names them in a comment.
  SystemOptions expected = options;
  expected.mode = back.mode;
  expected.deterministic = back.deterministic;
  EXPECT_TRUE(back == expected);  // every field, keys or not
  EXPECT_EQ(back.front_end.features.model, "models/x \"feat\": v2\\.onnx");
  EXPECT_EQ(back.mapping.triangulation.min_baseline_depth_ratio, 0.012345678901234567);
  EXPECT_EQ(formatSystemOptions(back), formatSystemOptions(expected));
  EXPECT_NE(formatSystemOptions(options).find("--mode mono-inertial\n"), std::string::npos);
  // The defaults round-trip too (and print whole numbers as reals: "2.0").
  EXPECT_TRUE(reloaded(SystemOptions{}, dir / "defaults.yaml") == SystemOptions{});
  EXPECT_EQ(defaults.at("stereo.max_epipolar_error_px"), "2.0");
}

TEST(OptionsFileWriter, AChangedOptionChangesTheFile) {
  const test::ScratchDir dir("system_options_changed");
  const std::string base = formatSystemOptions({});
  const std::vector<std::pair<std::string, std::function<void(SystemOptions&)>>> changes = {
      {"mapping.triangulation_ratio",
       [](SystemOptions& o) {
         o.mapping.triangulation.ratio = std::nextafter(o.mapping.triangulation.ratio, 1.0);
       }},
      {"tracker.min_inliers", [](SystemOptions& o) { ++o.tracker.min_inliers; }},
      {"features.class_wise_matching",
       [](SystemOptions& o) { o.front_end.features.class_wise_matching = false; }},
      {"features.model", [](SystemOptions& o) { o.front_end.features.model = "a.onnx"; }},
      {"features.type",
       [](SystemOptions& o) { o.front_end.features.type = features::FeatureType::kSuperPoint; }},
      {"pipeline.mapping_queue", [](SystemOptions& o) { o.mapping_queue = 4; }},
  };
  for (const auto& [key, change] : changes) {
    SystemOptions options;
    change(options);
    const std::string text = formatSystemOptions(options);
    EXPECT_NE(text, base) << key;
    // Exactly the changed key differs.
    const std::map<std::string, std::string> a = valuesOf(base), b = valuesOf(text);
    for (const auto& [name, value] : a)
      EXPECT_EQ(value == b.at(name), name != key) << name;
    EXPECT_TRUE(reloaded(options, dir / "changed.yaml") == options) << key;
  }
  // One ulp of a double is a different file, read back to that double.
  SystemOptions options;
  options.mapping.triangulation.ratio = std::nextafter(0.8, 1.0);
  EXPECT_EQ(reloaded(options, dir / "ulp.yaml").mapping.triangulation.ratio,
            std::nextafter(0.8, 1.0));
}

TEST(OptionsFileReader, AnUnknownKeySuggestsTheNearestKnownOne) {
  const test::ScratchDir dir("system_options_unknown");
  const auto expectHint = [&](const std::string& text, std::initializer_list<std::string> parts) {
    test::writeFile(dir / "bad.yaml", text);
    test::expectError([&] { loadSystemOptions(dir / "bad.yaml"); }, parts);
  };
  // A misspelt key of its section, a key put into another section, a misspelt section.
  expectHint(
      "tracker:\n  min_inlier: 5\n",
      {"bad.yaml:2", "unknown key 'tracker.min_inlier'; did you mean 'tracker.min_inliers'?"});
  expectHint("tracker:\n  refine_first_s: 4\n",
             {"unknown key 'tracker.refine_first_s'; did you mean 'mapping.refine_first_s'?"});
  expectHint("trackr:\n  min_inliers: 5\n",
             {"bad.yaml:1", "unknown section 'trackr'; did you mean 'tracker'?"});
  // Nothing near: no guess.
  test::writeFile(dir / "far.yaml", "tracker:\n  zebra: 1\n");
  try {
    loadSystemOptions(dir / "far.yaml");
    FAIL() << "an unknown key was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown key 'tracker.zebra'"), std::string::npos);
    EXPECT_EQ(std::string(e.what()).find("did you mean"), std::string::npos) << e.what();
  }
}

TEST(OptionsFileWriter, AnUnwritableFileIsAnErrorNamingIt) {
  const test::ScratchDir dir("system_options_unwritable");
  test::expectError([&] { writeSystemOptions(dir / "missing" / "x.yaml", SystemOptions{}); },
                    {"x.yaml", "cannot open"});
}

}  // namespace
}  // namespace superdyna::system
