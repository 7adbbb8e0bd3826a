// The gmsh (OpenCASCADE) geometry and graded tetrahedral meshes of the benchmark bodies B1-B5
// and the test box (one file: the bodies share the patch-rim circle, the size law and the
// physical groups that the FEM and the MFS rely on).
#include "touchstone/meshes/benchmark_geometry.hpp"

#include "text_of.hpp"
#include "gmsh_session.hpp"
#include "touchstone/meshes/organ_body_mesh.hpp"

#include <gmsh.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::meshes {

using internal::require_writable;
using internal::write_msh_whole;

namespace {

constexpr double pi = 3.14159265358979323846;
constexpr int max_refinement = 6;

// ---------------------------------------------------------------------------------------------
// Validation helpers: every message names the field as "MeshParameters.<field> = <value>".

using internal::text_of;

[[noreturn]] void reject(const char* field, double value, const std::string& requirement) {
  throw std::invalid_argument("MeshParameters." + std::string(field) + " = " + text_of(value) +
                              " " + requirement);
}

void require_positive(const char* field, double value) {
  if (!std::isfinite(value)) reject(field, value, "must be finite");
  if (!(value > 0)) reject(field, value, "must be > 0");
}

// ---------------------------------------------------------------------------------------------
// Small vector algebra for classifying geometry by evaluated points.

using Point = std::array<double, 3>;

double norm(const Point& p) { return std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]); }
double dot(const Point& p, const Point& q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; }
Point minus(const Point& p, const Point& q) { return {p[0] - q[0], p[1] - q[1], p[2] - q[2]}; }

/// Points of an entity's underlying curve or surface: a curve is sampled over its whole
/// parameter range (edges are never trimmed), a surface over the interior of its UV box (the
/// points may fall outside a trimmed face, but they lie on its carrier sphere or plane, which is
/// all the classification asks of them).
std::vector<Point> sample_entity(int dim, int tag) {
  std::vector<double> lo;
  std::vector<double> hi;
  gmsh::model::getParametrizationBounds(dim, tag, lo, hi);
  std::vector<double> parameters;
  if (dim == 1) {
    constexpr int count = 17;
    for (int i = 0; i < count; ++i) {
      parameters.push_back(lo[0] + (hi[0] - lo[0]) * i / (count - 1));
    }
  } else {
    for (double fu : {0.2, 0.45, 0.7}) {
      for (double fv : {0.3, 0.55, 0.8}) {
        parameters.push_back(lo[0] + (hi[0] - lo[0]) * fu);
        parameters.push_back(lo[1] + (hi[1] - lo[1]) * fv);
      }
    }
  }
  std::vector<double> xyz;
  gmsh::model::getValue(dim, tag, parameters, xyz);
  std::vector<Point> points(xyz.size() / 3);
  for (std::size_t i = 0; i < points.size(); ++i) {
    points[i] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
  }
  return points;
}

template <class Predicate>
bool all_of_points(const std::vector<Point>& points, Predicate predicate) {
  return !points.empty() && std::all_of(points.begin(), points.end(), predicate);
}

/// Sample points of every curve bounding a face.
std::vector<Point> sample_face_boundary(int face_tag) {
  gmsh::vectorpair edges;
  gmsh::model::getBoundary({{2, face_tag}}, edges, false, false, false);
  std::vector<Point> points;
  for (const auto& [dim, tag] : edges) {
    const auto edge_points = sample_entity(dim, std::abs(tag));
    points.insert(points.end(), edge_points.begin(), edge_points.end());
  }
  return points;
}

// ---------------------------------------------------------------------------------------------
// Geometry description of one benchmark, in the terms the classifier needs.

/// The analytic surfaces of a benchmark. Classification tests each face against these, so it
/// never depends on the tags a boolean operation happens to return.
struct Shape {
  MeshParameters parameters;
  Point patch_axis{0, 0, 1};   ///< n: unit direction from the origin to the patch centre
  double patch_height = 0;     ///< n·x on the patch circle: sqrt(R² − a²) on spheres, 0 for B1
  Point pole{0, 0, 0};         ///< (0, 0, R): centre of the B3 cut ball
  Point contact{0, 0, 0};      ///< c: centre of the cut ball of an exterior mesh
  double tolerance = 0;        ///< absolute distance tolerance for "lies on" tests [m]
};

Shape make_shape(const MeshParameters& p) {
  Shape shape;
  shape.parameters = p;
  const double length_scale = p.benchmark == Benchmark::Box
                                  ? *std::max_element(p.box_size_m.begin(), p.box_size_m.end())
                                  : p.body_radius_m;
  // OpenCASCADE's own confusion tolerance is 1e-7 m; analytic evaluations are far tighter.
  shape.tolerance = 1e-6 * length_scale;
  if (p.benchmark == Benchmark::B2 || p.benchmark == Benchmark::B3 ||
      p.benchmark == Benchmark::B5) {
    const double theta = p.benchmark == Benchmark::B5 ? p.contact_polar_angle_rad : 0.0;
    shape.patch_axis = {std::sin(theta), 0.0, std::cos(theta)};
    shape.patch_height = std::sqrt(p.body_radius_m * p.body_radius_m -
                                   p.tool_radius_m * p.tool_radius_m);
    shape.pole = {0.0, 0.0, p.body_radius_m};
    shape.contact = {p.body_radius_m * shape.patch_axis[0], 0.0, p.body_radius_m * shape.patch_axis[2]};
  }
  return shape;
}

/// The surface groups of the written mesh, and the curves of the patch edge.
struct Classified {
  std::vector<int> volumes;
  std::map<int, std::vector<int>> surfaces;  ///< physical tag → surface tags
  std::vector<int> patch_edge_curves;
};

