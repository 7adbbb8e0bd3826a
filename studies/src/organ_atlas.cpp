#include "touchstone/studies/organ_atlas.hpp"

#include "fem_reference/setting_fields.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include "touchstone/fem/richardson.hpp"
#include "touchstone/meshes/organ_body_mesh.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/realtime/mfs/punch_field.hpp"
#include "touchstone/realtime/mfs/quadrature_rules.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/version.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace touchstone::studies {
namespace fs = std::filesystem;
using nlohmann::json;
using realtime::mfs::PunchFrame;
using realtime::mfs::PunchMode;

namespace {

constexpr double pi = 3.14159265358979323846;

/// Energy converges at the order of the geometry error: the curved cut and free surfaces are
/// faceted (linear mapping), an O(h²) change of the domain; the P2 field error itself enters the
/// energy at O(h⁴) for the smooth traces here.
constexpr double energy_convergence_order = 2.0;

Eigen::Vector3d to_eigen(const std::array<double, 3>& p) { return {p[0], p[1], p[2]}; }

constexpr std::array<PunchMode, 3> mode_order{{PunchMode::normal, PunchMode::tangential_1, PunchMode::tangential_2}};

int mode_count(AtlasModes modes) { return modes == AtlasModes::normal ? 1 : 3; }

/// The Dirichlet traces on the cut, per unit amplitude: the punch modes, then the cut's uniform
/// translations along the frame's e₃, e₁, e₂ (the modes' order).
struct CutTrace {
  std::string name;
  std::function<Eigen::Vector3d(const Eigen::Vector3d&)> field;  ///< [m per unit amplitude]
};

std::vector<CutTrace> cut_traces(AtlasModes modes, bool cut_translations, const PunchFrame& frame, double a,
                                 const geometry::Material& material) {
  static const char* const mode_names[3] = {"normal", "tangential_1", "tangential_2"};
  static const char* const shift_names[3] = {"shift_e3", "shift_e1", "shift_e2"};
  std::vector<CutTrace> traces;
  for (int m = 0; m < mode_count(modes); ++m) {
    const PunchMode mode = mode_order[static_cast<std::size_t>(m)];
    traces.push_back({mode_names[m], [frame, a, material, mode](const Eigen::Vector3d& x) {
                        return realtime::mfs::punch_field(mode, frame, a, material, x).displacement;
                      }});
  }
  if (cut_translations) {
    const Eigen::Vector3d axes[3] = {frame.axes.col(2), frame.axes.col(0), frame.axes.col(1)};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d e = axes[k];
      traces.push_back({shift_names[k], [e](const Eigen::Vector3d&) { return e; }});
    }
  }
  return traces;
}

std::string sample_label(const meshes::MeshParameters& g) {
  if (g.benchmark == meshes::Benchmark::B1) return "top_centre";
  if (g.benchmark == meshes::Benchmark::Organ) {
    const auto& p = g.organ.contact_point_m;
    return "site(" + format_number(std::round(p[0] * 1e7) / 1e4) + "," + format_number(std::round(p[1] * 1e7) / 1e4) + "," +
           format_number(std::round(p[2] * 1e7) / 1e4) + ")mm";
  }
  return "theta=" + format_number(std::round(g.contact_polar_angle_rad * 180 / pi * 1e6) / 1e6) + "deg";
}

}  // namespace

std::string to_string(AtlasModes modes) { return modes == AtlasModes::normal ? "normal" : "all"; }

