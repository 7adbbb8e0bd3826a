// The oriented box on its own: Gottschalk's covariance fit finds a rotated slab's axes and
// encloses its corners, and the segment–box overlap test equals clipping against the slabs.
#include "touchstone/realtime/collision/oriented_box.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

namespace touchstone::realtime::collision {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

TEST(OrientedBox, FitFindsTheAxesOfARotatedSlabAndEnclosesItsCorners) {
  // A 40 × 10 × 2 mm box surface, rotated: the fit's first axis is the long side. The corners
  // of its 12 triangles (two per face), as a tree node hands them to the fit.
  const Matrix3d rotation = (Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()) *
                             Eigen::AngleAxisd(-0.4, Vector3d::UnitZ())).toRotationMatrix();
  std::vector<Vector3d> vertices;
  for (int i = 0; i < 8; ++i) {
    const Vector3d unit((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1);
    vertices.push_back(rotation * Vector3d(0.02 * unit.x(), 0.005 * unit.y(), 0.001 * unit.z()) +
                       Vector3d(0.1, -0.2, 0.3));
  }
  const int triangles[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  std::vector<Vector3d> corners;
  for (const auto& t : triangles) {
    for (int k = 0; k < 3; ++k) corners.push_back(vertices[t[k]]);
  }
  const OrientedBox box = fit_oriented_box(corners);
  EXPECT_NEAR(std::abs(box.axes.row(0).dot(rotation.col(0).transpose())), 1, 1e-12);
  EXPECT_NEAR(std::abs(box.axes.row(1).dot(rotation.col(1).transpose())), 1, 1e-12);
  EXPECT_NEAR((box.axes * box.axes.transpose() - Matrix3d::Identity()).norm(), 0, 1e-14);
  EXPECT_NEAR(box.axes.determinant(), 1, 1e-14);
  EXPECT_NEAR(box.half_extents.x(), 0.02, 1e-14);
  EXPECT_NEAR(box.half_extents.y(), 0.005, 1e-14);
  EXPECT_NEAR(box.half_extents.z(), 0.001, 1e-14);
  EXPECT_LT((box.center - Vector3d(0.1, -0.2, 0.3)).norm(), 1e-14);
  for (const Vector3d& c : corners) {
    EXPECT_TRUE((box.to_local(c).cwiseAbs() - box.half_extents).maxCoeff() < 1e-15);
  }
  // One triangle: a flat box in its plane. Degenerate input still gives a finite box.
  const OrientedBox flat = fit_oriented_box({Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)});
  EXPECT_NEAR(flat.half_extents.minCoeff(), 0, 1e-15);
  const OrientedBox point = fit_oriented_box({Vector3d(1, 1, 1), Vector3d(1, 1, 1), Vector3d(1, 1, 1)});
  EXPECT_TRUE(point.axes.allFinite());
  EXPECT_EQ(point.half_extents, Vector3d::Zero());
}

TEST(OrientedBox, SegmentTestEqualsClippingAgainstTheSlabs) {
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> uniform(-1, 1);
  const auto random_vector = [&] { return Vector3d(uniform(random), uniform(random), uniform(random)); };
  int overlaps = 0;
  for (int i = 0; i < 20000; ++i) {
    OrientedBox box;
    box.axes = Eigen::Quaterniond(Eigen::Vector4d(random_vector().homogeneous().normalized())).toRotationMatrix();
    box.center = 0.3 * random_vector();
    box.half_extents = 0.5 * random_vector().cwiseAbs();
    const Vector3d a = random_vector();
    const Vector3d b = i % 10 == 0 ? a : random_vector();
    // Reference: clip the parameter interval [0, 1] against the three slabs in the box frame.
    const Vector3d p = box.to_local(a);
    const Vector3d d = box.to_local(b) - p;
    double low = 0, high = 1;
    for (int k = 0; k < 3; ++k) {
      if (d[k] == 0) {
        if (std::abs(p[k]) > box.half_extents[k]) high = -1;
        continue;
      }
      double t0 = (-box.half_extents[k] - p[k]) / d[k];
      double t1 = (box.half_extents[k] - p[k]) / d[k];
      if (t0 > t1) std::swap(t0, t1);
      low = std::max(low, t0);
      high = std::min(high, t1);
    }
    const bool expected = low <= high;
    // Skip near-touching cases where rounding may decide either way.
    if (std::abs(high - low) < 1e-9) continue;
    overlaps += expected;
    ASSERT_EQ(segment_overlaps(box, 0.5 * (a + b), 0.5 * (b - a)), expected) << "case " << i;
    // The distance to the box is zero exactly for points inside it.
    EXPECT_EQ(squared_distance(box, a) == 0, (p.cwiseAbs() - box.half_extents).maxCoeff() <= 0);
  }
  EXPECT_GT(overlaps, 2000);
}

}  // namespace
}  // namespace touchstone::realtime::collision
