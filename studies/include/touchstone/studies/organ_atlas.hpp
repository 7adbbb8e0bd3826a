#pragma once
/// @file
/// `touchstone atlas`: the organ atlas of the enriched real-time model, computed offline by FEM.
///
/// For each sample contact c on the organ (the hemisphere: polar angles θ from a list, the tool
/// along the inward normal; B1: the centre of the top face; a user's organ surface: the points of
/// a hexagonal lattice over a region of it, each moved onto the surface, the tool along the
/// inward normal there), K_ext [N/m] is the energy bilinear
/// form of the EXTERIOR BODY (organ ∖ ball(c, L), its base clamped, traction-free elsewhere)
/// under the Dirichlet trace u = ψ_m on the cut sphere, ψ_m the closed-form punch fields of
/// realtime/mfs/punch_field.hpp, and optionally the three uniform cut translations: one solve
/// per trace g_j, K_jk = W_jk / δ² with W_jk the work of solve j's reaction on the cut against
/// δ g_k (fem::BoundaryWork, = a(u_j, u_k) in the discrete space; W_jj = 2 E_j is checked), each
/// on a sequence of meshes and Richardson-extrapolated. The
/// half-space closed form, K_mn = −∮ ψ_m·σ(ψ_n) n dA over the hemisphere of radius L below the
/// surface (n out of the ball), is reported next to it. The atlas file is read by
/// realtime/mfs/organ_atlas.hpp.

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/geometry/material.hpp"
#include "touchstone/realtime/mfs/organ_atlas.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <limits>
#include <string>
#include <vector>

