#include "touchstone/meshes/organ_geometry.hpp"

#include "text_of.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "gmsh_session.hpp"

#include <Eigen/Geometry>
#include <gmsh.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace touchstone::meshes {

namespace {

using Eigen::Vector3d;
using Eigen::Vector3i;

constexpr double pi = 3.14159265358979323846;

using internal::text_of;

[[noreturn]] void reject(const char* field, double value, const std::string& requirement) {
  throw std::invalid_argument("OrganParameters." + std::string(field) + " = " + text_of(value) + " " + requirement);
}

// ---------------------------------------------------------------------------------------------
// The stomach's profile at scale 1: centre-line points in the x–z plane (z up) from the fundus
// to the pylorus, and the in-plane semi-axis of the section there. The centre line turns by
// about 135° at the bottom (the greater curvature); its radius of curvature stays above the
// local section radius, so the loft never folds onto itself at the lesser curvature.

struct Station {
  double x_m, z_m, radius_m;
};

constexpr std::array<Station, 8> stomach_profile{{
    {0.000, 0.100, 0.050},   // fundus
    {0.004, 0.060, 0.048},
    {0.015, 0.015, 0.043},   // body
    {0.035, -0.025, 0.036},
    {0.068, -0.050, 0.029},  // antrum, lowest point
    {0.100, -0.045, 0.022},
    {0.122, -0.025, 0.016},
    {0.135, -0.005, 0.012},  // pylorus
}};

/// The end caps are ellipsoids slightly larger than the end sections, centred a little inside
/// the tube, so that they cut the loft at a small angle (about 14°): a tangent cut would be
/// the hardest case for OpenCASCADE's booleans.
constexpr double cap_enlargement = 1.03;

/// Triangles per unit area times h² of gmsh's frontal-Delaunay surface meshes at uniform size
/// h (measured on both shapes: 2.4–2.7); only the first guess of the size search uses it.
constexpr double triangles_per_area_h2 = 2.6;

std::string describe(const OrganParameters& p) {
  std::ostringstream text;
  text << to_string(p.shape) << " with " << p.target_triangles << " triangles (tolerance " << p.relative_tolerance;
  if (p.shape == OrganShape::stomach) {
    text << ", scale " << p.stomach_scale << ", flattening " << p.stomach_flattening;
  } else {
    text << ", R = " << p.hemisphere_radius_m << " m";
  }
  text << ")";
  return text.str();
}

/// Builds the stomach solid; returns its volume tag.
int build_stomach(const OrganParameters& p) {
  const double f = p.stomach_flattening;
  const double s = p.stomach_scale;
  const int n = static_cast<int>(stomach_profile.size());
  std::vector<int> wires;
  for (int i = 0; i < n; ++i) {
    // Tangent by central differences (one-sided at the ends): the section is normal to it.
    const Station& before = stomach_profile[std::max(i - 1, 0)];
    const Station& after = stomach_profile[std::min(i + 1, n - 1)];
    const double angle = std::atan2(after.x_m - before.x_m, after.z_m - before.z_m);
    const Station& here = stomach_profile[i];
    // An ellipse in the x–y plane (major axis along x, in the centre-line plane) rotated about
    // y turns its normal from z to the tangent; the seam stays on the greater curvature side
    // for every section, so the loft does not twist.
    const int curve = gmsh::model::occ::addEllipse(0, 0, 0, s * here.radius_m, f * s * here.radius_m);
    gmsh::model::occ::rotate({{1, curve}}, 0, 0, 0, 0, 1, 0, angle);
    gmsh::model::occ::translate({{1, curve}}, s * here.x_m, 0, s * here.z_m);
    wires.push_back(gmsh::model::occ::addWire({curve}));
  }
  gmsh::vectorpair loft;
  gmsh::model::occ::addThruSections(wires, loft, -1, true, false);
  int tube = -1;
  for (const auto& [dim, tag] : loft) {
    if (dim == 3) tube = tag;
  }
  if (tube < 0) throw std::runtime_error("the loft through the stomach sections made no solid");

  const auto cap = [&](int end, int inner) {
    const Station& e = stomach_profile[end];
    const Station& i = stomach_profile[inner];
    const double dx = i.x_m - e.x_m;
    const double dz = i.z_m - e.z_m;
    const double length = std::hypot(dx, dz);
    const double radius = cap_enlargement * e.radius_m;
    // Centre moved inward so that the ball cuts the end plane in the section's circle.
    const double inward = std::sqrt(radius * radius - e.radius_m * e.radius_m);
    const double cx = s * (e.x_m + dx / length * inward);
    const double cz = s * (e.z_m + dz / length * inward);
    const int ball = gmsh::model::occ::addSphere(cx, 0, cz, s * radius);
    // Flattened in y like the sections; an ellipsoid with semi-axes (r, f r, r) is symmetric
    // about the y axis, so it needs no rotation.
    gmsh::model::occ::dilate({{3, ball}}, cx, 0, cz, 1, f, 1);
    return ball;
  };
  const int fundus = cap(0, 1);
  const int pylorus = cap(n - 1, n - 2);
  gmsh::vectorpair fused;
  std::vector<gmsh::vectorpair> map;
  gmsh::model::occ::fuse({{3, tube}}, {{3, fundus}, {3, pylorus}}, fused, map);
  if (fused.size() != 1 || fused[0].first != 3) {
    throw std::runtime_error("fusing the stomach tube with its caps gave " + std::to_string(fused.size()) +
                             " entities instead of one solid");
  }
  return fused[0].second;
}

/// Builds the hemisphere solid (ball cut at z = 0, polar angles [0, π/2]); returns its tag.
int build_hemisphere(const OrganParameters& p) {
  return gmsh::model::occ::addSphere(0, 0, 0, p.hemisphere_radius_m, -1, 0, pi / 2);
}

/// Meshes the surfaces at uniform size h; returns 3 gmsh node tags per triangle, each face's
/// triangles as gmsh orients them (consistent within the face, not across faces).
std::vector<std::size_t> mesh_surfaces(double h, const gmsh::vectorpair& faces) {
  gmsh::model::mesh::clear();
  gmsh::option::setNumber("Mesh.MeshSizeMin", h);
  gmsh::option::setNumber("Mesh.MeshSizeMax", h);
  gmsh::model::mesh::generate(2);
  std::vector<std::size_t> triangle_nodes;
  for (const auto& [dim, tag] : faces) {
    std::vector<std::size_t> element_tags;
    std::vector<std::size_t> node_tags;
    constexpr int triangle = 2;
    gmsh::model::mesh::getElementsByType(triangle, element_tags, node_tags, tag);
    triangle_nodes.insert(triangle_nodes.end(), node_tags.begin(), node_tags.end());
  }
  return triangle_nodes;
}

/// Orients the triangles consistently across edges shared by two triangles (breadth first from
/// the lowest triangle of each piece), then outward: a negative enclosed volume flips all.
/// gmsh orients each face by its parametrisation, and OpenCASCADE's face orientation flags do
/// not always say which faces that leaves inward, so the mesh itself decides.
void orient_outward(const std::vector<Vector3d>& vertices, std::vector<Vector3i>& triangles) {
  const int n = static_cast<int>(triangles.size());
  std::unordered_map<long long, std::vector<int>> edges;  // key low · vertex count + high → triangles
  const long long stride = static_cast<long long>(vertices.size());
  const auto key = [&](int a, int b) { return std::min(a, b) * stride + std::max(a, b); };
  for (int t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) edges[key(triangles[t][k], triangles[t][(k + 1) % 3])].push_back(t);
  }
  std::vector<char> visited(n, 0);
  std::vector<int> queue;
  for (int seed = 0; seed < n; ++seed) {
    if (visited[seed]) continue;
    visited[seed] = 1;
    queue.assign(1, seed);
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const int t = queue[head];
      for (int k = 0; k < 3; ++k) {
        const int a = triangles[t][k];
        const int b = triangles[t][(k + 1) % 3];
        const std::vector<int>& sharing = edges[key(a, b)];
        if (sharing.size() != 2) continue;
        const int u = sharing[0] == t ? sharing[1] : sharing[0];
        if (visited[u]) continue;
        visited[u] = 1;
        // A consistent neighbour runs the shared edge b → a.
        for (int m = 0; m < 3; ++m) {
          if (triangles[u][m] == a && triangles[u][(m + 1) % 3] == b) {
            std::swap(triangles[u][1], triangles[u][2]);
            break;
          }
        }
        queue.push_back(u);
      }
    }
  }
  double volume = 0;
  for (const Vector3i& t : triangles) volume += vertices[t[0]].dot(vertices[t[1]].cross(vertices[t[2]]));
  if (volume < 0) {
    for (Vector3i& t : triangles) std::swap(t[1], t[2]);
  }
}

