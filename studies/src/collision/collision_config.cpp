// A `touchstone collision` study file: its settings tables (one definition per setting for the
// reader, config.resolved.toml and results.json params), the defaults, and validation. The
// organ counts and the trees are sweeps (one case each), read by hand around the tables.
#include "touchstone/studies/collision_study.hpp"

#include "prediction_fields.hpp"
#include "touchstone/studies/output_files.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace touchstone::studies {
namespace rc = realtime::collision;
namespace hm = realtime::hand_motion;
using nlohmann::json;

namespace {

const std::vector<Named<rc::BoundingVolume>> bounding_volumes{{"obb", rc::BoundingVolume::obb},
                                                              {"aabb", rc::BoundingVolume::aabb}};
const std::vector<Named<rc::SplitRule>> split_rules{{"median", rc::SplitRule::median}, {"mean", rc::SplitRule::mean}};
const std::vector<Named<hm::TremorSpectrum>> spectra{{"band_noise", hm::TremorSpectrum::band_noise},
                                                     {"sinusoids", hm::TremorSpectrum::sinusoids}};

// ---------------------------------------------------------------------------------------------
// The predictor's settings, shared by collision studies and sim scenes ([prediction]).

using Prediction = rc::PredictionSettings;

std::vector<SettingField<Prediction>> make_prediction_fields() {
  const auto integer = [](FieldNames n, auto get) { return field::integer<Prediction>(n, get); };
  const auto real = [](FieldNames n, auto get) { return field::real<Prediction>(n, get); };
  const auto length = [](FieldNames n, auto get) { return field::quantity<Prediction>(n, Dimension::length, get); };
  std::vector<SettingField<Prediction>> f;
  f.push_back(integer({"", "window_samples", "samples", "m of eq. 2: positions averaged into the mean tool path"},
                      [](auto& p) -> auto& { return p.window_samples; }));
  f.push_back(integer({"", "sample_period_cycles", "cycles", "the history takes a sample every this many cycles"},
                      [](auto& p) -> auto& { return p.sample_period_cycles; }));
  f.push_back(length({"", "straight_line_range", "m", "motion taken as straight within this of the predicted point"},
                     [](auto& p) -> auto& { return p.straight_line_range_m; }));
  f.push_back(field::quantity<Prediction>({"", "direction_threshold", "rad", "a turn beyond this is a change of direction"},
                                          Dimension::angle, [](auto& p) -> auto& { return p.direction_threshold_rad; }));
  f.push_back(length({"", "margin", "m", "subtracted from every certified radius (tip size, rounding)"},
                     [](auto& p) -> auto& { return p.margin_m; }));
  f.push_back(length({"", "handover_distance", "m", "full detection every cycle within this of the surface"},
                     [](auto& p) -> auto& { return p.handover_distance_m; }));
  f.push_back(length({"", "near_exit_distance", "m", "back to prediction this far from where full detection began"},
                     [](auto& p) -> auto& { return p.near_exit_distance_m; }));
  f.push_back(real({"", "corridor_step_fraction", "check radii", "corridor ball spacing along the straight path"},
                   [](auto& p) -> auto& { return p.corridor_step_fraction; }));
  f.push_back(integer({"", "corridor_balls", "balls", "balls per corridor"}, [](auto& p) -> auto& { return p.corridor_balls; }));
  f.push_back(length({"", "ray_max_distance", "m", "longest ray cast for the predicted point"},
                     [](auto& p) -> auto& { return p.ray_max_distance_m; }));
  f.push_back(length({"", "min_path_length", "m", "shorter mean tool paths give no direction"},
                     [](auto& p) -> auto& { return p.min_path_length_m; }));
  f.push_back(integer({"", "detection_period_cycles", "cycles", "prediction queries every N-th cycle only"},
                      [](auto& p) -> auto& { return p.detection_period_cycles; }));
  f.push_back(real({"", "max_tip_speed_m_per_s", "m/s", "speed bound behind a detection period > 1"},
                   [](auto& p) -> auto& { return p.max_tip_speed_m_per_s; }));
  f.push_back(integer({"", "direction_check_period_cycles", "cycles", "direction checks every this many cycles (0: none)"},
                      [](auto& p) -> auto& { return p.direction_check_period_cycles; }));
  f.push_back(field::boolean<Prediction>({"", "audit", "", "also run full detection every cycle and count misses"},
                                         [](auto& p) -> auto& { return p.audit; }));
  assign_params_keys(f, "prediction");
  return f;
}

// ---------------------------------------------------------------------------------------------
// The study's scalar settings. Sections are the study file's tables.

std::vector<SettingField<CollisionStudy>> make_study_fields() {
  using S = CollisionStudy;
  const auto integer = [](FieldNames n, auto get) { return field::integer<S>(n, get); };
  const auto real = [](FieldNames n, auto get) { return field::real<S>(n, get); };
  const auto length = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::length, get); };
  const auto time = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::time, get); };
  std::vector<SettingField<S>> f;
  f.push_back(field::text<S>({"", "study", "", "the study's name (results.json, the report)"},
                             [](auto& s) -> auto& { return s.name; }));

  f.push_back(integer({"approach", "trajectories", "trajectories", "approach-press-release runs per organ"},
                      [](auto& s) -> auto& { return s.trajectories; }));
  f.push_back(field::seed<S>({"approach", "seed", "", "seed of the first trajectory (then +1 each)"},
                             [](auto& s) -> auto& { return s.seed; }));
  f.push_back(length({"approach", "start_distance_min", "m", "approaches start at least this far from the target"},
                     [](auto& s) -> auto& { return s.approach.start_distance_min_m; }));
  f.push_back(length({"approach", "start_distance_max", "m", "approaches start at most this far from the target"},
                     [](auto& s) -> auto& { return s.approach.start_distance_max_m; }));
  f.push_back(field::quantity<S>({"approach", "max_approach_angle", "rad", "half-angle of the cone about the normal"},
                                 Dimension::angle, [](auto& s) -> auto& { return s.approach.max_approach_angle_rad; }));
  f.push_back(real({"approach", "speed_min_m_per_s", "m/s", "slowest mean approach speed"},
                   [](auto& s) -> auto& { return s.approach.speed_min_m_per_s; }));
  f.push_back(real({"approach", "speed_max_m_per_s", "m/s", "fastest mean approach speed"},
                   [](auto& s) -> auto& { return s.approach.speed_max_m_per_s; }));
  f.push_back(length({"approach", "press_depth_min", "m", "shallowest press beyond the target"},
                     [](auto& s) -> auto& { return s.approach.press_depth_min_m; }));
  f.push_back(length({"approach", "press_depth_max", "m", "deepest press beyond the target"},
                     [](auto& s) -> auto& { return s.approach.press_depth_max_m; }));
  f.push_back(time({"approach", "rest", "s", "at rest before the approach"}, [](auto& s) -> auto& { return s.approach.rest_s; }));
  f.push_back(time({"approach", "hold", "s", "pressed"}, [](auto& s) -> auto& { return s.approach.hold_s; }));
  f.push_back(time({"approach", "final_rest", "s", "at rest after the release"},
                   [](auto& s) -> auto& { return s.approach.final_rest_s; }));
  f.push_back(time({"approach", "min_segment", "s", "shortest approach or release"},
                   [](auto& s) -> auto& { return s.approach.min_segment_s; }));
  f.push_back(real({"approach", "sample_rate_hz", "Hz", "device sampling rate (the haptic rate)"},
                   [](auto& s) -> auto& { return s.approach.sample_rate_hz; }));

  f.push_back(length({"approach.tremor", "rms_per_axis", "m", "RMS tremor per axis"},
                     [](auto& s) -> auto& { return s.approach.tremor.rms_per_axis_m; }));
  f.push_back(real({"approach.tremor", "band_low_hz", "Hz", "lower edge of the tremor band"},
                   [](auto& s) -> auto& { return s.approach.tremor.band_low_hz; }));
  f.push_back(real({"approach.tremor", "band_high_hz", "Hz", "upper edge of the tremor band"},
                   [](auto& s) -> auto& { return s.approach.tremor.band_high_hz; }));
  f.push_back(field::choice<S>({"approach.tremor", "spectrum", "", "band_noise or sinusoids"}, spectra,
                               [](auto& s) -> auto& { return s.approach.tremor.spectrum; }));
  f.push_back(integer({"approach.tremor", "filter_order", "", "band-pass filter order (band_noise)"},
                      [](auto& s) -> auto& { return s.approach.tremor.filter_order; }));
  f.push_back(integer({"approach.tremor", "sinusoid_count", "sinusoids", "sinusoids per axis (sinusoids)"},
                      [](auto& s) -> auto& { return s.approach.tremor.sinusoid_count; }));

  append_member_fields(f, prediction_fields(), "prediction", "", [](auto& s) -> auto& { return s.prediction; });

  f.push_back(field::quantity_list<S>({"tremor_study", "amplitudes", "m", "RMS tremor per axis, one set of runs each"},
                                      Dimension::length, [](auto& s) -> auto& { return s.tremor.amplitudes_m; }));
  f.push_back(field::integer_list<S>({"tremor_study", "windows", "samples", "m of eq. 2 (1: eq. 1)"},
                                     [](auto& s) -> auto& { return s.tremor.windows; }));
  f.push_back(field::integer_list<S>({"tremor_study", "sample_period_cycles", "cycles", "history sampling periods"},
                                     [](auto& s) -> auto& { return s.tremor.sample_period_cycles; }));
  f.push_back(length({"tremor_study", "evaluate_at", "m", "predict when the smooth hand is this far from its target"},
                     [](auto& s) -> auto& { return s.tremor.evaluate_at_m; }));
  f.push_back(integer({"tremor_study", "trajectories", "trajectories", "runs per amplitude"},
                      [](auto& s) -> auto& { return s.tremor.trajectories; }));
  f.push_back(length({"tremor_study", "start_distance_min", "m", "approaches start at least this far from the target"},
                     [](auto& s) -> auto& { return s.tremor.start_distance_min_m; }));
  f.push_back(field::choice<S>({"tremor_study", "organ", "", "stomach or hemisphere"}, organ_shapes,
                               [](auto& s) -> auto& { return s.tremor.shape; }));
  f.push_back(integer({"tremor_study", "organ_triangles", "triangles", "the organ's target triangle count"},
                      [](auto& s) -> auto& { return s.tremor.target_triangles; }));
  f.push_back(field::seed<S>({"tremor_study", "seed", "", "seed of the first tremor-study trajectory"},
                             [](auto& s) -> auto& { return s.tremor.seed; }));

  f.push_back(time({"timing", "min_time", "s", "each query time is measured over passes lasting this long"},
                   [](auto& s) -> auto& { return s.min_timing_s; }));
  assign_params_keys(f, "collision");
  return f;
}

