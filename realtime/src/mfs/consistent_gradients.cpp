/// @file
/// Variationally consistent integration: the constraint residuals, the affine-blind correction
/// and its N × N system.

#include "touchstone/realtime/mfs/consistent_gradients.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

/// R_J = Σ_b w N_J n − Σ_q w ∇N_J (rows: nodes), and Σ|terms| per entry to judge it against.
void constraint_residuals(std::size_t node_count, const ShapeSamples& volume, const ShapeSamples& boundary,
                          Eigen::MatrixX3d& residual, Eigen::MatrixX3d* magnitude) {
  if (volume.gradient.size() != volume.node.size())
    throw std::invalid_argument("consistent gradients: the volume samples carry no gradients");
  residual.setZero(static_cast<Eigen::Index>(node_count), 3);
  if (magnitude) magnitude->setZero(static_cast<Eigen::Index>(node_count), 3);
  for (std::size_t q = 0; q < volume.size(); ++q)
    for (int e = volume.offset[q]; e < volume.offset[q + 1]; ++e) {
      const Eigen::Index J = volume.node[static_cast<std::size_t>(e)];
      const Eigen::Vector3d term = volume.weights[q] * volume.gradient[static_cast<std::size_t>(e)];
      residual.row(J) -= term.transpose();
      if (magnitude) magnitude->row(J) += term.cwiseAbs().transpose();
    }
  for (std::size_t b = 0; b < boundary.size(); ++b)
    for (int e = boundary.offset[b]; e < boundary.offset[b + 1]; ++e) {
      const Eigen::Index J = boundary.node[static_cast<std::size_t>(e)];
      const Eigen::Vector3d term = boundary.weights[b] * boundary.value[static_cast<std::size_t>(e)] * boundary.normals[b];
      residual.row(J) += term.transpose();
      if (magnitude) magnitude->row(J) += term.cwiseAbs().transpose();
    }
}

}  // namespace

void ShapeSamples::reserve(std::size_t point_count, std::size_t entry_count, bool with_gradients) {
  points.reserve(point_count);
  normals.reserve(point_count);
  weights.reserve(point_count);
  offset.reserve(point_count + 1);
  node.reserve(entry_count);
  value.reserve(entry_count);
  if (with_gradients) gradient.reserve(entry_count);
}

void ShapeSamples::add(const Eigen::Vector3d& x, const Eigen::Vector3d& normal, double weight, const std::vector<int>& nodes,
                       const std::vector<double>& values, const std::vector<Eigen::Vector3d>* gradients) {
  add(x, normal, weight, nodes.data(), values.data(), gradients ? gradients->data() : nullptr, nodes.size());
}

void ShapeSamples::add(const Eigen::Vector3d& x, const Eigen::Vector3d& normal, double weight, const int* nodes,
                       const double* values, const Eigen::Vector3d* gradients, std::size_t count) {
  points.push_back(x);
  normals.push_back(normal);
  weights.push_back(weight);
  node.insert(node.end(), nodes, nodes + count);
  value.insert(value.end(), values, values + count);
  if (gradients) gradient.insert(gradient.end(), gradients, gradients + count);
  offset.push_back(static_cast<int>(node.size()));
}

double integration_constraint_violation(const std::vector<Eigen::Vector3d>& nodes, const ShapeSamples& volume,
                                        const ShapeSamples& boundary) {
  Eigen::MatrixX3d residual, magnitude;
  constraint_residuals(nodes.size(), volume, boundary, residual, &magnitude);
  double worst = 0;
  for (Eigen::Index J = 0; J < residual.rows(); ++J)
    for (int i = 0; i < 3; ++i)
      if (magnitude(J, i) > 0) worst = std::max(worst, std::abs(residual(J, i)) / magnitude(J, i));
  return worst;
}

