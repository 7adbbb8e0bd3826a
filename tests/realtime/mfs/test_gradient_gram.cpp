// The MLS–MLS stiffness from the gradient Gram matrix: equal to the per-pair 3 × 3 block
// formula whatever the batching, and giving the exact strain energy of an affine field.

#include "touchstone/realtime/mfs/gradient_gram.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

namespace {

using touchstone::realtime::mfs::GradientGram;
using touchstone::realtime::mfs::sort_points_spatially;

struct Point {
  std::vector<int> nodes;
  std::vector<Eigen::Vector3d> gradients;
  double weight;
};

/// Random points, each with a random subset of the nodes and random gradients [1/m].
std::vector<Point> random_points(int node_count, int point_count, int per_point, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> g(-300.0, 300.0), w(1e-9, 4e-9);
  std::vector<int> all(static_cast<std::size_t>(node_count));
  for (int i = 0; i < node_count; ++i) all[static_cast<std::size_t>(i)] = i;
  std::vector<Point> points(static_cast<std::size_t>(point_count));
  for (Point& p : points) {
    std::shuffle(all.begin(), all.end(), rng);
    p.nodes.assign(all.begin(), all.begin() + per_point);
    for (int k = 0; k < per_point; ++k) p.gradients.emplace_back(g(rng), g(rng), g(rng));
    p.weight = w(rng);
  }
  return points;
}

/// The textbook assembly: per point and node pair, w (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I).
Eigen::MatrixXd pairwise_stiffness(int node_count, const std::vector<Point>& points, double lambda, double mu) {
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(3 * node_count, 3 * node_count);
  for (const Point& p : points)
    for (std::size_t a = 0; a < p.nodes.size(); ++a)
      for (std::size_t b = 0; b < p.nodes.size(); ++b) {
        const Eigen::Vector3d& ga = p.gradients[a];
        const Eigen::Vector3d& gb = p.gradients[b];
        Eigen::Matrix3d block = lambda * ga * gb.transpose() + mu * gb * ga.transpose();
        block.diagonal().array() += mu * ga.dot(gb);
        k.block<3, 3>(3 * p.nodes[a], 3 * p.nodes[b]) += p.weight * block;
      }
  return k;
}

TEST(GradientGram, EqualsThePairwiseAssemblyForAnyBatching) {
  const int nodes = 40;
  const std::vector<Point> points = random_points(nodes, 150, 12, 7);
  const double lambda = 3.1e4, mu = 3.4e3;  // [Pa]
  const Eigen::MatrixXd expected = pairwise_stiffness(nodes, points, lambda, mu);
  // One point per batch; small unions; the defaults.
  for (const auto& [batch_points, growth] : std::vector<std::pair<int, double>>{{1, 1.0}, {8, 1.2}, {64, 2.0}, {200, 10.0}}) {
    GradientGram gram(nodes, batch_points, growth);
    for (const Point& p : points) gram.add(p.nodes, p.gradients, p.weight);
    Eigen::MatrixXd k = Eigen::MatrixXd::Zero(3 * nodes, 3 * nodes);
    gram.add_isotropic_stiffness(lambda, mu, k);
    EXPECT_LE((k - expected).norm(), 1e-13 * expected.norm())
        << "batches of ≤ " << batch_points << " points, union growth " << growth;
    EXPECT_LE((k - k.transpose()).norm(), 1e-15 * k.norm());
  }
}

// The product overhead counts multiplications: a batch of P points over a union of u nodes
// makes P · 3u(3u + 1)/2, each point of k nodes needs 3k(3k + 1)/2.
TEST(GradientGram, ProductOverheadCountsTheUnionsProducts) {
  const std::vector<Eigen::Vector3d> gradients(4, Eigen::Vector3d(1.0, 2.0, 3.0));
  const auto lower = [](double rows) { return rows * (rows + 1) / 2; };
  {
    GradientGram gram(20);
    EXPECT_EQ(gram.product_overhead(), 0.0);  // nothing closed yet
    for (int p = 0; p < 5; ++p) gram.add({2, 5, 7, 11}, gradients, 1e-9);
    gram.gram();
    EXPECT_DOUBLE_EQ(gram.product_overhead(), 1.0);  // the same four nodes at every point
  }
  {
    // Two points with disjoint sets of four nodes in one batch (growth 2 admits the union of 8).
    GradientGram gram(20, 64, 2.0);
    gram.add({0, 1, 2, 3}, gradients, 1e-9);
    gram.add({4, 5, 6, 7}, gradients, 1e-9);
    gram.gram();
    EXPECT_DOUBLE_EQ(gram.product_overhead(), 2 * lower(24) / (2 * lower(12)));
  }
  {
    // The same points with no growth allowed: two batches, no overhead.
    GradientGram gram(20, 64, 1.0);
    gram.add({0, 1, 2, 3}, gradients, 1e-9);
    gram.add({4, 5, 6, 7}, gradients, 1e-9);
    gram.gram();
    EXPECT_DOUBLE_EQ(gram.product_overhead(), 1.0);
  }
}

TEST(GradientGram, AnAffineFieldHasTheExactStrainEnergy) {
  // The linear tetrahedron's shape functions reproduce affine fields: for u = Fx the nodal
  // values give ε = sym F at every point, so uᵀKu = V (λ (tr ε)² + 2μ ε:ε) exactly.
  const int nodes = 4;
  const Eigen::Vector3d x[nodes] = {{0, 0, 0}, {1e-3, 0, 0}, {0, 1e-3, 0}, {0, 0, 1e-3}};
  // Linear tetrahedron shape functions: ∇N_1 = e_x/h, …, ∇N_0 = −Σ.
  const std::vector<Eigen::Vector3d> gradients = {Eigen::Vector3d(-1e3, -1e3, -1e3), Eigen::Vector3d(1e3, 0, 0),
                                                  Eigen::Vector3d(0, 1e3, 0), Eigen::Vector3d(0, 0, 1e3)};
  const std::vector<int> all = {0, 1, 2, 3};
  const double volume = 1e-9 / 6, lambda = 2e4, mu = 5e3;
  GradientGram gram(nodes, 2, 1.0);
  for (int q = 0; q < 3; ++q) gram.add(all, gradients, volume / 3);
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(3 * nodes, 3 * nodes);
  gram.add_isotropic_stiffness(lambda, mu, k);
  Eigen::Matrix3d f;
  f << 1e-2, 3e-3, -2e-3, 0, -4e-3, 5e-3, 1e-3, 2e-3, 6e-3;
  Eigen::VectorXd u(3 * nodes);
  for (int a = 0; a < nodes; ++a) u.segment<3>(3 * a) = f * x[a];
  const Eigen::Matrix3d strain = 0.5 * (f + f.transpose());
  const double energy = volume * (lambda * strain.trace() * strain.trace() + 2 * mu * strain.squaredNorm());
  EXPECT_NEAR(u.dot(k * u), energy, 1e-12 * energy);
}

TEST(GradientGram, RefusesBadLimitsAndTooSmallMatrices) {
  EXPECT_THROW(GradientGram(-1), std::invalid_argument);
  EXPECT_THROW(GradientGram(4, 0), std::invalid_argument);
  EXPECT_THROW(GradientGram(4, 8, 0.5), std::invalid_argument);
  GradientGram gram(4);
  Eigen::MatrixXd small = Eigen::MatrixXd::Zero(6, 6);
  EXPECT_THROW(gram.add_isotropic_stiffness(1.0, 1.0, small), std::invalid_argument);
}

TEST(SortPointsSpatially, IsAPermutationThatKeepsCellsTogether) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 0.01);
  std::vector<Eigen::Vector3d> points(500);
  for (Eigen::Vector3d& p : points) p = Eigen::Vector3d(u(rng), u(rng), u(rng));
  points.front().setZero();  // the grid starts at the lowest corner
  const std::vector<int> order = sort_points_spatially(points, 0.0025);
  ASSERT_EQ(order.size(), points.size());
  EXPECT_EQ(std::set<int>(order.begin(), order.end()).size(), points.size());
  // A Z-order visits each of the 4 × 4 × 4 cells in one run: 64 runs, one per occupied cell.
  int runs = 0;
  Eigen::Vector3i previous(-1, -1, -1);
  for (int p : order) {
    const Eigen::Vector3i cell = (points[static_cast<std::size_t>(p)] / 0.0025).array().floor().cast<int>();
    if (cell != previous) ++runs;
    previous = cell;
  }
  EXPECT_EQ(runs, 64);
}

}  // namespace
