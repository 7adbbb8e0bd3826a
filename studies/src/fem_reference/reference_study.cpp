// `touchstone fem`: mesh every level of every problem variant, solve it with the deal.II
// reference (or take it from the cache of finished solves), Richardson-extrapolate the force per
// mesh family, and write results.json and the VTU/PVD series.
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include "least_squares_line.hpp"

#include "touchstone/fem/richardson.hpp"
#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/studies/fem_reference/probes.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/version.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <unistd.h>

namespace touchstone::studies {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// What makes a cached level record unusable, or "" when it is whole: the level's own parameters
/// (a different problem under a colliding key is not reused), status "ok", and a finite number
/// at every value the reports read.
std::string level_record_defect(const json& level, const json& params) {
  if (!level.is_object()) return "not a JSON object";
  if (level.value("status", "") != "ok") return "its status is not \"ok\"";
  if (!level.contains("params") || level.at("params") != params) return "its parameters are not this level's";
  for (const char* pointer : {"/qoi/axial_force_N", "/qoi/stiffness_N_per_m", "/qoi/energy_J", "/qoi/energy_force_N",
                              "/qoi/k_star", "/mesh/vertices", "/mesh/tetrahedra", "/mesh/fe_nodes", "/mesh/dofs",
                              "/time_s/mesh", "/time_s/read_mesh", "/time_s/setup", "/time_s/assembly",
                              "/time_s/solve", "/time_s/postprocess", "/time_s/build", "/time_s/total"}) {
    const json::json_pointer at(pointer);
    if (!level.contains(at) || !is_finite_number(level.at(at))) return std::string(pointer).substr(1) + " is not a finite number";
  }
  if (!level.contains("/qoi/force_N"_json_pointer) || !is_finite_vector(level.at("/qoi/force_N"_json_pointer)))
    return "qoi/force_N is not three finite numbers";
  if (!level.contains("/mesh/mesh_file"_json_pointer) || !level.at("/mesh/mesh_file"_json_pointer).is_string())
    return "mesh/mesh_file is not a path";
  const json probes = level.at("/qoi"_json_pointer).value("probes", json());
  if (!probes.is_array()) return "qoi/probes is not a list";
  for (const json& probe : probes)
    if (!probe.is_object() || !probe.value("found", json()).is_boolean() ||
        !is_finite_vector(probe.value("displacement_m", json())))
      return "a probe of qoi/probes has no finite displacement_m or no found flag";
  return "";
}

/// Asymptotic convergence order of the punch force: 1, set by the r^(1/2) edge singularity
/// (first order in the edge mesh size). Richardson reports how far the observed order is from it.
constexpr double punch_convergence_order = 1.0;


/// One problem of the study: the study's settings with one value of each sweep.
struct Problem {
  meshes::MeshParameters geometry;
  geometry::Material material;
  fem::RigidPunch punch;
  std::string physical_id;  ///< "B2-frictionless-nu0.45-R0.05": the problem, whatever the mesh
  std::string id;           ///< physical_id, plus "-F<n>" when several mesh families are run
};

std::vector<Problem> expand(const ReferenceStudy& study) {
  const auto or_single = [](auto list, auto value) {
    if (list.empty()) list.push_back(value);
    return list;
  };
  const auto families = or_single(study.edge_sizes_m, study.geometry.edge_size_m);
  std::vector<Problem> problems;
  for (const double radius : or_single(study.body_radii_m, study.geometry.body_radius_m))
    for (const double nu : or_single(study.poisson_ratios, study.material.poisson_ratio))
      for (const geometry::ContactCondition contact : or_single(study.contacts, study.punch.contact))
        for (std::size_t family = 0; family < families.size(); ++family) {
          Problem p{study.geometry, study.material, study.punch, "", ""};
          p.geometry.body_radius_m = radius;
          p.geometry.edge_size_m = families[family];
          if (p.geometry.benchmark == meshes::Benchmark::B1)
            p.geometry.max_size_m = std::max(study.geometry.max_size_m, radius / 4);
          p.material.poisson_ratio = nu;
          p.punch.contact = contact;
          p.physical_id = meshes::to_string(p.geometry.benchmark) + "-" + geometry::to_string(contact) + "-nu" +
                          format_number(nu) + "-" + (p.geometry.benchmark == meshes::Benchmark::B1 ? "W" : "R") +
                          format_number(radius);
          p.id = families.size() > 1 ? p.physical_id + "-F" + std::to_string(family + 1) : p.physical_id;
          problems.push_back(p);
        }
  return problems;
}


/// A level's mesh and where it came from.
struct LevelMesh {
  meshes::MeshSummary summary;  ///< seconds: the wall time this run spent on it (meshing, or taking a cached mesh)
  bool reused = false;          ///< taken from the mesh cache
  double generation_s = 0;      ///< the wall time gmsh took to make it, in this run or when it was cached
};

/// A hard link (no copy of a large mesh) where the file system allows one, else a copy.
void link_or_copy(const fs::path& from, const fs::path& to) {
  std::error_code error;
  fs::remove(to, error);
  fs::create_hard_link(from, to, error);
  if (error) fs::copy_file(from, to, fs::copy_options::overwrite_existing);
}

json problem_params(const Problem& p, const fem::SolverParameters& solver) {
  json params = mesh_parameters_json(p.geometry);
  params["youngs_modulus_Pa"] = p.material.youngs_modulus_Pa;
  params["poisson_ratio"] = p.material.poisson_ratio;
  params["depth_m"] = p.punch.depth_m;
  params["direction"] = vector_json(p.punch.direction.normalized());
  params["contact"] = geometry::to_string(p.punch.contact);
  params["degree"] = solver.degree;
  params["solver"] = fem::to_string(solver.solver);
  params["relative_tolerance"] = solver.relative_tolerance;
  params["formulation"] = fem::to_string(solver.formulation);  // part of the cache key
  return params;
}

/// Axial force: the component of the force on the tissue along the push direction d.
double axial_force(const Eigen::Vector3d& force_on_tissue_N, const Eigen::Vector3d& direction) {
  return force_on_tissue_N.dot(direction.normalized());
}

/// Relative L2 and max-abs difference over matching probes.
std::pair<double, double> probe_errors(const json& probes, const json& reference) {
  double diff2 = 0, ref2 = 0, max_abs = 0;
  for (std::size_t i = 0; i < probes.size() && i < reference.size(); ++i) {
    if (!probes[i].at("found").get<bool>() || !reference[i].at("found").get<bool>()) continue;
    const Eigen::Vector3d u = vector_from_json(probes[i].at("displacement_m"));
    const Eigen::Vector3d r = vector_from_json(reference[i].at("displacement_m"));
    diff2 += (u - r).squaredNorm();
    ref2 += r.squaredNorm();
    max_abs = std::max(max_abs, (u - r).norm());
  }
  return {ref2 > 0 ? std::sqrt(diff2 / ref2) : 0.0, max_abs};
}

class Runner {
 public:
  Runner(const ReferenceStudy& study, const RunOptions& options)
      : study_(study), options_(options), rank0_(fem::MpiSession::rank() == 0) {}