/// Shortest decimal text that reads back as exactly the same double.
std::string number(double value) {
  char text[32];
  for (const int digits : {15, 16, 17}) {
    std::snprintf(text, sizeof text, "%.*g", digits, value);
    if (std::strtod(text, nullptr) == value) break;
  }
  return text;
}

std::string entity_list(const gmsh::vectorpair& dim_tags) {
  static const char* const kinds[4] = {"Point", "Curve", "Surface", "Volume"};
  std::string text;
  for (const auto& [dim, tag] : dim_tags) {
    text += std::string(" ") + kinds[dim] + "{" + std::to_string(tag) + "};";
  }
  return text;
}

std::string tag_list(const std::vector<int>& tags) {
  std::string text;
  for (std::size_t i = 0; i < tags.size(); ++i) text += (i ? ", " : "") + std::to_string(tags[i]);
  return text;
}

/// Performs OCC operations, options and size fields through the gmsh API and records each as
/// the equivalent .geo statement. gmsh 4.8 cannot export OCC spheres to .geo_unrolled (it
/// approximates or skips trimmed faces), but replaying the same operations in the same order
/// through the same kernel reproduces the same entities and tags, so the recorded script is an
/// exact description of the model.
class ScriptedModel {
 public:
  ScriptedModel() { script_ << "SetFactory(\"OpenCASCADE\");\n"; }

  int add_box(double x, double y, double z, double dx, double dy, double dz) {
    const int tag = gmsh::model::occ::addBox(x, y, z, dx, dy, dz);
    script_ << "Box(" << tag << ") = {" << list({x, y, z, dx, dy, dz}) << "};\n";
    return tag;
  }
  int add_cylinder(double x, double y, double z, double dx, double dy, double dz, double r) {
    const int tag = gmsh::model::occ::addCylinder(x, y, z, dx, dy, dz, r);
    script_ << "Cylinder(" << tag << ") = {" << list({x, y, z, dx, dy, dz, r}) << "};\n";
    return tag;
  }
  /// Sphere of polar opening [polar_min, polar_max] (latitudes in [-π/2, π/2]).
  int add_sphere(double x, double y, double z, double r, double polar_min, double polar_max) {
    const int tag = gmsh::model::occ::addSphere(x, y, z, r, -1, polar_min, polar_max);
    script_ << "Sphere(" << tag << ") = {" << list({x, y, z, r, polar_min, polar_max, 2 * pi})
            << "};\n";
    return tag;
  }
  /// Circle of radius r centred at (x, y, z) in a plane of constant z.
  int add_circle(double x, double y, double z, double r) {
    const int tag = gmsh::model::occ::addCircle(x, y, z, r);
    script_ << "Circle(" << tag << ") = {" << list({x, y, z, r, 0, 2 * pi}) << "};\n";
    return tag;
  }
  void rotate(const gmsh::vectorpair& dim_tags, const Point& origin, const Point& axis,
              double angle) {
    gmsh::model::occ::rotate(dim_tags, origin[0], origin[1], origin[2], axis[0], axis[1],
                             axis[2], angle);
    script_ << "Rotate {{" << list({axis[0], axis[1], axis[2]}) << "}, {"
            << list({origin[0], origin[1], origin[2]}) << "}, " << number(angle) << "} {"
            << entity_list(dim_tags) << " }\n";
  }
  gmsh::vectorpair intersect(const gmsh::vectorpair& objects, const gmsh::vectorpair& tools) {
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> out_map;
    gmsh::model::occ::intersect(objects, tools, out, out_map);
    record_boolean("BooleanIntersection", objects, tools);
    return out;
  }
  gmsh::vectorpair cut(const gmsh::vectorpair& objects, const gmsh::vectorpair& tools) {
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> out_map;
    gmsh::model::occ::cut(objects, tools, out, out_map);
    record_boolean("BooleanDifference", objects, tools);
    return out;
  }
  gmsh::vectorpair fragment(const gmsh::vectorpair& objects, const gmsh::vectorpair& tools) {
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> out_map;
    gmsh::model::occ::fragment(objects, tools, out, out_map);
    record_boolean("BooleanFragments", objects, tools);
    return out;
  }
  void synchronize() { gmsh::model::occ::synchronize(); }

  void add_physical_group(int dim, const std::vector<int>& tags, int tag, const std::string& name) {
    gmsh::model::addPhysicalGroup(dim, tags, tag);
    gmsh::model::setPhysicalName(dim, tag, name);
    script_ << (dim == 3 ? "Physical Volume(\"" : "Physical Surface(\"") << name << "\", " << tag
            << ") = {" << tag_list(tags) << "};\n";
  }

  void set_option(const std::string& name, double value) {
    gmsh::option::setNumber(name, value);
    script_ << name << " = " << number(value) << ";\n";
  }

  int add_field(const std::string& type) {
    const int tag = gmsh::model::mesh::field::add(type);
    script_ << "Field[" << tag << "] = " << type << ";\n";
    return tag;
  }
  void set_field_number(int field, const std::string& option, double value) {
    gmsh::model::mesh::field::setNumber(field, option, value);
    script_ << "Field[" << field << "]." << option << " = " << number(value) << ";\n";
  }
  void set_field_tags(int field, const std::string& option, const std::vector<int>& tags) {
    gmsh::model::mesh::field::setNumbers(field, option,
                                         std::vector<double>(tags.begin(), tags.end()));
    script_ << "Field[" << field << "]." << option << " = {" << tag_list(tags) << "};\n";
  }
  void set_field_string(int field, const std::string& option, const std::string& value) {
    gmsh::model::mesh::field::setString(field, option, value);
    script_ << "Field[" << field << "]." << option << " = \"" << value << "\";\n";
  }
  void set_background_field(int field) {
    gmsh::model::mesh::field::setAsBackgroundMesh(field);
    script_ << "Background Field = " << field << ";\n";
  }

