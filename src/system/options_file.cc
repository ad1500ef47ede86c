// YAML options file of the SLAM system: one map per section, one number, true/false or name per
// key.

#include <cmath>
#include <functional>
#include <map>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/io/yaml_file.h"
#include "superdyna/system/system.h"

namespace superdyna::system {

namespace {

using Setter = std::function<void(const io::YamlFile&, const YAML::Node&, const std::string&)>;
using Section = std::map<std::string, Setter>;

Setter doubleSetter(double& target) {
  return [&target](const io::YamlFile& file, const YAML::Node& node, const std::string& field) {
    target = file.number(node, field);
  };
}

Setter intSetter(int& target) {
  return [&target](const io::YamlFile& file, const YAML::Node& node, const std::string& field) {
    const double value = file.number(node, field);
    if (value != std::round(value) || std::abs(value) > 1e9) {
      throw InputError(file.at(node, field), "expected an integer");
    }
    target = static_cast<int>(value);
  };
}

Setter boolSetter(bool& target) {
  return [&target](const io::YamlFile& file, const YAML::Node& node, const std::string& field) {
    const std::string value = file.scalar(node, field);
    if (value != "true" && value != "false") {
      throw InputError(file.at(node, field), "expected true or false");
    }
    target = value == "true";
  };
}

Setter stringSetter(std::string& target) {
  return [&target](const io::YamlFile& file, const YAML::Node& node, const std::string& field) {
    target = file.scalar(node, field);
  };
}

Setter featureTypeSetter(features::FeatureType& target) {
  return [&target](const io::YamlFile& file, const YAML::Node& node, const std::string& field) {
    const std::string value = file.scalar(node, field);
    try {
      target = features::parseFeatureType(value, field);
    } catch (const OptionError&) {
      throw InputError(file.at(node, field),
                       "expected orb, xfeat or superpoint, got '" + value + "'");
    }
  };
}

std::map<std::string, Section> sectionsOf(SystemOptions& o) {
  auto& t = o.tracker;
  auto& f = o.front_end;
  return {
      {"features",
       {{"type", featureTypeSetter(f.features.type)},
        {"model", stringSetter(f.features.model)},
        {"max_keypoints", intSetter(f.features.max_keypoints)},
        {"detection_threshold", doubleSetter(f.features.detection_threshold)},
        {"nms_radius_px", intSetter(f.features.nms_radius_px)},
        {"grid_cell_px", intSetter(f.features.grid_cell_px)},
        {"subpixel_radius_px", intSetter(f.features.subpixel_radius_px)},
        {"inference_threads", intSetter(f.features.inference_threads)},
        {"class_wise_matching", boolSetter(f.features.class_wise_matching)},
        {"parallel_extraction", boolSetter(f.parallel_extraction)}}},
      {"orb",
       {{"features", intSetter(f.features.orb.features)},
        {"scale_factor", doubleSetter(f.features.orb.scale_factor)},
        {"levels", intSetter(f.features.orb.levels)},
        {"fast_threshold", intSetter(f.features.orb.fast_threshold)},
        {"min_fast_threshold", intSetter(f.features.orb.min_fast_threshold)},
        {"cell_size", intSetter(f.features.orb.cell_size)},
        {"edge_threshold", intSetter(f.features.orb.edge_threshold)},
        {"blur_sigma", doubleSetter(f.features.orb.blur_sigma)}}},
      {"stereo",
       {{"max_epipolar_error_px", doubleSetter(f.stereo.max_epipolar_error_px)},
        {"max_distance", intSetter(f.stereo.max_distance)},
        {"max_l2_distance", doubleSetter(f.stereo.max_l2_distance)},
        {"ratio", doubleSetter(f.stereo.ratio)},
        {"max_octave_difference", intSetter(f.stereo.max_octave_difference)},
        {"max_angle_difference_deg", doubleSetter(f.stereo.max_angle_difference_deg)},
        {"min_depth_m", doubleSetter(f.stereo.min_depth_m)},
        {"max_depth_m", doubleSetter(f.stereo.max_depth_m)}}},
      {"projection",
       {{"radius_px", doubleSetter(t.projection.radius_px)},
        {"max_distance", intSetter(t.projection.max_distance)},
        {"max_l2_distance", doubleSetter(t.projection.max_l2_distance)},
        {"ratio", doubleSetter(t.projection.ratio)},
        {"max_octave_difference", intSetter(t.projection.max_octave_difference)},
        {"check_orientation", boolSetter(t.projection.check_orientation)}}},
      {"pose",
       {{"rounds", intSetter(t.pose.rounds)},
        {"iterations_per_round", intSetter(t.pose.iterations_per_round)},
        {"robust_rounds", intSetter(t.pose.robust_rounds)},
        {"sigma0_px", doubleSetter(t.pose.sigma0_px)},
        {"chi2_mono", doubleSetter(t.pose.chi2_mono)},
        {"min_inliers", intSetter(t.pose.min_inliers)}}},
      {"tracker",
       {{"wide_radius_px", doubleSetter(t.wide_radius_px)},
        {"min_projection_matches", intSetter(t.min_projection_matches)},
        {"refine_radius_px", doubleSetter(t.refine_radius_px)},
        {"min_inliers", intSetter(t.min_inliers)},
        {"local_keyframes", intSetter(t.local_keyframes)},
        {"keyframe_tracked_ratio", doubleSetter(t.keyframe_tracked_ratio)},
        {"keyframe_max_interval_s", doubleSetter(t.keyframe_max_interval_s)},
        {"keyframe_min_tracked", intSetter(t.keyframe_min_tracked)},
        {"keyframe_min_interval_s", doubleSetter(t.keyframe_min_interval_s)},
        {"keyframe_weak_inliers", intSetter(t.keyframe_weak_inliers)},
        {"mono_wait_for_mapping", boolSetter(t.mono_wait_for_mapping)},
        {"mono_inertial_wait_for_keyframe_ba", boolSetter(t.mono_inertial_wait_for_keyframe_ba)},
        {"keyframe_min_stereo", intSetter(t.keyframe_min_stereo)},
        {"close_depth_baselines", doubleSetter(t.close_depth_baselines)},
        {"min_new_points", intSetter(t.min_new_points)},
        {"stereo_pose_observations", boolSetter(t.stereo_pose_observations)},
        {"imu_translation_prediction", boolSetter(t.imu_translation_prediction)},
        {"imu_rotation_prior_sigma_deg", doubleSetter(t.imu_rotation_prior_sigma_deg)},
        {"imu_min_keyframe_interval_s", doubleSetter(t.imu_min_keyframe_interval_s)},
        {"imu_bridge_s", doubleSetter(t.imu_bridge_s)},
        {"viewing_limits", boolSetter(t.viewing_limits)},
        {"reference_matching", boolSetter(t.reference_matching.enabled)},
        {"reference_max_distance", intSetter(t.reference_matching.matching.max_distance)},
        {"reference_max_l2_distance", doubleSetter(t.reference_matching.matching.max_l2_distance)},
        {"reference_ratio", doubleSetter(t.reference_matching.matching.ratio)},
        {"reference_ransac_threshold_px", doubleSetter(t.reference_matching.ransac_threshold_px)},
        {"reference_search_radius_px", doubleSetter(t.reference_matching.search_radius_px)},
        {"reference_min_inliers", intSetter(t.reference_matching.min_inliers)},
        {"imu_prior_velocity_sigma", doubleSetter(t.imu_prior.velocity_sigma)},
        {"imu_prior_position_sigma_m", doubleSetter(t.imu_prior.position_sigma_m)},
        {"imu_prior_rotation_sigma_deg", doubleSetter(t.imu_prior.rotation_sigma_deg)}}},
      {"mono_init",
       {{"min_features", intSetter(t.mono_init.min_features)},
        {"min_matches", intSetter(t.mono_init.min_matches)},
        {"search_radius_px", doubleSetter(t.mono_init.search_radius_px)},
        {"max_distance", intSetter(t.mono_init.max_distance)},
        {"max_l2_distance", doubleSetter(t.mono_init.max_l2_distance)},
        {"ratio", doubleSetter(t.mono_init.ratio)},
        {"ransac_threshold_px", doubleSetter(t.mono_init.ransac_threshold_px)},
        {"min_parallax_deg", doubleSetter(t.mono_init.min_parallax_deg)},
        {"min_triangulated", intSetter(t.mono_init.min_triangulated)},
        {"ambiguity_ratio", doubleSetter(t.mono_init.ambiguity_ratio)},
        {"homography_score_ratio", doubleSetter(t.mono_init.homography_score_ratio)},
        {"max_reference_age_s", doubleSetter(t.mono_init.max_reference_age_s)}}},
      {"mapping",
       {{"window_keyframes", intSetter(o.mapping.window_keyframes)},
        {"fixed_observer_keyframes", intSetter(o.mapping.fixed_observer_keyframes)},
        {"iterations", intSetter(o.mapping.iterations)},
        {"chi2_outlier", doubleSetter(o.mapping.chi2_outlier)},
        {"cull_after_keyframes", intSetter(o.mapping.cull_after_keyframes)},
        {"min_observations", intSetter(o.mapping.min_observations)},
        {"min_found_ratio", doubleSetter(o.mapping.min_found_ratio)},
        {"sigma0_px", doubleSetter(o.mapping.sigma0_px)},
        {"triangulate", boolSetter(o.mapping.triangulate)},
        {"triangulation_neighbours", intSetter(o.mapping.triangulation.neighbours)},
        {"triangulation_max_distance", intSetter(o.mapping.triangulation.max_distance)},
        {"triangulation_max_l2_distance", doubleSetter(o.mapping.triangulation.max_l2_distance)},
        {"triangulation_ratio", doubleSetter(o.mapping.triangulation.ratio)},
        {"triangulation_min_baseline_depth_ratio",
         doubleSetter(o.mapping.triangulation.min_baseline_depth_ratio)},
        {"fusion", boolSetter(o.mapping.fusion.enabled)},
        {"fusion_neighbours", intSetter(o.mapping.fusion.neighbours)},
        {"fusion_second_neighbours", intSetter(o.mapping.fusion.second_neighbours)},
        {"fusion_radius_px", doubleSetter(o.mapping.fusion.radius_px)},
        {"fusion_max_distance", intSetter(o.mapping.fusion.max_distance)},
        {"fusion_max_l2_distance", doubleSetter(o.mapping.fusion.max_l2_distance)},
        {"cull_keyframes", boolSetter(o.mapping.keyframe_culling.enabled)},
        {"cull_redundancy", doubleSetter(o.mapping.keyframe_culling.redundancy)},
        {"cull_min_observers", intSetter(o.mapping.keyframe_culling.min_observers)},
        {"cull_max_gap_s", doubleSetter(o.mapping.keyframe_culling.max_gap_s)},
        {"cull_max_gap_inertial_s", doubleSetter(o.mapping.keyframe_culling.max_gap_inertial_s)},
        {"inertial", boolSetter(o.mapping.inertial)},
        {"inertial_init_min_keyframes", intSetter(o.mapping.inertial_init.min_keyframes)},
        {"inertial_init_min_duration_s", doubleSetter(o.mapping.inertial_init.min_duration_s)},
        {"refine_first_s", doubleSetter(o.mapping.refine_first_s)},
        {"refine_second_s", doubleSetter(o.mapping.refine_second_s)},
        {"full_ba_iterations", intSetter(o.mapping.full_ba_iterations)},
        {"inertial_window_keyframes", intSetter(o.mapping.inertial_window_keyframes)},
        {"inertial_fixed_covisible", intSetter(o.mapping.inertial_fixed_covisible)},
        {"inertial_iterations", intSetter(o.mapping.inertial_iterations)}}},
  };
}

void applySection(const io::YamlFile& file, const std::string& name, const YAML::Node& node,
                  const Section& section) {
  if (!node.IsMap()) throw InputError(file.at(node, name), "expected a map of options");
  for (const auto& entry : node) {
    const std::string key = entry.first.Scalar();
    const std::string field = name + "." + key;
    const auto setter = section.find(key);
    if (setter == section.end()) {
      throw InputError(file.at(entry.first, field), "unknown key '" + field + "'");
    }
    setter->second(file, entry.second, field);
  }
}

}  // namespace

SystemOptions loadSystemOptions(const std::filesystem::path& path, SystemOptions defaults) {
  const io::YamlFile file = io::YamlFile::load(path);
  const YAML::Node& root = file.root();
  if (root.IsNull()) return defaults;
  if (!root.IsMap()) throw InputError(file.at(root, ""), "expected a map of option sections");
  const std::map<std::string, Section> sections = sectionsOf(defaults);
  for (const auto& entry : root) {
    const std::string name = entry.first.Scalar();
    const auto section = sections.find(name);
    if (section == sections.end()) {
      throw InputError(file.at(entry.first, name), "unknown section '" + name + "'");
    }
    applySection(file, name, entry.second, section->second);
  }
  try {
    defaults.validate();
  } catch (const OptionError& e) {
    throw InputError(InputLocation{path}, e.what());
  }
  return defaults;
}

}  // namespace superdyna::system