  json run() {
    const auto problems = expand(study_);
    const std::size_t total = problems.size() * study_.refinements.size();
    json document{{"study", study_.name}, {"provenance", provenance(options_.config_text)}, {"cases", json::array()}};
    json& cases = document["cases"];
    json convergence = json::array();
    std::size_t done = 0;
    const auto start = std::chrono::steady_clock::now();
    for (const auto& problem : problems) {
      std::vector<json> levels;
      for (const int refinement : study_.refinements) {
        levels.push_back(solve_level(problem, refinement));
        ++done;
        progress(done, total, start, levels.back());
      }
      add_problem_cases(problem, levels, cases, convergence);
    }
    document["convergence"] = convergence;
    if (study_.edge_sizes_m.size() > 1) document["references"] = combine_families(problems, cases);
    if (study_.geometry.benchmark == meshes::Benchmark::B1) document["half_space_extrapolation"] = half_space_extrapolation(problems, cases);
    if (rank0_) {
      write_file_atomically(options_.output_directory + "/config.resolved.toml", resolved_reference_study_toml(study_));
      write_file_atomically(options_.output_directory + "/results.json", document.dump(2) + "\n");
      write_pvd(cases);
    }
    return document;
  }

 private:
  void progress(std::size_t done, std::size_t total, std::chrono::steady_clock::time_point start, const json& level) const {
    if (!rank0_ || options_.quiet) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double remaining = elapsed / done * (total - done);
    std::printf("[%zu/%zu] %-44s %8zu dofs  F = %.6e N  %s  (elapsed %.0f s, ~%.0f s left)\n", done, total,
                level.at("id").get<std::string>().c_str(), level.at("mesh").at("dofs").get<std::size_t>(),
                axial_force(vector_from_json(level.at("qoi").at("force_N")), study_.punch.direction),
                level.value("cached", false) ? "cached" : "solved", elapsed, remaining);
    std::fflush(stdout);
  }