  std::string script() const { return script_.str(); }

 private:
  static std::string list(std::initializer_list<double> values) {
    std::string text;
    for (const double value : values) text += (text.empty() ? "" : ", ") + number(value);
    return text;
  }
  void record_boolean(const char* operation, const gmsh::vectorpair& objects,
                      const gmsh::vectorpair& tools) {
    script_ << operation << "{" << entity_list(objects) << " Delete; }{" << entity_list(tools)
            << " Delete; }\n";
  }

  std::ostringstream script_;
};

gmsh::vectorpair volumes_of(const gmsh::vectorpair& entities) {
  gmsh::vectorpair volumes;
  for (const auto& entity : entities) {
    if (entity.first == 3) volumes.push_back(entity);
  }
  if (volumes.empty()) throw std::runtime_error("a boolean operation left no volume");
  return volumes;
}

/// Builds the OCC solid of the benchmark with the patch circle imprinted on its boundary.
/// The circle is fragmented into the boundary face rather than cut out by an internal disk: a
/// disk at z0 = sqrt(R² − a²) would split off a lens only R − z0 ≈ a²/(2R) thick (62 µm for
/// the default B2) under the patch, which forces flat slivers exactly where the stress is
/// singular.
void build_solid(const Shape& shape, ScriptedModel& model) {
  const MeshParameters& p = shape.parameters;
  switch (p.benchmark) {
    case Benchmark::Organ:
      throw std::logic_error("build_solid: organ bodies are meshed by generate_organ_body_mesh");
    case Benchmark::Box:
      model.add_box(0, 0, 0, p.box_size_m[0], p.box_size_m[1], p.box_size_m[2]);
      break;
    case Benchmark::B1: {
      const double w = p.body_radius_m;
      const int cylinder = model.add_cylinder(0, 0, -w, 0, 0, w, w);
      if (p.exterior_of_local_ball) {
        const int ball = model.add_sphere(0, 0, 0, p.local_radius_m, -pi / 2, pi / 2);
        volumes_of(model.cut({{3, cylinder}}, {{3, ball}}));
        break;
      }
      const int circle = model.add_circle(0, 0, 0, p.tool_radius_m);
      model.fragment({{3, cylinder}}, {{1, circle}});
      break;
    }
    case Benchmark::B2:
    case Benchmark::B3:
    case Benchmark::B5: {
      // OCC spheres carry two degenerate poles and a seam meridian, and a patch circle passing
      // near either makes fragments fragile. Every patch centre lies in the quarter circle from
      // +z to +x of the plane y = 0, so the sphere's axis is turned to (−1, 0, 1)/√2 and its
      // seam to the far side: the poles and the seam stay at least 15° (π/4 − asin(1/2)) away
      // from any admissible patch.
      const double r = p.body_radius_m;
      const int sphere = model.add_sphere(0, 0, 0, r, -pi / 2, pi / 2);
      model.rotate({{3, sphere}}, {0, 0, 0}, {0, 0, 1}, pi);
      model.rotate({{3, sphere}}, {0, 0, 0}, {0, 1, 0}, -pi / 4);
      const int upper_half_space = model.add_box(-2 * r, -2 * r, 0, 4 * r, 4 * r, 2 * r);
      gmsh::vectorpair body = volumes_of(model.intersect({{3, sphere}}, {{3, upper_half_space}}));
      if (p.benchmark == Benchmark::B3) {
        // The ball keeps its axis along z, so its south pole is an interior point of the cut
        // face: gmsh's frontal surface mesher handles that well, whereas with the poles turned
        // sideways it failed on some sizes.
        const int ball = model.add_sphere(0, 0, r, p.local_radius_m, -pi / 2, pi / 2);
        body = volumes_of(model.intersect(body, {{3, ball}}));
      }
      if (p.exterior_of_local_ball) {
        // The ball is built around the pole with its axis along z and turned with the contact,
        // so its south pole, the deepest point of the cut, is an interior point of the cut face
        // (as for B3) and its north pole and seam lie outside the body where they are cut away.
        const int ball = model.add_sphere(0, 0, r, p.local_radius_m, -pi / 2, pi / 2);
        if (p.benchmark == Benchmark::B5 && p.contact_polar_angle_rad != 0) {
          model.rotate({{3, ball}}, {0, 0, 0}, {0, 1, 0}, p.contact_polar_angle_rad);
        }
        volumes_of(model.cut(body, {{3, ball}}));
        break;
      }
      const int circle = model.add_circle(0, 0, shape.patch_height, p.tool_radius_m);
      if (p.benchmark == Benchmark::B5 && p.contact_polar_angle_rad != 0) {
        // Rotating e_z by θ about +y gives (sin θ, 0, cos θ), the documented patch direction.
        model.rotate({{1, circle}}, {0, 0, 0}, {0, 1, 0}, p.contact_polar_angle_rad);
      }
      model.fragment(body, {{1, circle}});
      break;
    }
  }
  model.synchronize();
}

