// Variationally consistent integration on a cube of MLS nodes: with a coarse volume rule the
// corrected gradients satisfy the discrete divergence theorem of every node, affine fields keep
// their gradient exactly, and a boundary rule that misses a face is reported, not hidden.

#include "touchstone/realtime/mfs/consistent_gradients.hpp"
#include "touchstone/realtime/mfs/mls_shape_functions.hpp"
#include "touchstone/realtime/mfs/quadrature_rules.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace {

using namespace touchstone::realtime::mfs;

constexpr double side_m = 0.01;  // the cube [0, side]³

struct Cloud {
  std::vector<Eigen::Vector3d> nodes;
  std::vector<double> radii;
};

/// A 5 × 5 × 5 lattice, jittered by up to a fifth of its spacing, with supports of 2.2 spacings.
Cloud jittered_lattice(unsigned seed) {
  Cloud c;
  std::mt19937 rng(seed);
  const double h = side_m / 4;
  std::uniform_real_distribution<double> jitter(-0.2 * h, 0.2 * h);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j)
      for (int k = 0; k < 5; ++k) {
        Eigen::Vector3d x(i * h, j * h, k * h);
        for (int d = 0; d < 3; ++d)
          if (x[d] > 0 && x[d] < side_m) x[d] += jitter(rng);  // nodes on the faces stay there
        c.nodes.push_back(x);
        c.radii.push_back(2.2 * h);
      }
  return c;
}

/// Tensor Gauss–Legendre with `per_axis` points per axis in each of cells³ sub-cubes.
std::vector<std::pair<Eigen::Vector3d, double>> volume_rule(int cells, int per_axis) {
  std::vector<double> x, w;
  gauss_legendre(per_axis, x, w);
  const double h = side_m / cells;
  std::vector<std::pair<Eigen::Vector3d, double>> rule;
  for (int ci = 0; ci < cells; ++ci)
    for (int cj = 0; cj < cells; ++cj)
      for (int ck = 0; ck < cells; ++ck)
        for (int i = 0; i < per_axis; ++i)
          for (int j = 0; j < per_axis; ++j)
            for (int k = 0; k < per_axis; ++k)
              rule.push_back({Eigen::Vector3d((ci + x[i]) * h, (cj + x[j]) * h, (ck + x[k]) * h), w[i] * w[j] * w[k] * h * h * h});
  return rule;
}

ShapeSamples sample_volume(const Cloud& c, int cells, int per_axis) {
  ShapeSamples s;
  MlsEvaluation eval;
  for (const auto& [x, w] : volume_rule(cells, per_axis)) {
    evaluate_mls(x, c.nodes, c.radii, {}, MlsSettings{}, Derivatives::gradients, eval);
    EXPECT_EQ(eval.status, MlsStatus::ok);
    s.add(x, Eigen::Vector3d::Zero(), w, eval.neighbours, eval.value, &eval.gradient);
  }
  return s;
}

/// The six faces (or all but the x = side face), 12 × 12 Gauss points each, normals out.
ShapeSamples sample_boundary(const Cloud& c, bool skip_one_face = false) {
  std::vector<double> x, w;
  gauss_legendre(12, x, w);
  ShapeSamples s;
  MlsEvaluation eval;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      if (skip_one_face && axis == 0 && side == 1) continue;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (std::size_t i = 0; i < x.size(); ++i)
        for (std::size_t j = 0; j < x.size(); ++j) {
          Eigen::Vector3d p = Eigen::Vector3d::Zero(), n = Eigen::Vector3d::Zero();
          p[axis] = side * side_m;
          p[u] = x[i] * side_m;
          p[v] = x[j] * side_m;
          n[axis] = side == 0 ? -1 : 1;
          evaluate_mls(p, c.nodes, c.radii, {}, MlsSettings{}, Derivatives::values, eval);
          EXPECT_EQ(eval.status, MlsStatus::ok);
          s.add(p, n, w[i] * w[j] * side_m * side_m, eval.neighbours, eval.value, nullptr);
        }
    }
  return s;
}