  /// A level's mesh. With a cache, meshes are kept under cache/meshes by their geometry alone, so
  /// the levels that differ only in material, contact, depth or solver (a Poisson sweep, the
  /// frictionless and bonded references) mesh once. A cache entry is complete only once its
  /// record is written after the mesh; an entry without it, or whose mesh is not the recorded
  /// size (a run killed mid-write, a damaged file), is made again.
  LevelMesh mesh_of_level(const meshes::MeshParameters& geometry, const std::string& msh_path) const {
    LevelMesh out;
    if (options_.cache_directory.empty()) {
      out.summary = meshes::generate_mesh(geometry, msh_path);
      out.generation_s = out.summary.seconds;
      return out;
    }
    const auto start = std::chrono::steady_clock::now();
    const std::string key =
        sha256_hex(mesh_parameters_json(geometry).dump() + touchstone::version::mesh_source_hash + meshes::mesher_version());
    const fs::path directory = fs::path(options_.cache_directory) / "meshes" / key.substr(0, 24);
    const fs::path cached_mesh = directory / "mesh.msh", record_path = directory / "mesh.json";
    std::error_code error;
    if (fs::exists(record_path, error)) {
      try {
        const json record = json::parse(read_file(record_path.string()));
        if (fs::file_size(cached_mesh) == record.at("bytes").get<std::uintmax_t>()) {
          link_or_copy(cached_mesh, msh_path);
          out.summary = {msh_path, record.at("vertices").get<std::size_t>(), record.at("tetrahedra").get<std::size_t>(),
                         record.at("patch_triangles").get<std::size_t>(), seconds_since(start)};
          out.reused = true;
          out.generation_s = record.at("generation_s").get<double>();
          return out;
        }
      } catch (const std::exception&) {
        // Unreadable or inconsistent: made again below, over the damaged entry.
      }
    }
    fs::create_directories(directory);
    // gmsh picks the format from the extension: the temporary must end in .msh.
    const fs::path temporary = directory / ("mesh.part-" + std::to_string(::getpid()) + ".msh");
    try {
      out.summary = meshes::generate_mesh(geometry, temporary.string());
    } catch (...) {
      fs::remove(temporary, error);
      throw;
    }
    fs::rename(temporary, cached_mesh);
    write_file_atomically(record_path.string(), json{{"vertices", out.summary.node_count},
                                                     {"tetrahedra", out.summary.tetrahedron_count},
                                                     {"patch_triangles", out.summary.patch_triangle_count},
                                                     {"generation_s", out.summary.seconds},
                                                     {"bytes", fs::file_size(cached_mesh)},
                                                     {"mesher", meshes::mesher_version()},
                                                     {"geometry", mesh_parameters_json(geometry)}}
                                                    .dump(2) + "\n");
    link_or_copy(cached_mesh, msh_path);
    out.summary.path = msh_path;
    out.generation_s = out.summary.seconds;
    return out;
  }

  /// One mesh level of one problem: from the cache when the same inputs were solved by the
  /// same FEM sources (version::fem_source_hash), else meshed and solved (VTU kept in the
  /// cache entry).
  json solve_level(const Problem& problem, int refinement) {
    Problem p = problem;
    p.geometry.refinement = refinement;
    const std::string id = problem.id + "-L" + std::to_string(refinement);
    json params = problem_params(p, study_.solver);
    const std::string key = sha256_hex(params.dump() + touchstone::version::fem_source_hash + "deal.II-9.4");
    const std::string entry = options_.cache_directory.empty()
                                  ? options_.output_directory + "/work/" + id
                                  : options_.cache_directory + "/fem/" + key.substr(0, 24);
    const std::string cached_json = entry + "/case.json";

    fem::MpiSession::barrier();
    if (!options_.cache_directory.empty() && fs::exists(cached_json)) {
      // Every rank reads the same file, so every rank takes the same branch.
      json level = read_cached_level(cached_json, params);
      if (!level.is_null()) {
        level["id"] = id;
        level["cached"] = true;
        copy_vtu(level, id);
        return level;
      }
    }

    LevelMesh level_mesh;
    const std::string msh_path = entry + "/mesh.msh";
    if (rank0_) {
      fs::create_directories(entry);
      level_mesh = mesh_of_level(p.geometry, msh_path);
    }
    fem::MpiSession::barrier();
    const meshes::MeshSummary& mesh = level_mesh.summary;

    fem::ElasticityProblem fem_problem;
    fem_problem.mesh_path = msh_path;
    fem_problem.material = p.material;
    fem_problem.punch = p.punch;
    fem_problem.solver = study_.solver;
    const auto probes = indentation_probes(p.geometry, p.punch.direction);
    for (const auto& probe : probes) fem_problem.probes.push_back(probe.position_m);
    if (study_.write_vtu) {
      fem_problem.vtu_directory = entry;
      fem_problem.vtu_basename = "solution";
    }
    const fem::ElasticitySolution s = fem::solve_elasticity(fem_problem);

    const double f = axial_force(s.force_N, p.punch.direction);
    const double a = p.geometry.tool_radius_m, delta = p.punch.depth_m, e = p.material.youngs_modulus_Pa;
    json probe_list = json::array();
    for (std::size_t i = 0; i < probes.size(); ++i)
      probe_list.push_back({{"name", probes[i].name},
                            {"position_m", vector_json(probes[i].position_m)},
                            {"displacement_m", vector_json(s.probe_displacements_m[i])},
                            {"found", static_cast<bool>(s.probe_found[i])}});
    const double build = s.setup_s + s.assembly_s;
    json level{
        {"id", id},
        {"model", "fem"},
        {"params", params},
        {"qoi",
         {{"force_N", vector_json(s.force_N)},
          {"axial_force_N", f},
          {"stiffness_N_per_m", f / delta},
          {"energy_J", s.energy_J},
          {"energy_force_N", s.energy_force_N},
          {"k_star", f / (e * a * delta)},
          {"probes", probe_list}}},
        {"mesh",
         {{"vertices", mesh.node_count},
          {"tetrahedra", s.cell_count},
          {"fe_nodes", s.node_count},
          {"dofs", s.dof_count},
          {"mesh_file", msh_path}}},
        {"solver",
         {{"name", s.solver_name},
          {"iterations", s.solver_iterations},
          {"residual", s.solver_residual},
          {"mpi_processes", s.mpi_processes}}},
        // time_s.mesh and the total count gmsh's time even when the mesh came from the cache: a
        // level's cost, which the speed comparisons use, must not depend on what the cache held.
        {"time_s",
         {{"mesh", level_mesh.generation_s},
          {"mesh_reused", level_mesh.reused},
          {"mesh_this_run", mesh.seconds},
          {"read_mesh", s.read_mesh_s},
          {"setup", s.setup_s},
          {"assembly", s.assembly_s},
          {"solve", s.solve_s},
          {"postprocess", s.postprocess_s},
          {"output", s.output_s},
          {"build", build},
          {"total", level_mesh.generation_s + s.read_mesh_s + build + s.solve_s + s.postprocess_s}}},
        {"vtu", s.vtu_file.empty() ? "" : fs::path(s.vtu_file).filename().string()},
        {"status", "ok"},
        {"cached", false}};
    if (rank0_) write_file_atomically(cached_json, level.dump(2) + "\n");
    // Every rank needs the same record; the mesh counts are known on rank 0 only.
    fem::MpiSession::barrier();
    level = json::parse(read_file(cached_json));
    copy_vtu(level, id);
    return level;
  }