Classified classify(const Shape& shape) {
  const MeshParameters& p = shape.parameters;
  const double tol = shape.tolerance;
  Classified result;

  gmsh::vectorpair volumes;
  gmsh::model::getEntities(volumes, 3);
  for (const auto& entity : volumes) result.volumes.push_back(entity.second);
  if (result.volumes.empty()) throw std::runtime_error("the geometry has no volume");

  // Combined boundary: faces shared by two volumes cancel, so only the outer skin remains.
  gmsh::vectorpair faces;
  gmsh::model::getBoundary(volumes, faces, true, false, false);

  const auto on_sphere = [tol](const Point& centre, double radius) {
    return [centre, radius, tol](const Point& x) {
      return std::abs(norm(minus(x, centre)) - radius) <= tol;
    };
  };
  const auto on_plane = [tol](int axis, double value) {
    return [axis, value, tol](const Point& x) { return std::abs(x[axis] - value) <= tol; };
  };
  const Point origin{0, 0, 0};

  for (const auto& [dim, signed_tag] : faces) {
    const int tag = std::abs(signed_tag);
    const auto points = sample_entity(dim, tag);
    int group = 0;
    switch (p.benchmark) {
      case Benchmark::Organ:
        throw std::logic_error("classify: organ bodies are meshed by generate_organ_body_mesh");
      case Benchmark::Box: {
        constexpr std::array<std::array<int, 2>, 3> tags{{
            {boundary_tags::x_min, boundary_tags::x_max},
            {boundary_tags::y_min, boundary_tags::y_max},
            {boundary_tags::z_min, boundary_tags::z_max},
        }};
        for (int axis = 0; axis < 3 && group == 0; ++axis) {
          if (all_of_points(points, on_plane(axis, 0.0))) group = tags[axis][0];
          if (all_of_points(points, on_plane(axis, p.box_size_m[axis]))) group = tags[axis][1];
        }
        break;
      }
      case Benchmark::B1: {
        const double w = p.body_radius_m;
        if (all_of_points(points, on_plane(2, -w))) {
          group = boundary_tags::base;
        } else if (p.exterior_of_local_ball && all_of_points(points, on_sphere(shape.contact, p.local_radius_m))) {
          group = boundary_tags::cut;
        } else if (p.exterior_of_local_ball && all_of_points(points, on_plane(2, 0.0))) {
          group = boundary_tags::free;
        } else if (all_of_points(points, on_plane(2, 0.0))) {
          const auto inside_patch = [&](const Point& x) {
            return std::hypot(x[0], x[1]) <= p.tool_radius_m + tol;
          };
          group = all_of_points(sample_face_boundary(tag), inside_patch) ? boundary_tags::tool_patch
                                                                         : boundary_tags::free;
        } else if (all_of_points(points, [&](const Point& x) {
                     return std::abs(std::hypot(x[0], x[1]) - w) <= tol;
                   })) {
          group = boundary_tags::free;
        }
        break;
      }
      case Benchmark::B2:
      case Benchmark::B3:
      case Benchmark::B5: {
        if (all_of_points(points, on_plane(2, 0.0))) {
          group = boundary_tags::base;
        } else if (p.exterior_of_local_ball && all_of_points(points, on_sphere(shape.contact, p.local_radius_m))) {
          group = boundary_tags::cut;
        } else if (p.exterior_of_local_ball && all_of_points(points, on_sphere(origin, p.body_radius_m))) {
          group = boundary_tags::free;
        } else if (all_of_points(points, on_sphere(origin, p.body_radius_m))) {
          const auto inside_patch = [&](const Point& x) {
            return dot(shape.patch_axis, x) >= shape.patch_height - tol;
          };
          group = all_of_points(sample_face_boundary(tag), inside_patch) ? boundary_tags::tool_patch
                                                                         : boundary_tags::free;
        } else if (p.benchmark == Benchmark::B3 &&
                   all_of_points(points, on_sphere(shape.pole, p.local_radius_m))) {
          group = boundary_tags::cut;
        }
        break;
      }
    }
    if (group == 0) {
      std::ostringstream text;
      text << "boundary surface " << tag << " lies on none of the benchmark's planes or spheres";
      throw std::runtime_error(text.str());
    }
    result.surfaces[group].push_back(tag);
  }

  if (p.exterior_of_local_ball && result.surfaces.count(boundary_tags::cut) == 0) {
    throw std::runtime_error("no boundary surface was recognised as the cut sphere");
  }
  if (p.benchmark != Benchmark::Box && !p.exterior_of_local_ball) {
    if (result.surfaces.count(boundary_tags::tool_patch) == 0) {
      throw std::runtime_error("no boundary surface was recognised as the tool patch");
    }
    gmsh::vectorpair curves;
    gmsh::model::getEntities(curves, 1);
    const auto on_patch_edge = [&](const Point& x) {
      if (p.benchmark == Benchmark::B1) {
        return std::abs(x[2]) <= tol && std::abs(std::hypot(x[0], x[1]) - p.tool_radius_m) <= tol;
      }
      return std::abs(norm(x) - p.body_radius_m) <= tol &&
             std::abs(dot(shape.patch_axis, x) - shape.patch_height) <= tol;
    };
    for (const auto& curve : curves) {
      if (all_of_points(sample_entity(1, curve.second), on_patch_edge)) {
        result.patch_edge_curves.push_back(curve.second);
      }
    }
    if (result.patch_edge_curves.empty()) {
      throw std::runtime_error("the patch-edge circle is not a curve of the geometry");
    }
  }
  return result;
}

const char* group_name(int group) {
  switch (group) {
    case boundary_tags::base: return "base";
    case boundary_tags::tool_patch: return "tool_patch";
    case boundary_tags::free: return "free";
    case boundary_tags::cut: return "cut";
    case boundary_tags::x_min: return "x_min";
    case boundary_tags::x_max: return "x_max";
    case boundary_tags::y_min: return "y_min";
    case boundary_tags::y_max: return "y_max";
    case boundary_tags::z_min: return "z_min";
    case boundary_tags::z_max: return "z_max";
    case boundary_tags::tissue: return "tissue";
    default: throw std::logic_error("no name for physical group " + std::to_string(group));
  }
}

void add_physical_groups(const Classified& classified, ScriptedModel& model) {
  for (const auto& [group, tags] : classified.surfaces) {
    model.add_physical_group(2, tags, group, group_name(group));
  }
  model.add_physical_group(3, classified.volumes, boundary_tags::tissue,
                           group_name(boundary_tags::tissue));
}

