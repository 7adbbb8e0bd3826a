// A `touchstone sim` scene file: its settings table (one definition per setting for the reader,
// the run's config.resolved.toml and summary.json params), the defaults, and validation. The
// engine's sections under [model] are the MFS settings table; [prediction] is the predictor's.
// Paths, palpation sites and the device's own settings are read around the table.
#include "touchstone/studies/sim_scene.hpp"

#include "collision/prediction_fields.hpp"
#include "mfs_settings_fields.hpp"
#include "fem_reference/setting_fields.hpp"
#include "touchstone/studies/output_files.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace rt = realtime::runtime;
using nlohmann::json;

namespace {

const std::vector<Named<DeviceKind>> device_kinds{{"none", DeviceKind::none},
                                                  {"scripted", DeviceKind::scripted},
                                                  {"replay", DeviceKind::replay},
                                                  {"openigtlink", DeviceKind::openigtlink},
                                                  {"openhaptics", DeviceKind::openhaptics}};
const std::vector<Named<rt::ForceMode>> force_modes{{"stiffness", rt::ForceMode::stiffness},
                                                    {"extrapolation", rt::ForceMode::extrapolation}};

/// Palpation sites are keys site0, site1, … of [device.scripted] (at most this many).
constexpr int max_palpation_sites = 16;

std::vector<SettingField<SimScene>> make_fields() {
  using S = SimScene;
  const auto integer = [](FieldNames n, auto get) { return field::integer<S>(n, get); };
  const auto real = [](FieldNames n, auto get) { return field::real<S>(n, get); };
  const auto boolean = [](FieldNames n, auto get) { return field::boolean<S>(n, get); };
  const auto text = [](FieldNames n, auto get) { return field::text<S>(n, get); };
  const auto length = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::length, get); };
  const auto time = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::time, get); };
  const auto force = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::force, get); };
  std::vector<SettingField<S>> f;

  f.push_back(text({"", "scene", "", "the scene's name (the default output folder)"}, [](auto& s) -> auto& { return s.name; }));
  f.push_back(time({"", "duration", "s", "simulated time"}, [](auto& s) -> auto& { return s.settings.duration_s; }));
  f.push_back(field::choice<S>({"", "force_mode", "", "stiffness (K_t U) or extrapolation (the paper's)"}, force_modes,
                               [](auto& s) -> auto& { return s.settings.force_mode; }));

  f.push_back(field::choice<S>({"organ", "shape", "", "generated organ: stomach or hemisphere"}, organ_shapes,
                               [](auto& s) -> auto& { return s.generated_organ.shape; }));
  f.push_back(real({"organ", "unit_scale", "m per file unit", "scale of the surface file's coordinates (0.001: millimetres)"},
                   [](auto& s) -> auto& { return s.surface_unit_scale; }));
  f.push_back(integer({"organ", "triangles", "triangles", "generated organ's target triangle count"},
                      [](auto& s) -> auto& { return s.generated_organ.target_triangles; }));
  f.push_back(length({"organ", "hemisphere_radius", "m", "generated hemisphere's radius"},
                     [](auto& s) -> auto& { return s.generated_organ.hemisphere_radius_m; }));

  f.push_back(field::required(field::quantity<S>({"material", "youngs_modulus", "Pa", "Young's modulus E"}, Dimension::pressure,
                                                 [](auto& s) -> auto& { return s.settings.material.youngs_modulus_Pa; })));
  f.push_back(field::required(real({"material", "poisson_ratio", "", "Poisson's ratio"},
                                   [](auto& s) -> auto& { return s.settings.material.poisson_ratio; })));

  f.push_back(field::required(length({"tool", "tip_radius", "m", "radius a of the tool tip (the contact patch)"},
                                     [](auto& s) -> auto& { return s.settings.tool.tip_radius_m; })));
  f.push_back(length({"tool", "shaft_length", "m", "drawn shaft length"}, [](auto& s) -> auto& { return s.settings.tool.shaft_length_m; }));
  f.push_back(length({"tool", "shaft_radius", "m", "drawn shaft radius"}, [](auto& s) -> auto& { return s.settings.tool.shaft_radius_m; }));
  f.push_back(field::choice<S>({"tool", "contact", "", "frictionless or bonded"}, contact_conditions,
                               [](auto& s) -> auto& { return s.settings.tool.condition; }));

  // The engine: the same sections as `touchstone mfs`, under [model]; its node count and local
  // radius are study keys there, here scene keys of [model.sprinkling].
  append_member_fields(f, local_model_fields(), "model", "model_", [](auto& s) -> auto& { return s.settings.model; });
  f.push_back(integer({"model.sprinkling", "node_count", "nodes", "nodes of the local model"},
                      [](auto& s) -> auto& { return s.settings.model.sprinkling.node_count; }));
  // Default 5 tip radii: the paper's local ball (read after [tool]).
  SettingField<S> local_radius = length({"model.sprinkling", "local_radius", "m", "radius L of the local ball (default 5 a)"},
                                        [](auto& s) -> auto& { return s.settings.model.sprinkling.local_radius_m; });
  local_radius.read = [](ConfigTable& t, S& s) {
    s.settings.model.sprinkling.local_radius_m = t.quantity("local_radius", Dimension::length, 5 * s.settings.tool.tip_radius_m);
  };
  f.push_back(local_radius);

  f.push_back(field::choice<S>({"device", "kind", "", "none, scripted, replay, openigtlink or openhaptics"}, device_kinds,
                               [](auto& s) -> auto& { return s.device; }));
  f.push_back(force({"device", "max_force", "N", "the device's own force limit"}, [](auto& s) -> auto& { return s.device_max_force_N; }));
  f.push_back(integer({"device.scripted", "generated_sites", "sites", "palpation sites generated when none is listed"},
                      [](auto& s) -> auto& { return s.palpation.generated_sites; }));
  f.push_back(length({"device.scripted", "site_spread", "m", "generated sites within this of the top"},
                     [](auto& s) -> auto& { return s.palpation.site_spread_m; }));
  f.push_back(length({"device.scripted", "hover", "m", "start and end of a palpation above the site"},
                     [](auto& s) -> auto& { return s.palpation.hover_m; }));
  f.push_back(length({"device.scripted", "press_depth", "m", "below the surface at the site"},
                     [](auto& s) -> auto& { return s.palpation.press_depth_m; }));
  f.push_back(length({"device.scripted", "slide", "m", "along the surface while pressed"}, [](auto& s) -> auto& { return s.palpation.slide_m; }));
  f.push_back(time({"device.scripted", "approach", "s", "descent to the press"}, [](auto& s) -> auto& { return s.palpation.approach_s; }));
  f.push_back(time({"device.scripted", "hold", "s", "pressed"}, [](auto& s) -> auto& { return s.palpation.hold_s; }));
  f.push_back(time({"device.scripted", "slide_time", "s", "the slide"}, [](auto& s) -> auto& { return s.palpation.slide_s; }));
  f.push_back(time({"device.scripted", "release", "s", "the release"}, [](auto& s) -> auto& { return s.palpation.release_s; }));
  f.push_back(time({"device.scripted", "rest", "s", "at rest between palpations"}, [](auto& s) -> auto& { return s.palpation.rest_s; }));
  f.push_back(length({"device.scripted", "lift", "m", "lift between sites"}, [](auto& s) -> auto& { return s.palpation.lift_m; }));
  f.push_back(time({"device.scripted", "transfer", "s", "move between sites"}, [](auto& s) -> auto& { return s.palpation.transfer_s; }));
  f.push_back(length({"device.scripted", "tremor_rms", "m", "RMS hand tremor per axis"},
                     [](auto& s) -> auto& { return s.palpation.tremor.rms_per_axis_m; }));
  f.push_back(field::seed<S>({"device.scripted", "seed", "", "seed of the generated sites and the tremor"},
                             [](auto& s) -> auto& { return s.palpation.seed; }));
  f.push_back(integer({"device.openigtlink", "port", "", "TCP port the OpenIGTLink server listens on"},
                      [](auto& s) -> auto& { return s.igtl_port; }));
  f.push_back(length({"device.openigtlink", "length_unit", "m", "the peer's length unit"},
                     [](auto& s) -> auto& { return s.igtl_length_unit_m; }));
  f.push_back(text({"device.openhaptics", "name", "", "OpenHaptics device name"},
                   [](auto& s) -> auto& { return s.openhaptics_device_name; }));

  f.push_back(real({"rates", "haptic_hz", "Hz", "haptic loop rate"}, [](auto& s) -> auto& { return s.settings.rates.haptic_hz; }));
  f.push_back(real({"rates", "model_hz", "Hz", "model loop rate"}, [](auto& s) -> auto& { return s.settings.rates.model_hz; }));
  f.push_back(real({"rates", "graphics_hz", "Hz", "graphics loop rate"}, [](auto& s) -> auto& { return s.settings.rates.graphics_hz; }));

  f.push_back(real({"contact", "keep_fraction", "", "a build is kept while the tip stays within this of L"},
                   [](auto& s) -> auto& { return s.settings.contact.keep_fraction; }));
  f.push_back(real({"contact", "usable_fraction", "", "a build is usable while the tip stays within this of L"},
                   [](auto& s) -> auto& { return s.settings.contact.usable_fraction; }));
  f.push_back(time({"contact", "crossfade", "s", "force cross-fade between builds"},
                   [](auto& s) -> auto& { return s.settings.contact.crossfade_s; }));
  f.push_back(boolean({"contact", "prebuild_on_prediction", "", "build at the predicted contact before it happens"},
                      [](auto& s) -> auto& { return s.settings.contact.prebuild_on_prediction; }));
  f.push_back(time({"contact", "prebuild_horizon", "s", "prebuild when contact is predicted within this"},
                   [](auto& s) -> auto& { return s.settings.contact.prebuild_horizon_s; }));
  f.push_back(time({"contact", "extrapolation_horizon", "s", "longest force extrapolation (extrapolation mode)"},
                   [](auto& s) -> auto& { return s.settings.contact.extrapolation_horizon_s; }));

  f.push_back(force({"safety", "max_force", "N", "force clamp of the safety filter"},
                    [](auto& s) -> auto& { return s.settings.safety.max_force_N; }));
  f.push_back(real({"safety", "max_rate_N_per_s", "N/s", "force slew-rate limit"},
                   [](auto& s) -> auto& { return s.settings.safety.max_rate_N_per_s; }));
  f.push_back(time({"safety", "stale_after", "s", "watchdog: model data older than this fades the force"},
                   [](auto& s) -> auto& { return s.settings.safety.stale_after_s; }));

  append_member_fields(f, prediction_fields(), "prediction", "prediction_",
                       [](auto& s) -> auto& { return s.settings.prediction; });

  f.push_back(time({"timing", "spin_tail", "s", "busy-wait before each deadline"}, [](auto& s) -> auto& { return s.settings.timing.spin_tail_s; }));
  f.push_back(boolean({"timing", "fifo", "", "ask for SCHED_FIFO"}, [](auto& s) -> auto& { return s.settings.timing.request_fifo; }));
  f.push_back(integer({"timing", "fifo_priority", "", "SCHED_FIFO priority"}, [](auto& s) -> auto& { return s.settings.timing.fifo_priority; }));
  f.push_back(time({"timing", "late_threshold", "s", "a tick this late counts as late"},
                   [](auto& s) -> auto& { return s.settings.timing.late_threshold_s; }));

  // Default output/<scene> (read after the scene's name).
  SettingField<S> directory = text({"output", "directory", "", "output folder"}, [](auto& s) -> auto& { return s.output_directory; });
  directory.read = [](ConfigTable& t, S& s) { s.output_directory = t.string("directory", "output/" + s.name); };
  f.push_back(directory);
  f.push_back(boolean({"output", "time_series", "", "ParaView PVD/VTP of the organ and the tool"},
                      [](auto& s) -> auto& { return s.write_time_series; }));
  f.push_back(integer({"output", "frame_stride", "frames", "every this many graphics frames in the time series"},
                      [](auto& s) -> auto& { return s.time_series_frame_stride; }));
  f.push_back(boolean({"output", "window", "", "interactive VTK window (needs a display)"}, [](auto& s) -> auto& { return s.window; }));
  f.push_back(text({"output", "screenshot", "", "PNG of the window at the end (relative to the output folder)"},
                   [](auto& s) -> auto& { return s.screenshot_path; }));
  f.push_back(boolean({"output", "openigtlink_polydata", "", "send the deformed organ to the OpenIGTLink peer"},
                      [](auto& s) -> auto& { return s.igtl_polydata; }));
  f.push_back(boolean({"output", "force_history", "", "forces.csv, one line per haptic tick"},
                      [](auto& s) -> auto& { return s.write_force_history; }));
  assign_params_keys(f, "sim scene");
  return f;
}