  /// A cached level's record, or null when the entry is damaged (a hand edit, a disk error, a
  /// file from another version): the level is then solved again over it, with a warning that
  /// names the file and what is wrong, instead of a bare JSON error ending the run.
  json read_cached_level(const std::string& path, const json& params) const {
    std::string defect;
    try {
      json level = json::parse(read_file(path));
      defect = level_record_defect(level, params);
      if (defect.empty()) return level;
    } catch (const std::exception& e) {
      defect = e.what();
    }
    if (rank0_)
      std::fprintf(stderr, "warning: %s: damaged FEM cache entry (%s); solving the level again\n", path.c_str(),
                   defect.c_str());
    return nullptr;
  }

  /// The VTU of a level lives in its cache entry; the output folder gets its own copy so that
  /// it is self-contained for ParaView.
  void copy_vtu(json& level, const std::string& id) {
    if (!rank0_ || level.value("vtu", "").empty()) return;
    const fs::path entry = fs::path(level.at("mesh").at("mesh_file").get<std::string>()).parent_path();
    const fs::path target = fs::path(options_.output_directory) / "vtu" / id;
    fs::create_directories(target);
    for (const auto& file : fs::directory_iterator(entry)) {
      const auto ext = file.path().extension();
      if (ext == ".vtu" || ext == ".pvtu") fs::copy_file(file.path(), target / file.path().filename(), fs::copy_options::overwrite_existing);
    }
    level["vtu"] = (fs::path("vtu") / id / level.at("vtu").get<std::string>()).string();
  }

