// The graded tetrahedral mesh of a user's organ surface with the tool patch cut in (see the
// header for the steps).
#include "touchstone/meshes/organ_body_mesh.hpp"

#include "text_of.hpp"
#include "gmsh_session.hpp"
#include "touchstone/geometry/closest_point_on_triangle.hpp"
#include "touchstone/meshes/local_ball_cut.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/meshes/tool_patch_imprint.hpp"

#include <Eigen/Geometry>
#include <gmsh.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace touchstone::meshes {

namespace {

constexpr double pi = 3.14159265358979323846;

using internal::text_of;

Eigen::Vector3d vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }
std::array<double, 3> arr(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// The organ surface as read and validated, with the geometry core's closest-point tree.
struct Surface {
  geometry::TriangleSurface body;
  double diagonal_m = 0;
};

Surface read_valid_surface(const OrganBody& organ) {
  SurfaceReadOptions options;
  options.unit_scale = organ.unit_scale;
  options.weld_vertices = true;
  try {
    Surface surface{load_surface(organ.surface_path, options), 0};
    Eigen::Vector3d lower = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), upper = -lower;
    for (const auto& v : surface.body.vertices()) lower = lower.cwiseMin(v), upper = upper.cwiseMax(v);
    surface.diagonal_m = (upper - lower).norm();
    return surface;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("organ surface '" + organ.surface_path + "' is not usable as an organ body: " + e.what());
  }
}

Eigen::Vector3d corner(const std::vector<Eigen::Vector3d>& vertices, const Eigen::Vector3i& t, int k) {
  return vertices[static_cast<std::size_t>(t[k])];
}

