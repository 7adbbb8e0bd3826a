#pragma once
/// @file
/// Tool force from a solved local model, and the 3×3 tool stiffness K_t that lets the haptic
/// loop compute F = K_t U_tool exactly in nine multiply-adds.

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/collocation.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"

#include <Eigen/Core>

#include <vector>

namespace touchstone::realtime::mfs {

/// Quadrature of the tool patch: points on the organ surface under the punch, their outward
/// normals and weights [m²]. The contact pressure of a flat punch is singular like
/// (a² − r²)^(−1/2) at the edge, so the radial rule is Gauss–Legendre in φ with r = a sin φ,
/// which absorbs that singularity.
struct PatchQuadrature {
  std::vector<Eigen::Vector3d> points, normals;
  std::vector<double> weights;

  /// Room for `count` points, so that a rule built point by point does not regrow.
  void reserve(std::size_t count) {
    points.reserve(count);
    normals.reserve(count);
    weights.reserve(count);
  }
};

PatchQuadrature patch_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact,
                                 int radial_points = 12, int angular_points = 24);

/// Quadrature of the cut surface Γ_c = organ ∩ sphere(c, L) (c = the contact point on the
/// surface), with normals pointing out of the local domain (radially). Per azimuth the polar
/// range runs from the inward normal to where the sphere leaves the organ (found by bisection
/// on the signed distance), with Gauss–Legendre in the polar angle: no masked cells.
/// `marching_steps`: steps in the polar angle before the bisection (a surface that leaves and
/// re-enters the sphere within one step is missed).
PatchQuadrature cut_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact, double local_radius_m,
                               int polar_points = 24, int azimuth_points = 48, int marching_steps = 128);

/// Volume quadrature of Ω = organ ∩ ball(c, L): per direction (polar, azimuth about the inward
/// normal) the ray from c is cut where it leaves the organ or reaches L, with Gauss–Legendre in
/// t for ρ = a (e^{κt} − 1), κ = ln(1 + reach/a) (a = the tool radius): points graded like the
/// node cloud. `normals` are unused (zero). Weights in [m³].
PatchQuadrature volume_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact, double local_radius_m,
                                  int radial_points = 32, int polar_points = 24, int azimuth_points = 32);

/// The cutoff w of the domain form of the traction integral: 1 for ρ ≤ inner, 0 for ρ ≥ outer,
/// a C² quintic in between; `slope_per_m` (if given) receives dw/dρ [1/m].
double extraction_cutoff(double distance_m, double inner_m, double outer_m, double* slope_per_m = nullptr);
/// The traction integral in its domain form (Babuška–Miller extraction): with w = 1 on the tool
/// patch and 0 on the cut, div σ = 0 and σn = 0 on the free surface, the divergence theorem
/// gives ∫_patch σn dA = ∫_Ω σ ∇w dV. Only the shell inner < |x − c| < outer contributes, away
/// from the punch edge whose r^(−1/2) stress a smooth MLS field cannot carry pointwise; the
/// error is then that of the stresses in the shell, which converges. Points of that shell with
/// "normals" ∇w [1/m] and weights [m³], so surface_traction_map on it is this integral [N].
PatchQuadrature extraction_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact, double inner_m,
                                      double outer_m, int radial_points = 8, int polar_points = 24,
                                      int azimuth_points = 48);
/// The linear map U ↦ ∫ σ(u_h) n dA [N] over any surface quadrature (3 × 3N); on the patch
/// quadrature it is the force of the tool on the tissue. Returns false
/// (and leaves `map` empty) when a shape-function evaluation fails at a quadrature point.
bool surface_traction_map(const NodeCloud& cloud, const geometry::Material& material, const MlsSettings& mls,
                          const PatchQuadrature& quadrature, Eigen::Matrix<double, 3, Eigen::Dynamic>& map);

/// Strain energy U = ½ ∫_Ω σ(u_h) : ε(u_h) dV [J] of the nodal parameters over a volume
/// quadrature. NaN never escapes: a failed shape-function evaluation returns false.
bool strain_energy(const NodeCloud& cloud, const geometry::Material& material, const MlsSettings& mls,
                   const PatchQuadrature& volume, const Eigen::VectorXd& parameters, double& energy_J);

/// Tributary areas [m²] of the tool-patch nodes (the paper's force mode scales each patch
/// node's traction row by its share of the patch): a node's share is the part of the patch
/// disk closer to it than to any other patch node, estimated on the patch quadrature.
std::vector<double> tributary_areas(const NodeCloud& cloud, const PatchQuadrature& patch);

}  // namespace touchstone::realtime::mfs