  void add_problem_cases(const Problem& problem, std::vector<json>& levels, json& cases, json& convergence) {
    const Eigen::Vector3d d = problem.punch.direction.normalized();
    const double a = problem.geometry.tool_radius_m, delta = problem.punch.depth_m;
    const double e = problem.material.youngs_modulus_Pa;
    std::vector<double> forces;
    for (const auto& level : levels) forces.push_back(level.at("qoi").at("axial_force_N").get<double>());

    const std::string richardson_id = problem.id + "-richardson";
    const std::string analytic_id = problem.physical_id + "-halfspace";
    const bool has_analytic = problem.geometry.benchmark == meshes::Benchmark::B1 ||
                              problem.geometry.benchmark == meshes::Benchmark::B2;
    const json& finest = levels.back();
    const json& reference_probes = finest.at("qoi").at("probes");

    json summary{{"problem", problem.id}, {"physical_problem", problem.physical_id},
                 {"edge_size_m", problem.geometry.edge_size_m}, {"levels", json::array()}};
    for (auto& level : levels) {
      summary["levels"].push_back({{"dofs", level.at("mesh").at("dofs")}, {"axial_force_N", level.at("qoi").at("axial_force_N")}});
    }
    double extrapolated = forces.back();
    if (forces.size() >= 3) {
      const fem::RichardsonEstimate r = fem::richardson_extrapolate(forces, 2.0, punch_convergence_order);
      extrapolated = r.extrapolated;
      summary["observed_order"] = std::isfinite(r.observed_order) ? json(r.observed_order) : json(nullptr);
      summary["extrapolated_force_N"] = r.extrapolated;
      summary["finest_relative_error"] = r.finest_relative_error;
      summary["gci_finest"] = r.gci_finest;
      summary["extrapolated_relative_uncertainty"] = r.extrapolated_relative_uncertainty;
      summary["asymptotic"] = r.asymptotic;
    } else {
      summary["note"] = "fewer than three levels: no extrapolation";
    }

    for (auto& level : levels) {
      const double f = level.at("qoi").at("axial_force_N").get<double>();
      const auto [rel_l2, max_abs] = probe_errors(level.at("qoi").at("probes"), reference_probes);
      level["reference"] = richardson_id;
      level["error"] = {{"force_rel", std::abs(f - extrapolated) / std::abs(extrapolated)},
                        {"disp_rel_l2", rel_l2},
                        {"disp_max_m", max_abs},
                        {"disp_reference", finest.at("id")}};
      cases.push_back(level);
    }

    const double k_star = extrapolated / (e * a * delta);
    json richardson{{"id", richardson_id},
                    {"model", "fem"},
                    {"params", finest.at("params")},
                    {"qoi",
                     {{"force_N", vector_json(extrapolated * d)},
                      {"axial_force_N", extrapolated},
                      {"stiffness_N_per_m", extrapolated / delta},
                      {"energy_J", 0.5 * extrapolated * delta},
                      {"k_star", k_star},
                      {"probes", reference_probes}}},
                    {"convergence", summary},
                    {"time_s", {{"build", 0.0}, {"solve", 0.0}, {"total", 0.0}}},
                    {"status", forces.size() >= 3 && summary.value("asymptotic", false) ? "ok" : "not_asymptotic"}};
    richardson["params"]["refinement"] = "extrapolated";
    if (has_analytic) {
      const double f_hs = half_space_punch_force_N(problem.material, a, delta, problem.punch.contact);
      richardson["reference"] = analytic_id;
      richardson["error"] = {{"force_rel", std::abs(extrapolated - f_hs) / f_hs}, {"disp_rel_l2", nullptr}, {"disp_max_m", nullptr}};
      richardson["qoi"]["ratio_to_half_space"] = extrapolated / f_hs;
      summary["ratio_to_half_space"] = extrapolated / f_hs;
      summary["k_star_half_space"] = f_hs / (e * a * delta);
      cases.push_back(richardson);
      const bool listed = std::any_of(cases.begin(), cases.end(), [&](const json& c) { return c.at("id") == analytic_id; });
      if (!listed)
        cases.push_back({{"id", analytic_id},
                       {"model", "analytic"},
                       {"params", {{"formula", problem.punch.contact == geometry::ContactCondition::frictionless
                                                   ? "Sneddon F = 2 E a delta / (1 - nu^2)"
                                                   : "Mossakovskii F = 4 G a delta ln(3 - 4 nu) / (1 - 2 nu)"},
                                   {"youngs_modulus_Pa", e},
                                   {"poisson_ratio", problem.material.poisson_ratio},
                                   {"tool_radius_m", a},
                                   {"depth_m", delta}}},
                       {"qoi", {{"force_N", vector_json(f_hs * d)}, {"axial_force_N", f_hs}, {"stiffness_N_per_m", f_hs / delta},
                                {"energy_J", 0.5 * f_hs * delta}, {"k_star", f_hs / (e * a * delta)}}},
                       {"reference", nullptr},
                       {"error", {{"force_rel", nullptr}, {"disp_rel_l2", nullptr}, {"disp_max_m", nullptr}}},
                       {"time_s", {{"build", 0.0}, {"solve", 0.0}, {"total", 0.0}}},
                       {"status", "ok"}});
    } else {
      richardson["reference"] = nullptr;
      richardson["error"] = {{"force_rel", nullptr}, {"disp_rel_l2", nullptr}, {"disp_max_m", nullptr}};
      cases.push_back(richardson);
    }
    summary["k_star"] = k_star;
    convergence.push_back(summary);
    if (rank0_ && !options_.quiet) print_summary(summary);
  }