std::vector<std::array<double, 3>> organ_atlas_sites(const OrganAtlasStudy& study) {
  const meshes::OrganBody& organ = study.geometry.organ;
  meshes::OrganBody centre_query = organ;
  centre_query.tool_axis = {0.0, 0.0, 0.0};
  if (std::isnan(study.region_centre_m[0])) {
    meshes::SurfaceReadOptions read;
    read.unit_scale = organ.unit_scale;
    read.weld_vertices = true;
    const meshes::SurfaceMesh surface = meshes::read_surface_mesh(organ.surface_path, read);
    if (surface.vertices.empty()) throw std::invalid_argument("organ surface '" + organ.surface_path + "' has no vertices");
    const Eigen::Vector3d top = *std::max_element(surface.vertices.begin(), surface.vertices.end(),
                                                  [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return a.z() < b.z(); });
    centre_query.contact_point_m = {top.x(), top.y(), top.z()};
  } else {
    centre_query.contact_point_m = study.region_centre_m;
  }
  const meshes::OrganContactSite centre = meshes::organ_contact_site(centre_query);
  const Eigen::Vector3d c = to_eigen(centre.point_m), n = to_eigen(centre.outward_normal);
  const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
  const double spacing = study.sample_spacing_m > 0 ? study.sample_spacing_m : study.geometry.local_radius_m;
  const int reach = static_cast<int>(std::ceil(study.region_radius_m / spacing)) + 1;
  std::vector<std::array<double, 3>> sites;
  for (int j = -reach; j <= reach; ++j)
    for (int i = -2 * reach; i <= 2 * reach; ++i) {
      const Eigen::Vector2d lattice = spacing * Eigen::Vector2d(i + 0.5 * j, std::sqrt(3.0) / 2 * j);
      if (lattice.norm() > study.region_radius_m * (1 + 1e-12)) continue;
      const Eigen::Vector3d p = c + lattice.x() * t1 + lattice.y() * t2;
      sites.push_back({p.x(), p.y(), p.z()});
    }
  std::sort(sites.begin(), sites.end(), [&c](const auto& a, const auto& b) {
    return (to_eigen(a) - c).squaredNorm() < (to_eigen(b) - c).squaredNorm();
  });
  return sites;
}

realtime::mfs::PunchFrame atlas_punch_frame(const meshes::MeshParameters& geometry) {
  const meshes::ContactSite site = meshes::contact_site(geometry);
  const Eigen::Vector3d c = to_eigen(site.point_m), n = to_eigen(site.outward_normal);
  Eigen::Vector3d origin = c;
  if (geometry.benchmark == meshes::Benchmark::Organ) {
    origin = to_eigen(meshes::organ_rim_centre(geometry.organ, geometry.tool_radius_m));
  } else if (geometry.benchmark != meshes::Benchmark::B1) {
    const double r = geometry.body_radius_m, a = geometry.tool_radius_m;
    origin = c - (r - std::sqrt(r * r - a * a)) * n;
  }
  return PunchFrame::along(origin, -n);
}