/// Per input triangle: held by the attachment rule.
std::vector<char> attached_triangles(const OrganBody& organ, const Surface& surface) {
  const OrganAttachment& rule = organ.attachment;
  std::vector<char> held(surface.body.triangles().size(), 0);
  std::string described;
  if (rule.has_plane()) {
    const Eigen::Vector3d p = vec(rule.plane_point_m), n = vec(rule.plane_normal).normalized();
    const double tolerance = 1e-6 * surface.diagonal_m;
    for (std::size_t i = 0; i < held.size(); ++i) {
      bool below = true;
      for (int k = 0; k < 3; ++k) below = below && (corner(surface.body.vertices(), surface.body.triangles()[i], k) - p).dot(n) <= tolerance;
      held[i] = below ? 1 : 0;
    }
    described = "the plane rule (point " + text_of(p.x()) + ", " + text_of(p.y()) + ", " + text_of(p.z()) + " m, normal " +
                text_of(n.x()) + ", " + text_of(n.y()) + ", " + text_of(n.z()) + ")";
  } else if (!rule.msh_group.empty()) {
    SurfaceReadOptions options;
    options.unit_scale = organ.unit_scale;
    options.weld_vertices = true;
    options.msh_groups = {rule.msh_group};
    const SurfaceMesh group = read_surface_mesh(organ.surface_path, options);
    // The group's triangles are found by their corner coordinates (the same nodes of the file).
    const auto corners_key = [](std::array<Eigen::Vector3d, 3> c) {
      std::sort(c.begin(), c.end(), [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
        return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
      });
      return std::array<double, 9>{c[0].x(), c[0].y(), c[0].z(), c[1].x(), c[1].y(), c[1].z(), c[2].x(), c[2].y(), c[2].z()};
    };
    std::set<std::array<double, 9>> in_group;
    for (const auto& t : group.triangles)
      in_group.insert(corners_key({corner(group.vertices, t, 0), corner(group.vertices, t, 1), corner(group.vertices, t, 2)}));
    for (std::size_t i = 0; i < held.size(); ++i) {
      const auto& t = surface.body.triangles()[i];
      held[i] = in_group.count(corners_key({corner(surface.body.vertices(), t, 0), corner(surface.body.vertices(), t, 1), corner(surface.body.vertices(), t, 2)})) ? 1 : 0;
    }
    described = "the physical group '" + rule.msh_group + "'";
  } else if (!rule.triangles_path.empty()) {
    std::ifstream in(rule.triangles_path);
    if (!in) throw std::invalid_argument("cannot read the attachment triangle list '" + rule.triangles_path + "'");
    std::string line;
    int line_number = 0;
    while (std::getline(in, line)) {
      ++line_number;
      line = line.substr(0, line.find('#'));
      std::istringstream words(line);
      std::string word;
      while (words >> word) {
        std::size_t used = 0;
        long long index = -1;
        try {
          index = std::stoll(word, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used != word.size() || index < 0 || static_cast<std::size_t>(index) >= held.size())
          throw std::invalid_argument("attachment triangle list '" + rule.triangles_path + "', line " + std::to_string(line_number) +
                                      ": '" + word + "' is not a triangle number of '" + organ.surface_path + "' (0 … " +
                                      std::to_string(held.size() - 1) + ")");
        held[static_cast<std::size_t>(index)] = 1;
      }
    }
    described = "the triangle list '" + rule.triangles_path + "'";
  }
  if (rule.rule_count() > 0 && std::count(held.begin(), held.end(), 1) == 0)
    throw std::invalid_argument("organ attachment: " + described + " selects no triangle of '" + organ.surface_path + "'");
  return held;
}

/// Gives every triangle the orientation of its neighbours and makes the enclosed volume
/// positive (gmsh's remeshed pieces come in their own orientations).
void orient_outward(const std::vector<Eigen::Vector3d>& vertices, std::vector<Eigen::Vector3i>& triangles) {
  std::map<std::pair<int, int>, std::vector<std::size_t>> edge_triangles;
  for (std::size_t i = 0; i < triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[i][k], b = triangles[i][(k + 1) % 3];
      edge_triangles[{std::min(a, b), std::max(a, b)}].push_back(i);
    }
  const auto has_directed = [&](std::size_t i, int a, int b) {
    for (int k = 0; k < 3; ++k)
      if (triangles[i][k] == a && triangles[i][(k + 1) % 3] == b) return true;
    return false;
  };
  std::vector<char> done(triangles.size(), 0);
  for (std::size_t start = 0; start < triangles.size(); ++start) {
    if (done[start]) continue;
    std::vector<std::size_t> stack{start}, component{start};
    done[start] = 1;
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      for (int k = 0; k < 3; ++k) {
        const int a = triangles[i][k], b = triangles[i][(k + 1) % 3];
        for (const std::size_t j : edge_triangles[{std::min(a, b), std::max(a, b)}]) {
          if (done[j]) continue;
          if (has_directed(j, a, b)) std::swap(triangles[j][1], triangles[j][2]);
          done[j] = 1;
          stack.push_back(j);
          component.push_back(j);
        }
      }
    }
    double volume = 0;
    for (const std::size_t i : component)
      volume += corner(vertices, triangles[i], 0).dot(corner(vertices, triangles[i], 1).cross(corner(vertices, triangles[i], 2)));
    if (volume < 0)
      for (const std::size_t i : component) std::swap(triangles[i][1], triangles[i][2]);
  }
}

/// The benchmarks' size law as a function of the distance d to the patch rim [m].
double graded_size_m(const MeshParameters& p, double d) {
  const double t = d / p.tool_radius_m, t0 = p.power_grading_extent, beta = p.size_exponent;
  const double g = std::pow(std::min(t, t0), beta) + beta * std::pow(t0, beta - 1) * std::max(t - t0, 0.0);
  return std::min(p.max_size_m, p.edge_size_m + p.size_growth * p.tool_radius_m * g) / std::ldexp(1.0, p.refinement);
}