  static void print_summary(const json& s) {
    std::printf("\n%s\n", s.at("problem").get<std::string>().c_str());
    for (const auto& level : s.at("levels"))
      std::printf("  %9zu dofs   F = %.8e N\n", level.at("dofs").get<std::size_t>(), level.at("axial_force_N").get<double>());
    if (s.contains("extrapolated_force_N")) {
      std::printf("  Richardson: F = %.8e N, observed order %s, finest-mesh error %.3f %%, GCI %.3f %%, "
                  "extrapolation uncertainty %.3f %%\n",
                  s.at("extrapolated_force_N").get<double>(),
                  s.at("observed_order").is_null() ? "n/a" : format_number(s.at("observed_order").get<double>()).c_str(),
                  100 * s.at("finest_relative_error").get<double>(), 100 * s.at("gci_finest").get<double>(),
                  100 * s.at("extrapolated_relative_uncertainty").get<double>());
    }
    if (s.contains("ratio_to_half_space"))
      std::printf("  k* = F/(E a delta) = %.5f; half-space k* = %.5f; ratio %.5f\n", s.at("k_star").get<double>(),
                  s.at("k_star_half_space").get<double>(), s.at("ratio_to_half_space").get<double>());
  }

  /// Several mesh families (different edge sizes, same grading) give independent Richardson
  /// values. If a first-order error term (from the edge floor) still dominated, their
  /// extrapolations would differ by a sizeable fraction of it; their spread therefore bounds the
  /// error left in the extrapolated force better than one family can. The reference is the
  /// mean; its uncertainty the spread (max − min) / mean.
  json combine_families(const std::vector<Problem>& problems, json& cases) const {
    json out = json::array();
    std::vector<std::string> physical_ids;
    for (const auto& p : problems)
      if (std::find(physical_ids.begin(), physical_ids.end(), p.physical_id) == physical_ids.end()) physical_ids.push_back(p.physical_id);
    for (const auto& physical_id : physical_ids) {
      std::vector<double> values;
      const json* last = nullptr;
      for (const auto& c : cases) {
        const std::string id = c.at("id");
        if (id.rfind(physical_id + "-F", 0) == 0 && id.size() > 11 && id.substr(id.size() - 11) == "-richardson") {
          values.push_back(c.at("qoi").at("axial_force_N").get<double>());
          last = &c;
        }
      }
      if (values.empty() || last == nullptr) continue;
      double mean = 0;
      for (const double v : values) mean += v / values.size();
      const auto [low, high] = std::minmax_element(values.begin(), values.end());
      const double spread = (*high - *low) / std::abs(mean);
      json reference = *last;
      reference["id"] = physical_id + "-reference";
      reference["params"]["edge_size_m"] = "families";
      reference["qoi"]["force_N"] = vector_json(mean / last->at("qoi").at("axial_force_N").get<double>() *
                                                vector_from_json(last->at("qoi").at("force_N")));
      reference["qoi"]["axial_force_N"] = mean;
      reference["qoi"]["stiffness_N_per_m"] = mean / study_.punch.depth_m;
      reference["qoi"]["energy_J"] = 0.5 * mean * study_.punch.depth_m;
      const double e = last->at("params").at("youngs_modulus_Pa").get<double>(), a = last->at("params").at("tool_radius_m").get<double>();
      reference["qoi"]["k_star"] = mean / (e * a * study_.punch.depth_m);
      reference["convergence"] = {{"family_forces_N", values}, {"family_spread_relative", spread}};
      reference["status"] = "ok";
      if (reference.contains("reference") && reference.at("reference").is_string()) {
        for (const auto& c : cases)
          if (c.at("id") == reference.at("reference")) {
            const double f_hs = c.at("qoi").at("axial_force_N").get<double>();
            reference["error"]["force_rel"] = std::abs(mean - f_hs) / f_hs;
            reference["qoi"]["ratio_to_half_space"] = mean / f_hs;
          }
      }
      json summary{{"problem", physical_id}, {"family_forces_N", values}, {"reference_force_N", mean},
                   {"relative_uncertainty", spread}, {"k_star", reference["qoi"]["k_star"]}};
      if (reference["qoi"].contains("ratio_to_half_space")) summary["ratio_to_half_space"] = reference["qoi"]["ratio_to_half_space"];
      if (rank0_ && !options_.quiet)
        std::printf("\n%s reference over %zu mesh families: F = %.8e N, k* = %.5f, spread %.4f %%%s\n", physical_id.c_str(),
                    values.size(), mean, reference["qoi"]["k_star"].get<double>(), 100 * spread,
                    summary.contains("ratio_to_half_space")
                        ? (", ratio to half-space " + format_number(summary["ratio_to_half_space"].get<double>())).c_str()
                        : "");
      out.push_back(summary);
      cases.push_back(reference);
    }
    return out;
  }

