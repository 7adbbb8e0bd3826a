#pragma once
/// @file
/// The palpation replay: a recorded palpation of an organ driven through both models, to say how
/// right the forces a trainee feels on *this* organ are.
///
/// 1. The real-time runtime runs the scene on its virtual clock (the scene's scripted hand, or a
///    `touchstone sim --record` recording in its place): the same code, sprinkling, model switches
///    and organ atlas as a live run. Every local model it makes current is one contact: its point
///    c, push direction d and tool stiffness K_t (RunSummary::models); every haptic tick names the
///    model its force came from.
/// 2. At each verified contact the reference FEM solves the whole organ (held where the study
///    says, the tool patch of radius a cut in at c, axis d) for its tool stiffness K_ref: elasticity
///    is linear in the tool displacement U, so one set of unit solves per mesh level serves every
///    tick of that contact; three levels and Richardson extrapolation give K_ref and its error
///    estimate. Contacts are independent: under `mpirun -np K` each rank solves its own share.
/// 3. Tick by tick: F_mfs = K_t U (what the haptic loop computed) against F_ref = K_ref U, both
///    push-only, with U = tip − c. At each verified contact the surface displacements of both
///    models (the MFS's deformation map, the FEM at the same vertices) are compared at the tick of
///    deepest press and written for ParaView.

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/organ_body.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace touchstone::studies {

/// Which contacts of the run get a reference solve.
enum class ContactSelection {
  all,     ///< every model that gave a force
  every,   ///< every k-th of them, in order (the first always)
  frames,  ///< the models in use at the times a user lists
};
std::string to_string(ContactSelection selection);  ///< "all", "every", "frames"

struct PalpationReplayStudy {
  std::string name = "palpation_replay";
  std::string config_path;
  std::string scene_path;      ///< the scene (organ, material, tool, model, atlas, device)
  std::string recording_path;  ///< replayed in place of the scene's device; empty: the scene's device
  double duration_s = 0;       ///< 0: the scene's duration

  ContactSelection selection = ContactSelection::all;
  int every = 1;
  std::vector<double> frame_times_s;  ///< selection = frames: run times [s]

  /// Where the reference holds the organ; it must be the attachment the organ atlas was made with
  /// (the real-time model's exterior knows only that one).
  meshes::OrganAttachment attachment;
  double feature_angle_rad = 0.6981317007977318;  ///< 40°, as `touchstone fem`
  /// Mesh size law of the reference around the patch rim (as `touchstone fem`'s [mesh]) [m].
  double edge_size_m = 0.625e-3;
  double size_growth = 0.5;
  double size_exponent = 0.75;
  double max_size_m = 0.025;
  int levels = 3;  ///< refinements 0 … levels−1, each halving every size; ≥ 3 for Richardson
  /// The unit push of the unit solves [m] (linear: any value gives the same K in exact arithmetic).
  double unit_depth_m = 1e-4;
  fem::SolverParameters solver;

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Reads a replay study: `study`, [replay] scene, recording, duration, contacts, every, frames;
/// [organ] the attachment rule and feature_angle; [mesh] edge_size, size_growth, size_exponent,
/// max_size, levels; [tool] unit_depth; [solver]. Unknown keys are errors naming the file and key.
PalpationReplayStudy read_palpation_replay_study(ConfigTable& config);

/// The study with every default filled in, quantities in SI and paths absolute, as TOML that
/// read_palpation_replay_study reads back (config.resolved.toml).
std::string resolved_palpation_replay_toml(const PalpationReplayStudy& study);

/// results.json params: every setting under its params key.
nlohmann::json palpation_replay_params(const PalpationReplayStudy& study);

/// True when a config file is a palpation replay (it has a [replay] table), for `touchstone study`.
bool is_palpation_replay_config(const std::string& path);

struct SimScene;

/// How the replay's reference agrees with the scene's organ atlas, as results.json records it
/// under "atlas_agreement": {atlas, attachment (the replay's, in describe_attachment's words),
/// attachment_checked, note}. The real-time model's body-aware exterior knows only the
/// attachment the atlas was made with, so a different one throws std::invalid_argument naming
/// both, before anything runs. An atlas that does not record its attachment is noted.
nlohmann::json replay_atlas_agreement(const PalpationReplayStudy& study, const SimScene& scene);

struct ReplayRunOptions {
  std::string output_directory = "output/palpation_replay";
  std::string cache_directory = ".cache/touchstone";  ///< empty: no cache
  std::string config_text;                            ///< for provenance
  /// Verify only contacts whose label ("model<id>") contains one of these texts (empty: all).
  std::vector<std::string> only;
  bool quiet = false;
};

/// Runs the replay (collective over MPI ranks: rank 0 runs the real-time model and writes; the
/// contacts' reference solves are spread over the ranks). Writes results.json, frames.csv,
/// contacts.csv and the ParaView files into the output folder; returns results.json.
nlohmann::json run_palpation_replay(const PalpationReplayStudy& study, const ReplayRunOptions& options);

}  // namespace touchstone::studies
