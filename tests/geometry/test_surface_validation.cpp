// validate_surface: every defect kind counted, with one example each and the file's own
// labels, and the coincident-vertex welding that readers run before it (the tests of
// geometry/src/surface_validation.cpp and coincident_vertices.cpp).
#include "support/test_surfaces.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::geometry {
namespace {

using touchstone::testing::torus;

using Eigen::Vector3d;
using Eigen::Vector3i;

using Mesh = TriangleMeshData;

/// The kinds of the defects found, in order.
std::vector<SurfaceDefectKind> kinds(const std::vector<SurfaceDefect>& defects) {
  std::vector<SurfaceDefectKind> result;
  for (const SurfaceDefect& defect : defects) result.push_back(defect.kind);
  return result;
}

bool mentions(const SurfaceDefect& defect, const std::string& fragment) {
  return defect.message.find(fragment) != std::string::npos;
}

TEST(ValidateSurface, ValidSurfacesHaveNoDefects) {
  const Mesh sphere = icosphere(2, 0.03);
  EXPECT_TRUE(validate_surface(sphere.vertices, sphere.triangles).empty());
  const Mesh ring = torus(24, 12, 1.0, 0.3);
  EXPECT_TRUE(validate_surface(ring.vertices, ring.triangles).empty());
  // An unused vertex, even a non-finite one far away, is not a defect of the surface... but a
  // non-finite coordinate anywhere is reported.
  Mesh extra = sphere;
  extra.vertices.push_back({5, 5, 5});
  EXPECT_TRUE(validate_surface(extra.vertices, extra.triangles).empty());
  extra.vertices.back().x() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(kinds(validate_surface(extra.vertices, extra.triangles)),
            std::vector<SurfaceDefectKind>{SurfaceDefectKind::non_finite_coordinate});
}

// One vertex at 1e300 m (a unit or parse error) is named as such; it used to make every triangle
// "degenerate" (their areas overflowed), a vertex at the origin a "duplicate" of it, and the
// volume inward. A vertex within the limit is only where it is.
TEST(ValidateSurface, AVertexFarBeyondAnyOrganIsNamedAloneWithItsCoordinates) {
  Mesh sphere = icosphere(2, 0.03);
  sphere.vertices[0] = {1e300, 0.0, 0.0};
  const auto defects = validate_surface(sphere.vertices, sphere.triangles);
  ASSERT_EQ(kinds(defects), std::vector<SurfaceDefectKind>{SurfaceDefectKind::non_finite_coordinate});
  EXPECT_TRUE(mentions(defects[0], "coordinate beyond +-1e+09 m in 1 vertex")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], "1e+300")) << defects[0].message;
  sphere.vertices[0] = {max_surface_coordinate_m, 0.0, 0.0};
  for (const SurfaceDefect& defect : validate_surface(sphere.vertices, sphere.triangles))
    EXPECT_NE(defect.kind, SurfaceDefectKind::non_finite_coordinate) << defect.message;
}

// Two closed spheres in one surface: each is valid alone; overlapping, they pass through each
// other along a circle, and no inside exists. Apart, they are a valid two-shell surface.
TEST(ValidateSurface, FindsTrianglesThatPassThroughEachOther) {
  const Mesh sphere = icosphere(3, 1.0);
  const auto two_spheres = [&](double offset) {
    Mesh both = sphere;
    const int shift = static_cast<int>(sphere.vertices.size());
    for (const Vector3d& v : sphere.vertices) both.vertices.push_back(v + Vector3d(offset, 0.0, 0.0));
    for (const Vector3i& t : sphere.triangles) both.triangles.push_back(t + Vector3i::Constant(shift));
    return both;
  };
  const Mesh apart = two_spheres(2.5);
  EXPECT_TRUE(validate_surface(apart.vertices, apart.triangles).empty());
  const Mesh overlapping = two_spheres(1.05);  // not 1: vertices at x = ±0.5 would coincide
  const auto defects = validate_surface(overlapping.vertices, overlapping.triangles, "two.stl");
  ASSERT_EQ(kinds(defects), std::vector<SurfaceDefectKind>{SurfaceDefectKind::self_intersection});
  // The intersection circle (radius 0.85) crosses about 2π·0.85 / 0.15 ≈ 36 triangles of each.
  EXPECT_GT(defects[0].count, 30u);
  EXPECT_TRUE(mentions(defects[0], "two.stl: ")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], "passes through itself")) << defects[0].message;
}