  /// B1: the clamped base at depth W stiffens the punch by about a/W. Fit the converged force
  /// ratio F/F_half-space = r₀ + c·(a/W) by least squares per (contact, ν): r₀ − 1 is the error
  /// of the reference against the closed form, c the measured finite-size correction.
  json half_space_extrapolation(const std::vector<Problem>& problems, const json& cases) const {
    json out = json::array();
    std::map<std::pair<int, double>, std::vector<std::pair<double, double>>> series;
    for (const auto& problem : problems) {
      for (const auto& c : cases)
        if (c.at("id") == problem.id + "-richardson")
          series[{static_cast<int>(problem.punch.contact), problem.material.poisson_ratio}].push_back(
              {problem.geometry.tool_radius_m / problem.geometry.body_radius_m, c.at("qoi").at("ratio_to_half_space").get<double>()});
    }
    for (const auto& [key, points] : series) {
      json entry{{"contact", geometry::to_string(static_cast<geometry::ContactCondition>(key.first))}, {"poisson_ratio", key.second}};
      json xs = json::array(), ys = json::array();
      for (const auto& [x, y] : points) {
        xs.push_back(x);
        ys.push_back(y);
      }
      entry["a_over_W"] = xs;
      entry["force_ratio"] = ys;
      if (const std::optional<Line> line = least_squares_line(points)) {
        const double slope = line->slope, intercept = line->intercept;
        entry["extrapolated_ratio"] = intercept;
        entry["finite_size_slope"] = slope;
        entry["error_rel"] = std::abs(intercept - 1);
        if (rank0_ && !options_.quiet)
          std::printf("\nB1 half-space limit, %s, nu = %g: F/F_closed_form -> %.5f as a/W -> 0 (error %.3f %%), "
                      "finite-size correction F/F0 = 1 + %.3f a/W\n",
                      entry["contact"].get<std::string>().c_str(), key.second, intercept, 100 * std::abs(intercept - 1),
                      slope / intercept);
      }
      out.push_back(entry);
    }
    return out;
  }

  /// One PVD per problem, the levels as successive "times", so ParaView steps through them.
  void write_pvd(const json& cases) const {
    std::map<std::string, std::vector<std::pair<int, std::string>>> by_problem;
    for (const auto& c : cases) {
      if (c.at("model") != "fem" || c.value("vtu", "").empty() || !c.at("params").at("refinement").is_number()) continue;
      const std::string id = c.at("id");
      by_problem[id.substr(0, id.rfind("-L"))].push_back({c.at("params").at("refinement").get<int>(), c.at("vtu")});
    }
    for (const auto& [problem, files] : by_problem) {
      std::ostringstream pvd;
      pvd << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n";
      for (const auto& [level, file] : files) pvd << "    <DataSet timestep=\"" << level << "\" group=\"\" part=\"0\" file=\"" << file << "\"/>\n";
      pvd << "  </Collection>\n</VTKFile>\n";
      write_file_atomically(options_.output_directory + "/" + problem + ".pvd", pvd.str());
    }
  }

  const ReferenceStudy& study_;
  const RunOptions& options_;
  bool rank0_;
};

}  // namespace

double half_space_punch_force_N(const geometry::Material& material, double tool_radius_m, double depth_m,
                                geometry::ContactCondition contact) {
  const double e = material.youngs_modulus_Pa, nu = material.poisson_ratio;
  if (contact == geometry::ContactCondition::frictionless) return 2 * e * tool_radius_m * depth_m / (1 - nu * nu);
  return 4 * material.shear_modulus_Pa() * tool_radius_m * depth_m * std::log(3 - 4 * nu) / (1 - 2 * nu);
}

void ReferenceStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("study name is empty");
  meshes::MeshParameters checked = geometry;
  if (!generated_organ.empty()) {
    if (geometry.benchmark != meshes::Benchmark::Organ)
      throw std::invalid_argument("organ.generate = '" + generated_organ + "' needs geometry.benchmark = organ");
    if (!geometry.organ.surface_path.empty())
      throw std::invalid_argument("organ.generate and organ.surface are both set: give one");
    validate_generated_organ(generated_organ, generated_organ_triangles);
    checked.organ.surface_path = "(generated)";
  }
  checked.validate();
  if (geometry.benchmark == meshes::Benchmark::Organ && geometry.organ.attachment.rule_count() == 0) {
    const bool frictionless = contacts.empty() ? punch.contact == geometry::ContactCondition::frictionless
                                               : std::count(contacts.begin(), contacts.end(), geometry::ContactCondition::frictionless) > 0;
    if (frictionless)
      throw std::invalid_argument(
          "organ: no attachment is set, and a frictionless tool holds only the push direction: the organ could slide and spin "
          "(rigid-body modes). Set organ.attachment_plane_point/attachment_plane_normal, attachment_group or attachment_triangles, "
          "or use a bonded tool");
  }
  material.validate();
  punch.validate();
  solver.validate();
  if (refinements.empty()) throw std::invalid_argument("mesh.refinements is empty");
  for (std::size_t i = 1; i < refinements.size(); ++i)
    if (refinements[i] != refinements[i - 1] + 1)
      throw std::invalid_argument("mesh.refinements must be consecutive levels (each halves the size), e.g. [0, 1, 2]");
  for (const double nu : poisson_ratios) {
    geometry::Material m = material;
    m.poisson_ratio = nu;
    m.validate();
  }
  // A tool pushed through the body is no indentation: the depth must stay inside the body's
  // thickness under the tool (W on B1's flat top, R along the sphere's inward normal on B2 and
  // B5, the smaller of R and L on B3).
  const auto check_depth_inside = [&](const meshes::MeshParameters& g) {
    double thickness = std::numeric_limits<double>::infinity();
    std::string bound;
    switch (g.benchmark) {
      case meshes::Benchmark::B1: thickness = g.body_radius_m, bound = "geometry.body_radius_m (W)"; break;
      case meshes::Benchmark::B2:
      case meshes::Benchmark::B5: thickness = g.body_radius_m, bound = "geometry.body_radius_m (R)"; break;
      case meshes::Benchmark::B3:
        thickness = std::min(g.body_radius_m, g.local_radius_m), bound = "the smaller of geometry.body_radius_m and local_radius_m";
        break;
      default: return;
    }
    if (!(punch.depth_m < thickness))
      throw std::invalid_argument("tool.depth_m = " + format_number(punch.depth_m) + " must be < " + format_number(thickness) +
                                  " m, the body's thickness under the tool (" + bound + ")");
  };
  check_depth_inside(geometry);
  for (const double r : body_radii_m) {
    meshes::MeshParameters g = geometry;
    g.body_radius_m = r;
    g.validate();
    check_depth_inside(g);
  }
  for (const double h : edge_sizes_m) {
    meshes::MeshParameters g = geometry;
    g.edge_size_m = h;
    g.validate();
  }
}