/// Distance to the rim circle: centre c + s_rim n on the axis n, radius a.
struct RimCircle {
  Eigen::Vector3d centre;
  Eigen::Vector3d axis;
  double radius = 0;
  double distance(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d w = x - centre;
    const double s = w.dot(axis);
    const double rho = (w - s * axis).norm();
    return std::hypot(rho - radius, s);
  }
};

/// The rim's height along the axis: where lines parallel to the axis at distance a from it meet
/// the surface nearest to the contact, averaged over 32 directions.
RimCircle rim_circle(const Surface& surface, const Eigen::Vector3d& contact, const Eigen::Vector3d& axis, double a) {
  const Eigen::Vector3d e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  double offset_sum = 0;
  int hits = 0;
  for (int k = 0; k < 32; ++k) {
    const double phi = 2 * pi * k / 32;
    const Eigen::Vector3d origin = contact + a * (std::cos(phi) * e1 + std::sin(phi) * e2);
    double best = std::numeric_limits<double>::infinity();
    for (const auto& t : surface.body.triangles()) {
      // Line origin + s axis against the triangle (Möller–Trumbore, any s).
      const Eigen::Vector3d p0 = corner(surface.body.vertices(), t, 0), e_a = corner(surface.body.vertices(), t, 1) - p0,
                            e_b = corner(surface.body.vertices(), t, 2) - p0;
      const Eigen::Vector3d h = axis.cross(e_b);
      const double det = e_a.dot(h);
      if (std::abs(det) < 1e-300) continue;
      const Eigen::Vector3d r = origin - p0;
      const double u = r.dot(h) / det;
      if (u < 0 || u > 1) continue;
      const Eigen::Vector3d q = r.cross(e_a);
      const double v = axis.dot(q) / det;
      if (v < 0 || u + v > 1) continue;
      const double s = e_b.dot(q) / det;
      if (std::abs(s) < std::abs(best)) best = s;
    }
    if (std::isfinite(best)) offset_sum += best, ++hits;
  }
  if (hits < 32)
    throw std::invalid_argument("the tool patch (radius " + text_of(a) + " m) does not fit on the organ surface at the contact (" +
                                text_of(contact.x()) + ", " + text_of(contact.y()) + ", " + text_of(contact.z()) +
                                ") m: lines along the tool axis at the patch radius miss the surface");
  return {contact + (offset_sum / hits) * axis, axis, a};
}

/// The current gmsh model's triangles (all surfaces) with their nodes renumbered from 0.
void gmsh_triangles(std::vector<Eigen::Vector3d>& vertices, std::vector<Eigen::Vector3i>& triangles) {
  std::vector<std::size_t> node_tags;
  std::vector<double> coordinates, parametric;
  gmsh::model::mesh::getNodes(node_tags, coordinates, parametric, -1, -1, true, false);
  std::unordered_map<std::size_t, int> index;
  for (std::size_t i = 0; i < node_tags.size(); ++i) {
    if (index.count(node_tags[i])) continue;
    index[node_tags[i]] = static_cast<int>(vertices.size());
    vertices.emplace_back(coordinates[3 * i], coordinates[3 * i + 1], coordinates[3 * i + 2]);
  }
  std::vector<std::size_t> element_tags, element_nodes;
  constexpr int triangle_type = 2;
  gmsh::model::mesh::getElementsByType(triangle_type, element_tags, element_nodes, -1);
  for (std::size_t e = 0; e < element_tags.size(); ++e)
    triangles.emplace_back(index.at(element_nodes[3 * e]), index.at(element_nodes[3 * e + 1]), index.at(element_nodes[3 * e + 2]));
}

}  // namespace