const std::vector<SettingField<SimScene>>& scene_fields() {
  static const auto fields = make_fields();
  return fields;
}

/// A scene with the defaults a scene file does not state. The energy and traction extractions
/// are study quantities (a volume quadrature per solve, a shell quadrature per build): off
/// unless asked for; a traction_integral haptic method needs traction = true.
SimScene default_scene() {
  SimScene scene;
  rt::SceneSettings& s = scene.settings;
  s.duration_s = 60.0;
  s.material.youngs_modulus_Pa = 10e3;
  s.material.poisson_ratio = 0.45;
  s.model.force.energy = false;
  s.model.force.traction = false;
  s.model.sprinkling.node_count = 60;
  scene.generated_organ.target_triangles = 20000;
  scene.generated_organ.hemisphere_radius_m = 0.05;
  return scene;
}

}  // namespace

std::string to_string(DeviceKind kind) { return name_of(device_kinds, kind); }

SimScene read_sim_scene(const std::string& path) {
  ConfigTable config = ConfigTable::from_file(path);
  const std::string directory = fs::path(path).parent_path().string();
  SimScene scene = default_scene();
  scene.config_path = path;
  scene.config_text = config.source_text();
  read_fields(scene_fields(), config, scene);
  rt::SceneSettings& s = scene.settings;
  s.prediction.cycle_period_s = 1.0 / s.rates.haptic_hz;

  // Files, relative to the scene's folder.
  ConfigTable organ = config.table("organ");
  scene.surface_path = path_relative_to(directory, organ.string("surface", ""));
  if (!scene.surface_path.empty()) require_input_file(organ.where("surface"), scene.surface_path);
  scene.atlas_path = path_relative_to(directory, organ.string("atlas", ""));
  if (!scene.atlas_path.empty()) {
    require_input_file(organ.where("atlas"), scene.atlas_path, "make it with touchstone atlas");
    try {
      s.organ_atlas = std::make_shared<const realtime::mfs::OrganAtlas>(realtime::mfs::read_organ_atlas(scene.atlas_path));
    } catch (const std::exception& error) {
      throw ConfigError(organ.where("atlas") + ": " + error.what());
    }
  }
  ConfigTable device = config.table("device");
  ConfigTable replay = device.table("replay");
  scene.replay_path = path_relative_to(directory, replay.string("file", ""));
  if (scene.device == DeviceKind::replay && scene.replay_path.empty())
    throw ConfigError(replay.where("file") + ": the replay device needs a recording (touchstone sim --record)");
  // Palpation sites as site0, site1, … = [x, y, z] (lengths), in order; none: generated.
  ConfigTable scripted = device.table("scripted");
  for (int i = 0; i < max_palpation_sites; ++i) {
    const std::string key = "site" + std::to_string(i);
    if (!scripted.has(key)) break;
    const auto v = scripted.vector3(key, Dimension::length, {{0, 0, 0}});
    scene.palpation.sites.emplace_back(v[0], v[1], v[2]);
  }

  config.finish();
  try {
    s.validate();
    scene.palpation.validate();
    scene.generated_organ.validate();
    if (!(scene.device_max_force_N > 0)) throw std::invalid_argument("device.max_force must be > 0");
    if (!(scene.surface_unit_scale > 0) || !std::isfinite(scene.surface_unit_scale))
      throw std::invalid_argument("organ.unit_scale = " + format_number(scene.surface_unit_scale) + " must be finite and > 0");
    // Every model build would fail (the patch would not fit in the local ball): refused here,
    // as `touchstone mfs` refuses it, rather than a run that feels nothing.
    const double L = s.model.sprinkling.local_radius_m;
    if (!(s.tool.tip_radius_m < 0.5 * L))
      throw std::invalid_argument("tool.tip_radius = " + format_number(s.tool.tip_radius_m) +
                                  " m must be < model.sprinkling.local_radius / 2 = " + format_number(0.5 * L) + " m");
    // The scripted hand presses the tool this far: beyond L/2 it would leave the local ball (as
    // `touchstone mfs` refuses a depth beyond L/2), and a press through the organ is no palpation.
    if (scene.device == DeviceKind::scripted && !(scene.palpation.press_depth_m <= 0.5 * L))
      throw std::invalid_argument("device.scripted.press_depth = " + format_number(scene.palpation.press_depth_m) +
                                  " m must be <= model.sprinkling.local_radius / 2 = " + format_number(0.5 * L) +
                                  " m (the tool would leave the local ball)");
    if (scene.time_series_frame_stride < 1) throw std::invalid_argument("output.frame_stride must be >= 1");
  } catch (const std::invalid_argument& error) {
    throw ConfigError(path + ": " + error.what());
  }
  scene.defaults_filled = config.defaults_filled();
  return scene;
}

