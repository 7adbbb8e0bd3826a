#pragma once
/// @file
/// Tool force from a solved local model (DESIGN.md §4.6), and the 3×3 tool stiffness K_t that
/// lets the haptic loop compute F = K_t U_tool exactly in nine multiply-adds (§4.5).

#include "touchstone/realtime/geometry/triangle_surface.hpp"
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
};

PatchQuadrature patch_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact,
                                 int radial_points = 12, int angular_points = 24);

/// The linear map U ↦ F = ∫_patch σ(u_h) n dA [N] (force of the tool on the tissue), as a
/// 3 × 3N matrix. Returns false (and leaves `map` empty) when a shape-function evaluation
/// fails at a quadrature point.
bool traction_force_map(const NodeCloud& cloud, const Material& material, const MlsSettings& mls,
                        const PatchQuadrature& quadrature, Eigen::Matrix<double, 3, Eigen::Dynamic>& map);

}  // namespace touchstone::realtime::mfs