Eigen::Matrix3d half_space_exterior_stiffness_N_per_m(double tool_radius_m, double local_radius_m,
                                                      const geometry::Material& material, int polar_points,
                                                      int azimuth_points) {
  if (!(local_radius_m > tool_radius_m) || !(tool_radius_m > 0))
    throw std::invalid_argument("half_space_exterior_stiffness_N_per_m: local_radius_m = " +
                                format_number(local_radius_m) + " must exceed tool_radius_m = " +
                                format_number(tool_radius_m) + " > 0");
  if (polar_points < 2 || azimuth_points < 4)
    throw std::invalid_argument("half_space_exterior_stiffness_N_per_m: needs >= 2 polar and >= 4 azimuth points");
  material.validate();
  const PunchFrame frame = PunchFrame::along(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
  std::vector<double> x, w;
  realtime::mfs::gauss_legendre(polar_points, x, w);
  const double l = local_radius_m;
  Eigen::Matrix3d k = Eigen::Matrix3d::Zero();
  for (int i = 0; i < polar_points; ++i) {
    const double phi = 0.5 * pi * x[i];  // from the axis e₃ (into the body) to the surface
    const double polar_weight = 0.5 * pi * w[i] * l * l * std::sin(phi);
    for (int j = 0; j < azimuth_points; ++j) {
      const double alpha = 2 * pi * j / azimuth_points;
      const Eigen::Vector3d normal(std::sin(phi) * std::cos(alpha), std::sin(phi) * std::sin(alpha), std::cos(phi));
      const Eigen::Vector3d point = l * normal;
      const double weight = polar_weight * 2 * pi / azimuth_points;
      std::array<realtime::mfs::PunchFieldSample, 3> fields;
      for (int m = 0; m < 3; ++m) fields[m] = realtime::mfs::punch_field(mode_order[m], frame, tool_radius_m, material, point);
      for (int m = 0; m < 3; ++m)
        for (int n = 0; n < 3; ++n)
          k(m, n) -= weight * fields[m].displacement.dot(fields[n].stress_Pa_per_m * normal);
    }
  }
  return 0.5 * (k + k.transpose());
}

ExteriorStiffness exterior_stiffness_fem(const meshes::MeshParameters& geometry, const geometry::Material& material,
                                         AtlasModes modes, bool cut_translations, const std::vector<int>& refinements,
                                         double trace_depth_m, const fem::SolverParameters& solver,
                                         const AtlasRunOptions& options, const std::string& work_directory) {
  using Matrix = ExteriorStiffness::Matrix;
  const bool rank0 = fem::MpiSession::rank() == 0;
  meshes::MeshParameters g = geometry;
  g.exterior_of_local_ball = true;
  const PunchFrame frame = atlas_punch_frame(geometry);
  const std::vector<CutTrace> traces = cut_traces(modes, cut_translations, frame, g.tool_radius_m, material);
  const int n = static_cast<int>(traces.size());

  ExteriorStiffness result;
  const auto start = std::chrono::steady_clock::now();
  for (const int level : refinements) {
    g.refinement = level;
    json key_params{{"geometry", mesh_parameters_json(g)},
                    {"youngs_modulus_Pa", material.youngs_modulus_Pa},
                    {"poisson_ratio", material.poisson_ratio},
                    {"trace_depth_m", trace_depth_m},
                    {"degree", solver.degree},
                    {"formulation", fem::to_string(solver.formulation)},
                    {"solver", fem::to_string(solver.solver)},
                    {"relative_tolerance", solver.relative_tolerance},
                    {"frame_origin_m", vector_json(frame.origin)},
                    {"frame_e1", vector_json(frame.axes.col(0))},
                    {"frame_e3", vector_json(frame.axes.col(2))}};
    const std::string key = sha256_hex(key_params.dump() + touchstone::version::atlas_source_hash);
    const std::string entry = options.cache_directory.empty()
                                  ? (fs::path(work_directory) / ("L" + std::to_string(level))).string()
                                  : options.cache_directory + "/atlas/" + key.substr(0, 24);
    const std::string solves_path = entry + "/solves.json";
    const std::string msh_path = entry + "/mesh.msh";

    fem::MpiSession::barrier();
    // One entry per trace: its energy and its reaction's work against every trace of this run
    // (an entry made without some of them is solved again).
    json solves = json::object();
    if (!options.cache_directory.empty() && fs::exists(solves_path)) solves = json::parse(read_file(solves_path));
    const auto complete = [&](const CutTrace& t) {
      if (!solves.contains(t.name)) return false;
      const json& works = solves.at(t.name).at("works_J");
      return std::all_of(traces.begin(), traces.end(), [&](const CutTrace& u) { return works.contains(u.name); });
    };
    const bool missing = !std::all_of(traces.begin(), traces.end(), complete);
    if (missing && (options.cache_directory.empty() || !fs::exists(msh_path))) {
      if (rank0) {
        fs::create_directories(entry);
        meshes::generate_mesh(g, msh_path);
      }
      fem::MpiSession::barrier();
    }
    for (const CutTrace& trace : traces) {
      if (complete(trace)) {
        ++result.cached_solves;
        continue;
      }
      fem::ElasticityProblem problem;
      problem.mesh_path = msh_path;
      problem.material = material;
      problem.clamped_boundaries = {"base"};
      problem.solver = solver;
      const auto field = trace.field;
      problem.conditions.push_back({"cut", fem::BoundaryCondition::Kind::displacement,
                                    [field, trace_depth_m](const Eigen::Vector3d& x) {
                                      return Eigen::Vector3d(trace_depth_m * field(x));
                                    }});
      for (const CutTrace& other : traces) {
        const auto other_field = other.field;
        problem.boundary_works.push_back(
            {"cut", [other_field, trace_depth_m](const Eigen::Vector3d& x) { return Eigen::Vector3d(trace_depth_m * other_field(x)); }});
      }
      const auto solve_start = std::chrono::steady_clock::now();
      const fem::ElasticitySolution s = fem::solve_elasticity(problem);
      json works = json::object();
      for (std::size_t k = 0; k < traces.size(); ++k) works[traces[k].name] = s.boundary_work_J[k];
      solves[trace.name] = {{"energy_J", s.energy_J},
                            {"works_J", works},
                            {"dofs", s.dof_count},
                            {"iterations", s.solver_iterations},
                            {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - solve_start).count()}};
      ++result.solves;
      if (rank0) write_file_atomically(solves_path, solves.dump(2) + "\n");
      fem::MpiSession::barrier();
    }

    const double scale = 1.0 / (trace_depth_m * trace_depth_m);
    Matrix k = Matrix::Zero();
    for (int j = 0; j < n; ++j) {
      const json& solve = solves.at(traces[static_cast<std::size_t>(j)].name);
      for (int i = 0; i < n; ++i) k(i, j) = solve.at("works_J").at(traces[static_cast<std::size_t>(i)].name).get<double>() * scale;
      // The reaction's work against the solve's own trace is twice its energy.
      const double energy = 2 * solve.at("energy_J").get<double>() * scale;
      if (!(std::abs(k(j, j) - energy) <= 1e-6 * std::abs(energy)))
        throw std::runtime_error(entry + ": trace '" + traces[static_cast<std::size_t>(j)].name + "': the reaction's work " +
                                 format_number(k(j, j)) + " differs from twice the energy " + format_number(energy) +
                                 " (the cut's degrees of freedom were not all found)");
    }
    const double largest = k.diagonal().head(n).cwiseAbs().maxCoeff();
    result.asymmetry = std::max(result.asymmetry, (k - k.transpose()).cwiseAbs().maxCoeff() / largest);
    result.levels_N_per_m.push_back(0.5 * (k + k.transpose()));
    result.dofs.push_back(solves.at(traces.front().name).at("dofs").get<std::size_t>());
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // Richardson with the normal entry's observed order for every entry, so the extrapolated
  // matrix stays one consistent linear combination of the last two levels (symmetric, and
  // positive definite whenever both are, for a positive correction weight below one).
  const auto& levels = result.levels_N_per_m;
  const Matrix& finest = levels.back();
  result.stiffness_N_per_m = finest;
  result.observed_order = std::numeric_limits<double>::quiet_NaN();
  if (levels.size() >= 3) {
    std::vector<double> normal;
    for (const auto& k : levels) normal.push_back(k(0, 0));
    const fem::RichardsonEstimate r = fem::richardson_extrapolate(normal, 2.0, energy_convergence_order);
    result.observed_order = r.observed_order;
    result.asymptotic = r.asymptotic;
    for (int m = 1; m < n; ++m) {
      std::vector<double> values;
      for (const auto& k : levels) values.push_back(k(m, m));
      result.asymptotic = result.asymptotic && fem::richardson_extrapolate(values, 2.0, energy_convergence_order).asymptotic;
    }
    if (std::isfinite(r.observed_order) && r.observed_order > 0) {
      const Matrix& previous = levels[levels.size() - 2];
      result.stiffness_N_per_m = finest + (finest - previous) / (std::pow(2.0, r.observed_order) - 1);
    }
  }
  double error = 0;
  const Matrix& previous = levels.size() >= 2 ? levels[levels.size() - 2] : finest;
  for (int m = 0; m < n; ++m) {
    const double k = result.stiffness_N_per_m(m, m);
    const double correction = std::abs(k - finest(m, m));
    // Without an extrapolation the last change is the estimate (one level: none, reported as 0).
    error = std::max(error, (correction > 0 ? correction : std::abs(finest(m, m) - previous(m, m))) / std::abs(k));
  }
  result.relative_error = error;
  return result;
}

void OrganAtlasStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("OrganAtlasStudy.name is empty");
  if (geometry.benchmark != meshes::Benchmark::B1 && geometry.benchmark != meshes::Benchmark::B2 &&
      geometry.benchmark != meshes::Benchmark::Organ)
    throw std::invalid_argument("OrganAtlasStudy.geometry.benchmark = " + meshes::to_string(geometry.benchmark) +
                                " must be B1 (the cylinder), B2 (the hemisphere) or organ (a surface)");
  material.validate();
  solver.validate();
  if (geometry.benchmark == meshes::Benchmark::Organ) {
    if (generated_organ.empty() == geometry.organ.surface_path.empty())
      throw std::invalid_argument("OrganAtlasStudy: give exactly one of organ.surface and organ.generate");
    if (!generated_organ.empty()) validate_generated_organ(generated_organ, generated_organ_triangles);
    if (!std::isnan(region_centre_m[0]))
      for (const double x : region_centre_m)
        if (!std::isfinite(x)) throw std::invalid_argument("OrganAtlasStudy.region_centre_m has a non-finite coordinate");
    if (!std::isfinite(region_radius_m) || region_radius_m < 0)
      throw std::invalid_argument("OrganAtlasStudy.region_radius_m = " + format_number(region_radius_m) + " must be >= 0");
    if (!std::isfinite(sample_spacing_m) || sample_spacing_m < 0)
      throw std::invalid_argument("OrganAtlasStudy.sample_spacing_m = " + format_number(sample_spacing_m) + " must be >= 0");
    const double spacing = sample_spacing_m > 0 ? sample_spacing_m : geometry.local_radius_m;
    if (region_radius_m / spacing > 50)
      throw std::invalid_argument("OrganAtlasStudy: region_radius_m / sample_spacing_m = " + format_number(region_radius_m / spacing) +
                                  " asks for thousands of samples (at most 50 spacings across)");
    meshes::MeshParameters g = geometry;
    g.exterior_of_local_ball = true;
    if (g.organ.surface_path.empty()) g.organ.surface_path = "(generated)";
    g.validate();
  }
  if (polar_angles_rad.empty()) throw std::invalid_argument("OrganAtlasStudy.polar_angles_rad is empty");
  for (const double theta : polar_angles_rad) {
    if (geometry.benchmark == meshes::Benchmark::Organ) break;
    meshes::MeshParameters g = geometry;
    g.exterior_of_local_ball = true;
    if (g.benchmark == meshes::Benchmark::B2 && theta != 0) {
      g.benchmark = meshes::Benchmark::B5;
      g.contact_polar_angle_rad = theta;
    }
    if (geometry.benchmark == meshes::Benchmark::B1 && theta != 0)
      throw std::invalid_argument("OrganAtlasStudy.polar_angles_rad: B1 has one sample, the top centre (theta = 0)");
    g.validate();
  }
  if (refinements.empty()) throw std::invalid_argument("OrganAtlasStudy.refinements is empty");
  for (std::size_t i = 1; i < refinements.size(); ++i)
    if (refinements[i] != refinements[i - 1] + 1)
      throw std::invalid_argument("OrganAtlasStudy.refinements must be consecutive levels, e.g. [0, 1, 2]");
  if (!std::isfinite(trace_depth_m) || trace_depth_m <= 0)
    throw std::invalid_argument("OrganAtlasStudy.trace_depth_m = " + format_number(trace_depth_m) + " must be > 0");
  // The trace's amplitude drops out of K_ext (a linear solve, divided by its square), but a
  // punch pushed farther than L/2 would leave the local ball: such an input is a mistake.
  if (!(trace_depth_m <= 0.5 * geometry.local_radius_m))
    throw std::invalid_argument("OrganAtlasStudy.trace_depth_m = " + format_number(trace_depth_m) +
                                " must be <= local_radius / 2 = " + format_number(0.5 * geometry.local_radius_m));
  if (half_space_polar_points < 2)
    throw std::invalid_argument("OrganAtlasStudy.half_space_polar_points = " + std::to_string(half_space_polar_points) +
                                " must be >= 2");
  if (half_space_azimuth_points < 4)
    throw std::invalid_argument("OrganAtlasStudy.half_space_azimuth_points = " +
                                std::to_string(half_space_azimuth_points) + " must be >= 4");
}

