#include "touchstone/realtime/collision/oriented_box.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <limits>

namespace touchstone::realtime::collision {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

/// Orthonormal, right-handed rows from the eigenvectors of a symmetric 3×3 matrix.
Matrix3d frame_from_covariance(const Matrix3d& covariance) {
  const Eigen::SelfAdjointEigenSolver<Matrix3d> solver(covariance);
  if (solver.info() != Eigen::Success || !solver.eigenvectors().allFinite()) return Matrix3d::Identity();
  // Eigenvalues ascend; the largest spread comes first so that axis 0 is the principal axis.
  Matrix3d axes;
  axes.row(0) = solver.eigenvectors().col(2).normalized().transpose();
  Vector3d second = solver.eigenvectors().col(1);
  second -= second.dot(axes.row(0).transpose()) * axes.row(0).transpose();
  axes.row(1) = second.normalized().transpose();
  axes.row(2) = axes.row(0).cross(axes.row(1));
  if (!axes.allFinite()) return Matrix3d::Identity();
  return axes;
}

}  // namespace

OrientedBox fit_oriented_box(const std::vector<Vector3d>& corners) {
  const std::size_t triangle_count = corners.size() / 3;
  if (triangle_count == 0) return OrientedBox{};

  // Moments about the mean corner: the covariance is translation invariant, and a nearby origin
  // avoids cancelling large coordinates.
  Vector3d origin = Vector3d::Zero();
  for (std::size_t i = 0; i < 3 * triangle_count; ++i) origin += corners[i];
  origin /= static_cast<double>(3 * triangle_count);

  double total_area = 0;
  Vector3d first_moment = Vector3d::Zero();
  Matrix3d second_moment = Matrix3d::Zero();
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const Vector3d p = corners[3 * t] - origin;
    const Vector3d q = corners[3 * t + 1] - origin;
    const Vector3d r = corners[3 * t + 2] - origin;
    const double area = 0.5 * (q - p).cross(r - p).norm();
    const Vector3d centroid = (p + q + r) / 3;
    total_area += area;
    first_moment += area * centroid;
    second_moment += (area / 12) * (9 * centroid * centroid.transpose() + p * p.transpose() +
                                    q * q.transpose() + r * r.transpose());
  }
  Matrix3d covariance;
  if (total_area > 0 && std::isfinite(total_area)) {
    const Vector3d mean = first_moment / total_area;
    covariance = second_moment / total_area - mean * mean.transpose();
  } else {
    // All triangles degenerate: the spread of the corners still orients the box.
    covariance.setZero();
    for (std::size_t i = 0; i < 3 * triangle_count; ++i) {
      const Vector3d p = corners[i] - origin;
      covariance += p * p.transpose();
    }
  }
  return enclose_with_axes(frame_from_covariance(covariance), corners.data(), 3 * triangle_count);
}

OrientedBox enclose_with_axes(const Matrix3d& axes, const Vector3d* points, std::size_t count) {
  OrientedBox box;
  box.axes = axes;
  if (count == 0) return box;
  Vector3d lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
  Vector3d upper = -lower;
  for (std::size_t i = 0; i < count; ++i) {
    const Vector3d local = axes * points[i];
    lower = lower.cwiseMin(local);
    upper = upper.cwiseMax(local);
  }
  box.center = axes.transpose() * (0.5 * (lower + upper));
  box.half_extents = 0.5 * (upper - lower);
  return box;
}

}  // namespace touchstone::realtime::collision