OrganMesh generate(const OrganParameters& p) {
  const auto start = std::chrono::steady_clock::now();
  const int volume = p.shape == OrganShape::stomach ? build_stomach(p) : build_hemisphere(p);
  gmsh::model::occ::synchronize();

  OrganMesh result;
  gmsh::model::occ::getMass(3, volume, result.geometry_volume_m3);
  gmsh::vectorpair faces;
  gmsh::model::getBoundary({{3, volume}}, faces, false, false, false);
  for (const auto& [dim, tag] : faces) {
    double area = 0;
    gmsh::model::occ::getMass(2, std::abs(tag), area);
    result.geometry_area_m2 += area;
  }

  gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
  gmsh::option::setNumber("Mesh.Algorithm", 6);  // frontal-Delaunay: near-equilateral triangles
  gmsh::option::setNumber("Mesh.ElementOrder", 1);

  // Size search: N ∝ h⁻² predicts the next size; once the target is bracketed, a prediction
  // outside the bracket is replaced by its geometric midpoint (gmsh's count is not exactly
  // monotone in h, so the bracket guarantees progress).
  const double target = p.target_triangles;
  double h = std::sqrt(triangles_per_area_h2 * result.geometry_area_m2 / target);
  double too_fine = 0;                                          // largest h with too many triangles
  double too_coarse = std::numeric_limits<double>::infinity();  // smallest h with too few
  std::vector<std::size_t> mesh;
  std::string history;
  for (result.passes = 1;; ++result.passes) {
    mesh = mesh_surfaces(h, faces);
    const double count = static_cast<double>(mesh.size() / 3);
    history += (history.empty() ? "" : ", ") + ("h = " + text_of(h) + " m: " + text_of(count));
    if (std::abs(count - target) <= p.relative_tolerance * target) break;
    if (result.passes >= p.max_passes) {
      throw std::runtime_error("no mesh size within the tolerance after " + std::to_string(result.passes) +
                               " passes (" + history + ")");
    }
    if (count > target) {
      too_fine = std::max(too_fine, h);
    } else {
      too_coarse = std::min(too_coarse, h);
    }
    double next = h * std::sqrt(std::max(count, 1.0) / target);
    if (!(next > too_fine && next < too_coarse)) {
      next = std::isfinite(too_coarse) && too_fine > 0 ? std::sqrt(too_fine * too_coarse) : next;
    }
    h = next;
  }
  result.mesh_size_m = h;

  // Vertices: the nodes in use, in increasing tag order (deterministic).
  std::vector<std::size_t> tags = mesh;
  std::sort(tags.begin(), tags.end());
  tags.erase(std::unique(tags.begin(), tags.end()), tags.end());
  std::unordered_map<std::size_t, int> index_of;
  index_of.reserve(tags.size());
  for (std::size_t i = 0; i < tags.size(); ++i) index_of[tags[i]] = static_cast<int>(i);
  {
    std::vector<std::size_t> node_tags;
    std::vector<double> coordinates;
    std::vector<double> parametric;
    gmsh::model::mesh::getNodes(node_tags, coordinates, parametric, -1, -1, false, false);
    result.vertices.resize(tags.size());
    for (std::size_t i = 0; i < node_tags.size(); ++i) {
      const auto found = index_of.find(node_tags[i]);
      if (found == index_of.end()) continue;
      result.vertices[found->second] = Vector3d(coordinates[3 * i], coordinates[3 * i + 1], coordinates[3 * i + 2]);
    }
  }
  result.triangles.reserve(mesh.size() / 3);
  for (std::size_t e = 0; e + 2 < mesh.size(); e += 3) {
    result.triangles.emplace_back(index_of.at(mesh[e]), index_of.at(mesh[e + 1]), index_of.at(mesh[e + 2]));
  }
  orient_outward(result.vertices, result.triangles);

  const std::vector<geometry::SurfaceDefect> defects =
      geometry::validate_surface(result.vertices, result.triangles, "the generated " + to_string(p.shape));
  if (!defects.empty()) throw std::runtime_error(defects.front().message);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

/// Fails before the meshing if the file cannot be written; leaves no file behind.
void require_writable(const std::string& path) {
  if (path.empty()) throw std::runtime_error("the output path is empty");
  const bool existed = std::ifstream(path).good();
  std::ofstream probe(path, std::ios::app);
  if (!probe) throw std::runtime_error("cannot write '" + path + "'");
  probe.close();
  if (!existed) std::remove(path.c_str());
}

}  // namespace