/// The shape parameters every listed organ shares ([organ]; the counts are the sweep).
std::vector<SettingField<meshes::OrganParameters>> make_organ_fields() {
  using O = meshes::OrganParameters;
  std::vector<SettingField<O>> f;
  f.push_back(field::real<O>({"", "relative_tolerance", "", "accepted relative miss of the target triangle count"},
                             [](auto& o) -> auto& { return o.relative_tolerance; }));
  f.push_back(field::real<O>({"", "stomach_scale", "", "size of the stomach-like organ"},
                             [](auto& o) -> auto& { return o.stomach_scale; }));
  f.push_back(field::real<O>({"", "stomach_flattening", "", "flattening of the stomach-like organ"},
                             [](auto& o) -> auto& { return o.stomach_flattening; }));
  f.push_back(field::quantity<O>({"", "hemisphere_radius", "m", "radius of the hemisphere"}, Dimension::length,
                                 [](auto& o) -> auto& { return o.hemisphere_radius_m; }));
  f.push_back(field::integer<O>({"", "max_passes", "", "meshing passes toward the target count"},
                                [](auto& o) -> auto& { return o.max_passes; }));
  assign_params_keys(f, "organ");
  return f;
}

const std::vector<SettingField<CollisionStudy>>& study_fields() {
  static const auto fields = make_study_fields();
  return fields;
}