double correct_gradients(const std::vector<Eigen::Vector3d>& nodes, const ShapeSamples& boundary,
                         GradientCorrection correction, ShapeSamples& volume) {
  if (correction == GradientCorrection::automatic)
    throw std::invalid_argument("correct_gradients: the correction 'automatic' must be chosen by the caller");
  if (correction == GradientCorrection::none) return 0;
  const Eigen::Index n = static_cast<Eigen::Index>(nodes.size());
  Eigen::MatrixX3d residual;
  constraint_residuals(nodes.size(), volume, boundary, residual, nullptr);
  const double largest = residual.cwiseAbs().maxCoeff();
  if (!(largest > 0)) return 0;

  // The affine nodal vectors (1, x_J) in a frame centred and scaled on the cloud, orthonormal.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& x : nodes) centre += x / static_cast<double>(n);
  double reach = 0;
  for (const Eigen::Vector3d& x : nodes) reach = std::max(reach, (x - centre).norm());
  const double scale = reach > 0 ? 1 / reach : 1;
  Eigen::MatrixXd affine(n, 4);
  for (Eigen::Index J = 0; J < n; ++J) affine.row(J) << 1, scale * (nodes[static_cast<std::size_t>(J)] - centre).transpose();
  const Eigen::MatrixXd affine_basis = Eigen::HouseholderQR<Eigen::MatrixXd>(affine).householderQ() * Eigen::MatrixXd::Identity(n, 4);

  // Per point, Π_q's orthonormal basis Q_q = E_q L_q⁻ᵀ (E_q the k × 4 affine vectors over the
  // point's nodes, L_q Lᵀ_q = E_qᵀ E_q), kept for the correction below, and
  // A = Σ_q w_q (1 − Q_q Q_qᵀ): its diagonal part per point, the products Σ_q (√w Q_q)(√w Q_q)ᵀ in
  // batches of consecutive points over the union of their nodes (one dense rank update each).
  Eigen::MatrixXd system = Eigen::MatrixXd::Zero(n, n);
  std::vector<double> basis(4 * volume.node.size());  // Q_q row by row, at 4 × the point's offset
  // A batch closes at 32 points, or before a point would take the union of nodes past twice
  // the widest point's set: on large clouds a union of every node made each product dense.
  constexpr int batch_points = 32;
  constexpr double max_union_growth = 2.0;
  int batch_widest = 0;
  std::vector<int> slot(static_cast<std::size_t>(n), -1), union_nodes;
  Eigen::MatrixXd batch, batch_gram;
  std::size_t batch_first = 0;
  const auto flush = [&](std::size_t end) {
    if (end == batch_first) return;
    const Eigen::Index u = static_cast<Eigen::Index>(union_nodes.size());
    batch.setZero(u, 4 * static_cast<Eigen::Index>(end - batch_first));
    for (std::size_t q = batch_first; q < end; ++q) {
      const double root_w = std::sqrt(std::max(volume.weights[q], 0.0));
      for (int e = volume.offset[q]; e < volume.offset[q + 1]; ++e)
        for (int c = 0; c < 4; ++c)
          batch(slot[static_cast<std::size_t>(volume.node[static_cast<std::size_t>(e)])], 4 * static_cast<Eigen::Index>(q - batch_first) + c) =
              root_w * basis[4 * static_cast<std::size_t>(e) + static_cast<std::size_t>(c)];
    }
    batch_gram.setZero(u, u);
    batch_gram.selfadjointView<Eigen::Lower>().rankUpdate(batch);
    // Into A's lower triangle (the union is in first-seen order, not sorted).
    for (Eigen::Index b = 0; b < u; ++b)
      for (Eigen::Index a = b; a < u; ++a) {
        const int i = union_nodes[static_cast<std::size_t>(a)], j = union_nodes[static_cast<std::size_t>(b)];
        system(std::max(i, j), std::min(i, j)) -= batch_gram(a, b);
      }
    for (int node : union_nodes) slot[static_cast<std::size_t>(node)] = -1;
    union_nodes.clear();
    batch_first = end;
    batch_widest = 0;
  };
  for (std::size_t q = 0; q < volume.size(); ++q) {
    const int first = volume.offset[q], k = volume.offset[q + 1] - first;
    int fresh = 0;
    for (int a = 0; a < k; ++a) fresh += slot[static_cast<std::size_t>(volume.node[static_cast<std::size_t>(first + a)])] < 0 ? 1 : 0;
    if (q - batch_first == batch_points ||
        (q > batch_first && static_cast<double>(union_nodes.size() + static_cast<std::size_t>(fresh)) > max_union_growth * std::max(batch_widest, k)))
      flush(q);
    batch_widest = std::max(batch_widest, k);
    // The 4 × 4 moments Σ e eᵀ, e = (1, d), as running sums of d and of d dᵀ's six entries in
    // registers: a vector e assembled on the stack and read back whole stalled every node
    // (its narrow stores cannot be forwarded to the wide load). Each entry is the same sum, in
    // the same order, as the outer products would give.
    Eigen::Vector3d first_moments = Eigen::Vector3d::Zero();
    double xx = 0, yy = 0, zz = 0, xy = 0, yz = 0, zx = 0;
    for (int a = 0; a < k; ++a) {
      const Eigen::Vector3d d =
          scale * (nodes[static_cast<std::size_t>(volume.node[static_cast<std::size_t>(first + a)])] - volume.points[q]);
      first_moments += d;
      xx += d.x() * d.x(), yy += d.y() * d.y(), zz += d.z() * d.z();
      xy += d.x() * d.y(), yz += d.y() * d.z(), zx += d.z() * d.x();
    }
    Eigen::Matrix4d moments;
    moments << k, first_moments.x(), first_moments.y(), first_moments.z(),  //
        first_moments.x(), xx, xy, zx,                                      //
        first_moments.y(), xy, yy, yz,                                      //
        first_moments.z(), zx, yz, zz;
    const Eigen::LLT<Eigen::Matrix4d> cholesky(moments);
    if (cholesky.info() != Eigen::Success)
      throw std::invalid_argument("consistent gradients: the nodes seen at volume point " + std::to_string(q) +
                                  " do not span the affine fields");
    // Row a of Q = E L⁻ᵀ is (L⁻¹ e_a)ᵀ. The forward substitution of Eigen's unrolled 4 × 4
    // solve, written out with its operations in its order (the same bits), four nodes to a
    // vector: one node's chain of dependent divisions set the pace.
    const Eigen::Matrix4d& l = cholesky.matrixLLT();
    const double q0 = 1.0 / l(0, 0);  // e's first entry is 1 at every node
    for (int a0 = 0; a0 < k; a0 += 4) {
      const int count = std::min(4, k - a0);
      // The lanes are built in registers (scalar stores read back as one vector would stall);
      // a short last group repeats its last node.
      const auto offset_of = [&](int t) {
        const int a = a0 + std::min(t, count - 1);
        return Eigen::Vector3d(scale * (nodes[static_cast<std::size_t>(volume.node[static_cast<std::size_t>(first + a)])] - volume.points[q]));
      };
      const Eigen::Vector3d d0 = offset_of(0), d1 = offset_of(1), d2 = offset_of(2), d3 = offset_of(3);
      const Eigen::Array4d dx(d0.x(), d1.x(), d2.x(), d3.x()), dy(d0.y(), d1.y(), d2.y(), d3.y()),
          dz(d0.z(), d1.z(), d2.z(), d3.z());
      const Eigen::Array4d q1 = (dx - l(1, 0) * q0) / l(1, 1);
      const Eigen::Array4d q2 = (dy - (l(2, 0) * q0 + l(2, 1) * q1)) / l(2, 2);
      const Eigen::Array4d q3 = (dz - (l(3, 0) * q0 + (l(3, 1) * q1 + l(3, 2) * q2))) / l(3, 3);
      for (int t = 0; t < count; ++t) {
        double* row = &basis[4 * static_cast<std::size_t>(first + a0 + t)];
        row[0] = q0, row[1] = q1[t], row[2] = q2[t], row[3] = q3[t];
      }
    }
    for (int a = 0; a < k; ++a) {
      const int J = volume.node[static_cast<std::size_t>(first + a)];
      system(J, J) += volume.weights[q];
      if (slot[static_cast<std::size_t>(J)] < 0) {
        slot[static_cast<std::size_t>(J)] = static_cast<int>(union_nodes.size());
        union_nodes.push_back(J);
      }
    }
  }
  flush(volume.size());
  system.triangularView<Eigen::StrictlyUpper>() = system.transpose();
  // The affine vectors span A's null space: take R's component there out (the rules'
  // disagreement) and fix ξ's component there (it changes no gradient) by adding their projector.
  const Eigen::MatrixX3d compatible = residual - affine_basis * (affine_basis.transpose() * residual);
  const double unremovable = (residual - compatible).cwiseAbs().maxCoeff() / largest;
  const double diagonal_mean = system.diagonal().mean();
  for (Eigen::Index J = 0; J < n; ++J)
    if (!(system(J, J) > 0)) system(J, J) = diagonal_mean;  // a node no volume point sees: ξ_J = 0
  system.noalias() += diagonal_mean * affine_basis * affine_basis.transpose();
  Eigen::MatrixX3d xi = compatible;
  Eigen::LLT<Eigen::MatrixXd> cholesky(system);
  if (cholesky.info() != Eigen::Success)
    throw std::invalid_argument("consistent gradients: the correction's system is not positive definite (the volume points' node sets do not overlap)");
  cholesky.solveInPlace(xi);

  Eigen::Matrix<double, 4, 3> projected;
  for (std::size_t q = 0; q < volume.size(); ++q) {
    const int first = volume.offset[q], k = volume.offset[q + 1] - first;
    projected.setZero();
    for (int a = 0; a < k; ++a)
      projected.noalias() += Eigen::Map<const Eigen::Vector4d>(&basis[4 * static_cast<std::size_t>(first + a)]) *
                             xi.row(volume.node[static_cast<std::size_t>(first + a)]);
    for (int a = 0; a < k; ++a) {
      const int J = volume.node[static_cast<std::size_t>(first + a)];
      volume.gradient[static_cast<std::size_t>(first + a)] +=
          (xi.row(J) - Eigen::Map<const Eigen::Vector4d>(&basis[4 * static_cast<std::size_t>(first + a)]).transpose() * projected).transpose();
    }
  }
  return unremovable;
}

}  // namespace touchstone::realtime::mfs