/// growth · a · g(d/a) for the distance expression d: g(t) = t for β = 1 (linear grading); for
/// β < 1, g(t) = t^β up to t₀ = power_grading_extent (harder grading where the r^(1/2)
/// singularity lives) and its tangent line beyond, so that large domains (B1) are not filled
/// with small elements.
std::string graded_size(const MeshParameters& p, const std::string& d) {
  const std::string t = "(" + d + " / " + number(p.tool_radius_m) + ")";
  const double t0 = p.power_grading_extent, beta = p.size_exponent;
  return beta == 1.0 ? number(p.size_growth) + " * " + d
                     : number(p.size_growth * p.tool_radius_m) + " * (min(" + t + ", " + number(t0) + ")^" +
                           number(beta) + " + " + number(beta * std::pow(t0, beta - 1)) + " * max(" + t + " - " +
                           number(t0) + ", 0))";
}

/// Size field h(x) = min(max, edge + growth · a · g(d(x)/a)) / 2^refinement (g: MeshParameters), d = distance to the patch
/// edge (exterior meshes: to the cut sphere); the Box gets the uniform size edge / 2^refinement. Then the mesh options, so that the
/// recorded script meshes exactly as generate_mesh does.
void set_mesh_options(const Shape& shape, const Classified& classified, ScriptedModel& model) {
  const MeshParameters& p = shape.parameters;
  const double scale = std::ldexp(1.0, p.refinement);

  int size = 0;
  if (p.benchmark == Benchmark::Box) {
    size = model.add_field("MathEval");
    model.set_field_string(size, "F", number(p.edge_size_m / scale));
  } else if (p.exterior_of_local_ball) {
    // The distance to the cut sphere in closed form, d = |x − c| − L ≥ 0 in the exterior: exact,
    // and cheaper than sampling the sphere's faces. The trace on the cut is smooth (the patch
    // edge lies inside the ball), so the linear law (β = 1) is the natural choice.
    size = model.add_field("MathEval");
    const Point& c = shape.contact;
    const std::string d = "max(sqrt((x - " + number(c[0]) + ")^2 + (y - " + number(c[1]) + ")^2 + (z - " +
                          number(c[2]) + ")^2) - " + number(p.local_radius_m) + ", 0)";
    model.set_field_string(size, "F", "min(" + number(p.max_size_m) + ", " + number(p.edge_size_m) + " + " +
                                          graded_size(p, d) + ") / " + number(scale));
  } else {
    const int distance = model.add_field("Distance");
    model.set_field_tags(distance, "CurvesList", classified.patch_edge_curves);
    // The field measures distance to sample points, so space them well below the edge size.
    const double circumference = 2 * pi * p.tool_radius_m;
    const double samples = std::max(200.0, std::ceil(4 * circumference * scale / p.edge_size_m));
    try {
      model.set_field_number(distance, "Sampling", samples);
    } catch (const std::string&) {
      model.set_field_number(distance, "NNodesByEdge", samples);  // its name before gmsh 4.9
    }
    size = model.add_field("MathEval");
    const std::string d = "F" + std::to_string(distance);
    model.set_field_string(size, "F",
                           "min(" + number(p.max_size_m) + ", " + number(p.edge_size_m) + " + " +
                               graded_size(p, d) + ") / " + number(scale));
  }
  model.set_background_field(size);

  model.set_option("Mesh.MeshSizeExtendFromBoundary", 0);
  model.set_option("Mesh.MeshSizeFromPoints", 0);
  model.set_option("Mesh.MeshSizeFromCurvature", 0);
  const double largest = (p.benchmark == Benchmark::Box ? p.edge_size_m : p.max_size_m) / scale;
  model.set_option("Mesh.MeshSizeMax", largest);
  model.set_option("Mesh.ElementOrder", 1);
  // Frontal-Delaunay surfaces; generate_checked_mesh falls back to others if it gives up.
  model.set_option("Mesh.Algorithm", 6);
  // Delaunay: the 3-D algorithm that recovers boundaries most reliably on these solids.
  model.set_option("Mesh.Algorithm3D", 1);
  model.set_option("Mesh.Optimize", 1);
  model.set_option("Mesh.MshFileVersion", 2.2);
  model.set_option("Mesh.Binary", 0);
  model.set_option("Mesh.SaveAll", 0);
}

/// Builds, classifies and prepares the model for meshing; shared by generate_mesh and
/// write_geometry_script so both describe the same thing.
Classified prepare_model(const Shape& shape, ScriptedModel& model) {
  build_solid(shape, model);
  const Classified classified = classify(shape);
  add_physical_groups(classified, model);
  set_mesh_options(shape, classified, model);
  return classified;
}

std::string describe_parameters(const MeshParameters& p) {
  std::ostringstream text;
  text << "benchmark " << to_string(p.benchmark);
  if (p.benchmark == Benchmark::Box) {
    text << " (size " << p.box_size_m[0] << " x " << p.box_size_m[1] << " x " << p.box_size_m[2]
         << " m";
  } else {
    text << " (R = " << p.body_radius_m << " m, a = " << p.tool_radius_m << " m";
    if (p.benchmark == Benchmark::B3) text << ", L = " << p.local_radius_m << " m";
    if (p.exterior_of_local_ball) text << ", exterior of the ball L = " << p.local_radius_m << " m";
    if (p.benchmark == Benchmark::B5) text << ", theta = " << p.contact_polar_angle_rad << " rad";
    text << ", max_size = " << p.max_size_m << " m, size_growth = " << p.size_growth;
  }
  text << ", edge_size = " << p.edge_size_m << " m, refinement = " << p.refinement << ")";
  return text.str();
}

