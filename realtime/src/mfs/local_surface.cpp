#include "touchstone/realtime/mfs/local_surface.hpp"

#include <Eigen/Geometry>
#include <Eigen/QR>

#include <cmath>
#include <vector>

namespace touchstone::realtime::mfs {
namespace {

constexpr int fit_degree = 4;
constexpr double fold_cosine = 0.2588190451;  // cos 75°

/// The monomials u^i v^j (i + j ≤ 4) in a fixed order, and their u and v derivatives.
void monomials(double u, double v, double* value, double* du, double* dv) {
  double up[fit_degree + 1], vp[fit_degree + 1];
  up[0] = vp[0] = 1;
  for (int k = 1; k <= fit_degree; ++k) {
    up[k] = up[k - 1] * u;
    vp[k] = vp[k - 1] * v;
  }
  int index = 0;
  for (int total = 0; total <= fit_degree; ++total)
    for (int i = total; i >= 0; --i, ++index) {
      const int j = total - i;
      value[index] = up[i] * vp[j];
      if (du) du[index] = i > 0 ? i * up[i - 1] * vp[j] : 0.0;
      if (dv) dv[index] = j > 0 ? j * up[i] * vp[j - 1] : 0.0;
    }
}

/// Where monomials() puts u^i v^j: the terms of total degree below i + j come first, and within
/// a degree the power of u falls.
constexpr int coefficient_index(int i, int j) {
  const int total = i + j;
  return total * (total + 1) / 2 + (total - i);
}

}  // namespace

LocalSurface::LocalSurface(const geometry::TriangleSurface& organ, const Eigen::Vector3d& contact_point_m, double reach_m)
    : organ_(organ), reach_m_(reach_m) {
  const geometry::SurfaceProjection hit = organ.project(contact_point_m);
  centre_ = hit.point;
  normal_ = hit.normal;
  contact_offset_m_ = hit.distance_m;
  const Eigen::Vector3d helper = std::abs(normal_.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  t1_ = normal_.cross(helper).normalized();
  t2_ = normal_.cross(t1_);

  // Fit, then once more in the frame of the fitted surface itself: the closest feature's
  // pseudo-normal of a triangulation can be a fraction of a degree off the smooth surface's.
  if (!fit(organ, reach_m)) return;
  double du = 0, dv = 0;
  const double d0 = depth(0, 0, &du, &dv);
  centre_ -= d0 * normal_;
  normal_ = (normal_ + du * t1_ + dv * t2_).normalized();
  const Eigen::Vector3d helper2 = std::abs(normal_.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  t1_ = normal_.cross(helper2).normalized();
  t2_ = normal_.cross(t1_);
  fitted_ = fit(organ, reach_m);
}

bool LocalSurface::fit(const geometry::TriangleSurface& organ, double reach_m) {
  // The vertices within reach, in tangent coordinates, unless one faces away (a fold or the far
  // side of a thin organ: no height field there).
  const auto& vertices = organ.vertices();
  const auto& normals = organ.vertex_normals();
  std::vector<Eigen::Vector3d> local;
  for (const int k : organ.vertices_within(centre_, reach_m)) {
    const Eigen::Vector3d x = vertices[k] - centre_;
    if (normals[k].dot(normal_) < fold_cosine) return false;
    local.emplace_back(x.dot(t1_), x.dot(t2_), -x.dot(normal_));
  }
  constexpr int terms = 15;
  if (static_cast<int>(local.size()) < 2 * terms) return false;
  // Scaled coordinates keep the least-squares problem well conditioned.
  Eigen::MatrixXd a(static_cast<Eigen::Index>(local.size()), terms);
  Eigen::VectorXd b(static_cast<Eigen::Index>(local.size()));
  double row[terms];
  for (std::size_t k = 0; k < local.size(); ++k) {
    monomials(local[k].x() / reach_m, local[k].y() / reach_m, row, nullptr, nullptr);
    for (int t = 0; t < terms; ++t) a(static_cast<Eigen::Index>(k), t) = row[t];
    b[static_cast<Eigen::Index>(k)] = local[k].z();
  }
  const Eigen::VectorXd scaled = a.householderQr().solve(b);
  residual_m_ = (a * scaled - b).cwiseAbs().maxCoeff();
  if (!scaled.allFinite() || !(residual_m_ < 1e-3 * reach_m)) {
    residual_m_ = 0;
    return false;
  }
  // Back to metres: the coefficient of u^i v^j divides by reach^(i+j).
  int index = 0;
  for (int total = 0; total <= fit_degree; ++total)
    for (int i = total; i >= 0; --i, ++index) coefficients_[index] = scaled[index] / std::pow(reach_m, total);
  return true;
}

double LocalSurface::depth(double u, double v, double* du, double* dv) const {
  if (!du && !dv) {
    // Horner in v within u: the quadrature's inside tests call this thousands of times per build.
    double d = 0;
    for (int i = fit_degree; i >= 0; --i) {
      double row = 0;
      for (int j = fit_degree - i; j >= 0; --j) row = row * v + coefficients_[coefficient_index(i, j)];
      d = d * u + row;
    }
    return d;
  }
  double value[15], d_u[15], d_v[15];
  monomials(u, v, value, d_u, d_v);
  double d = 0, gu = 0, gv = 0;
  for (int t = 0; t < 15; ++t) {
    d += coefficients_[t] * value[t];
    gu += coefficients_[t] * d_u[t];
    gv += coefficients_[t] * d_v[t];
  }
  if (du) *du = gu;
  if (dv) *dv = gv;
  return d;
}

bool LocalSurface::inside(const Eigen::Vector3d& x, double margin_m) const {
  if (!fitted_) return organ_.signed_distance(x) < -margin_m;
  const Eigen::Vector3d y = x - centre_;
  return -y.dot(normal_) > depth(y.dot(t1_), y.dot(t2_)) + margin_m;
}

bool LocalSurface::on_line(const Eigen::Vector3d& x0, const Eigen::Vector3d& d, Eigen::Vector3d& point,
                           Eigen::Vector3d& normal) const {
  const double tolerance = 1e-12 * reach_m_;
  if (!fitted_) {
    // Closest points, keeping the position across the line and taking the one along it.
    Eigen::Vector3d x = x0;
    for (int iteration = 0; iteration < 12; ++iteration) {
      const geometry::SurfaceProjection p = organ_.project(x);
      const Eigen::Vector3d next = x0 + d * d.dot(p.point - x0);
      const double moved = (next - x).norm();
      x = next;
      point = p.point;
      normal = p.normal;
      if (moved < 1e3 * tolerance) {
        const Eigen::Vector3d offset = point - x0;
        return (offset - d * d.dot(offset)).norm() < 1e5 * tolerance;
      }
    }
    return false;
  }
  // Newton on g(s) = h − depth(u, v) along x₀ + s d, h the height below the tangent plane.
  double s = 0;
  for (int iteration = 0; iteration < 30; ++iteration) {
    const Eigen::Vector3d y = x0 + s * d - centre_;
    const double u = y.dot(t1_), v = y.dot(t2_);
    double du = 0, dv = 0;
    const double g = -y.dot(normal_) - depth(u, v, &du, &dv);
    const double slope = -d.dot(normal_) - du * d.dot(t1_) - dv * d.dot(t2_);
    if (std::abs(g) < tolerance) {
      if (std::hypot(u, v) > 1.05 * reach_m_) return false;  // beyond the fitted patch
      point = centre_ + y;
      normal = (normal_ + du * t1_ + dv * t2_).normalized();
      return true;
    }
    if (!(std::abs(slope) > 1e-6)) return false;
    s -= g / slope;
  }
  return false;
}

}  // namespace touchstone::realtime::mfs
