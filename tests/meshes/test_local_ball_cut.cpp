// The ball cut out of an organ surface (meshes/local_ball_cut): on a box with the ball centred on
// its top face the result must be the box minus a half ball — closed, outward, the cut curve on
// the circle, the cap on the sphere with the half-sphere's area and the removed volume — and
// the cases with no single cut curve must be refused naming the cause.
#include "support/expect_invalid_argument.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/meshes/local_ball_cut.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <tuple>
#include <vector>

namespace touchstone::meshes {
namespace {

constexpr double pi = 3.14159265358979323846;
constexpr double length = 0.0125;  // L [m]

struct Box {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
};

/// The closed surface of [−2L, 2L]² × [−depth, 0] on a lattice of spacing L/8 (z: depth/nz), two
/// triangles per square, outward.
Box box(double depth, int nz) {
  const int n = 32;
  Box b;
  std::map<std::tuple<int, int, int>, int> index;
  const auto vertex = [&](int i, int j, int k) {
    const auto [it, inserted] = index.try_emplace({i, j, k}, static_cast<int>(b.vertices.size()));
    if (inserted) b.vertices.emplace_back(-2 * length + 4 * length * i / n, -2 * length + 4 * length * j / n, -depth + depth * k / nz);
    return it->second;
  };
  const int size[3] = {n, n, nz};
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (int a = 0; a < size[u]; ++a)
        for (int c = 0; c < size[v]; ++c) {
          const auto corner = [&](int da, int dc) {
            int ijk[3];
            ijk[axis] = side * size[axis];
            ijk[u] = a + da;
            ijk[v] = c + dc;
            return vertex(ijk[0], ijk[1], ijk[2]);
          };
          Eigen::Vector3i t1(corner(0, 0), corner(1, 0), corner(1, 1)), t2(corner(0, 0), corner(1, 1), corner(0, 1));
          for (Eigen::Vector3i t : {t1, t2}) {
            const Eigen::Vector3d normal = (b.vertices[static_cast<std::size_t>(t[1])] - b.vertices[static_cast<std::size_t>(t[0])])
                                               .cross(b.vertices[static_cast<std::size_t>(t[2])] - b.vertices[static_cast<std::size_t>(t[0])]);
            if ((side == 0 ? -1.0 : 1.0) * normal[axis] < 0) std::swap(t[1], t[2]);
            b.triangles.push_back(t);
          }
        }
    }
  return b;
}

LocalBall top_ball() {
  LocalBall ball;
  ball.centre_m = Eigen::Vector3d::Zero();
  ball.radius_m = length;
  ball.outward_direction = Eigen::Vector3d::UnitZ();
  ball.cap_edge_m = length / 8;
  return ball;
}

TEST(LocalBallCut, BoxMinusAHalfBallIsClosedWithTheCapOnTheSphere) {
  const double depth = 2 * length;
  const Box input = box(depth, 16);
  const BallCutSurface cut = cut_out_local_ball(input.vertices, input.triangles, top_ball());

  // A valid closed, outward surface (no hole along the cut curve, no crossing of cap and box).
  const auto defects = geometry::validate_surface(cut.vertices, cut.triangles, "box minus ball");
  for (const auto& d : defects) ADD_FAILURE() << d.message;

  // The cut curve: the circle of radius L on the top face, exactly (roots and radial moves).
  ASSERT_GT(cut.cut_curve.size(), 40u);
  for (const int v : cut.cut_curve) {
    const Eigen::Vector3d& p = cut.vertices[static_cast<std::size_t>(v)];
    EXPECT_NEAR(p.z(), 0.0, 1e-15);
    EXPECT_NEAR(p.norm(), length, 1e-14);
  }
  EXPECT_LT(cut.sphere_relative_deviation, 1e-13);

  // Flat triangles with their corners on the sphere: the cap's area lies below the half sphere's
  // 2πL², by the chord error O(h²/L²) (h = L/8: under 1 %); the enclosed volume lies above the box's
  // less the half ball (the removed polyhedron is inscribed in it), by less than 2 % of the half ball.
  const double half_sphere = 2 * pi * length * length, half_ball = 2.0 / 3 * pi * length * length * length;
  EXPECT_LT(cut.cap_area_m2, half_sphere);
  EXPECT_GT(cut.cap_area_m2, 0.99 * half_sphere);
  const double volume = surface_statistics(cut.vertices, cut.triangles).volume_m3;
  const double exact = 16 * length * length * depth - half_ball;
  EXPECT_GT(volume, exact);
  EXPECT_LT(volume, exact + 0.02 * half_ball);
  // Every cap corner is on the sphere and inside the box.
  for (std::size_t i = 0; i < cut.triangles.size(); ++i) {
    if (!cut.on_cap[i]) continue;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& p = cut.vertices[static_cast<std::size_t>(cut.triangles[i][k])];
      EXPECT_NEAR(p.norm(), length, 1e-14);
      EXPECT_LE(p.z(), 1e-15);
    }
  }
}

TEST(LocalBallCut, RefusesBallsThatDoNotCutTheSurfaceOnce) {
  const Box deep = box(2 * length, 16);
  LocalBall away = top_ball();
  away.centre_m = Eigen::Vector3d(0, 0, 3 * length);
  testing::expect_invalid_argument([&] { cut_out_local_ball(deep.vertices, deep.triangles, away); }, {"does not cut the surface"});

  LocalBall everything = top_ball();
  everything.radius_m = 10 * length;
  testing::expect_invalid_argument([&] { cut_out_local_ball(deep.vertices, deep.triangles, everything); }, {"holds the whole surface"});

  // A slab thinner than the ball: the sphere leaves through the bottom face too.
  const Box thin = box(0.5 * length, 4);
  testing::expect_invalid_argument([&] { cut_out_local_ball(thin.vertices, thin.triangles, top_ball()); },
                                   {"2 separate curves", "thinner than the ball"});

  // The pole inside the organ: the plane polygon bounds the wrong side of the sphere.
  LocalBall inward = top_ball();
  inward.outward_direction = -Eigen::Vector3d::UnitZ();
  testing::expect_invalid_argument([&] { cut_out_local_ball(deep.vertices, deep.triangles, inward); }, {"must point out of the organ"});

  LocalBall bad = top_ball();
  bad.cap_edge_m = 0;
  testing::expect_invalid_argument([&] { cut_out_local_ball(deep.vertices, deep.triangles, bad); }, {"LocalBall.cap_edge_m"});
}

}  // namespace
}  // namespace touchstone::meshes
