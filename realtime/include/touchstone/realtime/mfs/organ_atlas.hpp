#pragma once
/// @file
/// The organ atlas: the exterior stiffness of the enriched local model, precomputed offline per
/// contact site and looked up at run time.
///
/// The enriched model's displacement on the local domain Ω = organ ∩ ball(c, L) is an MLS part
/// that vanishes on the cut Γ = organ ∩ sphere(c, L) plus Σ_m c_m ψ_m, the closed-form punch
/// fields (punch_field.hpp) of the modes normal, tangential_1, tangential_2. The organ outside the
/// ball is represented by the amplitudes alone: its elastic energy is ½ cᵀ K_ext c, where
/// K_ext,mn = a_ext(û_m, û_n) and û_m is the displacement of the EXTERIOR BODY (organ ∖ ball, its
/// own attachment clamped, traction-free elsewhere) with the trace u = ψ_m on Γ. On a half-space
/// K_ext is a closed-form boundary integral; on a real organ the finite body, its curvature and
/// its clamped attachment make it stiffer, which is what the atlas records (computed by FEM in
/// studies/, organ_atlas there).
///
/// K_ext is in [N/m] per metre of punch displacement in each mode, in the mode order (normal,
/// tangential_1, tangential_2) of the sample's PunchFrame; an atlas made with the normal mode
/// only holds the 1×1 block. At fixed ν, K_ext ∝ E: a lookup rescales to the model's E.
///
/// Cut translations (optional). The trace c_m ψ_m has the half-space's shape; on a finite organ
/// the displacement on the cut differs from it mostly by a rigid shift (the clamped base holds
/// the far field back). An atlas with cut_translations adds three traces, the uniform unit
/// displacements along the frame's e₃, e₁, e₂ (the punch modes' order), so that the model can
/// carry u = Σ c_m ψ_m + t on the cut, with the exterior energy ½ [c; t]ᵀ K_ext [c; t]: K_ext
/// is then (n + 3) × (n + 3), the modes first.
///
/// File format (JSON, SI units; unknown keys are ignored, every listed key is required):
///   { "format": "touchstone.organ_atlas", "version": 1,
///     "organ": text, "axisymmetric_about_z": bool, "modes": "normal" | "all",
///     optional "surface_sha256": hex text, "attachment": text,
///     "samples": [ { "label": text,
///                    "contact_point_m": [x, y, z], "direction": [dx, dy, dz],
///                    "frame": { "origin_m": [3], "e1": [3], "e2": [3], "e3": [3] },
///                    "tool_radius_m", "local_radius_m", "youngs_modulus_Pa", "poisson_ratio",
///                    "stiffness_N_per_m": s×s, "half_space_stiffness_N_per_m": n×n,
///                    "relative_error", "dofs", "seconds" } ],
///     optional "cut_translations": bool (false when absent) }
/// with n = 1 ("normal") or 3 ("all") and s = n, or n + 3 with cut_translations; matrices as
/// arrays of rows.

#include "touchstone/geometry/material.hpp"
#include "touchstone/realtime/mfs/punch_field.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <vector>

