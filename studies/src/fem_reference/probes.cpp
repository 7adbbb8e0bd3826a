#include "touchstone/studies/fem_reference/probes.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <sstream>

namespace touchstone::studies {
namespace {

using meshes::Benchmark;

bool has_spherical_surface(Benchmark b) { return b == Benchmark::B2 || b == Benchmark::B3 || b == Benchmark::B5; }

std::string multiple_of_a(const std::string& prefix, double value) {
  std::ostringstream name;
  name << prefix << "_" << value << "a";
  return name.str();
}

}  // namespace

Eigen::Vector3d outward_normal(const meshes::MeshParameters& geometry) {
  if (geometry.benchmark == Benchmark::Organ) {
    const auto n = meshes::contact_site(geometry).outward_normal;
    return {n[0], n[1], n[2]};
  }
  if (!has_spherical_surface(geometry.benchmark)) return Eigen::Vector3d::UnitZ();
  const double theta = geometry.benchmark == Benchmark::B5 ? geometry.contact_polar_angle_rad : 0.0;
  return {std::sin(theta), 0.0, std::cos(theta)};
}

Eigen::Vector3d contact_point(const meshes::MeshParameters& geometry) {
  if (geometry.benchmark == Benchmark::Organ) {
    const auto c = meshes::contact_site(geometry).point_m;
    return {c[0], c[1], c[2]};
  }
  if (!has_spherical_surface(geometry.benchmark)) return Eigen::Vector3d::Zero();
  return geometry.body_radius_m * outward_normal(geometry);
}

std::vector<Probe> indentation_probes(const meshes::MeshParameters& geometry,
                                      const Eigen::Vector3d& tool_direction) {
  const double a = geometry.tool_radius_m;
  const Eigen::Vector3d c = contact_point(geometry);
  const Eigen::Vector3d n = outward_normal(geometry);
  const Eigen::Vector3d d = tool_direction.normalized();
  // The meridian runs in the plane of n and the x axis (for the pole: along +x).
  Eigen::Vector3d t = Eigen::Vector3d::UnitY().cross(n).normalized();
  const bool local = geometry.benchmark == Benchmark::B3;
  const double reach = local ? 0.9 * geometry.local_radius_m : 1e300;

  std::vector<Probe> probes;
  for (const double s : {0.25, 0.5, 1.0, 2.0, 4.0, 8.0})
    if (s * a < reach) probes.push_back({multiple_of_a("axis", s), c + s * a * d});
  for (const double rho : {0.0, 0.5, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0}) {
    if (rho * a >= reach) continue;
    // A user's surface is known only by its triangles: the contact point alone lies on it.
    if (geometry.benchmark == Benchmark::Organ && rho > 0) continue;
    Eigen::Vector3d p;
    if (has_spherical_surface(geometry.benchmark)) {
      const double phi = std::asin(rho * a / geometry.body_radius_m);
      p = geometry.body_radius_m * (std::cos(phi) * n + std::sin(phi) * t);
    } else {
      p = c + rho * a * t;
    }
    probes.push_back({multiple_of_a("meridian", rho), p});
  }
  return probes;
}

}  // namespace touchstone::studies