void OrganBody::validate() const {
  const auto fail = [](const std::string& field, const std::string& value, const std::string& requirement) {
    throw std::invalid_argument("OrganBody." + field + " = " + value + " " + requirement);
  };
  if (surface_path.empty()) fail("surface_path", "\"\"", "must name a surface file");
  if (!std::isfinite(unit_scale) || !(unit_scale > 0)) fail("unit_scale", text_of(unit_scale), "must be finite and > 0");
  for (int d = 0; d < 3; ++d) {
    if (!std::isfinite(contact_point_m[static_cast<std::size_t>(d)])) fail("contact_point_m", text_of(contact_point_m[static_cast<std::size_t>(d)]), "must be finite");
    if (!std::isfinite(tool_axis[static_cast<std::size_t>(d)])) fail("tool_axis", text_of(tool_axis[static_cast<std::size_t>(d)]), "must be finite");
  }
  if (!(feature_angle_rad > 0 && feature_angle_rad < pi)) fail("feature_angle_rad", text_of(feature_angle_rad), "must be in (0, pi)");
  if (attachment.rule_count() > 1)
    throw std::invalid_argument("OrganBody.attachment sets " + std::to_string(attachment.rule_count()) +
                                " rules (plane, msh_group, triangles_path): set exactly one");
}

namespace {

/// The contact site on an already read surface: its closest point to the given one, with the
/// outward pseudo-normal there (the face's inside a face, averaged on an edge or at a corner).
OrganContactSite contact_site_on(const Surface& surface, const OrganBody& organ) {
  const geometry::SurfaceProjection nearest = surface.body.project(vec(organ.contact_point_m));
  OrganContactSite site;
  site.point_m = arr(nearest.point);
  site.outward_normal = arr(nearest.normal.normalized());
  const Eigen::Vector3d axis = vec(organ.tool_axis);
  site.tool_axis = axis.norm() > 0 ? arr(axis.normalized()) : arr(-nearest.normal.normalized());
  site.distance_to_given_point_m = nearest.distance_m;
  site.bounding_box_diagonal_m = surface.diagonal_m;
  return site;
}

}  // namespace

OrganContactSite organ_contact_site(const OrganBody& organ) {
  organ.validate();
  return contact_site_on(read_valid_surface(organ), organ);
}

std::array<double, 3> organ_rim_centre(const OrganBody& organ, double tool_radius_m) {
  organ.validate();
  const Surface surface = read_valid_surface(organ);
  const OrganContactSite site = contact_site_on(surface, organ);
  return arr(rim_circle(surface, vec(site.point_m), vec(site.tool_axis), tool_radius_m).centre);
}

