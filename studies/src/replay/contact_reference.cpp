// One contact of the palpation replay against the reference FEM of the whole organ (see the
// header): each mesh level from the cache or solved on this rank, Richardson per contact, and the
// real-time model rebuilt at the contact.
#include "contact_reference.hpp"

#include "touchstone/fem/richardson.hpp"
#include "touchstone/fem/tool_stiffness.hpp"
#include "touchstone/realtime/runtime/contact_model.hpp"
#include "touchstone/realtime/runtime/surface_deformation.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/version.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

namespace touchstone::studies::replay {

namespace {
namespace fs = std::filesystem;
namespace rt = realtime::runtime;
using nlohmann::json;

/// The punch force converges at first order in the rim mesh size (the r^(1/2) edge singularity).
constexpr double punch_convergence_order = 1.0;

/// What makes a cached stiffness record unusable, or "" when it is whole: another level's
/// parameters, a stiffness that is not a finite 3 × 3 matrix, or a probe map that is neither
/// null (a probe outside the mesh) nor one.
std::string stiffness_record_defect(const json& record, const json& params) {
  if (!record.is_object()) return "not a JSON object";
  if (record.value("params", json()) != params) return "its parameters are not this level's";
  if (!is_finite_matrix(record.value("stiffness_N_per_m", json()))) return "stiffness_N_per_m is not a finite 3 x 3 matrix";
  for (const char* key : {"dofs", "tetrahedra", "solves", "seconds", "mesh_seconds"})
    if (!is_finite_number(record.value(key, json()))) return std::string(key) + " is not a finite number";
  const json maps = record.value("probe_unit_maps", json());
  if (!maps.is_array()) return "probe_unit_maps is not a list";
  for (const json& map : maps)
    if (!map.is_null() && !is_finite_matrix(map)) return "a probe_unit_maps entry is neither null nor a finite 3 x 3 matrix";
  return "";
}

/// The reference's tool stiffness at one contact and mesh level: from the cache, or meshed and
/// solved on this rank alone (MPI_COMM_SELF). `probes` are the surface vertices whose
/// displacement the finest level reports; `vtu_directory` gets its unit fields.
json solve_level(const meshes::MeshParameters& geometry, const PalpationReplayStudy& study,
                 const rt::SceneSettings& scene, const std::vector<Eigen::Vector3d>& probes,
                 const std::string& vtu_directory, const ReplayRunOptions& options, const std::string& work_directory) {
  json params = mesh_parameters_json(geometry);
  params["youngs_modulus_Pa"] = scene.material.youngs_modulus_Pa;
  params["poisson_ratio"] = scene.material.poisson_ratio;
  params["contact"] = geometry::to_string(scene.tool.condition);
  params["unit_depth_m"] = study.unit_depth_m;
  params["degree"] = study.solver.degree;
  params["solver"] = fem::to_string(study.solver.solver);
  params["relative_tolerance"] = study.solver.relative_tolerance;
  params["formulation"] = fem::to_string(study.solver.formulation);
  json probe_list = json::array();
  for (const auto& p : probes) probe_list.push_back(vector_json(p));
  params["probes_sha256"] = sha256_hex(probe_list.dump());
  const std::string key = sha256_hex(params.dump() + touchstone::version::fem_source_hash + "deal.II-9.4");
  const std::string entry = options.cache_directory.empty()
                                ? (fs::path(work_directory) / key.substr(0, 24)).string()
                                : options.cache_directory + "/replay/" + key.substr(0, 24);
  const std::string record_path = entry + "/stiffness.json";
  if (!options.cache_directory.empty() && fs::exists(record_path)) {
    try {
      json record = json::parse(read_file(record_path));
      const std::string defect = stiffness_record_defect(record, params);
      if (!defect.empty()) throw std::runtime_error(defect);
      record["cached"] = true;
      record["entry"] = entry;
      return record;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "note: cache entry %s cannot be read (%s): solving again\n", record_path.c_str(), e.what());
    }
  }
  fs::create_directories(entry);
  const std::string msh_path = entry + "/mesh.msh";
  const meshes::MeshSummary mesh = meshes::generate_mesh(geometry, msh_path);

