/// @file
/// The gradient Gram matrix of the MLS–MLS stiffness, in dense batches.

#include "touchstone/realtime/mfs/gradient_gram.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace touchstone::realtime::mfs {

GradientGram::GradientGram(int node_count, int max_batch_points, double max_union_growth)
    : node_count_(node_count), max_batch_points_(max_batch_points), max_union_growth_(max_union_growth) {
  if (node_count < 0 || max_batch_points < 1 || !(max_union_growth >= 1))
    throw std::invalid_argument("GradientGram: node_count must be ≥ 0, max_batch_points ≥ 1 and max_union_growth ≥ 1");
  gram_lower_.setZero(3 * node_count, 3 * node_count);
  slot_.assign(static_cast<std::size_t>(node_count), -1);
  batch_offset_.reserve(static_cast<std::size_t>(max_batch_points) + 1);
}

void GradientGram::add(const std::vector<int>& nodes, const std::vector<Eigen::Vector3d>& gradients_per_m,
                       double weight_m3) {
  if (gradients_per_m.size() != nodes.size()) throw std::invalid_argument("GradientGram::add: one gradient per node is needed");
  add(nodes.data(), gradients_per_m.data(), static_cast<int>(nodes.size()), weight_m3);
}

void GradientGram::add(const int* nodes, const Eigen::Vector3d* gradients_per_m, int count, double weight_m3) {
  int fresh = 0;
  for (int k = 0; k < count; ++k) fresh += slot_[static_cast<std::size_t>(nodes[k])] < 0 ? 1 : 0;
  const int widest = std::max(batch_widest_, count);
  if (batch_size_ == max_batch_points_ ||
      (batch_size_ > 0 && static_cast<double>(union_nodes_.size() + fresh) > max_union_growth_ * widest))
    flush();
  batch_widest_ = std::max(batch_widest_, count);
  const double root_weight = std::sqrt(std::max(weight_m3, 0.0));
  for (int k = 0; k < count; ++k) {
    batch_gradients_.push_back(root_weight * gradients_per_m[k]);
    batch_nodes_.push_back(nodes[k]);
    if (slot_[static_cast<std::size_t>(nodes[k])] < 0) {
      slot_[static_cast<std::size_t>(nodes[k])] = 0;  // marked; numbered in flush()
      union_nodes_.push_back(nodes[k]);
    }
  }
  batch_offset_.push_back(static_cast<int>(batch_nodes_.size()));
  ++batch_size_;
}

void GradientGram::flush() {
  if (batch_size_ == 0) return;
  // Slots in ascending node order, so that the local lower triangle maps into the global one.
  std::sort(union_nodes_.begin(), union_nodes_.end());
  const int u = static_cast<int>(union_nodes_.size());
  for (int s = 0; s < u; ++s) slot_[static_cast<std::size_t>(union_nodes_[static_cast<std::size_t>(s)])] = s;
  local_gradients_.setZero(3 * u, batch_size_);
  for (int p = 0; p < batch_size_; ++p)
    for (int e = batch_offset_[static_cast<std::size_t>(p)]; e < batch_offset_[static_cast<std::size_t>(p) + 1]; ++e) {
      const int s = slot_[static_cast<std::size_t>(batch_nodes_[static_cast<std::size_t>(e)])];
      for (int i = 0; i < 3; ++i) local_gradients_(i * u + s, p) = batch_gradients_[static_cast<std::size_t>(e)](i);
    }
  // Only the lower triangle is read: zero only it (the whole square was most of the time in
  // memset on large clouds).
  local_gram_.resize(3 * u, 3 * u);
  local_gram_.triangularView<Eigen::Lower>().setZero();
  local_gram_.selfadjointView<Eigen::Lower>().rankUpdate(local_gradients_);
  const auto lower_triangle = [](double rows) { return rows * (rows + 1) / 2; };
  products_made_ += lower_triangle(3.0 * u) * batch_size_;
  for (std::size_t p = 0; p < static_cast<std::size_t>(batch_size_); ++p)
    products_needed_ += lower_triangle(3.0 * (batch_offset_[p + 1] - batch_offset_[p]));
  // Each local row's global row, once per batch rather than a division per entry.
  global_row_.resize(static_cast<std::size_t>(3 * u));
  for (int r = 0; r < 3 * u; ++r)
    global_row_[static_cast<std::size_t>(r)] = (r / u) * node_count_ + union_nodes_[static_cast<std::size_t>(r % u)];
  for (int c = 0; c < 3 * u; ++c) {
    double* column = gram_lower_.col(global_row_[static_cast<std::size_t>(c)]).data();
    const double* local = local_gram_.col(c).data();
    for (int r = c; r < 3 * u; ++r) column[global_row_[static_cast<std::size_t>(r)]] += local[r];
  }
  for (int node : union_nodes_) slot_[static_cast<std::size_t>(node)] = -1;
  union_nodes_.clear();
  batch_nodes_.clear();
  batch_gradients_.clear();
  batch_offset_.resize(1);
  batch_size_ = 0;
  batch_widest_ = 0;
}