TEST(ValidateSurface, CountsHolesAndBoundaryEdges) {
  const Mesh good = icosphere(1, 1.0);
  // Two triangles far apart: two holes of three edges each.
  Mesh two = good;
  const Vector3i first = two.triangles[0];
  int far = -1;
  for (int t = 1; t < static_cast<int>(good.triangles.size()) && far < 0; ++t) {
    bool touches = false;
    for (int k = 0; k < 3; ++k) {
      for (int m = 0; m < 3; ++m) touches = touches || good.triangles[t][k] == first[m];
    }
    if (!touches) far = t;
  }
  ASSERT_GT(far, 0);
  two.triangles.erase(two.triangles.begin() + far);
  two.triangles.erase(two.triangles.begin());
  auto defects = validate_surface(two.vertices, two.triangles, "two.obj");
  ASSERT_EQ(kinds(defects), std::vector<SurfaceDefectKind>{SurfaceDefectKind::boundary_edge});
  EXPECT_EQ(defects[0].count, 6u);
  EXPECT_TRUE(mentions(defects[0], "two.obj: the surface is not closed: 2 holes (6 boundary edges")) << defects[0].message;
  // The example edge with its end points.
  EXPECT_TRUE(mentions(defects[0], " from (")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], " belongs only to triangle ")) << defects[0].message;

  // Two neighbours: one hole of four edges.
  Mesh adjacent = good;
  int neighbour = -1;
  for (int t = 1; t < static_cast<int>(good.triangles.size()) && neighbour < 0; ++t) {
    int shared = 0;
    for (int k = 0; k < 3; ++k) {
      for (int m = 0; m < 3; ++m) shared += good.triangles[t][k] == first[m];
    }
    if (shared == 2) neighbour = t;
  }
  adjacent.triangles.erase(adjacent.triangles.begin() + neighbour);
  adjacent.triangles.erase(adjacent.triangles.begin());
  defects = validate_surface(adjacent.vertices, adjacent.triangles);
  ASSERT_EQ(defects.size(), 1u);
  EXPECT_EQ(defects[0].count, 4u);
  EXPECT_TRUE(mentions(defects[0], "1 hole (4 boundary edges")) << defects[0].message;
}

TEST(ValidateSurface, CountsFlippedTrianglesAndFindsNonOrientableSurfaces) {
  const Mesh good = icosphere(1, 1.0);
  Mesh flipped = good;
  for (const int t : {3, 10, 11, 40}) std::swap(flipped.triangles[t][1], flipped.triangles[t][2]);
  auto defects = validate_surface(flipped.vertices, flipped.triangles);
  ASSERT_EQ(kinds(defects), std::vector<SurfaceDefectKind>{SurfaceDefectKind::inconsistent_orientation});
  EXPECT_EQ(defects[0].count, 4u);
  EXPECT_TRUE(mentions(defects[0], "4 triangles flipped against their neighbours")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], "e.g. triangle 3 and triangle ")) << defects[0].message;

  // All but one flipped: the one is the odd one out.
  Mesh most = good;
  for (std::size_t t = 1; t < most.triangles.size(); ++t) std::swap(most.triangles[t][1], most.triangles[t][2]);
  defects = validate_surface(most.vertices, most.triangles);
  ASSERT_EQ(defects.size(), 1u);
  EXPECT_TRUE(mentions(defects[0], "1 triangle flipped against its neighbours")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], "e.g. triangle 0 and")) << defects[0].message;

  // The real projective plane as a hemi-icosahedron: the icosahedron with antipodal vertices
  // identified (6 vertices, 10 triangles). Closed and manifold, but no orientation exists.
  const Mesh ico = icosphere(0, 1.0);
  std::vector<int> representative(ico.vertices.size());
  for (std::size_t v = 0; v < ico.vertices.size(); ++v) {
    for (std::size_t u = 0; u < ico.vertices.size(); ++u) {
      if ((ico.vertices[u] + ico.vertices[v]).norm() < 1e-12) representative[v] = static_cast<int>(std::min(u, v));
    }
  }
  std::map<int, int> index;
  Mesh plane;
  for (std::size_t v = 0; v < ico.vertices.size(); ++v) {
    if (representative[v] == static_cast<int>(v)) {
      index[static_cast<int>(v)] = static_cast<int>(plane.vertices.size());
      plane.vertices.push_back(ico.vertices[v]);
    }
  }
  std::set<std::array<int, 3>> seen;
  for (const Vector3i& t : ico.triangles) {
    const Vector3i mapped(index[representative[t[0]]], index[representative[t[1]]], index[representative[t[2]]]);
    std::array<int, 3> key{mapped[0], mapped[1], mapped[2]};
    std::sort(key.begin(), key.end());
    if (seen.insert(key).second) plane.triangles.push_back(mapped);
  }
  ASSERT_EQ(plane.vertices.size(), 6u);
  ASSERT_EQ(plane.triangles.size(), 10u);
  defects = validate_surface(plane.vertices, plane.triangles, "plane");
  ASSERT_FALSE(defects.empty());
  EXPECT_EQ(defects[0].kind, SurfaceDefectKind::inconsistent_orientation);
  EXPECT_TRUE(mentions(defects[0], "non-orientable")) << defects[0].message;
  EXPECT_THROW(TriangleSurface(plane.vertices, plane.triangles), std::invalid_argument);
}