  fem::ElasticityProblem problem;
  problem.mesh_path = msh_path;
  problem.material = scene.material;
  problem.solver = study.solver;
  fem::RigidPunch punch;
  punch.depth_m = study.unit_depth_m;
  punch.direction = Eigen::Vector3d(geometry.organ.tool_axis[0], geometry.organ.tool_axis[1], geometry.organ.tool_axis[2]);
  punch.contact = scene.tool.condition;
  problem.punch = punch;
  problem.probes = probes;
  if (!vtu_directory.empty()) {
    problem.vtu_directory = entry;
    problem.vtu_basename = "unit";
  }
  const fem::ToolStiffness k = fem::solve_tool_stiffness(problem, MPI_COMM_SELF);
  json unit_maps = json::array();
  for (std::size_t p = 0; p < probes.size(); ++p)
    unit_maps.push_back(k.probe_found[p] ? matrix_json(k.probe_displacement_per_displacement[p]) : json(nullptr));
  json record{{"params", params},
              {"stiffness_N_per_m", matrix_json(k.force_per_displacement_N_per_m)},
              {"dofs", k.dof_count},
              {"tetrahedra", mesh.tetrahedron_count},
              {"solves", k.solves},
              {"seconds", k.seconds + mesh.seconds},
              {"mesh_seconds", mesh.seconds},
              {"probe_unit_maps", unit_maps},
              {"cached", false}};
  write_file_atomically(record_path, record.dump(1) + "\n");
  record["entry"] = entry;
  return record;
}

}  // namespace

std::vector<double> pack(const std::vector<Contact>& contacts) {
  std::vector<double> out;
  for (const auto& c : contacts) {
    out.push_back(static_cast<double>(c.model_id));
    for (int k = 0; k < 3; ++k) out.push_back(c.point_m[k]);
    for (int k = 0; k < 3; ++k) out.push_back(c.direction[k]);
  }
  return out;
}

std::vector<Contact> unpack(const std::vector<double>& values) {
  std::vector<Contact> out;
  for (std::size_t i = 0; i + 7 <= values.size(); i += 7) {
    Contact c;
    c.model_id = static_cast<std::uint64_t>(values[i]);
    c.point_m = {values[i + 1], values[i + 2], values[i + 3]};
    c.direction = {values[i + 4], values[i + 5], values[i + 6]};
    out.push_back(c);
  }
  return out;
}

meshes::MeshParameters reference_geometry(const PalpationReplayStudy& study, const rt::SceneSettings& scene,
                                          const std::string& organ_file, double organ_unit_scale) {
  meshes::MeshParameters g;
  g.benchmark = meshes::Benchmark::Organ;
  g.tool_radius_m = scene.tool.tip_radius_m;
  g.local_radius_m = scene.model.sprinkling.local_radius_m;
  g.edge_size_m = study.edge_size_m;
  g.size_growth = study.size_growth;
  g.size_exponent = study.size_exponent;
  g.max_size_m = study.max_size_m;
  g.organ.surface_path = organ_file;
  g.organ.unit_scale = organ_unit_scale;
  g.organ.attachment = study.attachment;
  g.organ.feature_angle_rad = study.feature_angle_rad;
  return g;
}