namespace touchstone::realtime::mfs {

/// K_ext of up to three modes and three cut translations [N/m]; the top-left block of the
/// atlas's matrix size is set, the rest is zero.
using ExteriorMatrix = Eigen::Matrix<double, 6, 6>;

/// One contact site of the atlas.
struct OrganAtlasSample {
  std::string label;                                           ///< e.g. "theta=30deg"
  Eigen::Vector3d contact_point_m = Eigen::Vector3d::Zero();   ///< c: where the tool axis meets the surface [m]
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();        ///< push direction into the body (unit)
  PunchFrame frame;             ///< origin at the rim-circle centre, e₃ = direction
  double tool_radius_m = 0;     ///< a [m]
  double local_radius_m = 0;    ///< L [m]
  double youngs_modulus_Pa = 0; ///< E [Pa] of the solves
  double poisson_ratio = 0;     ///< ν
  /// K_ext [N/m] in the frame's mode order, then the cut translations; only the top-left
  /// OrganAtlas::matrix_size() block is set.
  ExteriorMatrix stiffness_N_per_m = ExteriorMatrix::Zero();
  /// The modes' block on a half-space (closed form), for reference [N/m].
  Eigen::Matrix3d half_space_stiffness_N_per_m = Eigen::Matrix3d::Zero();
  double relative_error = 0;    ///< estimated relative discretisation error of stiffness_N_per_m
  std::size_t dofs = 0;         ///< degrees of freedom of the finest solve
  double seconds = 0;           ///< wall time spent on this sample offline [s]
};

struct OrganAtlas {
  std::string organ;                  ///< what body it was made for, in words
  /// For a user's organ: the sha256 of its surface file, and where it was held, in the canonical
  /// words of meshes::describe_attachment. A reference that verifies the real-time model must hold
  /// the organ the same way, since the exterior stiffness knows only this attachment. Empty when
  /// not recorded (a benchmark body, or an atlas written before these were recorded).
  std::string surface_sha256;
  std::string attachment;
  bool axisymmetric_about_z = false;  ///< the organ (and its attachment) is symmetric about the z axis
  int mode_count = 3;                 ///< 1: normal mode only; 3: all three
  bool cut_translations = false;      ///< the matrices also hold the three cut translations
  std::vector<OrganAtlasSample> samples;
  int matrix_size() const { return mode_count + (cut_translations ? 3 : 0); }
};

/// Reads an atlas file. Throws std::runtime_error naming the file and the key
/// ("atlas.json: samples[2].stiffness_N_per_m[1][0]: ...") for a missing, mistyped,
/// non-finite or inconsistent entry.
OrganAtlas read_organ_atlas(const std::string& path);
/// Writes an atlas file (the format above). Throws std::runtime_error naming the path.
void write_organ_atlas(const OrganAtlas& atlas, const std::string& path);

/// What the local model asks for.
struct OrganAtlasQuery {
  Eigen::Vector3d contact_point_m = Eigen::Vector3d::Zero();  ///< c [m]
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();      ///< push direction into the body
  double tool_radius_m = 0.0025;                              ///< a [m]
  double local_radius_m = 0.0125;                             ///< L [m]
  geometry::Material material;
};

struct OrganAtlasLookupSettings {
  /// Samples within this distance of the query's contact point are interpolated [m]; 0: the
  /// query's local radius L (the atlas's samples should then be less than 2L apart).
  double search_radius_m = 0;
  /// Samples whose push direction differs from the query's by more than this are not used [rad]
  /// (10°: the direction of a tool along the surface normal turns by half the sample spacing
  /// between samples 15° apart on a sphere).
  double max_direction_deviation_rad = 10.0 * 3.14159265358979323846 / 180.0;
  /// a, L and ν must agree with the atlas's within this relative difference.
  double parameter_tolerance = 1e-6;
  /// Inverse-distance weighting exponent: w = 1 / d^power.
  double power = 2;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

enum class OrganAtlasStatus {
  ok,
  no_sample_nearby,     ///< no sample within the search radius
  parameters_differ,    ///< a, L or ν of the atlas differ from the model's
  direction_differs,    ///< samples nearby, none with the query's push direction
};

struct OrganAtlasLookup {
  OrganAtlasStatus status = OrganAtlasStatus::no_sample_nearby;
  std::string message;  ///< empty when ok; otherwise what is wrong, with the numbers
  /// K_ext [N/m] in the mode order of the query's frame PunchFrame::along(·, direction), then
  /// its cut translations (along e₃, e₁, e₂) when the atlas has them, scaled to the query's E;
  /// top-left mode_count (+ 3) block.
  ExteriorMatrix stiffness_N_per_m = ExteriorMatrix::Zero();
  int mode_count = 0;
  bool cut_translations = false;
  std::size_t samples_used = 0;
  double nearest_distance_m = 0;  ///< distance to the nearest sample (after the symmetry map)
  double relative_error = 0;      ///< weighted mean of the samples' estimated errors
};

/// K_ext at a contact site: inverse-distance weighting of the samples within the search radius
/// (a sample at the query's point is returned as is). On an axisymmetric atlas the query is first
/// turned about z onto the half plane y = 0, x ≥ 0 where the samples lie. Each sample's matrix is
/// moved into the query's frame by the rotation that carries the sample's frame onto it: the
/// smallest rotation taking e₃ onto the query's e₃, then the turn about e₃ that aligns e₁ (in the
/// mode basis K transforms as a tensor, ψ being axisymmetric about e₃).
OrganAtlasLookup lookup_exterior_stiffness(const OrganAtlas& atlas, const OrganAtlasQuery& query,
                                           const OrganAtlasLookupSettings& settings = {});

std::string to_string(OrganAtlasStatus status);  ///< "ok", "no_sample_nearby", …

}  // namespace touchstone::realtime::mfs