TEST(ValidateSurface, ListsEveryDefectInOrderWithFileLabels) {
  const Mesh good = icosphere(1, 1.0);
  Mesh broken = good;
  // A seam: vertex 0 copied, the copy used by one triangle of its fan (duplicate vertex and a
  // hole), triangle 30 repeated (duplicate, non-manifold edges), triangle 50 with a repeated
  // vertex (degenerate).
  broken.vertices.push_back(good.vertices[0]);
  int fan = -1;
  for (int t = 0; t < static_cast<int>(good.triangles.size()) && fan < 0; ++t) {
    for (int k = 0; k < 3; ++k) {
      if (good.triangles[t][k] == 0) {
        fan = t;
        broken.triangles[t][k] = static_cast<int>(good.vertices.size());
      }
    }
  }
  broken.triangles.push_back(good.triangles[30]);
  broken.triangles[50][2] = broken.triangles[50][0];

  SurfaceLabels labels;
  labels.vertex_kind = "OBJ vertex";
  labels.triangle_kind = "OBJ face";
  for (std::size_t v = 0; v < broken.vertices.size(); ++v) labels.vertex_tags.push_back(static_cast<long long>(v) + 1);
  for (std::size_t t = 0; t < broken.triangles.size(); ++t) labels.triangle_tags.push_back(static_cast<long long>(t) + 1);

  const auto defects = validate_surface(broken.vertices, broken.triangles, "organ.obj", labels);
  ASSERT_EQ(kinds(defects), (std::vector<SurfaceDefectKind>{
                                SurfaceDefectKind::degenerate_triangle, SurfaceDefectKind::duplicate_triangle,
                                SurfaceDefectKind::duplicate_vertex, SurfaceDefectKind::non_manifold_edge,
                                SurfaceDefectKind::boundary_edge}))
      << defects.front().message;
  for (const SurfaceDefect& defect : defects) {
    EXPECT_EQ(defect.message.rfind("organ.obj: ", 0), 0u) << defect.message;
    EXPECT_FALSE(std::string(to_string(defect.kind)).empty());
  }
  EXPECT_TRUE(mentions(defects[0], "triangle 50 (OBJ face 51) repeats vertex")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[1], "triangle 30 (OBJ face 31) and triangle 80 (OBJ face 81) are duplicates"))
      << defects[1].message;
  EXPECT_TRUE(mentions(defects[2], "vertex 0 (OBJ vertex 1) and vertex 42 (OBJ vertex 43) at (")) << defects[2].message;
  EXPECT_TRUE(mentions(defects[3], "(OBJ vertices ")) << defects[3].message;
  EXPECT_EQ(defects[3].count, 3u);

  // The constructor throws the first and names the others.
  try {
    TriangleSurface(broken.vertices, broken.triangles, "organ.obj", labels);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    EXPECT_EQ(message.rfind(defects[0].message, 0), 0u) << message;
    EXPECT_NE(message.find("(further defects: duplicate triangle, duplicated vertex, non-manifold edge, "
                           "hole (boundary edge))"),
              std::string::npos)
        << message;
  }
  // No triangles at all.
  const auto nothing = validate_surface({}, {}, "empty.stl");
  ASSERT_EQ(nothing.size(), 1u);
  EXPECT_EQ(nothing[0].message, "empty.stl: the surface has no triangles");
}

TEST(ValidateSurface, CoincidentVerticesJoinTheLowestWithinTolerance) {
  const std::vector<Vector3d> points{{0, 0, 0}, {1, 0, 0}, {1e-7, 0, 0}, {1, 5e-8, 0},
                                     {0, 0, 0}, {std::nan(""), 0, 0}, {2, 2, 2}, {2, 2, 2}};
  EXPECT_EQ(coincident_vertices(points, 0), (std::vector<int>{0, 1, 2, 3, 0, 5, 6, 6}));
  EXPECT_EQ(coincident_vertices(points, 2e-7), (std::vector<int>{0, 1, 0, 1, 0, 5, 6, 6}));
  // Vertices left out by `used` keep their own index and attract no others.
  std::vector<char> used(points.size(), 1);
  used[0] = 0;
  EXPECT_EQ(coincident_vertices(points, 2e-7, used), (std::vector<int>{0, 1, 2, 1, 2, 5, 6, 6}));
  // A point within reach of two representatives joins the lower one, whatever the grid.
  const std::vector<Vector3d> chain{{0.3, 0, 0}, {0, 0, 0}, {0.2, 0, 0}};
  EXPECT_EQ(coincident_vertices(chain, 0.25), (std::vector<int>{0, 1, 0}));
  EXPECT_TRUE(coincident_vertices({}, 1).empty());
}

}  // namespace
}  // namespace touchstone::geometry