namespace {

using ErrorFactory = std::function<std::runtime_error(const std::string&)>;
using SizeLaw = std::function<double(double, double, double)>;

/// The read surface, what its attachment holds and the contact, checked against the tool size.
struct OrganInput {
  Surface surface;
  std::vector<char> held;
  OrganContactSite site;
  Eigen::Vector3d contact, axis;
};

OrganInput read_organ_input(const MeshParameters& p) {
  const OrganBody& organ = p.organ;
  OrganInput in{read_valid_surface(organ), {}, {}, {}, {}};
  in.held = attached_triangles(organ, in.surface);
  in.site = contact_site_on(in.surface, organ);
  in.contact = vec(in.site.point_m);
  in.axis = vec(in.site.tool_axis);
  const double a = p.tool_radius_m;
  if (in.site.distance_to_given_point_m > a)
    throw std::invalid_argument("organ contact_point (" + text_of(organ.contact_point_m[0]) + ", " + text_of(organ.contact_point_m[1]) + ", " +
                                text_of(organ.contact_point_m[2]) + ") m lies " + text_of(in.site.distance_to_given_point_m) +
                                " m off the surface of '" + organ.surface_path + "', farther than the tool radius " + text_of(a) +
                                " m: is it in the file's units, or on another organ?");
  if (a > 0.25 * in.surface.diagonal_m)
    throw std::invalid_argument("MeshParameters.tool_radius_m = " + text_of(a) + " is too large for the organ '" + organ.surface_path +
                                "' (bounding-box diagonal " + text_of(in.surface.diagonal_m) + " m); is the unit scale right?");
  return in;
}

/// Step 1–2: gmsh remeshes the surface on its reparametrised pieces under the size law.
void remesh_surface(const Surface& input, const MeshParameters& p, const SizeLaw& size_at, const ErrorFactory& fail,
                    std::vector<Eigen::Vector3d>& vertices, std::vector<Eigen::Vector3i>& triangles) {
  internal::GmshSession session("organ_surface");
  try {
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.MeshSizeMax", p.max_size_m / std::ldexp(1.0, p.refinement));
    gmsh::option::setNumber("Mesh.Algorithm", 6);
    gmsh::model::mesh::setSizeCallback([&size_at](int, int, double x, double y, double z) { return size_at(x, y, z); });

    const int surface_tag = gmsh::model::addDiscreteEntity(2);
    std::vector<std::size_t> node_tags(input.body.vertices().size());
    std::vector<double> coordinates;
    coordinates.reserve(3 * input.body.vertices().size());
    for (std::size_t v = 0; v < input.body.vertices().size(); ++v) {
      node_tags[v] = v + 1;
      coordinates.insert(coordinates.end(), {input.body.vertices()[v].x(), input.body.vertices()[v].y(), input.body.vertices()[v].z()});
    }
    gmsh::model::mesh::addNodes(2, surface_tag, node_tags, coordinates);
    std::vector<std::size_t> element_tags, element_nodes;
    for (std::size_t i = 0; i < input.body.triangles().size(); ++i) {
      element_tags.push_back(i + 1);
      for (int k = 0; k < 3; ++k) element_nodes.push_back(static_cast<std::size_t>(input.body.triangles()[i][k]) + 1);
    }
    gmsh::model::mesh::addElementsByType(surface_tag, 2, element_tags, element_nodes);
    gmsh::model::mesh::classifySurfaces(p.organ.feature_angle_rad, true, true, pi);
    gmsh::model::mesh::createGeometry();
    gmsh::model::mesh::generate(2);
    gmsh_triangles(vertices, triangles);
  } catch (const std::string& message) {
    throw fail("gmsh could not remesh the surface: " + message);
  }
  if (triangles.empty()) throw fail("gmsh remeshed the surface into no triangles");
  orient_outward(vertices, triangles);
}

std::string group_name(int tag) {
  switch (tag) {
    case boundary_tags::base: return "base";
    case boundary_tags::tool_patch: return "tool_patch";
    case boundary_tags::cut: return "cut";
    default: return "free";
  }
}

/// Step 5: gmsh fills the closed, grouped surface with tetrahedra under the size law and writes
/// MSH 2.2 with the benchmark tags.
MeshSummary mesh_volume(const std::vector<Eigen::Vector3d>& vertices, const std::vector<Eigen::Vector3i>& triangles,
                        const std::vector<int>& group, const MeshParameters& p, const SizeLaw& size_at, const ErrorFactory& fail,
                        const std::string& msh_path) {
  MeshSummary summary;
  summary.path = msh_path;
  internal::GmshSession session("organ_volume");
  try {
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.MeshSizeMax", p.max_size_m / std::ldexp(1.0, p.refinement));
    gmsh::model::mesh::setSizeCallback([&size_at](int, int, double x, double y, double z) { return size_at(x, y, z); });
    std::map<int, std::vector<std::size_t>> group_nodes_of_elements;
    std::vector<int> owner(vertices.size(), 0);
    for (std::size_t i = 0; i < triangles.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const auto v = static_cast<std::size_t>(triangles[i][k]);
        if (owner[v] == 0) owner[v] = group[i];
        group_nodes_of_elements[group[i]].push_back(v + 1);
      }
    std::vector<int> surfaces;
    std::size_t next_element = 1;
    for (const int tag : {boundary_tags::base, boundary_tags::tool_patch, boundary_tags::free, boundary_tags::cut}) {
      if (!group_nodes_of_elements.count(tag)) continue;
      gmsh::model::addDiscreteEntity(2, tag);
      surfaces.push_back(tag);
    }
    for (const int tag : surfaces) {
      std::vector<std::size_t> nodes;
      std::vector<double> coordinates;
      for (std::size_t v = 0; v < vertices.size(); ++v) {
        if (owner[v] != tag) continue;
        nodes.push_back(v + 1);
        coordinates.insert(coordinates.end(), {vertices[v].x(), vertices[v].y(), vertices[v].z()});
      }
      gmsh::model::mesh::addNodes(2, tag, nodes, coordinates);
    }
    for (const int tag : surfaces) {
      const auto& nodes = group_nodes_of_elements[tag];
      std::vector<std::size_t> elements(nodes.size() / 3);
      for (auto& e : elements) e = next_element++;
      gmsh::model::mesh::addElementsByType(tag, 2, elements, nodes);
    }
    const int loop = gmsh::model::geo::addSurfaceLoop(surfaces);
    const int volume = gmsh::model::geo::addVolume({loop});
    gmsh::model::geo::synchronize();
    for (const int tag : surfaces) gmsh::model::setPhysicalName(2, gmsh::model::addPhysicalGroup(2, {tag}, tag), group_name(tag));
    gmsh::model::setPhysicalName(3, gmsh::model::addPhysicalGroup(3, {volume}, boundary_tags::tissue), "tissue");
    gmsh::option::setNumber("Mesh.Algorithm3D", 1);
    gmsh::option::setNumber("Mesh.Optimize", 1);
    gmsh::option::setNumber("Mesh.ElementOrder", 1);
    gmsh::option::setNumber("Mesh.MshFileVersion", 2.2);
    gmsh::option::setNumber("Mesh.Binary", 0);
    gmsh::option::setNumber("Mesh.SaveAll", 0);
    gmsh::model::mesh::generate(3);

    std::vector<std::size_t> tags, nodes;
    gmsh::model::mesh::getElementsByType(4, tags, nodes, volume);
    summary.tetrahedron_count = tags.size();
    if (group_nodes_of_elements.count(boundary_tags::tool_patch)) {
      gmsh::model::mesh::getElementsByType(2, tags, nodes, boundary_tags::tool_patch);
      summary.patch_triangle_count = tags.size();
    }
    std::vector<double> coordinates, parametric;
    gmsh::model::mesh::getNodes(tags, coordinates, parametric, -1, -1, false, false);
    summary.node_count = tags.size();
    if (summary.tetrahedron_count == 0) throw std::string("the volume mesh has no tetrahedra");
    internal::write_msh_whole(msh_path);
  } catch (const std::string& message) {
    throw fail("gmsh could not mesh the volume: " + message);
  }
  return summary;
}

/// The organ minus ball(c, L), c the contact: the exterior body of the organ atlas, graded toward
/// the cut sphere like the benchmarks' exterior meshes.
MeshSummary generate_organ_exterior_mesh(const MeshParameters& p, const std::string& msh_path) {
  const auto start = std::chrono::steady_clock::now();
  internal::require_writable(msh_path);
  const OrganInput in = read_organ_input(p);
  const double length = p.local_radius_m;
  if (length > 0.5 * in.surface.diagonal_m)
    throw std::invalid_argument("MeshParameters.local_radius_m = " + text_of(length) + " is too large for the organ '" + p.organ.surface_path +
                                "' (bounding-box diagonal " + text_of(in.surface.diagonal_m) + " m)");
  const Eigen::Vector3d centre = in.contact;
  const SizeLaw size_at = [&p, centre, length](double x, double y, double z) {
    return graded_size_m(p, std::max((Eigen::Vector3d(x, y, z) - centre).norm() - length, 0.0));
  };
  const ErrorFactory fail = [&](const std::string& what) {
    return std::runtime_error("generate_organ_body_mesh (exterior of the local ball) for '" + p.organ.surface_path + "' (local radius " +
                              text_of(length) + " m, edge size " + text_of(p.edge_size_m) + " m, refinement " +
                              std::to_string(p.refinement) + "), path '" + msh_path + "': " + what);
  };
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  remesh_surface(in.surface, p, size_at, fail, vertices, triangles);

  LocalBall ball;
  ball.centre_m = centre;
  ball.radius_m = length;
  ball.outward_direction = vec(in.site.outward_normal);
  ball.cap_edge_m = graded_size_m(p, 0);
  const BallCutSurface cut = cut_out_local_ball(vertices, triangles, ball);
  std::vector<int> group(cut.triangles.size(), boundary_tags::free);
  for (std::size_t i = 0; i < cut.triangles.size(); ++i) {
    if (cut.on_cap[i]) {
      group[i] = boundary_tags::cut;
      continue;
    }
    const Eigen::Vector3i& t = cut.triangles[i];
    const Eigen::Vector3d centroid = (corner(cut.vertices, t, 0) + corner(cut.vertices, t, 1) + corner(cut.vertices, t, 2)) / 3;
    if (in.held[static_cast<std::size_t>(in.surface.body.project(centroid).triangle)]) group[i] = boundary_tags::base;
  }
  MeshSummary summary = mesh_volume(cut.vertices, cut.triangles, group, p, size_at, fail, msh_path);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace

MeshSummary generate_organ_body_mesh(const MeshParameters& p, const std::string& msh_path) {
  p.validate();
  if (p.exterior_of_local_ball) return generate_organ_exterior_mesh(p, msh_path);
  const OrganBody& organ = p.organ;
  const auto start = std::chrono::steady_clock::now();
  internal::require_writable(msh_path);
  const OrganInput in = read_organ_input(p);
  const Eigen::Vector3d contact = in.contact, axis = in.axis;
  const double a = p.tool_radius_m;
  const RimCircle rim = rim_circle(in.surface, contact, axis, a);
  const SizeLaw size_at = [&p, &rim](double x, double y, double z) { return graded_size_m(p, rim.distance({x, y, z})); };
  const ErrorFactory fail = [&](const std::string& what) {
    return std::runtime_error("generate_organ_body_mesh for '" + organ.surface_path + "' (tool radius " + text_of(a) +
                              " m, edge size " + text_of(p.edge_size_m) + " m, refinement " + std::to_string(p.refinement) +
                              "), path '" + msh_path + "': " + what);
  };
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  remesh_surface(in.surface, p, size_at, fail, vertices, triangles);

  // 3–4: the patch cut in; the groups.
  ToolPatchCylinder tool;
  tool.contact_point_m = contact;
  tool.axis = axis;
  tool.radius_m = a;
  const ImprintedSurface imprinted = imprint_tool_patch(vertices, triangles, tool);
  std::vector<int> group(imprinted.triangles.size(), boundary_tags::free);
  for (std::size_t i = 0; i < imprinted.triangles.size(); ++i) {
    const Eigen::Vector3i& t = imprinted.triangles[i];
    const Eigen::Vector3d centroid =
        (corner(imprinted.vertices, t, 0) + corner(imprinted.vertices, t, 1) + corner(imprinted.vertices, t, 2)) / 3;
    const bool held = in.held[static_cast<std::size_t>(in.surface.body.project(centroid).triangle)] != 0;
    if (imprinted.in_patch[i] && held)
      throw std::invalid_argument("the tool patch at (" + text_of(contact.x()) + ", " + text_of(contact.y()) + ", " + text_of(contact.z()) +
                                  ") m with radius " + text_of(a) + " m touches the organ's attachment: move the contact or the attachment");
    group[i] = imprinted.in_patch[i] ? boundary_tags::tool_patch : held ? boundary_tags::base : boundary_tags::free;
  }
  MeshSummary summary = mesh_volume(imprinted.vertices, imprinted.triangles, group, p, size_at, fail, msh_path);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace touchstone::meshes