OrganAtlasStudy read_organ_atlas_study(ConfigTable& config) {
  OrganAtlasStudy study;
  study.name = config.string("study", study.name);
  ConfigTable geometry = config.table("geometry");
  meshes::MeshParameters& g = study.geometry;
  g.benchmark = meshes::benchmark_from_string(geometry.choice("benchmark", {"B1", "B2", "organ"}, "B2"));
  const bool organ = g.benchmark == meshes::Benchmark::Organ;
  // What defines the problem is required: the body's size (a generated or benchmark body), the
  // tool's radius and the material.
  const bool sized_by_body_radius = !organ || config.table("organ").string("generate", "") == "hemisphere";
  g.body_radius_m = sized_by_body_radius ? geometry.quantity("body_radius", Dimension::length)
                                         : geometry.quantity("body_radius", Dimension::length, g.body_radius_m);
  g.tool_radius_m = geometry.quantity("tool_radius", Dimension::length);
  g.local_radius_m = geometry.quantity("local_radius", Dimension::length, 5 * g.tool_radius_m);

  ConfigTable material = config.table("material");
  study.material.youngs_modulus_Pa = material.quantity("youngs_modulus", Dimension::pressure);
  study.material.poisson_ratio = material.number("poisson_ratio");

  if (organ) {
    // The surface, its units and attachment, as `touchstone fem` reads them; the contact is per sample.
    ConfigTable surface = config.table("organ", true);
    meshes::OrganBody& o = g.organ;
    o.surface_path = surface.file_path("surface", "");
    o.unit_scale = surface.number("unit_scale", o.unit_scale);
    o.attachment.plane_point_m = surface.vector3("attachment_plane_point", Dimension::length, o.attachment.plane_point_m);
    o.attachment.plane_normal = surface.vector3("attachment_plane_normal", Dimension::dimensionless, o.attachment.plane_normal);
    o.attachment.msh_group = surface.string("attachment_group", "");
    o.attachment.triangles_path = surface.file_path("attachment_triangles", "");
    o.feature_angle_rad = surface.quantity("feature_angle", Dimension::angle, o.feature_angle_rad);
    study.generated_organ = surface.string("generate", "");
    study.generated_organ_triangles = read_int(surface, "generate_triangles", study.generated_organ_triangles);
  }

  ConfigTable atlas = config.table("atlas");
  if (organ) {
    study.region_centre_m = atlas.vector3("region_centre", Dimension::length, study.region_centre_m);
    study.region_radius_m = atlas.quantity("region_radius", Dimension::length, study.region_radius_m);
    study.sample_spacing_m = atlas.quantity("sample_spacing", Dimension::length, study.sample_spacing_m);
  } else {
    study.polar_angles_rad = atlas.quantity_list("polar_angles", Dimension::angle, study.polar_angles_rad);
  }
  study.modes = atlas.choice("modes", {"normal", "all"}, "all") == "normal" ? AtlasModes::normal : AtlasModes::all;
  study.cut_translations = atlas.boolean("cut_translations", study.cut_translations);
  const int levels = read_int(atlas, "levels", 3);
  if (levels < 1 || levels > 5) throw ConfigError(atlas.where("levels") + ": " + std::to_string(levels) + " must be in [1, 5]");
  study.refinements.clear();
  for (int level = 0; level < levels; ++level) study.refinements.push_back(level);
  // Level 0 puts a/2 … a on the cut (the trace is smooth there: the rim lies L − a inside the
  // ball) and grows outward; each level halves every size.
  g.edge_size_m = atlas.quantity("edge_size", Dimension::length, g.tool_radius_m);
  g.size_growth = atlas.number("size_growth", 0.5);
  g.size_exponent = 1.0;
  g.max_size_m = atlas.quantity("max_size", Dimension::length, g.body_radius_m / 5);
  study.trace_depth_m = atlas.quantity("trace_depth", Dimension::length, study.trace_depth_m);
  study.half_space_polar_points = read_int(atlas, "half_space_polar_points", study.half_space_polar_points);
  study.half_space_azimuth_points = read_int(atlas, "half_space_azimuth_points", study.half_space_azimuth_points);

  ConfigTable solver = config.table("solver");
  study.solver.degree = static_cast<unsigned int>(solver.integer("degree", study.solver.degree));
  study.solver.solver = value_of(linear_solvers, solver.choice("method", names(linear_solvers), "cg_amg_trilinos"));
  study.solver.relative_tolerance = solver.number("relative_tolerance", study.solver.relative_tolerance);
  study.solver.max_iterations = static_cast<unsigned int>(solver.integer("max_iterations", study.solver.max_iterations));
  finish_and_validate(config, study);
  return study;
}

