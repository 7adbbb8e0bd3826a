#pragma once
/// @file
/// The MLS–MLS stiffness of an isotropic material from the Gram matrix of the shape-function
/// gradients,
///
///   A^{ij}_{ab} = Σ_q w_q ∂_i N_a(x_q) ∂_j N_b(x_q),
///   K_{(a,i),(b,j)} = λ A^{ij}_{ab} + μ A^{ji}_{ab} + μ δ_ij Σ_k A^{kk}_{ab}
///
/// (∫ ε(N_a e_i) : C : ε(N_b e_j) dV with C = λ I⊗I + 2μ 𝕀). A is accumulated batch by batch as
/// GᵀG, G the √w-weighted gradients of a batch of nearby points over the union of their nodes:
/// one dense, vectorised product per batch instead of a 3 × 3 block per node pair and point.
/// Batches close when they hold `max_batch_points` points or when a point would take the union
/// past `max_union_growth` times the largest node set of the batch's points, so a caller that feeds the points in a spatially coherent order
/// (sort_points_spatially) keeps the dense products small on large clouds.

#include <Eigen/Core>

#include <vector>

namespace touchstone::realtime::mfs {

class GradientGram {
 public:
  /// `node_count` nodes; a batch closes at `max_batch_points` points or when its union of nodes
  /// would exceed `max_union_growth` (≥ 1) times its widest point's node set.
  explicit GradientGram(int node_count, int max_batch_points = 64, double max_union_growth = 2.0);

  /// One quadrature point of weight `weight_m3` [m³] (≥ 0) whose shape functions of `nodes`
  /// (indices < node_count, no repeats) have gradients `gradients_per_m` [1/m].
  void add(const std::vector<int>& nodes, const std::vector<Eigen::Vector3d>& gradients_per_m, double weight_m3);
  /// The same for `count` nodes and gradients in arrays.
  void add(const int* nodes, const Eigen::Vector3d* gradients_per_m, int count, double weight_m3);

  /// K += the isotropic stiffness [N/m] of everything added (K is 3N × 3N or larger, node a's
  /// component i at row 3a + i). Flushes the open batch.
  void add_isotropic_stiffness(double lambda_Pa, double mu_Pa, Eigen::MatrixXd& stiffness);

  /// A (3N × 3N, row iN + a for ∂_i N_a), symmetric. Flushes the open batch.
  Eigen::MatrixXd gram();

  /// The multiplications the batches' dense products made over those the points' own node sets
  /// need (each point's lower triangle of its 3k × 3k outer product): 1 when every batch's
  /// points see the same nodes; it grows with the batches' unions. 0 before any batch closed.
  double product_overhead() const noexcept { return products_needed_ > 0 ? products_made_ / products_needed_ : 0.0; }

 private:
  void flush();

  int node_count_, max_batch_points_;
  double max_union_growth_;
  Eigen::MatrixXd gram_lower_;  // lower triangle of A, component-major (symmetrised when read)
  // The open batch: its points' nodes and √w-weighted gradients in compressed rows (point p's
  // are entries batch_offset_[p] … batch_offset_[p + 1] − 1), and the union of nodes with each
  // node's slot in it (−1: not in the batch).
  std::vector<int> batch_nodes_, batch_offset_{0};
  std::vector<Eigen::Vector3d> batch_gradients_;
  int batch_size_ = 0, batch_widest_ = 0;
  std::vector<int> union_nodes_, slot_;
  std::vector<Eigen::Index> global_row_;  // the open batch's local row → row of A
  Eigen::MatrixXd local_gradients_, local_gram_;
  double products_made_ = 0, products_needed_ = 0;
};

/// The order in which to visit `points` so that consecutive points are close: by the Morton
/// (Z-order) code of a grid of `cell_m` [m] cells.
std::vector<int> sort_points_spatially(const std::vector<Eigen::Vector3d>& points, double cell_m);

}  // namespace touchstone::realtime::mfs