const std::vector<SettingField<meshes::OrganParameters>>& organ_fields() {
  static const auto fields = make_organ_fields();
  return fields;
}

/// The organ counts of one shape, as the study lists them.
std::vector<int> counts_of(const CollisionStudy& study, meshes::OrganShape shape) {
  std::vector<int> counts;
  for (const auto& organ : study.organs)
    if (organ.shape == shape) counts.push_back(organ.target_triangles);
  return counts;
}

}  // namespace

const std::vector<SettingField<rc::PredictionSettings>>& prediction_fields() {
  static const auto fields = make_prediction_fields();
  return fields;
}

std::string to_string(rc::BoundingVolume volume) { return name_of(bounding_volumes, volume); }
std::string to_string(rc::SplitRule split) { return name_of(split_rules, split); }

// ---------------------------------------------------------------------------------------------
// Validation.

void TremorStudySettings::validate() const {
  if (amplitudes_m.empty()) throw std::invalid_argument("tremor_study.amplitudes is an empty list");
  for (const double a : amplitudes_m)
    if (!std::isfinite(a) || a < 0)
      throw std::invalid_argument("tremor_study.amplitudes: " + format_number(a) + " must be finite and >= 0");
  if (windows.empty()) throw std::invalid_argument("tremor_study.windows is an empty list");
  for (const int m : windows)
    if (m < 1 || m > rc::max_window_samples)
      throw std::invalid_argument("tremor_study.windows: " + std::to_string(m) + " must be in [1, " +
                                  std::to_string(rc::max_window_samples) + "]");
  if (sample_period_cycles.empty()) throw std::invalid_argument("tremor_study.sample_period_cycles is an empty list");
  for (const int s : sample_period_cycles)
    if (s < 1) throw std::invalid_argument("tremor_study.sample_period_cycles: " + std::to_string(s) + " must be >= 1");
  if (!(evaluate_at_m > 0) || !std::isfinite(evaluate_at_m))
    throw std::invalid_argument("tremor_study.evaluate_at = " + format_number(evaluate_at_m) + " must be > 0");
  if (trajectories < 1) throw std::invalid_argument("tremor_study.trajectories = " + std::to_string(trajectories) + " must be >= 1");
  if (!(start_distance_min_m > evaluate_at_m))
    throw std::invalid_argument("tremor_study.start_distance_min = " + format_number(start_distance_min_m) +
                                " must be > tremor_study.evaluate_at");
  meshes::OrganParameters organ;
  organ.shape = shape;
  organ.target_triangles = target_triangles;
  try {
    organ.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("tremor_study.organ: ") + e.what());
  }
}

void CollisionStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("study name is empty");
  if (organs.empty()) throw std::invalid_argument("organ: no organ (stomach_triangles and hemisphere_triangles are empty)");
  for (const auto& organ : organs) organ.validate();
  if (bounding_volumes.empty()) throw std::invalid_argument("bvh.bounding_volume is an empty list");
  if (trees.empty()) throw std::invalid_argument("bvh.trees is an empty list");
  for (const auto& tree : trees) {
    try {
      tree.settings.validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("bvh." + tree.name + ": " + e.what());
    }
  }
  approach.validate();
  if (trajectories < 1) throw std::invalid_argument("approach.trajectories = " + std::to_string(trajectories) + " must be >= 1");
  prediction.validate();
  if (std::abs(prediction.cycle_period_s * approach.sample_rate_hz - 1) > 1e-9)
    throw std::invalid_argument("prediction.cycle_period_s must be 1 / approach.sample_rate_hz");
  tremor.validate();
  if (!(tremor.start_distance_min_m <= approach.start_distance_max_m))
    throw std::invalid_argument("tremor_study.start_distance_min = " + format_number(tremor.start_distance_min_m) +
                                " must be <= approach.start_distance_max = " + format_number(approach.start_distance_max_m));
  if (!(min_timing_s >= 0) || !std::isfinite(min_timing_s))
    throw std::invalid_argument("timing.min_time = " + format_number(min_timing_s) + " must be finite and >= 0");
}

CollisionStudy default_collision_study() {
  CollisionStudy study;
  for (const int n : {500, 2500, 17000, 35000}) {
    meshes::OrganParameters organ;
    organ.target_triangles = n;
    study.organs.push_back(organ);
  }
  meshes::OrganParameters hemisphere;
  hemisphere.shape = meshes::OrganShape::hemisphere;
  hemisphere.target_triangles = 2500;
  study.organs.push_back(hemisphere);
  rc::BvhSettings binary;
  binary.children_per_node = 2;
  binary.max_leaf_triangles = 1;
  binary.entry_grid_cell = 0;
  study.trees = {{"binary", binary}, {"default", rc::BvhSettings{}}};
  study.prediction.cycle_period_s = 1 / study.approach.sample_rate_hz;
  return study;
}

// ---------------------------------------------------------------------------------------------
// Reading and writing.

void read_prediction_settings(ConfigTable& prediction, rc::PredictionSettings& settings) {
  read_fields(prediction_fields(), prediction, settings);
}

