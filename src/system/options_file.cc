// YAML options file of the SLAM system: one map per section, one number, true/false or name per
// key. One table (optionTable) names every key and the field it sets; the reader and the writer
// both walk it, so a key cannot be known in one direction only.

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>
#include <variant>
#include <vector>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/io/yaml_file.h"
#include "superdyna/system/system.h"

namespace superdyna::system {

namespace {

/// The field of SystemOptions one key sets; its type says how the value is read and written.
using Field =
    std::variant<double*, int*, bool*, std::string*, features::FeatureType*, dynamic::DynamicMode*>;

struct Key {
  const char* name;
  Field field;
};

struct Section {
  const char* name;
  std::vector<Key> keys;
};

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

int readInteger(const io::YamlFile& file, const YAML::Node& node, const std::string& name) {
  const double value = file.number(node, name);
  if (value != std::round(value) || std::abs(value) > 1e9) {
    throw InputError(file.at(node, name), "expected an integer");
  }
  return static_cast<int>(value);
}

bool readBool(const io::YamlFile& file, const YAML::Node& node, const std::string& name) {
  const std::string value = file.scalar(node, name);
  if (value != "true" && value != "false") {
    throw InputError(file.at(node, name), "expected true or false");
  }
  return value == "true";
}

features::FeatureType readFeatureType(const io::YamlFile& file, const YAML::Node& node,
                                      const std::string& name) {
  const std::string value = file.scalar(node, name);
  try {
    return features::parseFeatureType(value, name);
  } catch (const OptionError&) {
    throw InputError(file.at(node, name), "expected orb, xfeat or superpoint, got '" + value + "'");
  }
}

dynamic::DynamicMode readDynamicMode(const io::YamlFile& file, const YAML::Node& node,
                                     const std::string& name) {
  const std::string value = file.scalar(node, name);
  try {
    return dynamic::parseDynamicMode(value, name);
  } catch (const OptionError&) {
    throw InputError(file.at(node, name),
                     "expected off, semantic or semantic-geometric, got '" + value + "'");
  }
}

/// Sets `field` from the value `node` of the key `name` ("section.key", for messages).
void read(const io::YamlFile& file, const YAML::Node& node, const std::string& name, Field field) {
  std::visit(
      Overloaded{
          [&](double* target) { *target = file.number(node, name); },
          [&](int* target) { *target = readInteger(file, node, name); },
          [&](bool* target) { *target = readBool(file, node, name); },
          [&](std::string* target) { *target = file.scalar(node, name); },
          [&](features::FeatureType* target) { *target = readFeatureType(file, node, name); },
          [&](dynamic::DynamicMode* target) { *target = readDynamicMode(file, node, name); },
      },
      field);
}

/// A YAML double-quoted scalar holding `text` exactly.
std::string quoted(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt::format("\\x{:02x}", static_cast<unsigned char>(c));
    } else {
      out += c;
    }
  }
  return out + '"';
}

/// The shortest decimal text that reads back as `value` exactly, with ".0" on whole numbers so
/// that they read as the real numbers they are.
std::string formatDouble(double value) {
  std::string text = fmt::format("{}", value);
  if (text.find_first_not_of("-0123456789") == std::string::npos) text += ".0";
  return text;
}

/// The value of `field` as read() reads it back: numbers in their shortest exact form.
std::string format(Field field) {
  return std::visit(
      Overloaded{
          [](const double* value) { return formatDouble(*value); },
          [](const int* value) { return fmt::format("{}", *value); },
          [](const bool* value) { return std::string(*value ? "true" : "false"); },
          [](const std::string* value) { return quoted(*value); },
          [](const features::FeatureType* value) { return features::toString(*value); },
          [](const dynamic::DynamicMode* value) { return dynamic::toString(*value); },
      },
      field);
}

