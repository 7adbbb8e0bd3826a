#pragma once
/// @file
/// `touchstone sim <scene.toml>`: the real-time runtime on a scene — an organ, a material, the
/// MFS settings, a tool, a device, rates, a force mode, safety limits and outputs — run on real
/// threads until the trajectory ends, the device disconnects or Ctrl-C, or in study mode on a
/// virtual clock. Writes summary.json and prints the run summary.

#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/realtime/haptics/palpation_trajectory.hpp"
#include "touchstone/realtime/runtime/simulation.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace touchstone::studies {

enum class DeviceKind { none, scripted, replay, openigtlink, openhaptics };
std::string to_string(DeviceKind kind);

struct SimScene {
  std::string name = "scene";
  std::string config_path;
  std::string config_text;  ///< the scene file's text, as read (the run's provenance records it)
  /// The settings the scene file leaves at their defaults, "section.key = value" (printed by
  /// `touchstone sim`, so that nothing is filled in without a word).
  std::vector<std::string> defaults_filled;
  /// The organ: a surface file, or (empty) a generated shape.
  std::string surface_path;
  double surface_unit_scale = 1.0;  ///< metres per unit of the surface file (1e-3: millimetres)
  meshes::OrganParameters generated_organ;
  /// The organ atlas (`touchstone atlas`) of this organ for the enriched model's body-aware
  /// exterior; empty: none (every build then uses the half-space exterior, and says so).
  std::string atlas_path;
  realtime::runtime::SceneSettings settings;

  DeviceKind device = DeviceKind::scripted;
  double device_max_force_N = 3.3;  ///< the device's own limit (Phantom Omni: 3.3 N)
  realtime::haptics::PalpationSettings palpation;  ///< scripted
  std::string replay_path;                          ///< replay
  int igtl_port = 18944;                            ///< openigtlink
  double igtl_length_unit_m = 0.001;
  std::string openhaptics_device_name = "Default Device";

  std::string output_directory = "output/sim";
  bool write_time_series = true;  ///< ParaView PVD/VTP
  int time_series_frame_stride = 6;
  bool window = false;            ///< interactive VTK window (needs a display)
  std::string screenshot_path;    ///< PNG of the window at the end (relative to the output directory)
  bool igtl_polydata = true;      ///< openigtlink: send the deformed organ at the graphics rate
  bool write_force_history = false;  ///< forces.csv, one line per haptic tick (study mode: always)
};

/// Reads a scene; unknown keys are errors naming the file and key. Relative paths are taken
/// relative to the scene file's folder (the output directory relative to the working directory).
SimScene read_sim_scene(const std::string& path);

/// The scene with every default filled in, quantities in SI and paths absolute, as TOML that
/// read_sim_scene reads back to the same scene (written as config.resolved.toml by run_sim).
std::string resolved_scene_toml(const SimScene& scene);

/// summary.json params: every setting of the scene under one key (the same table as the reader
/// and the resolved config; the engine's under model_*, the predictor's under prediction_*).
nlohmann::json sim_scene_params(const SimScene& scene);

struct SimOptions {
  std::optional<double> duration_s;    ///< overrides the scene's
  std::optional<std::string> output_directory;
  std::string record_path;             ///< CSV of every tick's pose and force (replayable)
  std::string replay_path;             ///< plays this recording instead of the scene's device
  bool virtual_clock = false;          ///< study mode: lock-step, bit-reproducible
  std::optional<realtime::runtime::ForceMode> force_mode;  ///< overrides the scene's
  std::optional<bool> window;          ///< overrides the scene's
  std::string screenshot_path;         ///< overrides the scene's
  const std::atomic<bool>* stop = nullptr;  ///< Ctrl-C
  bool print = true;
  /// Also handed every chunk of the force history as forces.csv receives it (the palpation
  /// replay reads the run this way); null: none.
  std::function<void(const std::vector<realtime::runtime::ForceSample>&)> force_history_observer;
};

/// The file name a generated organ is cached under in the output folder: shape, triangle count
/// and a hash of every parameter, so that a changed parameter generates a new organ.
std::string generated_organ_cache_name(const meshes::OrganParameters& organ);

/// The organ's surface file as run_sim reads it: the scene's surface, or the generated organ
/// cached in `output_directory` (written by run_sim there).
std::string scene_organ_file(const SimScene& scene, const std::string& output_directory);

/// Runs the scene and writes <out>/summary.json (and forces.csv, the time series, the
/// recording). Returns the summary document.
nlohmann::json run_sim(const SimScene& scene, const SimOptions& options);

/// The run summary as JSON (the loops, safety, prediction and work counters, force statistics).
nlohmann::json summary_json(const realtime::runtime::RunSummary& summary);

/// The models a run made current (RunSummary::models), one object each: c, d, K_t, why and how.
nlohmann::json model_records_json(const std::vector<realtime::runtime::ModelRecord>& models);

/// The run summary as a few lines of text.
std::string summary_text(const realtime::runtime::RunSummary& summary);

}  // namespace touchstone::studies
