#pragma once
/// @file
/// Variationally consistent integration (after Chen, Hillman & Rüter 2013): shape-function
/// gradients corrected so that a volume rule of few points still satisfies the integration
/// constraint of the Galerkin weak form, the discrete divergence theorem of every node I,
///
///   Σ_q w_q ∇Ñ_I(x_q) = Σ_b w_b N_I(x_b) n(x_b),
///
/// q the volume points, b the points of the domain's whole boundary (normals out). With it a
/// linear field's weak form is integrated exactly however coarse the volume rule, which is what
/// keeps an under-integrated MLS Galerkin model from going soft.
///
/// The correction used by Chen et al., a constant c_I per node (∇Ñ_I = ∇N_I + c_I), breaks the
/// gradient reproduction of the trial space: Σ_J c_J u_J ≠ 0 for an affine field u_J = G x_J + b,
/// so an affine field would no longer have the strain G and the patch test would fail. Here the
/// correction at each point is made blind to affine fields: ∇Ñ_J(x_q) = ∇N_J(x_q) + [(1 − Π_q) ξ]_J,
/// Π_q the orthogonal projector onto the affine nodal vectors (1, x_J) over the nodes that x_q
/// sees, and ξ (one 3-vector per node) solves the N × N system Σ_q w_q (1 − Π_q) ξ = R, R the
/// constraint residuals. The system is singular on the affine vectors themselves (they change no
/// gradient); R has no component there when the volume and boundary rules agree on the
/// divergence theorem of 1 and x, and what little they disagree by is left uncorrected.

#include <Eigen/Core>

#include <vector>

namespace touchstone::realtime::mfs {

/// Shape-function samples at a set of points, in compressed rows: point q's nodes are
/// node[offset[q]] … node[offset[q + 1] − 1], with their values and gradients [1/m] alongside.
struct ShapeSamples {
  std::vector<Eigen::Vector3d> points;   ///< [m]
  std::vector<Eigen::Vector3d> normals;  ///< unit outward normals (boundary samples; unused for volume samples)
  std::vector<double> weights;           ///< [m³] volume points, [m²] boundary points
  std::vector<int> offset{0};
  std::vector<int> node;
  std::vector<double> value;
  std::vector<Eigen::Vector3d> gradient;  ///< empty for boundary samples

  std::size_t size() const { return weights.size(); }
  /// Room for `point_count` points with `entry_count` node entries in all, so that adding them
  /// neither reallocates nor copies (gradients too if `with_gradients`).
  void reserve(std::size_t point_count, std::size_t entry_count, bool with_gradients);
  /// Appends a point with its nodes' values (and gradients, for a volume sample).
  void add(const Eigen::Vector3d& x, const Eigen::Vector3d& normal, double weight, const std::vector<int>& nodes,
           const std::vector<double>& values, const std::vector<Eigen::Vector3d>* gradients);
  /// The same from arrays of `count` entries (gradients may be null).
  void add(const Eigen::Vector3d& x, const Eigen::Vector3d& normal, double weight, const int* nodes, const double* values,
           const Eigen::Vector3d* gradients, std::size_t count);
};

/// Whether the gradients are corrected.
enum class GradientCorrection : unsigned char {
  none,    ///< the shape functions' own gradients
  linear,  ///< corrected to the integration constraint, affine fields reproduced exactly
  /// chosen by the model that uses the gradients (EnrichedSettings); correct_gradients() does
  /// not accept it
  automatic,
};

/// The largest violation of the integration constraint over every node and component, relative
/// to the largest term of its sum [-].
double integration_constraint_violation(const std::vector<Eigen::Vector3d>& nodes, const ShapeSamples& volume,
                                        const ShapeSamples& boundary);

/// Corrects volume.gradient in place (GradientCorrection::linear; none leaves it; automatic
/// throws std::invalid_argument, the caller decides). Returns the
/// part of the constraint residuals that the correction cannot remove, relative to their
/// largest: how far the volume and boundary rules disagree on the divergence theorem of affine
/// fields (0 for rules that agree exactly).
double correct_gradients(const std::vector<Eigen::Vector3d>& nodes, const ShapeSamples& boundary,
                         GradientCorrection correction, ShapeSamples& volume);

}  // namespace touchstone::realtime::mfs