/// Runs a gmsh task and turns every failure (gmsh throws std::string) into a runtime_error that
/// names the operation, the parameters and the path.
template <class Task>
auto run_gmsh(const char* operation, const MeshParameters& p, const std::string& path, Task task) {
  const auto fail = [&](const std::string& reason) {
    return std::runtime_error(std::string(operation) + " failed for " + describe_parameters(p) +
                              ", path '" + path + "': " + reason);
  };
  try {
    internal::GmshSession session("touchstone");
    return task();
  } catch (const std::string& gmsh_error) {
    throw fail("gmsh: " + gmsh_error);
  } catch (const std::exception& error) {
    throw fail(error.what());
  }
}

/// Fails before the (possibly long) meshing if the file cannot be written; leaves no file behind.
/// Per physical group: its entities and their measures (volume or area).
using GroupFingerprints = std::map<std::pair<int, int>, std::vector<std::pair<int, double>>>;

GroupFingerprints physical_group_fingerprints() {
  GroupFingerprints result;
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups);
  for (const auto& [dim, group] : groups) {
    std::vector<int> tags;
    gmsh::model::getEntitiesForPhysicalGroup(dim, group, tags);
    auto& entries = result[{dim, group}];
    for (const int tag : tags) {
      double measure = 0;
      gmsh::model::occ::getMass(dim, tag, measure);
      entries.emplace_back(tag, measure);
    }
  }
  return result;
}

/// Same groups, same entity tags, and measures equal to 1e-9 relative: a renumbered entity
/// would show up as a different measure under the same tag.
bool same_fingerprints(const GroupFingerprints& a, const GroupFingerprints& b) {
  if (a.size() != b.size()) return false;
  for (auto i = a.begin(), j = b.begin(); i != a.end(); ++i, ++j) {
    if (i->first != j->first || i->second.size() != j->second.size()) return false;
    for (std::size_t k = 0; k < i->second.size(); ++k) {
      const auto& [tag_a, measure_a] = i->second[k];
      const auto& [tag_b, measure_b] = j->second[k];
      if (tag_a != tag_b || std::abs(measure_a - measure_b) > 1e-9 * std::abs(measure_a)) {
        return false;
      }
    }
  }
  return true;
}

std::size_t count_elements(int element_type, int entity_tag) {
  std::vector<std::size_t> element_tags;
  std::vector<std::size_t> node_tags;
  gmsh::model::mesh::getElementsByType(element_type, element_tags, node_tags, entity_tag);
  return element_tags.size();
}

/// Compares the mesh with the CAD model it claims to fill: every grouped surface's triangle
/// area and every volume's tetrahedron volume against the OpenCASCADE measure. Facets lose a
/// few per cent at most at sane sizes; a surface mesher that silently gives up (a fan of
/// boundary edges, or a volume left half empty) loses far more. Returns what is wrong, or "".
std::string mesh_defect(const Classified& classified) {
  std::vector<std::size_t> node_tags;
  std::vector<double> xyz;
  std::vector<double> parametric;
  gmsh::model::mesh::getNodes(node_tags, xyz, parametric, -1, -1, false, false);
  std::map<std::size_t, Point> nodes;
  for (std::size_t i = 0; i < node_tags.size(); ++i) {
    nodes[node_tags[i]] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
  }
  const auto cross = [](const Point& u, const Point& v) {
    return Point{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  };

  constexpr double tolerance = 0.1;
  const auto compare = [&](int dim, int tag, double meshed) -> std::string {
    double exact = 0;
    gmsh::model::occ::getMass(dim, tag, exact);
    if (std::abs(meshed - exact) <= tolerance * exact) return "";
    std::ostringstream text;
    text << (dim == 3 ? "volume " : "surface ") << tag << " meshes to " << meshed << " instead of "
         << exact << (dim == 3 ? " m^3" : " m^2");
    return text.str();
  };

  for (const auto& [group, surfaces] : classified.surfaces) {
    for (const int surface : surfaces) {
      std::vector<std::size_t> element_tags;
      std::vector<std::size_t> element_nodes;
      gmsh::model::mesh::getElementsByType(2, element_tags, element_nodes, surface);
      double area = 0;
      for (std::size_t i = 0; i + 2 < element_nodes.size(); i += 3) {
        const Point& x0 = nodes.at(element_nodes[i]);
        area += 0.5 * norm(cross(minus(nodes.at(element_nodes[i + 1]), x0),
                                 minus(nodes.at(element_nodes[i + 2]), x0)));
      }
      const std::string defect = compare(2, surface, area);
      if (!defect.empty()) return defect;
    }
  }
  for (const int volume_tag : classified.volumes) {
    std::vector<std::size_t> element_tags;
    std::vector<std::size_t> element_nodes;
    gmsh::model::mesh::getElementsByType(4, element_tags, element_nodes, volume_tag);
    double volume = 0;
    for (std::size_t i = 0; i + 3 < element_nodes.size(); i += 4) {
      const Point& x0 = nodes.at(element_nodes[i]);
      volume += std::abs(dot(minus(nodes.at(element_nodes[i + 1]), x0),
                             cross(minus(nodes.at(element_nodes[i + 2]), x0),
                                   minus(nodes.at(element_nodes[i + 3]), x0)))) /
                6;
    }
    const std::string defect = compare(3, volume_tag, volume);
    if (!defect.empty()) return defect;
  }
  return "";
}

/// Meshes in 3-D with gmsh's frontal-Delaunay surface mesher (the best-shaped triangles) and
/// falls back to the Delaunay and then the MeshAdapt surface mesher when the result does not
/// fill the geometry.
void generate_checked_mesh(const Classified& classified) {
  std::string defects;
  for (const int algorithm : {6, 5, 1}) {
    gmsh::model::mesh::clear();
    gmsh::option::setNumber("Mesh.Algorithm", algorithm);
    gmsh::model::mesh::generate(3);
    const std::string defect = mesh_defect(classified);
    if (defect.empty()) return;
    defects += (defects.empty() ? "" : "; ") + ("Mesh.Algorithm " + std::to_string(algorithm)) +
               ": " + defect;
  }
  throw std::runtime_error("every surface mesher left the mesh incomplete (" + defects + ")");
}

}  // namespace