json verify_contact(const Contact& contact, const PalpationReplayStudy& study, const SimScene& scene,
                    const geometry::TriangleSurface& organ, const std::string& organ_file, double organ_unit_scale,
                    const ReplayRunOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const rt::SceneSettings& s = scene.settings;
  realtime::mfs::ToolContact tool;
  tool.point = contact.point_m;
  tool.direction = contact.direction;
  tool.radius_m = s.tool.tip_radius_m;
  tool.condition = s.tool.condition;
  const realtime::mfs::LocalModel model = realtime::mfs::build_local_model(
      organ, tool, s.material, s.model, {}, realtime::mfs::exterior_from_atlas(s.organ_atlas));
  if (!model.ok()) throw std::runtime_error(contact.label() + ": the rebuilt local model failed: " + model.status);
  const rt::DeformationMap map = rt::make_deformation_map(model, organ, contact.model_id);
  // A surface vertex at a convex corner of the input can lie outside the reference's remeshed
  // surface (its facets cut the input's corners: tens of micrometres on a coarse organ); the
  // probe sits 0.02 a inside along d. The field there differs from the surface's by about
  // 0.02 a |grad u|, a per cent or two of the displacement at the patch, less farther out.
  const double probe_inset_m = 0.02 * s.tool.tip_radius_m;
  std::vector<Eigen::Vector3d> probes;
  for (const int v : map.vertices)
    probes.push_back(organ.vertices()[static_cast<std::size_t>(v)] + probe_inset_m * contact.direction);

  meshes::MeshParameters g = reference_geometry(study, s, organ_file, organ_unit_scale);
  g.organ.contact_point_m = {contact.point_m.x(), contact.point_m.y(), contact.point_m.z()};
  g.organ.tool_axis = {contact.direction.x(), contact.direction.y(), contact.direction.z()};

  const std::string work = (fs::path(options.output_directory) / "work").string();
  std::vector<json> levels;
  for (int level = 0; level < study.levels; ++level) {
    g.refinement = level;
    const bool finest = level + 1 == study.levels;
    levels.push_back(solve_level(g, study, s, finest ? probes : std::vector<Eigen::Vector3d>{}, finest ? "vtu" : "",
                                 options, work));
    if (!options.quiet)
      std::printf("[rank %u] %s level %d: %zu dofs, k = %.6g N/m (%s)\n", fem::MpiSession::rank(), contact.label().c_str(),
                  level, levels.back().at("dofs").get<std::size_t>(),
                  contact.direction.dot(matrix_from_json(levels.back().at("stiffness_N_per_m")) * contact.direction),
                  levels.back().value("cached", false) ? "cached" : "solved");
    std::fflush(stdout);
  }

  // Richardson with the axial entry's observed order for every entry: the extrapolated K is one
  // linear combination of the two finest levels.
  const Eigen::Vector3d d = contact.direction;
  std::vector<double> axial;
  for (const auto& l : levels) axial.push_back(d.dot(matrix_from_json(l.at("stiffness_N_per_m")) * d));
  const Eigen::Matrix3d finest = matrix_from_json(levels.back().at("stiffness_N_per_m"));
  Eigen::Matrix3d k_ref = finest;
  json convergence{{"levels_axial_N_per_m", axial}};
  double uncertainty = std::numeric_limits<double>::quiet_NaN();
  if (levels.size() >= 3) {
    const fem::RichardsonEstimate r = fem::richardson_extrapolate(axial, 2.0, punch_convergence_order);
    const double order = std::isfinite(r.observed_order) && r.observed_order > 0 ? r.observed_order : punch_convergence_order;
    const Eigen::Matrix3d previous = matrix_from_json(levels[levels.size() - 2].at("stiffness_N_per_m"));
    k_ref = finest + (finest - previous) / (std::pow(2.0, order) - 1);
    // The estimate: the extrapolation's own uncertainty, and never below the change it made.
    uncertainty = std::max(r.extrapolated_relative_uncertainty, std::abs(r.extrapolated - axial.back()) / std::abs(r.extrapolated));
    convergence["observed_order"] = json_number(r.observed_order);
    convergence["asymptotic"] = r.asymptotic;
    convergence["finest_relative_error"] = r.finest_relative_error;
  } else if (levels.size() == 2) {
    uncertainty = std::abs(axial[1] - axial[0]) / std::abs(axial[1]);
  }
  convergence["relative_uncertainty"] = json_number(uncertainty);

  // The displacement maps at the local vertices: the MFS's G_v and the reference's D_v.
  json vertices = json::array();
  const json& unit_maps = levels.back().at("probe_unit_maps");
  for (std::size_t i = 0; i < map.vertices.size(); ++i)
    vertices.push_back({{"vertex", map.vertices[i]},
                        {"mfs", matrix_json(map.unit_maps[i])},
                        {"mfs_offset_m", vector_json(map.load_offsets[i])},
                        {"reference", unit_maps.at(i)}});
  json solved_levels = json::array();
  for (const auto& l : levels)
    solved_levels.push_back({{"dofs", l.at("dofs")}, {"tetrahedra", l.at("tetrahedra")},
                             {"stiffness_N_per_m", l.at("stiffness_N_per_m")}, {"seconds", l.at("seconds")},
                             {"cached", l.value("cached", false)}});
  // The finest level's unit fields beside the surface files, for ParaView.
  json reference_vtu = json::array();
  const fs::path paraview = fs::path(options.output_directory) / "paraview";
  fs::create_directories(paraview);
  for (const auto& file : fs::directory_iterator(levels.back().at("entry").get<std::string>())) {
    const auto ext = file.path().extension();
    if (ext != ".vtu" && ext != ".pvtu") continue;
    const std::string name = contact.label() + "_reference_" + file.path().filename().string();
    fs::copy_file(file.path(), paraview / name, fs::copy_options::overwrite_existing);
    reference_vtu.push_back("paraview/" + name);
  }
  return {{"model_id", contact.model_id},
          {"label", contact.label()},
          {"rank", fem::MpiSession::rank()},
          {"rebuilt_tool_stiffness_N_per_m", matrix_json(model.tool_stiffness_N_per_m)},
          {"reference_stiffness_N_per_m", matrix_json(k_ref)},
          {"levels", solved_levels},
          {"convergence", convergence},
          {"vertices", vertices},
          {"outside_supports", map.outside_supports},
          {"reference_vtu", reference_vtu},
          {"seconds", seconds_since(start)}};
}

}  // namespace touchstone::studies::replay