void validate_generated_organ(const std::string& shape, int triangles) {
  meshes::organ_shape_from_string(shape);  // throws naming the value
  if (triangles < 100 || triangles > 1000000)
    throw std::invalid_argument("organ.generate_triangles = " + std::to_string(triangles) + " must be in [100, 1000000]");
}

std::string generated_organ_surface(const std::string& shape, int triangles, double hemisphere_radius_m, const std::string& folder) {
  const fs::path organs = fs::path(folder) / "organs";
  std::ostringstream name;
  name << shape << "_" << triangles << "_R" << format_number(hemisphere_radius_m) << ".stl";
  const std::string path = (organs / name.str()).string();
  if (fem::MpiSession::rank() == 0 && !fs::exists(path)) {
    fs::create_directories(organs);
    meshes::OrganParameters organ;
    organ.shape = meshes::organ_shape_from_string(shape);
    organ.target_triangles = triangles;
    organ.hemisphere_radius_m = hemisphere_radius_m;
    meshes::write_organ_mesh(organ, path + ".partial.stl");
    fs::rename(path + ".partial.stl", path);
  }
  fem::MpiSession::barrier();
  return fs::absolute(path).lexically_normal().string();
}

nlohmann::json run_reference_study(const ReferenceStudy& study, const RunOptions& options) {
  study.validate();
  if (study.generated_organ.empty()) return Runner(study, options).run();
  // The generated surface is deterministic: one file per shape, size and count, shared by runs.
  ReferenceStudy with_surface = study;
  with_surface.geometry.organ.surface_path =
      generated_organ_surface(study.generated_organ, study.generated_organ_triangles, study.geometry.body_radius_m,
                              options.cache_directory.empty() ? options.output_directory : options.cache_directory);
  with_surface.generated_organ.clear();  // config.resolved.toml names the file that was used
  return Runner(with_surface, options).run();
}

json mesh_parameters_json(const meshes::MeshParameters& g) {
  json parameters{{"benchmark", meshes::to_string(g.benchmark)},
          {"body_radius_m", g.body_radius_m},
          {"tool_radius_m", g.tool_radius_m},
          {"local_radius_m", g.local_radius_m},
          {"contact_polar_angle_rad", g.contact_polar_angle_rad},
          {"exterior_of_local_ball", g.exterior_of_local_ball},
          {"edge_size_m", g.edge_size_m},
          {"size_growth", g.size_growth},
          {"size_exponent", g.size_exponent},
          {"power_grading_extent", g.power_grading_extent},
          {"max_size_m", g.max_size_m},
          {"refinement", g.refinement}};
  if (g.benchmark != meshes::Benchmark::Organ) return parameters;
  // The surface by its content: an edited file is a new problem, a moved one is not.
  const meshes::OrganBody& o = g.organ;
  const meshes::OrganAttachment& held = o.attachment;
  parameters["organ"] = {{"surface_sha256", sha256_hex(read_file(o.surface_path))},
                         {"unit_scale", o.unit_scale},
                         {"contact_point_m", o.contact_point_m},
                         {"tool_axis", o.tool_axis},
                         {"attachment_plane_point_m", held.plane_point_m},
                         {"attachment_plane_normal", held.plane_normal},
                         {"attachment_group", held.msh_group},
                         {"attachment_triangles_sha256", held.triangles_path.empty() ? "" : sha256_hex(read_file(held.triangles_path))},
                         {"feature_angle_rad", o.feature_angle_rad}};
  return parameters;
}

}  // namespace touchstone::studies