std::string to_string(OrganShape shape) {
  switch (shape) {
    case OrganShape::stomach: return "stomach";
    case OrganShape::hemisphere: return "hemisphere";
  }
  throw std::invalid_argument("unknown OrganShape value " + std::to_string(static_cast<int>(shape)));
}

OrganShape organ_shape_from_string(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "stomach") return OrganShape::stomach;
  if (lower == "hemisphere") return OrganShape::hemisphere;
  throw std::invalid_argument("unknown organ shape '" + name + "' (valid names: stomach, hemisphere)");
}

void OrganParameters::validate() const {
  if (shape != OrganShape::stomach && shape != OrganShape::hemisphere) {
    reject("shape", static_cast<int>(shape), "is not an OrganShape");
  }
  // Below about 100 triangles the caps and the pylorus cannot be resolved; above 10⁶ meshing
  // takes minutes.
  if (target_triangles < 100 || target_triangles > 1000000) {
    reject("target_triangles", target_triangles, "must be in [100, 1000000]");
  }
  if (!std::isfinite(relative_tolerance) || relative_tolerance < 0.005 || relative_tolerance > 0.5) {
    reject("relative_tolerance", relative_tolerance, "must be in [0.005, 0.5]");
  }
  if (!std::isfinite(stomach_scale) || stomach_scale < 1e-3 || stomach_scale > 1e3) {
    reject("stomach_scale", stomach_scale, "must be in [1e-3, 1e3]");
  }
  if (!std::isfinite(stomach_flattening) || stomach_flattening <= 0.3 || stomach_flattening >= 1) {
    reject("stomach_flattening", stomach_flattening,
           "must be in (0.3, 1) (OpenCASCADE ellipses need the in-plane axis longer than the depth)");
  }
  if (!std::isfinite(hemisphere_radius_m) || hemisphere_radius_m < 1e-4 || hemisphere_radius_m > 10) {
    reject("hemisphere_radius_m", hemisphere_radius_m, "must be in [1e-4, 10] m");
  }
  if (max_passes < 1 || max_passes > 100) reject("max_passes", max_passes, "must be in [1, 100]");
}

OrganMesh generate_organ_mesh(const OrganParameters& parameters) {
  parameters.validate();
  try {
    internal::GmshSession session("organ");
    // One thread: the triangle count, and so the size search, must not depend on scheduling.
    gmsh::option::setNumber("General.NumThreads", 1);
    return generate(parameters);
  } catch (const std::string& gmsh_error) {
    throw std::runtime_error("generate_organ_mesh failed for " + describe(parameters) + ": gmsh: " + gmsh_error);
  } catch (const std::runtime_error& error) {
    throw std::runtime_error("generate_organ_mesh failed for " + describe(parameters) + ": " + error.what());
  }
}

OrganMesh write_organ_mesh(const OrganParameters& parameters, const std::string& path) {
  parameters.validate();
  surface_format_of(path);
  require_writable(path);
  OrganMesh mesh = generate_organ_mesh(parameters);
  write_surface_mesh(path, mesh.vertices, mesh.triangles);
  return mesh;
}

}  // namespace touchstone::meshes