namespace touchstone::studies {

/// Which punch modes the atlas holds: the normal one (frictionless contact: one solve per mesh)
/// or all three (bonded: three solves per mesh).
enum class AtlasModes { normal, all };
std::string to_string(AtlasModes modes);  ///< "normal", "all"

/// One study file of `touchstone atlas`.
struct OrganAtlasStudy {
  std::string name = "organ_atlas";
  /// benchmark B2 (the hemisphere; a sample at θ > 0 is meshed as B5) or B1, body_radius_m,
  /// tool_radius_m (a), local_radius_m (L); edge_size_m is the element size on the cut sphere at
  /// level 0, size_growth and max_size_m grade it outward. exterior_of_local_ball is set per solve.
  /// Organ: geometry.organ holds the surface and the optional attachment (the exterior body is
  /// held by the trace on the cut already); its contact point and tool axis are set per sample.
  meshes::MeshParameters geometry;
  geometry::Material material;
  std::vector<double> polar_angles_rad{0.0};  ///< hemisphere samples; B1 has its one sample
  /// Organ with no surface file: generate this organ ("stomach", or "hemisphere" of radius
  /// geometry.body_radius_m) with about this many triangles, cached like the FEM solves.
  std::string generated_organ;
  int generated_organ_triangles = 20000;
  /// Organ samples: a hexagonal lattice of spacing sample_spacing_m (0: the local radius L) in
  /// the tangent plane at the surface point nearest to region_centre_m (NaN: the organ's highest
  /// vertex, where the palpation scene's generated sites gather), its points within
  /// region_radius_m (0: that one point), each moved to the nearest surface point [m].
  std::array<double, 3> region_centre_m{{std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0}};
  double region_radius_m = 0;
  double sample_spacing_m = 0;
  AtlasModes modes = AtlasModes::all;
  /// Also the three uniform translations of the cut (three more solves per mesh): the model's
  /// cut may then shift rigidly against the organ's exterior (realtime organ_atlas.hpp). On by
  /// default: on a finite organ the half-space trace alone has the wrong shape on the cut, which
  /// puts the model's displacements off (docs/enriched_model.md, The cut's rigid shift).
  bool cut_translations = true;
  std::vector<int> refinements{0, 1, 2};      ///< consecutive levels; three or more for Richardson
  /// Depth scaling the trace [m]: the energies are divided by its square, so any value gives the
  /// same K in exact arithmetic; 1e-4 m keeps the solver's absolute numbers in a usual range.
  double trace_depth_m = 1.0e-4;
  fem::SolverParameters solver;
  int half_space_polar_points = 48;    ///< Gauss–Legendre points in the polar angle of the closed form
  int half_space_azimuth_points = 64;  ///< equally spaced points in azimuth (periodic: spectral)
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Reads [geometry] benchmark, body_radius, tool_radius, local_radius; [material]; [mesh]
/// edge_size, size_growth, max_size, refinements; [atlas] polar_angles, modes, cut_translations, trace_depth;
/// [solver]. Unknown keys are errors naming the file and the key.
OrganAtlasStudy read_organ_atlas_study(ConfigTable& config);

/// The contact points (queries; each sample's contact is the surface point nearest to one) of an
/// organ study whose surface is resolved (geometry.organ.surface_path set). Reads the surface.
std::vector<std::array<double, 3>> organ_atlas_sites(const OrganAtlasStudy& study);

/// Where an organ is held, in canonical words that an atlas records and a reference compares
/// with its own: "below the plane through (0, 0, 0) m with unit normal (0, 0, 1)", "on the
/// physical group 'base'", "on the triangles listed in a file of sha256 <first 16 hex digits>"
/// (the file's content, so a copy elsewhere matches), or "not held". Reads a triangles file.
std::string describe_attachment(const meshes::OrganAttachment& attachment);
/// The punch frame of a sample: origin at the centre of the rim circle (c − (R − √(R² − a²)) n on
/// a sphere of radius R, c itself on a flat face; on an organ surface the rim circle found on the
/// surface, meshes::organ_rim_centre), e₃ = −n, the inward normal.
realtime::mfs::PunchFrame atlas_punch_frame(const meshes::MeshParameters& geometry);

/// The half-space K_ext [N/m] (3×3, mode order normal, tangential_1, tangential_2):
/// −∮ ψ_m·σ(ψ_n)·n dA over the hemisphere of radius L below the surface, centred on the contact,
/// by Gauss–Legendre in the polar angle and the trapezoidal rule in azimuth. Symmetrised; the
/// quadrature is smooth (the rim lies L − a inside the ball).
Eigen::Matrix3d half_space_exterior_stiffness_N_per_m(double tool_radius_m, double local_radius_m,
                                                      const geometry::Material& material, int polar_points = 48,
                                                      int azimuth_points = 64);

/// K_ext of one sample on each mesh level and its extrapolation.
struct ExteriorStiffness {
  using Matrix = realtime::mfs::ExteriorMatrix;
  std::vector<Matrix> levels_N_per_m;   ///< per refinement level (top-left modes (+ translations) block set)
  std::vector<std::size_t> dofs;        ///< per level
  Matrix stiffness_N_per_m = Matrix::Zero();  ///< Richardson (≥ 3 levels), else the finest
  /// Largest |K_jk − K_kj| / max K_ii over the levels: the reciprocity of the work pairing
  /// (zero up to the solver tolerance).
  double asymmetry = 0;
  /// Observed convergence order of the normal entry (NaN when not monotone or < 3 levels).
  double observed_order = 0;
  /// Estimated relative error of stiffness_N_per_m: the largest relative Richardson correction of
  /// a diagonal entry (the extrapolated value is typically far better than the correction it
  /// applies), or with two levels the relative difference of the last two.
  double relative_error = 0;
  bool asymptotic = false;  ///< Richardson's monotone-and-plausible-order check on every diagonal entry
  double seconds = 0;       ///< wall time of the sample (meshing and solves; 0 for cached solves)
  std::size_t solves = 0, cached_solves = 0;
};

struct AtlasRunOptions {
  std::string output_directory = "output/organ_atlas";
  std::string cache_directory = ".cache/touchstone";  ///< empty: no cache
  std::string config_text;                            ///< for provenance
  bool quiet = false;
};

/// The FEM K_ext of one contact: `geometry` is the body with its contact (B1, B2 or B5;
/// exterior_of_local_ball is set here), one mesh per level in `work_directory` (or the cache).
ExteriorStiffness exterior_stiffness_fem(const meshes::MeshParameters& geometry, const geometry::Material& material,
                                         AtlasModes modes, bool cut_translations, const std::vector<int>& refinements,
                                         double trace_depth_m, const fem::SolverParameters& solver,
                                         const AtlasRunOptions& options, const std::string& work_directory);

/// Runs the study (collective over MPI ranks; rank 0 meshes and writes): writes
/// <output>/organ_atlas.json (realtime::mfs::read_organ_atlas reads it) and <output>/results.json
/// (per sample and level, with provenance). Returns the atlas.
realtime::mfs::OrganAtlas run_organ_atlas_study(const OrganAtlasStudy& study, const AtlasRunOptions& options);

}  // namespace touchstone::studies
