#include "support/temporary_directory.hpp"
#include "support/expect_invalid_argument.hpp"
#include "touchstone/meshes/organ_geometry.hpp"

#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

namespace touchstone::meshes {
namespace {

using touchstone::testing::TemporaryDirectory;
using touchstone::testing::expect_invalid_argument;

constexpr double pi = 3.14159265358979323846;

// The paper's sizes (Table 1's 500, 2,500, 17,000 and 35,000 triangles; the palpation scene's
// 20,000-triangle stomach): 500 and 2,500 in the fast set, 17,000 to 35,000 under the label
// "large" (the same source, built twice; the suites are named apart because ctest labels tests
// by name).
#ifdef TOUCHSTONE_LARGE_ORGANS
#define ORGAN_SUITE OrganGeometryLarge
const std::vector<int> targets{17000, 20000, 35000};
#else
#define ORGAN_SUITE OrganGeometry
const std::vector<int> targets{500, 2500};
#endif

/// Discretisation error bounds, measured (500 to 120,000 triangles) and given a margin of about
/// 1.5: flat facets through points of the surface miss area and volume by O((h/R)²), h the
/// element size and R = 0.05 m the largest curvature radius (fundus, hemisphere). The stomach's
/// reference values come from OpenCASCADE's integration over lofted B-spline faces, itself
/// accurate to about 1e-3: the meshes converge to 0.1 % below its area.
constexpr double curvature_radius_m = 0.05;
constexpr double stomach_volume_factor = 0.45;  // measured 0.30
constexpr double stomach_area_factor = 0.3;     // measured 0.21
constexpr double stomach_reference_error = 2e-3;
constexpr double hemisphere_volume_factor = 0.5;  // measured 0.37
constexpr double hemisphere_area_factor = 0.3;    // measured 0.19

OrganParameters parameters(OrganShape shape, int target) {
  OrganParameters p;
  p.shape = shape;
  p.target_triangles = target;
  return p;
}

/// Count within the tolerance, closed, manifold, outward, and loadable as a TriangleSurface.
SurfaceStatistics check_valid(const OrganMesh& mesh, int target) {
  EXPECT_LE(std::abs(static_cast<double>(mesh.triangles.size()) - target), 0.05 * target) << mesh.triangles.size();
  const auto defects = geometry::validate_surface(mesh.vertices, mesh.triangles, "organ");
  EXPECT_TRUE(defects.empty()) << defects.front().message;
  EXPECT_NO_THROW(geometry::TriangleSurface(mesh.vertices, mesh.triangles));
  // Every vertex is used: a closed surface has V − E + F = 2 (both shapes are spheres
  // topologically) with E = 3F/2.
  EXPECT_EQ(static_cast<long long>(mesh.vertices.size()), static_cast<long long>(mesh.triangles.size()) / 2 + 2);
  EXPECT_GE(mesh.passes, 1);
  EXPECT_GT(mesh.mesh_size_m, 0);
  return surface_statistics(mesh.vertices, mesh.triangles);
}

TEST(ORGAN_SUITE, StomachHitsTheTriangleCountsAndConverges) {
  for (const int target : targets) {
    SCOPED_TRACE(target);
    const OrganMesh mesh = generate_organ_mesh(parameters(OrganShape::stomach, target));
    const SurfaceStatistics s = check_valid(mesh, target);
    const double h2 = std::pow(mesh.mesh_size_m / curvature_radius_m, 2);
    EXPECT_NEAR(s.volume_m3 / mesh.geometry_volume_m3, 1, stomach_volume_factor * h2 + stomach_reference_error);
    EXPECT_NEAR(s.area_m2 / mesh.geometry_area_m2, 1, stomach_area_factor * h2 + stomach_reference_error);
    // A plausible stomach: about 1.1 L, 0.20 m wide (x), 0.09 m deep (y), 0.22 m tall (z).
    EXPECT_NEAR(mesh.geometry_volume_m3, 1.098e-3, 0.01e-3);
    EXPECT_NEAR(mesh.geometry_area_m2, 0.0653, 0.0005);
    const Eigen::Vector3d size = s.upper - s.lower;
    EXPECT_NEAR(size.x(), 0.195, 0.01);
    EXPECT_NEAR(size.y(), 0.086, 0.01);
    EXPECT_NEAR(size.z(), 0.217, 0.01);
    // Uniform elements: the edges stay within a small factor of the size.
    EXPECT_GT(s.min_edge_m, 0.2 * mesh.mesh_size_m);
    EXPECT_LT(s.max_edge_m, 2.0 * mesh.mesh_size_m);
  }
}

TEST(ORGAN_SUITE, HemisphereMatchesAnalyticAreaAndVolume) {
  const double r = 0.05;
  const double area = 3 * pi * r * r;
  const double volume = 2 * pi * r * r * r / 3;
  for (const int target : targets) {
    SCOPED_TRACE(target);
    const OrganMesh mesh = generate_organ_mesh(parameters(OrganShape::hemisphere, target));
    const SurfaceStatistics s = check_valid(mesh, target);
    EXPECT_NEAR(mesh.geometry_area_m2, area, 1e-9 * area);
    EXPECT_NEAR(mesh.geometry_volume_m3, volume, 1e-9 * volume);
    // Inscribed: vertices on the hemisphere, flat facets inside it.
    const double h2 = std::pow(mesh.mesh_size_m / r, 2);
    EXPECT_LT(s.volume_m3, volume);
    EXPECT_LT(s.area_m2, area);
    EXPECT_GT(s.volume_m3, volume * (1 - hemisphere_volume_factor * h2));
    EXPECT_GT(s.area_m2, area * (1 - hemisphere_area_factor * h2));
    for (const Eigen::Vector3d& x : mesh.vertices) {
      EXPECT_GE(x.z(), -1e-12 * r);
      EXPECT_LE(x.norm(), r * (1 + 1e-12));
      // On the base plane or on the sphere.
      EXPECT_TRUE(std::abs(x.z()) < 1e-12 * r || std::abs(x.norm() - r) < 1e-12 * r) << x.transpose();
    }
    EXPECT_NEAR(s.upper.z(), r, 1e-12);
  }
}

#ifndef TOUCHSTONE_LARGE_ORGANS

TEST(OrganGeometry, SameParametersGiveTheSameMesh) {
  for (const OrganShape shape : {OrganShape::stomach, OrganShape::hemisphere}) {
    const OrganMesh first = generate_organ_mesh(parameters(shape, 500));
    const OrganMesh second = generate_organ_mesh(parameters(shape, 500));
    EXPECT_EQ(first.vertices, second.vertices) << to_string(shape);
    EXPECT_EQ(first.triangles, second.triangles) << to_string(shape);
    EXPECT_EQ(first.mesh_size_m, second.mesh_size_m);
  }
}

TEST(OrganGeometry, WritesFilesThatReadBackExactly) {
  const TemporaryDirectory directory("organ");
  OrganParameters p = parameters(OrganShape::hemisphere, 600);
  for (const char* name : {"hemisphere.msh", "hemisphere.vtp"}) {
    SCOPED_TRACE(name);
    const std::string path = directory.path(name);
    const OrganMesh mesh = write_organ_mesh(p, path);
    const SurfaceMesh read = read_surface_mesh(path);
    EXPECT_EQ(read.vertices, mesh.vertices);
    EXPECT_EQ(read.triangles, mesh.triangles);
  }
  // The MSH file is what load_msh_surface reads (the MFS studies' loader).
  const auto surface = meshes::load_msh_surface(directory.path("hemisphere.msh"), {"surface"});
  EXPECT_NEAR(surface.volume_m3(), 2 * pi * std::pow(0.05, 3) / 3, 0.02 * 2 * pi * std::pow(0.05, 3) / 3);
}

TEST(OrganGeometry, RejectsBadParametersAndPaths) {
  const auto with = [](const std::function<void(OrganParameters&)>& change) {
    OrganParameters p;
    change(p);
    return p;
  };
  expect_invalid_argument([&] { with([](OrganParameters& p) { p.target_triangles = 10; }).validate(); },
               {"OrganParameters.target_triangles = 10"});
  expect_invalid_argument([&] { with([](OrganParameters& p) { p.relative_tolerance = 0; }).validate(); },
               {"OrganParameters.relative_tolerance = 0"});
  expect_invalid_argument([&] { with([](OrganParameters& p) { p.stomach_flattening = 1.2; }).validate(); },
               {"OrganParameters.stomach_flattening = 1.2", "ellipses"});
  expect_invalid_argument([&] { with([](OrganParameters& p) { p.stomach_scale = std::nan(""); }).validate(); },
               {"OrganParameters.stomach_scale = nan"});
  expect_invalid_argument([&] { with([](OrganParameters& p) { p.hemisphere_radius_m = -1; }).validate(); },
               {"OrganParameters.hemisphere_radius_m = -1"});
  expect_invalid_argument([&] { with([](OrganParameters& p) { p.max_passes = 0; }).validate(); }, {"OrganParameters.max_passes"});
  expect_invalid_argument([&] { organ_shape_from_string("liver"); }, {"'liver'", "stomach, hemisphere"});
  EXPECT_EQ(organ_shape_from_string("Hemisphere"), OrganShape::hemisphere);

  const TemporaryDirectory directory("organ");
  expect_invalid_argument([&] { write_organ_mesh(OrganParameters{}, directory.path("organ.ply")); }, {"organ.ply", "unsupported"});
  EXPECT_THROW(write_organ_mesh(OrganParameters{}, directory.path("no/such/dir/organ.msh")), std::runtime_error);
  // A search that cannot converge in one pass says so, with the counts it saw.
  OrganParameters one_pass = parameters(OrganShape::hemisphere, 5000);
  one_pass.max_passes = 1;
  one_pass.relative_tolerance = 0.005;
  try {
    generate_organ_mesh(one_pass);
    // The first guess may land within 0.5 %: then there is nothing to report.
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("hemisphere with 5000 triangles"), std::string::npos) << message;
    EXPECT_NE(message.find("after 1 passes"), std::string::npos) << message;
  }
}

#endif

}  // namespace
}  // namespace touchstone::meshes