void MeshParameters::validate() const {
  if (refinement < 0 || refinement > max_refinement) {
    reject("refinement", refinement, "must be in [0, " + std::to_string(max_refinement) + "]");
  }
  require_positive("edge_size_m", edge_size_m);

  if (benchmark == Benchmark::Box) {
    const char* fields[3] = {"box_size_m[0]", "box_size_m[1]", "box_size_m[2]"};
    for (int axis = 0; axis < 3; ++axis) require_positive(fields[axis], box_size_m[axis]);
    return;
  }
  if (benchmark == Benchmark::Organ) {
    organ.validate();
    require_positive("tool_radius_m", tool_radius_m);
    require_positive("max_size_m", max_size_m);
    require_positive("size_growth", size_growth);
    if (!(size_exponent >= 0.25 && size_exponent <= 1.0)) reject("size_exponent", size_exponent, "must be in [0.25, 1]");
    if (!(power_grading_extent >= 1.0)) reject("power_grading_extent", power_grading_extent, "must be >= 1");
    // The size at the patch rim, or on the cut sphere of an exterior mesh: small enough to resolve it.
    if (!exterior_of_local_ball && edge_size_m > tool_radius_m / 2)
      reject("edge_size_m", edge_size_m, "must be <= tool_radius_m / 2 = " + text_of(tool_radius_m / 2));
    if (exterior_of_local_ball && edge_size_m > local_radius_m / 2)
      reject("edge_size_m", edge_size_m, "must be <= local_radius_m / 2 = " + text_of(local_radius_m / 2) + " (the size on the cut sphere)");
    if (max_size_m < edge_size_m) reject("max_size_m", max_size_m, "must be >= edge_size_m = " + text_of(edge_size_m));
    if (exterior_of_local_ball) {
      require_positive("local_radius_m", local_radius_m);
      if (local_radius_m <= tool_radius_m)
        reject("local_radius_m", local_radius_m, "must be > tool_radius_m = " + text_of(tool_radius_m) + " (the patch lies inside the ball)");
    }
    return;
  }

  require_positive("body_radius_m", body_radius_m);
  require_positive("tool_radius_m", tool_radius_m);
  require_positive("max_size_m", max_size_m);
  require_positive("size_growth", size_growth);
  if (!(size_exponent >= 0.25 && size_exponent <= 1.0)) {
    reject("size_exponent", size_exponent, "must be in [0.25, 1]");
  }
  if (!(power_grading_extent >= 1.0)) {
    reject("power_grading_extent", power_grading_extent, "must be >= 1");
  }
  if (!(tool_radius_m < body_radius_m / 2)) {
    reject("tool_radius_m", tool_radius_m,
           "must be < body_radius_m / 2 = " + text_of(body_radius_m / 2));
  }
  // An exterior mesh has no patch edge to resolve; its size on the cut sphere must resolve that.
  if (exterior_of_local_ball && edge_size_m > local_radius_m / 2) {
    reject("edge_size_m", edge_size_m, "must be <= local_radius_m / 2 = " + text_of(local_radius_m / 2));
  }
  if (!exterior_of_local_ball && edge_size_m > tool_radius_m) {
    reject("edge_size_m", edge_size_m, "must be <= tool_radius_m = " + text_of(tool_radius_m));
  }
  if (max_size_m < edge_size_m) {
    reject("max_size_m", max_size_m, "must be >= edge_size_m = " + text_of(edge_size_m));
  }

  if (exterior_of_local_ball) {
    if (benchmark != Benchmark::B1 && benchmark != Benchmark::B2 && benchmark != Benchmark::B5) {
      throw std::invalid_argument("MeshParameters.exterior_of_local_ball = true needs benchmark B1, B2 or B5, not " +
                                  to_string(benchmark));
    }
    require_positive("local_radius_m", local_radius_m);
    // The patch must lie inside the ball (its edge is at chord distance sqrt(2R(R − z0)) from the
    // contact on a sphere, a on B1's flat top), and the ball must stay clear of the clamped base
    // (and of B1's side): a cut touching the base would impose ψ ≠ 0 against u = 0.
    const double patch_edge_distance =
        benchmark == Benchmark::B1
            ? tool_radius_m
            : std::sqrt(2 * body_radius_m *
                        (body_radius_m - std::sqrt(body_radius_m * body_radius_m - tool_radius_m * tool_radius_m)));
    if (!(local_radius_m > patch_edge_distance)) {
      reject("local_radius_m", local_radius_m,
             "must be > " + text_of(patch_edge_distance) + " (the distance from the contact to the patch edge)");
    }
    const double clearance = benchmark == Benchmark::B1
                                 ? body_radius_m - local_radius_m
                                 : body_radius_m * std::cos(benchmark == Benchmark::B5 ? contact_polar_angle_rad : 0.0) -
                                       local_radius_m;
    if (!(clearance > edge_size_m)) {
      reject("local_radius_m", local_radius_m,
             "leaves " + text_of(clearance) + " m between the cut ball and the base" +
                 (benchmark == Benchmark::B1 ? std::string(" or side") : std::string()) +
                 "; it must be > edge_size_m = " + text_of(edge_size_m));
    }
  }

  if (benchmark == Benchmark::B3) {
    require_positive("local_radius_m", local_radius_m);
    // Chord distance from the pole to the patch circle: the ball must contain the whole patch.
    const double z0 = std::sqrt(body_radius_m * body_radius_m - tool_radius_m * tool_radius_m);
    const double patch_edge_distance = std::sqrt(2 * body_radius_m * (body_radius_m - z0));
    if (!(local_radius_m > patch_edge_distance)) {
      reject("local_radius_m", local_radius_m,
             "must be > " + text_of(patch_edge_distance) +
                 " (the distance from the pole to the patch edge, just above tool_radius_m)");
    }
    if (local_radius_m > body_radius_m) {
      reject("local_radius_m", local_radius_m,
             "must be <= body_radius_m = " + text_of(body_radius_m));
    }
  }

  if (benchmark == Benchmark::B5) {
    const double theta = contact_polar_angle_rad;
    if (!std::isfinite(theta) || theta < 0 || theta >= pi / 2) {
      reject("contact_polar_angle_rad", theta, "must be in [0, pi/2)");
    }
    // Lowest point of the patch circle: polar angle θ + asin(a/R). Keep at least one edge
    // element between it and the clamped base.
    const double lowest =
        body_radius_m * std::cos(theta + std::asin(tool_radius_m / body_radius_m));
    if (!(lowest > edge_size_m)) {
      reject("contact_polar_angle_rad", theta,
             "puts the patch edge " + text_of(lowest) +
                 " m above the base plane; it must be > edge_size_m = " + text_of(edge_size_m));
    }
  }
}