Eigen::MatrixXd GradientGram::gram() {
  flush();
  gram_lower_.triangularView<Eigen::StrictlyUpper>() = gram_lower_.transpose();
  return gram_lower_;
}

void GradientGram::add_isotropic_stiffness(double lambda_Pa, double mu_Pa, Eigen::MatrixXd& stiffness) {
  const Eigen::Index n = node_count_;
  if (stiffness.rows() < 3 * n || stiffness.cols() < 3 * n)
    throw std::invalid_argument("GradientGram: the stiffness matrix is smaller than 3 × node_count");
  flush();
  // A made symmetric in place (no second 3N × 3N matrix), then K's 3 × 3 block of each node
  // pair read from it column by column.
  gram_lower_.triangularView<Eigen::StrictlyUpper>() = gram_lower_.transpose();
  const Eigen::MatrixXd& a = gram_lower_;
  const Eigen::MatrixXd trace = a.topLeftCorner(n, n) + a.block(n, n, n, n) + a.bottomRightCorner(n, n);
  for (Eigen::Index b = 0; b < n; ++b)
    for (int j = 0; j < 3; ++j) {
      double* column = stiffness.col(3 * b + j).data();
      for (Eigen::Index r = 0; r < n; ++r)
        for (int i = 0; i < 3; ++i) {
          double v = lambda_Pa * a(i * n + r, j * n + b) + mu_Pa * a(j * n + r, i * n + b);
          if (i == j) v += mu_Pa * trace(r, b);
          column[3 * r + i] += v;
        }
    }
}

std::vector<int> sort_points_spatially(const std::vector<Eigen::Vector3d>& points, double cell_m) {
  std::vector<int> order(points.size());
  std::iota(order.begin(), order.end(), 0);
  if (points.empty() || !(cell_m > 0)) return order;
  Eigen::Vector3d low = points.front();
  for (const Eigen::Vector3d& x : points) low = low.cwiseMin(x);
  // 21 bits per axis: interleaved into one 63-bit key.
  const auto spread = [](std::uint64_t v) {
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
  };
  std::vector<std::uint64_t> key(points.size());
  for (std::size_t p = 0; p < points.size(); ++p) {
    const Eigen::Vector3d cell = ((points[p] - low) / cell_m).array().floor().min(2097151.0).max(0.0);
    key[p] = spread(static_cast<std::uint64_t>(cell.x())) | spread(static_cast<std::uint64_t>(cell.y())) << 1 |
             spread(static_cast<std::uint64_t>(cell.z())) << 2;
  }
  std::stable_sort(order.begin(), order.end(), [&](int l, int r) { return key[static_cast<std::size_t>(l)] < key[static_cast<std::size_t>(r)]; });
  return order;
}

}  // namespace touchstone::realtime::mfs