// One Gauss point per octant (8 points for 125 nodes) breaks the discrete divergence theorem by
// a large margin; after the correction it holds to rounding. The rules agree on the divergence
// theorem of affine fields (both exact for them), so nothing is left uncorrected.
TEST(ConsistentGradients, CoarseRuleMeetsTheIntegrationConstraintAfterCorrection) {
  for (const unsigned seed : {1u, 2u, 3u}) {
    const Cloud c = jittered_lattice(seed);
    ShapeSamples volume = sample_volume(c, 2, 2);
    const ShapeSamples boundary = sample_boundary(c);
    const double before = integration_constraint_violation(c.nodes, volume, boundary);
    const double left = correct_gradients(c.nodes, boundary, GradientCorrection::linear, volume);
    const double after = integration_constraint_violation(c.nodes, volume, boundary);
    std::printf("seed %u: constraint violation %.1e before, %.1e after; left uncorrected %.1e\n", seed, before, after, left);
    EXPECT_GT(before, 1e-2);
    EXPECT_LT(after, 1e-12);
    EXPECT_LT(left, 1e-12);
  }
}

// The correction is blind to affine fields: Σ_J ∇Ñ_J (G x_J + b) = G at every volume point, as
// the quadratic MLS basis gives it before the correction.
TEST(ConsistentGradients, AffineFieldsKeepTheirGradient) {
  const Cloud c = jittered_lattice(4);
  ShapeSamples volume = sample_volume(c, 2, 2);
  const ShapeSamples original = volume;
  correct_gradients(c.nodes, sample_boundary(c), GradientCorrection::linear, volume);
  Eigen::Matrix3d g;
  g << 0.3, -1.2, 0.5, 2.0, 0.1, -0.7, -0.4, 0.9, 1.1;
  const Eigen::Vector3d b(1e-3, -2e-3, 5e-4);
  double changed = 0;
  for (std::size_t q = 0; q < volume.size(); ++q) {
    Eigen::Matrix3d reproduced = Eigen::Matrix3d::Zero();
    for (int e = volume.offset[q]; e < volume.offset[q + 1]; ++e) {
      const std::size_t k = static_cast<std::size_t>(e);
      reproduced += (g * c.nodes[static_cast<std::size_t>(volume.node[k])] + b) * volume.gradient[k].transpose();
      changed = std::max(changed, (volume.gradient[k] - original.gradient[k]).norm() * side_m);
    }
    EXPECT_LT((reproduced - g).cwiseAbs().maxCoeff(), 1e-11 * g.cwiseAbs().maxCoeff()) << "point " << q;
  }
  EXPECT_GT(changed, 1e-3);  // the correction did change the gradients
}

// A boundary rule that misses a face cannot satisfy the divergence theorem of a constant: the
// correction leaves that part in place and says how large it is.
TEST(ConsistentGradients, ARuleThatMissesAFaceIsReported) {
  const Cloud c = jittered_lattice(5);
  ShapeSamples volume = sample_volume(c, 2, 2);
  const double left = correct_gradients(c.nodes, sample_boundary(c, true), GradientCorrection::linear, volume);
  EXPECT_GT(left, 0.1);
  for (const Eigen::Vector3d& g : volume.gradient) EXPECT_TRUE(g.allFinite());
}

TEST(ConsistentGradients, NoneLeavesTheGradientsAndBadInputIsNamed) {
  const Cloud c = jittered_lattice(6);
  ShapeSamples volume = sample_volume(c, 2, 2);
  const ShapeSamples original = volume;
  EXPECT_EQ(correct_gradients(c.nodes, sample_boundary(c), GradientCorrection::none, volume), 0.0);
  for (std::size_t k = 0; k < volume.gradient.size(); ++k) EXPECT_EQ(volume.gradient[k], original.gradient[k]);
  ShapeSamples no_gradients = sample_boundary(c);
  EXPECT_THROW(correct_gradients(c.nodes, sample_boundary(c), GradientCorrection::linear, no_gradients), std::invalid_argument);
  // 'automatic' is the caller's choice to make, not a correction.
  EXPECT_THROW(correct_gradients(c.nodes, sample_boundary(c), GradientCorrection::automatic, volume), std::invalid_argument);
}

}  // namespace