CollisionStudy read_collision_study(ConfigTable& config) {
  CollisionStudy study = default_collision_study();
  read_fields(study_fields(), config, study);
  // The tremor is sampled with the device; the predictor's cycle is the device's.
  study.approach.tremor.sample_rate_hz = study.approach.sample_rate_hz;
  if (study.approach.sample_rate_hz > 0) study.prediction.cycle_period_s = 1 / study.approach.sample_rate_hz;

  // The organs: every listed count of each shape, sharing [organ]'s shape parameters.
  ConfigTable organ = config.table("organ");
  meshes::OrganParameters base = study.organs.front();
  read_fields(organ_fields(), organ, base);
  const std::vector<int> stomach = read_int_list(organ, "stomach_triangles", counts_of(study, meshes::OrganShape::stomach));
  const std::vector<int> hemisphere =
      read_int_list(organ, "hemisphere_triangles", counts_of(study, meshes::OrganShape::hemisphere));
  study.organs.clear();
  for (const auto& [shape, counts] : {std::pair{meshes::OrganShape::stomach, stomach},
                                      std::pair{meshes::OrganShape::hemisphere, hemisphere}})
    for (const int n : counts) {
      meshes::OrganParameters p = base;
      p.shape = shape;
      p.target_triangles = n;
      try {
        p.validate();
      } catch (const std::invalid_argument& e) {
        throw ConfigError(organ.where(shape == meshes::OrganShape::stomach ? "stomach_triangles" : "hemisphere_triangles") +
                          ": " + e.what());
      }
      study.organs.push_back(p);
    }

  // The trees: each named tree's settings in [bvh.<name>]; the bounding volume is swept.
  ConfigTable bvh = config.table("bvh");
  study.bounding_volumes.clear();
  for (const auto& name : bvh.choice_list("bounding_volume", names(bounding_volumes), names(bounding_volumes)))
    study.bounding_volumes.push_back(value_of(bounding_volumes, name));
  const std::vector<std::string> tree_names = bvh.choice_list("trees", {"binary", "default"}, {"binary", "default"});
  const std::vector<CollisionTree> defaults = study.trees;
  study.trees.clear();
  for (const std::string& name : tree_names) {
    ConfigTable t = bvh.table(name);
    CollisionTree tree = name == "binary" ? defaults[0] : defaults[1];
    rc::BvhSettings& s = tree.settings;
    s.split = value_of(split_rules, t.choice("split", names(split_rules), to_string(s.split)));
    s.max_leaf_triangles = read_int(t, "max_leaf_triangles", s.max_leaf_triangles);
    s.children_per_node = read_int(t, "children_per_node", s.children_per_node);
    s.entry_grid_cell = t.number("entry_grid_cell", s.entry_grid_cell);
    try {
      s.validate();
    } catch (const std::invalid_argument& e) {
      throw ConfigError(t.where("") + e.what());
    }
    study.trees.push_back(tree);
  }

  finish_and_validate(config, study);
  return study;
}

std::string resolved_config_toml(const CollisionStudy& study) {
  toml::table document;
  write_fields(study_fields(), document, study);
  toml::table organ;
  write_fields(organ_fields(), organ, study.organs.front());
  detail::insert_toml(organ, "stomach_triangles", json(counts_of(study, meshes::OrganShape::stomach)));
  detail::insert_toml(organ, "hemisphere_triangles", json(counts_of(study, meshes::OrganShape::hemisphere)));
  document.insert("organ", organ);
  toml::array volumes, tree_names;
  for (const auto v : study.bounding_volumes) volumes.push_back(to_string(v));
  toml::table bvh;
  for (const auto& tree : study.trees) {
    tree_names.push_back(tree.name);
    bvh.insert(tree.name, toml::table{{"split", to_string(tree.settings.split)},
                                      {"max_leaf_triangles", tree.settings.max_leaf_triangles},
                                      {"children_per_node", tree.settings.children_per_node},
                                      {"entry_grid_cell", tree.settings.entry_grid_cell}});
  }
  bvh.insert("bounding_volume", volumes);
  bvh.insert("trees", tree_names);
  document.insert("bvh", bvh);
  std::ostringstream text;
  text << "# " << study.name
       << ", resolved by `touchstone collision`: every default filled in, quantities in SI (m, s, rad).\n"
       << document << "\n";
  return text.str();
}

json collision_params(const CollisionStudy& study) {
  json params = json::object();
  add_params(study_fields(), params, study);
  add_params(organ_fields(), params, study.organs.front());
  return params;
}

}  // namespace touchstone::studies