/// Every key of the options file, section by section, in the order written.
std::vector<Section> optionTable(SystemOptions& o) {
  auto& t = o.tracker;
  auto& f = o.front_end;
  auto& s = o.semantics;
  return {
      {"features",
       {{"type", &f.features.type},
        {"model", &f.features.model},
        {"max_keypoints", &f.features.max_keypoints},
        {"detection_threshold", &f.features.detection_threshold},
        {"nms_radius_px", &f.features.nms_radius_px},
        {"grid_cell_px", &f.features.grid_cell_px},
        {"input_scale", &f.features.input_scale},
        {"subpixel_radius_px", &f.features.subpixel_radius_px},
        {"inference_threads", &f.features.inference_threads},
        {"class_wise_matching", &f.features.class_wise_matching},
        {"parallel_extraction", &f.parallel_extraction}}},
      {"orb",
       {{"features", &f.features.orb.features},
        {"scale_factor", &f.features.orb.scale_factor},
        {"levels", &f.features.orb.levels},
        {"fast_threshold", &f.features.orb.fast_threshold},
        {"min_fast_threshold", &f.features.orb.min_fast_threshold},
        {"cell_size", &f.features.orb.cell_size},
        {"edge_threshold", &f.features.orb.edge_threshold},
        {"blur_sigma", &f.features.orb.blur_sigma}}},
      {"stereo",
       {{"max_epipolar_error_px", &f.stereo.max_epipolar_error_px},
        {"max_distance", &f.stereo.max_distance},
        {"max_l2_distance", &f.stereo.max_l2_distance},
        {"ratio", &f.stereo.ratio},
        {"max_octave_difference", &f.stereo.max_octave_difference},
        {"max_angle_difference_deg", &f.stereo.max_angle_difference_deg},
        {"min_depth_m", &f.stereo.min_depth_m},
        {"max_depth_m", &f.stereo.max_depth_m},
        {"refine_on_images", &f.stereo.refine_on_images},
        {"refine_max_shift", &f.stereo.refine_max_shift},
        {"check_search_px", &f.stereo.check_search_px},
        {"check_ratio", &f.stereo.check_ratio}}},
      {"projection",
       {{"radius_px", &t.projection.radius_px},
        {"max_distance", &t.projection.max_distance},
        {"max_l2_distance", &t.projection.max_l2_distance},
        {"ratio", &t.projection.ratio},
        {"min_octave_offset", &t.projection.min_octave_offset},
        {"max_octave_offset", &t.projection.max_octave_offset},
        {"radius_octave_scale", &t.projection.radius_octave_scale},
        {"ratio_within_octave", &t.projection.ratio_within_octave},
        {"check_orientation", &t.projection.check_orientation}}},
      {"pose",
       {{"rounds", &t.pose.rounds},
        {"iterations_per_round", &t.pose.iterations_per_round},
        {"robust_rounds", &t.pose.robust_rounds},
        {"sigma0_px", &t.pose.sigma0_px},
        {"chi2_mono", &t.pose.chi2_mono},
        {"min_inliers", &t.pose.min_inliers}}},
      {"tracker",
       {{"wide_radius_px", &t.wide_radius_px},
        {"min_projection_matches", &t.min_projection_matches},
        {"refine_radius_px", &t.refine_radius_px},
        {"min_inliers", &t.min_inliers},
        {"local_keyframes", &t.local_keyframes},
        {"keyframe_tracked_ratio", &t.keyframe_tracked_ratio},
        {"keyframe_max_interval_s", &t.keyframe_max_interval_s},
        {"keyframe_min_tracked", &t.keyframe_min_tracked},
        {"keyframe_min_interval_s", &t.keyframe_min_interval_s},
        {"keyframe_weak_inliers", &t.keyframe_weak_inliers},
        {"mono_wait_for_mapping", &t.mono_wait_for_mapping},
        {"mono_inertial_wait_for_keyframe_ba", &t.mono_inertial_wait_for_keyframe_ba},
        {"keyframe_min_stereo", &t.keyframe_min_stereo},
        {"close_depth_baselines", &t.close_depth_baselines},
        {"min_new_points", &t.min_new_points},
        {"stereo_pose_observations", &t.stereo_pose_observations},
        {"imu_translation_prediction", &t.imu_translation_prediction},
        {"imu_rotation_prior_sigma_deg", &t.imu_rotation_prior_sigma_deg},
        {"imu_min_keyframe_interval_s", &t.imu_min_keyframe_interval_s},
        {"imu_weak_keyframes", &t.imu_weak_keyframes},
        {"imu_bridge_s", &t.imu_bridge_s},
        {"relocalization_s", &t.relocalization_s},
        {"relocalization_candidates", &t.relocalization_candidates},
        {"imu_reanchor", &t.imu_reanchor},
        {"imu_max_gap_s", &t.imu_max_gap_s},
        {"viewing_limits", &t.viewing_limits},
        {"predict_octave", &t.predict_octave},
        {"reference_matching", &t.reference_matching.enabled},
        {"reference_max_distance", &t.reference_matching.matching.max_distance},
        {"reference_max_l2_distance", &t.reference_matching.matching.max_l2_distance},
        {"reference_ratio", &t.reference_matching.matching.ratio},
        {"reference_ransac_threshold_px", &t.reference_matching.ransac_threshold_px},
        {"reference_search_radius_px", &t.reference_matching.search_radius_px},
        {"reference_min_inliers", &t.reference_matching.min_inliers},
        {"imu_prior_velocity_sigma", &t.imu_prior.velocity_sigma},
        {"imu_prior_position_sigma_m", &t.imu_prior.position_sigma_m},
        {"imu_prior_rotation_sigma_deg", &t.imu_prior.rotation_sigma_deg}}},
      {"dynamic",
       {{"mode", &t.dynamic.mode},
        {"min_pairs", &t.dynamic.min_pairs},
        {"skip_border_pairs", &t.dynamic.skip_border_pairs},
        {"max_tested_pairs", &t.dynamic.max_tested_pairs},
        {"threshold_scale", &t.dynamic.threshold_scale},
        {"min_threshold_px", &t.dynamic.min_threshold_px},
        {"fallback_threshold_px", &t.dynamic.fallback_threshold_px},
        {"min_background_pairs", &t.dynamic.min_background_pairs},
        {"moving_vote_share", &t.dynamic.moving_vote_share},
        {"min_votes", &t.dynamic.min_votes},
        {"min_translation_m", &t.dynamic.min_translation_m},
        {"stereo_reprojection", &t.dynamic.stereo_reprojection},
        {"refine_motion", &t.dynamic.refine_motion},
        {"static_confirmations", &t.dynamic.static_confirmations},
        {"clear_static_pairs", &t.dynamic.clear_static_pairs},
        {"moving_confirmations", &t.dynamic.moving_confirmations},
        {"drop_unverified", &t.dynamic.drop_unverified},
        {"background_pairs_for_new_objects", &t.dynamic.background_pairs_for_new_objects},
        {"cull_points_by_instance", &t.dynamic.cull_points_by_instance},
        {"background_radius_px", &t.dynamic.background_radius_px},
        {"object_search_radius_px", &t.dynamic.object_search_radius_px},
        {"match_ratio", &t.dynamic.match_ratio},
        {"max_pedestrian_speed_mps", &t.dynamic.max_pedestrian_speed_mps},
        {"max_vehicle_speed_mps", &t.dynamic.max_vehicle_speed_mps},
        {"max_hamming", &t.dynamic.max_hamming},
        {"max_l2_distance", &t.dynamic.max_l2_distance},
        {"seed", &t.dynamic.seed},
        {"baseline_frames", &t.dynamic.baseline_frames},
        {"geometric", &t.dynamic.geometric},
        {"geometric_cell_px", &t.dynamic.geometric_cell_px},
        {"geometric_min_outliers", &t.dynamic.geometric_min_outliers},
        {"geometric_outlier_share", &t.dynamic.geometric_outlier_share},
        {"geometric_threshold_factor", &t.dynamic.geometric_threshold_factor}}},
      {"mono_init",
       {{"min_features", &t.mono_init.min_features},
        {"min_matches", &t.mono_init.min_matches},
        {"search_radius_px", &t.mono_init.search_radius_px},
        {"max_distance", &t.mono_init.max_distance},
        {"max_l2_distance", &t.mono_init.max_l2_distance},
        {"ratio", &t.mono_init.ratio},
        {"ransac_threshold_px", &t.mono_init.ransac_threshold_px},
        {"min_parallax_deg", &t.mono_init.min_parallax_deg},
        {"min_triangulated", &t.mono_init.min_triangulated},
        {"ambiguity_ratio", &t.mono_init.ambiguity_ratio},
        {"homography_score_ratio", &t.mono_init.homography_score_ratio},
        {"max_reference_age_s", &t.mono_init.max_reference_age_s},
        {"max_gyro_rotation_error_deg", &t.mono_init.max_gyro_rotation_error_deg},
        {"gyro_bias_allowance_deg_s", &t.mono_init.gyro_bias_allowance_deg_s}}},
      {"mapping",
       {{"window_keyframes", &o.mapping.window_keyframes},
        {"fixed_observer_keyframes", &o.mapping.fixed_observer_keyframes},
        {"iterations", &o.mapping.iterations},
        {"chi2_outlier", &o.mapping.chi2_outlier},
        {"cull_after_keyframes", &o.mapping.cull_after_keyframes},
        {"min_observations", &o.mapping.min_observations},
        {"min_found_ratio", &o.mapping.min_found_ratio},
        {"sigma0_px", &o.mapping.sigma0_px},
        {"triangulate", &o.mapping.triangulate},
        {"triangulation_neighbours", &o.mapping.triangulation.neighbours},
        {"triangulation_max_distance", &o.mapping.triangulation.max_distance},
        {"triangulation_max_l2_distance", &o.mapping.triangulation.max_l2_distance},
        {"triangulation_ratio", &o.mapping.triangulation.ratio},
        {"triangulation_min_baseline_depth_ratio",
         &o.mapping.triangulation.min_baseline_depth_ratio},
        {"fusion", &o.mapping.fusion.enabled},
        {"fusion_neighbours", &o.mapping.fusion.neighbours},
        {"fusion_second_neighbours", &o.mapping.fusion.second_neighbours},
        {"fusion_radius_px", &o.mapping.fusion.radius_px},
        {"fusion_max_distance", &o.mapping.fusion.max_distance},
        {"fusion_max_l2_distance", &o.mapping.fusion.max_l2_distance},
        {"fusion_stereo_check", &o.mapping.fusion.stereo_check},
        {"cull_keyframes", &o.mapping.keyframe_culling.enabled},
        {"cull_redundancy", &o.mapping.keyframe_culling.redundancy},
        {"cull_min_observers", &o.mapping.keyframe_culling.min_observers},
        {"cull_max_gap_s", &o.mapping.keyframe_culling.max_gap_s},
        {"cull_max_gap_inertial_s", &o.mapping.keyframe_culling.max_gap_inertial_s},
        {"cull_max_gap_old_s", &o.mapping.keyframe_culling.max_gap_old_s},
        {"cull_old_after_s", &o.mapping.keyframe_culling.old_after_s},
        {"inertial", &o.mapping.inertial},
        {"inertial_init_min_keyframes", &o.mapping.inertial_init.min_keyframes},
        {"inertial_init_min_duration_s", &o.mapping.inertial_init.min_duration_s},
        {"refine_first_s", &o.mapping.refine_first_s},
        {"refine_second_s", &o.mapping.refine_second_s},
        {"full_ba_iterations", &o.mapping.full_ba_iterations},
        {"inertial_window_keyframes", &o.mapping.inertial_window_keyframes},
        {"inertial_fixed_covisible", &o.mapping.inertial_fixed_covisible},
        {"inertial_iterations", &o.mapping.inertial_iterations},
        {"inertial_free_anchor_velocity_below_s", &o.mapping.inertial_free_anchor_velocity_below_s},
        {"global_ba_iterations", &o.mapping.global_ba_iterations}}},
      {"semantics",
       {{"segmenter", &s.segmenter},
        {"dataset_format", &s.dataset_format},
        {"color_table", &s.color_table},
        {"movable_ids", &s.movable_ids},
        {"id_png_folder", &s.id_png_folder},
        {"id_png_folder_right", &s.id_png_folder_right},
        {"id_png_classes", &s.id_png_classes},
        {"id_png_tracked_ids", &s.id_png_tracked_ids},
        {"right_labels", &s.right_labels},
        {"mask_dilate", &s.mask_dilate},
        {"mask_erode", &s.mask_erode},
        {"error_false_objects_per_frame", &s.errors.false_objects_per_frame},
        {"error_false_object_frames", &s.errors.false_object_frames},
        {"error_false_object_min_px", &s.errors.false_object_min_px},
        {"error_false_object_max_px", &s.errors.false_object_max_px},
        {"error_miss_rate", &s.errors.miss_rate},
        {"error_seed", &s.errors.seed},
        {"every_n_frames", &s.every_n_frames},
        {"propagation_radius_px", &s.propagation.radius_px},
        {"propagation_max_hamming", &s.propagation.max_hamming},
        {"propagation_max_l2", &s.propagation.max_l2},
        {"propagation_ratio", &s.propagation.ratio},
        {"propagation_min_matches", &s.propagation.min_matches},
        {"propagation_min_instance_matches", &s.propagation.min_instance_matches},
        {"yolo_model", &s.yolo.model},
        {"yolo_input_size", &s.yolo.input_size},
        {"yolo_score_threshold", &s.yolo.score_threshold},
        {"yolo_nms_iou", &s.yolo.nms_iou},
        {"yolo_mask_threshold", &s.yolo.mask_threshold},
        {"yolo_min_area_px", &s.yolo.min_area_px},
        {"yolo_max_detections", &s.yolo.max_detections},
        {"yolo_inference_threads", &s.yolo.inference_threads},
        {"maskrcnn_model", &s.maskrcnn.model},
        {"maskrcnn_score_threshold", &s.maskrcnn.score_threshold},
        {"maskrcnn_mask_threshold", &s.maskrcnn.mask_threshold},
        {"maskrcnn_min_area_px", &s.maskrcnn.min_area_px},
        {"maskrcnn_max_detections", &s.maskrcnn.max_detections},
        {"maskrcnn_inference_threads", &s.maskrcnn.inference_threads},
        {"sam_encoder_model", &s.sam.encoder_model},
        {"sam_decoder_model", &s.sam.decoder_model},
        {"sam_detector_model", &s.sam.detector_model},
        {"sam_detector_score_threshold", &s.sam.detector_score_threshold},
        {"sam_nms_iou", &s.sam.nms_iou},
        {"sam_mask_threshold", &s.sam.mask_threshold},
        {"sam_min_area_px", &s.sam.min_area_px},
        {"sam_max_detections", &s.sam.max_detections},
        {"sam_inference_threads", &s.sam.inference_threads},
        {"pedestrian_labels", &s.taxonomy.pedestrian},
        {"vehicle_labels", &s.taxonomy.vehicle},
        {"other_movable_labels", &s.taxonomy.other_movable}}},
      {"loop",
       {{"enabled", &o.loop.enabled},
        {"database_neighbours", &o.loop.database.neighbours},
        {"database_max_descriptors", &o.loop.database.max_descriptors},
        {"database_max_hamming", &o.loop.database.max_hamming},
        {"database_min_similarity", &o.loop.database.min_similarity},
        {"database_hnsw_search", &o.loop.database.hnsw_search},
        {"database_hold_s", &o.loop.database.hold_s},
        {"database_max_culled_share", &o.loop.database.max_culled_share},
        {"min_time_gap_s", &o.loop.min_time_gap_s},
        {"min_score", &o.loop.min_score},
        {"group_keyframes", &o.loop.group_keyframes},
        {"consistency", &o.loop.consistency},
        {"max_candidates", &o.loop.max_candidates},
        {"keyframes_between_loops", &o.loop.keyframes_between_loops},
        {"match_max_hamming", &o.loop.match_max_hamming},
        {"match_max_l2", &o.loop.match_max_l2},
        {"match_ratio", &o.loop.match_ratio},
        {"ransac_iterations", &o.loop.ransac.iterations},
        {"ransac_min_inliers", &o.loop.ransac.min_inliers},
        {"ransac_seed", &o.loop.ransac.seed},
        {"ransac_chi2", &o.loop.ransac_chi2},
        {"guided_radius_px", &o.loop.guided_radius_px},
        {"min_inliers", &o.loop.min_inliers},
        {"max_roll_pitch_deg", &o.loop.max_roll_pitch_deg},
        {"max_correction_deg", &o.loop.max_correction_deg},
        {"max_correction_path_share", &o.loop.max_correction_path_share},
        {"min_correction_m", &o.loop.min_correction_m},
        {"pose_graph_iterations", &o.loop.pose_graph.iterations},
        {"pose_graph_rotation_weight", &o.loop.pose_graph.rotation_weight},
        {"strong_covisibility", &o.loop.strong_covisibility},
        {"fuse", &o.loop.fuse}}},
      {"pipeline", {{"frame_queue", &o.frame_queue}, {"mapping_queue", &o.mapping_queue}}},
  };
}