std::string resolved_scene_toml(const SimScene& scene) {
  toml::table document;
  write_fields(scene_fields(), document, scene);
  // Absolute paths: the resolved file reads back from any folder.
  const auto absolute = [](const std::string& path) { return path.empty() ? path : fs::absolute(path).lexically_normal().string(); };
  detail::toml_section_of(document, "organ").insert("surface", absolute(scene.surface_path));
  if (!scene.atlas_path.empty()) detail::toml_section_of(document, "organ").insert("atlas", absolute(scene.atlas_path));
  detail::toml_section_of(document, "device.replay").insert("file", absolute(scene.replay_path));
  toml::table& scripted = detail::toml_section_of(document, "device.scripted");
  for (std::size_t i = 0; i < scene.palpation.sites.size(); ++i) {
    const Eigen::Vector3d& site = scene.palpation.sites[i];
    scripted.insert("site" + std::to_string(i), toml::array{site.x(), site.y(), site.z()});
  }
  std::ostringstream text;
  text << "# " << scene.name << ", resolved by `touchstone sim`: every default filled in, quantities in SI (m, s, Pa, N).\n"
       << document << "\n";
  return text.str();
}

json sim_scene_params(const SimScene& scene) {
  json params = json::object();
  add_params(scene_fields(), params, scene);
  params["organ_atlas"] = scene.atlas_path;
  return params;
}

}  // namespace touchstone::studies
