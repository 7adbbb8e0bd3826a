#pragma once
/// @file
/// `touchstone mfs`: the MFS local model on indentation problems, one case per contact condition
/// and node count, written as results.json (the study contract) with a node-cloud VTU per case.
/// No reference is run here: the study runner compares these cases with the FEM.

#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace touchstone::studies {

/// One study file of `touchstone mfs`. Lists (node_count, contact) multiply into cases.
struct MfsStudy {
  std::string name = "mfs";
  /// The organ and the tool: benchmark (B2/B3: hemisphere with the tool at the pole, B5: at
  /// contact_polar_angle; B1: cylinder of radius = height = W, the tool at the centre of its top
  /// face z = 0, the origin), body radius R or W, tool radius a. When no surface file is given, the
  /// organ surface is generated from these with the mesh sizes edge_size_m, size_growth and
  /// max_size_m (only the boundary triangles are used).
  meshes::MeshParameters geometry;
  /// A closed triangle surface (gmsh .msh) to use as the organ instead; absolute path (the
  /// reader resolves relative paths against the config file's folder). Empty: generate.
  std::string surface_path;
  /// The physical group of the organ's .msh held at u = 0 (realtime::mfs::ClampedSurface):
  /// "base" for a generated benchmark (its clamped base; it matters when the local ball reaches
  /// it, e.g. B5 near the base), none ("") by default for a surface file.
  std::string clamped_group;
  /// The organ atlas (`touchstone atlas`) that gives the enriched model its body-aware exterior;
  /// absolute path, empty: none (the model then says it used the half-space exterior).
  std::string atlas_path;
  /// Contact point on the organ surface [m]; unset: the benchmark's (R n at the polar angle;
  /// the origin on B1).
  std::optional<Eigen::Vector3d> contact_point_m;

  geometry::Material material;
  double depth_m = 0.00025;                         ///< δ: U_tool = δ d
  Eigen::Vector3d direction{0.0, 0.0, -1.0};        ///< d, normalised when used
  std::vector<geometry::ContactCondition> contacts{geometry::ContactCondition::frictionless};

  /// Every knob of the local model; sprinkling.node_count is ignored in favour of node_counts.
  /// sprinkling.local_radius_m is L.
  realtime::mfs::LocalModelSettings model;
  std::vector<int> node_counts{100};
  bool write_vtu = true;

  /// Throws std::invalid_argument naming the field (including the engine structs' validate()).
  void validate() const;
};

/// The mesh parameters of a generated organ surface: B3 is the hemisphere seen through the local
/// ball, so the MFS cuts the ball itself and its organ is the whole hemisphere (B2), not the
/// truncated FEM domain; B1 (the cylinder), B2 and B5 are their own organ.
meshes::MeshParameters organ_surface_geometry(const MfsStudy& study);

/// Reads a study; every key is checked (unknown keys are errors naming the file and key), and
/// invalid values end in a ConfigError naming the file and the field. A relative
/// `surface` path is taken relative to `config_directory`. With `paper_mode = true` the
/// defaults are those of realtime::mfs::paper_settings() (34 nodes, linear basis, dense LU,
/// the paper's partition force); every key still overrides them.
MfsStudy read_mfs_study(ConfigTable& config, const std::string& config_directory = "");

/// The study with every default filled in and every quantity in SI, as TOML that
/// read_mfs_study reads back to the same study.
std::string resolved_config_toml(const MfsStudy& study);

struct MfsRunOptions {
  std::string output_directory = "output/mfs";
  std::string config_text;  ///< for provenance (config_sha256)
  bool quiet = false;
  /// A reference solution on a mesh (.vtu/.pvtu with a point array `displacement_m`, at the
  /// study's depth): each case then also writes <case id>_on_reference.vtu — that mesh with the
  /// MFS field sampled at its points, the difference MFS − reference and the local-domain mask —
  /// and reports the difference's relative L2 norm over the points (error.field_rel_l2).
  std::string reference_field_path;
};

/// Runs every case and writes <out>/results.json, <out>/config.resolved.toml and
/// <out>/<case id>.vtu (the node cloud with u_h for U_tool = δ d). A case that fails numerically
/// is recorded with status != "ok" and null numbers; the others still run. Returns the document.
nlohmann::json run_mfs_study(const MfsStudy& study, const MfsRunOptions& options);

/// The paper's model (paper_mode): the spacing s [m] of its tool-tip node at `node_count`, the
/// radius of eq. 9's tributary disc π s² — and of the FEM punch B4 pairs with it.
/// Sprinkles only (milliseconds), on study.surface_path (must be set). Throws
/// std::invalid_argument when the study is not in paper mode or has no surface file.
double paper_tip_spacing_m(const MfsStudy& study, int node_count);

/// "MFS-frictionless-N100": the case id of one contact condition and requested node count.
std::string mfs_case_id(geometry::ContactCondition contact, int node_count);

}  // namespace touchstone::studies