const Key* findKey(const Section& section, const std::string& name) {
  const auto key = std::find_if(section.keys.begin(), section.keys.end(),
                                [&](const Key& k) { return name == k.name; });
  return key == section.keys.end() ? nullptr : &*key;
}

const Section* findSection(const std::vector<Section>& table, const std::string& name) {
  const auto section =
      std::find_if(table.begin(), table.end(), [&](const Section& s) { return name == s.name; });
  return section == table.end() ? nullptr : &*section;
}

/// Levenshtein distance: the fewest insertions, deletions and substitutions from a to b.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j)
    row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitution = diagonal + (a[i - 1] == b[j - 1] ? 0 : 1);
      diagonal = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, substitution});
    }
  }
  return row[b.size()];
}

/// A misspelling is at most this far from what was meant: two edits, or one in three characters.
std::size_t nearEnough(const std::string& name) {
  return std::max<std::size_t>(2, name.size() / 3);
}

/// "; did you mean 'tracker.min_inliers'?" for the known key nearest to section.key (a key of
/// another section costs one edit more than the same key here), or "" when none is near.
std::string nearestKeyHint(const std::vector<Section>& table, const std::string& section,
                           const std::string& key) {
  std::string best;
  std::size_t best_cost = nearEnough(key) + 1;
  for (const Section& s : table) {
    for (const Key& k : s.keys) {
      const std::size_t cost = editDistance(key, k.name) + (section == s.name ? 0 : 1);
      if (cost >= best_cost) continue;
      best_cost = cost;
      best = fmt::format("{}.{}", s.name, k.name);
    }
  }
  return best.empty() ? "" : "; did you mean '" + best + "'?";
}