std::string mesher_version() { return std::string("gmsh ") + GMSH_API_VERSION; }

MeshSummary generate_mesh(const MeshParameters& parameters, const std::string& msh_path) {
  parameters.validate();
  if (parameters.benchmark == Benchmark::Organ) return generate_organ_body_mesh(parameters, msh_path);
  return run_gmsh("generate_mesh", parameters, msh_path, [&] {
    const auto start = std::chrono::steady_clock::now();
    require_writable(msh_path);

    ScriptedModel model;
    const Classified classified = prepare_model(make_shape(parameters), model);
    generate_checked_mesh(classified);

    MeshSummary summary;
    summary.path = msh_path;
    {
      std::vector<std::size_t> node_tags;
      std::vector<double> coordinates;
      std::vector<double> parametric;
      gmsh::model::mesh::getNodes(node_tags, coordinates, parametric, -1, -1, false, false);
      summary.node_count = node_tags.size();
    }
    constexpr int triangle = 2;
    constexpr int tetrahedron = 4;
    for (const int volume : classified.volumes) {
      summary.tetrahedron_count += count_elements(tetrahedron, volume);
    }
    if (classified.surfaces.count(boundary_tags::tool_patch) != 0) {
      for (const int surface : classified.surfaces.at(boundary_tags::tool_patch)) {
        summary.patch_triangle_count += count_elements(triangle, surface);
      }
    }
    if (summary.tetrahedron_count == 0) throw std::runtime_error("the mesh has no tetrahedra");

    write_msh_whole(msh_path);
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
  });
}

void write_geometry_script(const MeshParameters& parameters, const std::string& geo_path) {
  parameters.validate();
  if (parameters.benchmark == Benchmark::Organ)
    throw std::invalid_argument("write_geometry_script: an organ body has no OpenCASCADE geometry; open its mesh instead");
  run_gmsh("write_geometry_script", parameters, geo_path, [&] {
    require_writable(geo_path);
    ScriptedModel model;
    prepare_model(make_shape(parameters), model);
    const auto original = physical_group_fingerprints();
    {
      std::ofstream out(geo_path, std::ios::out | std::ios::trunc);
      out << "// " << describe_parameters(parameters) << "\n"
          << "// Written by touchstone::meshes::write_geometry_script; SI units (m).\n"
          << model.script();
      if (!out.flush()) throw std::runtime_error("writing the script failed");
    }
    // The script must rebuild the same groups from the same entities; replay it to be sure.
    gmsh::model::add("replay");
    gmsh::merge(geo_path);
    if (!same_fingerprints(physical_group_fingerprints(), original)) {
      throw std::runtime_error("replaying the written script does not reproduce the geometry");
    }
    return 0;
  });
}

ContactSite contact_site(const MeshParameters& parameters) {
  if (parameters.benchmark == Benchmark::Box) {
    throw std::invalid_argument("contact_site: the box benchmark has no contact");
  }
  if (parameters.benchmark == Benchmark::Organ) {
    const OrganContactSite organ = organ_contact_site(parameters.organ);
    return {organ.point_m, {-organ.tool_axis[0], -organ.tool_axis[1], -organ.tool_axis[2]}};
  }
  const Shape shape = make_shape(parameters);
  ContactSite site;
  site.outward_normal = shape.patch_axis;
  if (parameters.benchmark != Benchmark::B1) site.point_m = shape.contact;
  return site;
}

std::string to_string(Benchmark benchmark) {
  switch (benchmark) {
    case Benchmark::B1: return "B1";
    case Benchmark::B2: return "B2";
    case Benchmark::B3: return "B3";
    case Benchmark::B5: return "B5";
    case Benchmark::Box: return "box";
    case Benchmark::Organ: return "organ";
  }
  throw std::invalid_argument("unknown Benchmark value " +
                              std::to_string(static_cast<int>(benchmark)));
}

Benchmark benchmark_from_string(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const Benchmark benchmark :
       {Benchmark::B1, Benchmark::B2, Benchmark::B3, Benchmark::B5, Benchmark::Box, Benchmark::Organ}) {
    std::string candidate = to_string(benchmark);
    std::transform(candidate.begin(), candidate.end(), candidate.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (candidate == lower) return benchmark;
  }
  throw std::invalid_argument("unknown benchmark '" + name +
                              "' (valid names: B1, B2, B3, B5, box; case does not matter)");
}

}  // namespace touchstone::meshes