std::string describe_attachment(const meshes::OrganAttachment& attachment) {
  if (attachment.rule_count() == 0) return "not held";
  if (attachment.has_plane()) {
    const Eigen::Vector3d normal = to_eigen(attachment.plane_normal).normalized();
    const auto triple = [](const Eigen::Vector3d& v) {
      return "(" + format_number(v[0]) + ", " + format_number(v[1]) + ", " + format_number(v[2]) + ")";
    };
    return "below the plane through " + triple(to_eigen(attachment.plane_point_m)) + " m with unit normal " +
           triple(normal);
  }
  if (!attachment.msh_group.empty()) return "on the physical group '" + attachment.msh_group + "'";
  return "on the triangles listed in a file of sha256 " + sha256_hex(read_file(attachment.triangles_path)).substr(0, 16);
}

realtime::mfs::OrganAtlas run_organ_atlas_study(const OrganAtlasStudy& given, const AtlasRunOptions& options) {
  given.validate();
  OrganAtlasStudy study = given;
  if (!study.generated_organ.empty()) {
    study.geometry.organ.surface_path =
        generated_organ_surface(study.generated_organ, study.generated_organ_triangles, study.geometry.body_radius_m,
                                options.cache_directory.empty() ? options.output_directory : options.cache_directory);
    study.generated_organ.clear();
  }
  const bool on_organ = study.geometry.benchmark == meshes::Benchmark::Organ;
  // One sample per polar angle (the benchmarks) or per lattice site (an organ).
  std::vector<meshes::MeshParameters> sample_geometries;
  std::vector<double> sample_angles;
  if (on_organ) {
    for (const auto& site : organ_atlas_sites(study)) {
      meshes::MeshParameters g = study.geometry;
      g.organ.contact_point_m = site;
      g.organ.tool_axis = {0.0, 0.0, 0.0};
      sample_geometries.push_back(g);
      sample_angles.push_back(std::numeric_limits<double>::quiet_NaN());
    }
  } else {
    for (const double theta : study.polar_angles_rad) {
      meshes::MeshParameters g = study.geometry;
      if (g.benchmark == meshes::Benchmark::B2 && theta != 0) {
        g.benchmark = meshes::Benchmark::B5;
        g.contact_polar_angle_rad = theta;
      }
      sample_geometries.push_back(g);
      sample_angles.push_back(theta);
    }
  }
  const bool rank0 = fem::MpiSession::rank() == 0;
  const int n = mode_count(study.modes);
  const geometry::Material& punch_material = study.material;
  const double a = study.geometry.tool_radius_m, l = study.geometry.local_radius_m;

  const Eigen::Matrix3d half_space = half_space_exterior_stiffness_N_per_m(
      a, l, punch_material, study.half_space_polar_points, study.half_space_azimuth_points);

  realtime::mfs::OrganAtlas atlas;
  if (on_organ) {
    atlas.surface_sha256 = sha256_hex(read_file(study.geometry.organ.surface_path));
    atlas.attachment = describe_attachment(study.geometry.organ.attachment);
    atlas.organ = "organ surface '" + fs::path(study.geometry.organ.surface_path).filename().string() + "' (sha256 " +
                  atlas.surface_sha256.substr(0, 16) + "…), " +
                  (study.geometry.organ.attachment.rule_count() == 0 ? "not held (the exterior body is held by the cut)"
                                                                     : "held " + atlas.attachment);
    atlas.axisymmetric_about_z = false;
  } else {
    atlas.organ = study.geometry.benchmark == meshes::Benchmark::B1
                      ? "B1 cylinder W = " + format_number(study.geometry.body_radius_m) +
                            " m, top face z = 0, base z = -W clamped"
                      : "B2 hemisphere R = " + format_number(study.geometry.body_radius_m) + " m, base z = 0 clamped";
    atlas.axisymmetric_about_z = true;  // both benchmark bodies and their clamped bases are
  }
  atlas.mode_count = n;
  atlas.cut_translations = study.cut_translations;
  const int size = atlas.matrix_size();

  json samples = json::array();
  const auto start = std::chrono::steady_clock::now();
  if (rank0 && !options.quiet)
    std::printf("%s: %zu sample%s, modes %s, levels %d..%d; half-space K_ext normal %.6g N/m, tangential %.6g N/m\n",
                study.name.c_str(), sample_geometries.size(), sample_geometries.size() == 1 ? "" : "s",
                to_string(study.modes).c_str(), study.refinements.front(), study.refinements.back(), half_space(0, 0),
                half_space(1, 1));
  for (std::size_t sample_index = 0; sample_index < sample_geometries.size(); ++sample_index) {
    const meshes::MeshParameters& g = sample_geometries[sample_index];
    const double theta = sample_angles[sample_index];
    const std::string label = sample_label(g);
    const ExteriorStiffness k =
        exterior_stiffness_fem(g, study.material, study.modes, study.cut_translations, study.refinements,
                               study.trace_depth_m, study.solver, options,
                               (fs::path(options.output_directory) / "work" / label).string());

    realtime::mfs::OrganAtlasSample sample;
    sample.label = label;
    sample.contact_point_m = to_eigen(meshes::contact_site(g).point_m);
    sample.frame = atlas_punch_frame(g);
    sample.direction = sample.frame.axes.col(2);
    sample.tool_radius_m = a;
    sample.local_radius_m = l;
    sample.youngs_modulus_Pa = study.material.youngs_modulus_Pa;
    sample.poisson_ratio = study.material.poisson_ratio;
    sample.stiffness_N_per_m.topLeftCorner(size, size) = k.stiffness_N_per_m.topLeftCorner(size, size);
    sample.half_space_stiffness_N_per_m.topLeftCorner(n, n) = half_space.topLeftCorner(n, n);
    sample.relative_error = k.relative_error;
    sample.dofs = k.dofs.back();
    sample.seconds = k.seconds;
    atlas.samples.push_back(sample);

    json levels = json::array();
    for (std::size_t i = 0; i < k.levels_N_per_m.size(); ++i)
      levels.push_back({{"refinement", study.refinements[i]},
                        {"dofs", k.dofs[i]},
                        {"stiffness_N_per_m", matrix_json(k.levels_N_per_m[i], size)}});
    json ratio = json::array();
    for (int m = 0; m < n; ++m) ratio.push_back(k.stiffness_N_per_m(m, m) / half_space(m, m));
    samples.push_back({{"label", label},
                       {"contact_polar_angle_rad", std::isfinite(theta) ? json(theta) : json(nullptr)},
                       {"contact_point_m", vector_json(sample.contact_point_m)},
                       {"direction", vector_json(sample.direction)},
                       {"frame_origin_m", vector_json(sample.frame.origin)},
                       {"stiffness_N_per_m", matrix_json(sample.stiffness_N_per_m, size)},
                       {"asymmetry", k.asymmetry},
                       {"half_space_stiffness_N_per_m", matrix_json(sample.half_space_stiffness_N_per_m, n)},
                       {"ratio_to_half_space_diagonal", ratio},
                       {"observed_order", std::isfinite(k.observed_order) ? json(k.observed_order) : json(nullptr)},
                       {"asymptotic", k.asymptotic},
                       {"relative_error", k.relative_error},
                       {"levels", levels},
                       {"solves", k.solves},
                       {"cached_solves", k.cached_solves},
                       {"seconds", k.seconds}});
    if (rank0 && !options.quiet) {
      std::printf("  %-14s K_nn = %.6g N/m (x%.5f half-space)", label.c_str(), k.stiffness_N_per_m(0, 0), ratio[0].get<double>());
      if (n == 3)
        std::printf(", K_t1 = %.6g (x%.5f), K_t2 = %.6g (x%.5f), K_n,t1 = %.4g", k.stiffness_N_per_m(1, 1),
                    ratio[1].get<double>(), k.stiffness_N_per_m(2, 2), ratio[2].get<double>(), k.stiffness_N_per_m(0, 1));
      if (study.cut_translations)
        std::printf(", K_shift3 = %.6g, K_n,shift3 = %.4g", k.stiffness_N_per_m(n, n), k.stiffness_N_per_m(0, n));
      std::printf("; error %.3f %%, order %s, %zu dofs, %zu solves (%zu cached), %.1f s\n", 100 * k.relative_error,
                  std::isfinite(k.observed_order) ? format_number(k.observed_order).c_str() : "n/a", k.dofs.back(),
                  k.solves, k.cached_solves, k.seconds);
      std::fflush(stdout);
    }
  }
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (rank0) {
    fs::create_directories(options.output_directory);
    realtime::mfs::write_organ_atlas(atlas, options.output_directory + "/organ_atlas.json");
    json document{{"study", study.name},
                  {"provenance", provenance(options.config_text)},
                  {"organ", atlas.organ},
                  {"modes", to_string(study.modes)},
                  {"cut_translations", study.cut_translations},
                  {"tool_radius_m", a},
                  {"local_radius_m", l},
                  {"youngs_modulus_Pa", study.material.youngs_modulus_Pa},
                  {"poisson_ratio", study.material.poisson_ratio},
                  {"trace_depth_m", study.trace_depth_m},
                  {"half_space_stiffness_N_per_m", matrix_json(half_space, 3)},
                  {"samples", samples},
                  {"cost_s", {{"total", total}, {"per_sample", total / static_cast<double>(sample_geometries.size())}}}};
    write_file_atomically(options.output_directory + "/results.json", document.dump(2) + "\n");
    if (!options.quiet)
      std::printf("offline cost: %.1f s for the organ, %.1f s per sample (cached solves cost nothing)\n", total,
                  total / static_cast<double>(sample_geometries.size()));
  }
  return atlas;
}

}  // namespace touchstone::studies