/// "; did you mean 'tracker'?" for the section nearest to `name`, or "".
std::string nearestSectionHint(const std::vector<Section>& table, const std::string& name) {
  std::string best;
  std::size_t best_cost = nearEnough(name) + 1;
  for (const Section& s : table) {
    const std::size_t cost = editDistance(name, s.name);
    if (cost >= best_cost) continue;
    best_cost = cost;
    best = s.name;
  }
  return best.empty() ? "" : "; did you mean '" + best + "'?";
}

void readSection(const io::YamlFile& file, const std::string& name, const YAML::Node& node,
                 const Section& section, const std::vector<Section>& table) {
  if (!node.IsMap()) throw InputError(file.at(node, name), "expected a map of options");
  for (const auto& entry : node) {
    const std::string field = name + "." + entry.first.Scalar();
    const Key* key = findKey(section, entry.first.Scalar());
    if (key == nullptr) {
      throw InputError(
          file.at(entry.first, field),
          "unknown key '" + field + "'" + nearestKeyHint(table, name, entry.first.Scalar()));
    }
    read(file, entry.second, field, key->field);
  }
}

}  // namespace

SystemOptions loadSystemOptions(const std::filesystem::path& path, SystemOptions defaults) {
  const io::YamlFile file = io::YamlFile::load(path);
  const YAML::Node& root = file.root();
  if (root.IsNull()) return defaults;
  if (!root.IsMap()) throw InputError(file.at(root, ""), "expected a map of option sections");
  const std::vector<Section> table = optionTable(defaults);
  for (const auto& entry : root) {
    const std::string name = entry.first.Scalar();
    const Section* section = findSection(table, name);
    if (section == nullptr) {
      throw InputError(file.at(entry.first, name),
                       "unknown section '" + name + "'" + nearestSectionHint(table, name));
    }
    readSection(file, name, entry.second, *section, table);
  }
  try {
    defaults.validate();
  } catch (const OptionError& e) {
    throw InputError(InputLocation{path}, e.what());
  }
  return defaults;
}

std::string formatSystemOptions(const SystemOptions& options) {
  SystemOptions copy = options;  // the table points into it; nothing is changed
  std::string text = fmt::format(
      "# superdyna options: every key of every section (loadSystemOptions reads them back).\n"
      "# Given on the command line, not keys of this file: --mode {}{}\n",
      toString(options.mode), options.deterministic ? " --deterministic" : "");
  for (const Section& section : optionTable(copy)) {
    text += fmt::format("{}:\n", section.name);
    for (const Key& key : section.keys)
      text += fmt::format("  {}: {}\n", key.name, format(key.field));
  }
  return text;
}

void writeSystemOptions(const std::filesystem::path& path, const SystemOptions& options) {
  writeFileAtomically(path, formatSystemOptions(options));
}

}  // namespace superdyna::system
