#pragma once
/// @file
/// `touchstone fem`: a converged FEM reference for one or more indentation problems. Each
/// problem is solved on a sequence of meshes (every size halved per level), the force is
/// Richardson-extrapolated, and for B1 the converged forces at several a/W are extrapolated to
/// the half-space (a/W → 0) and compared with Sneddon / Mossakovskii.

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace touchstone::studies {

/// One study file of `touchstone fem`. Lists in [sweep] multiply into problems.
struct ReferenceStudy {
  std::string name = "fem_reference";
  meshes::MeshParameters geometry;          ///< level-0 mesh of the first problem
  std::vector<int> refinements{0, 1, 2};    ///< ≥ 3 levels for Richardson
  geometry::Material material;
  fem::RigidPunch punch;
  fem::SolverParameters solver;
  bool write_vtu = true;
  /// Sweeps (empty: the single value above).
  std::vector<geometry::ContactCondition> contacts;
  std::vector<double> poisson_ratios;
  std::vector<double> body_radii_m;         ///< W for B1 (a/W sweep), R otherwise
  /// Mesh families: level-0 edge sizes [m]; with two or more, each gets its own Richardson
  /// sequence and the reference is their mean, its uncertainty their spread.
  std::vector<double> edge_sizes_m;
  /// benchmark = organ without a surface file: generate this organ surface ("hemisphere" of
  /// radius geometry.body_radius_m, or "stomach") at this triangle count, once, into the cache.
  std::string generated_organ;
  int generated_organ_triangles = 20000;

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Reads a study from a config file; every key is checked (unknown keys are errors). The keys
/// that define the problem (material, tool radius and depth, the benchmark's body size) are
/// required, unless `problem_imposed`: a file read for `touchstone study`, whose [problem]
/// replaces them.
ReferenceStudy read_reference_study(ConfigTable& config, bool problem_imposed = false);

/// The study with every default filled in, quantities in SI, as TOML that read_reference_study
/// reads back to the same study (written as config.resolved.toml next to results.json).
std::string resolved_reference_study_toml(const ReferenceStudy& study);

/// Where results go, and the cache of finished solves.
struct RunOptions {
  std::string output_directory = "output/fem";
  std::string cache_directory = ".cache/touchstone";  ///< empty: no cache
  std::string config_text;                            ///< for provenance (config_sha256)
  bool quiet = false;
};

/// Runs the study (collective over MPI ranks; rank 0 meshes and writes). Returns the
/// results.json document that was written to <output>/results.json.
nlohmann::json run_reference_study(const ReferenceStudy& study, const RunOptions& options);

/// Throws std::invalid_argument naming organ.generate or organ.generate_triangles when `shape` is
/// not a generated organ's name or `triangles` lies outside [100, 1000000].
void validate_generated_organ(const std::string& shape, int triangles);

/// The surface file of a generated organ ("hemisphere" of radius hemisphere_radius_m, or
/// "stomach") with about `triangles` triangles, in <folder>/organs: written once (rank 0, moved
/// into place whole), then shared by every run with the same shape, size and count (the generator
/// is deterministic). Collective over MPI ranks. Returns the absolute path.
std::string generated_organ_surface(const std::string& shape, int triangles, double hemisphere_radius_m, const std::string& folder);

/// Closed forms for a rigid flat punch on a half-space [N]:
/// Sneddon 2Eaδ/(1−ν²) (frictionless), Mossakovskii 4Gaδ·ln(3−4ν)/(1−2ν) (bonded).
double half_space_punch_force_N(const geometry::Material& material, double tool_radius_m,
                                double depth_m, geometry::ContactCondition contact);

/// The mesh parameters as results.json and the cache keys write them (every field, SI units).
nlohmann::json mesh_parameters_json(const meshes::MeshParameters& geometry);

}  // namespace touchstone::studies
