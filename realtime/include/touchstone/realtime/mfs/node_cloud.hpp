#pragma once
/// @file
/// The nodes of a local MFS model and the three collocation rows each one carries.

#include "touchstone/realtime/mfs/mls_shape_functions.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace touchstone::realtime::mfs {

/// Where a node sits; decides its default rows.
enum class NodeKind : std::uint8_t {
  interior,      ///< Navier rows
  free_surface,  ///< traction rows (traction-free organ surface)
  tool_patch,    ///< under the tool: Dirichlet (bonded) or mixed (frictionless)
  cut,           ///< on the sphere |x − c| = L that bounds the local domain: the outer condition
};

/// One scalar equation at a node, written along a unit direction e:
///   navier:    e · (μ ∇²u + (λ+μ) ∇(∇·u))(x_I)      = value + tool · U_tool   (value = −e·b)
///   traction:  e · σ(u)(x_I) n_I                      = value + tool · U_tool
///   dirichlet: e · u(x_I) = Σ_J h_J(x_I) e · u_J      = value + tool · U_tool   (consistent: MLS does not interpolate)
/// `tool` makes the right-hand side linear in the tool displacement U_tool [m], so that one
/// factorisation serves every tool position and gives the tool stiffness K_t.
struct CollocationRow {
  enum class Type : std::uint8_t { navier, traction, dirichlet };
  Type type = Type::navier;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  double value = 0;                                      ///< [N/m³], [Pa] or [m] by type
  Eigen::Vector3d tool = Eigen::Vector3d::Zero();        ///< [-] for dirichlet rows
};

/// A collocation point that is not a node (least-squares collocation writes more equations
/// than there are unknowns, which stabilises the traction rows). Same rows and data as a node.
struct CollocationPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  NodeKind kind = NodeKind::interior;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< outward unit normal on boundaries
  double spacing = 0;                                ///< local node spacing [m] (row scaling)
  Eigen::Vector3d body_force = Eigen::Vector3d::Zero();  ///< b [N/m³]
  std::array<CollocationRow, 3> rows;
};

/// The sprinkled nodes: positions [m], sphere (support) radii [m], kind, outward normal (unit,
/// boundary nodes only) and the three rows of each node.
struct NodeCloud {
  std::vector<Eigen::Vector3d> positions;
  std::vector<double> radii;
  std::vector<NodeKind> kinds;
  std::vector<Eigen::Vector3d> normals;
  std::vector<std::array<CollocationRow, 3>> rows;
  /// Typical node spacing around each node [m] (sets the row scaling).
  std::vector<double> spacing;
  /// Body force b(x_I) [N/m³] per node, or empty for none. Navier rows carry −e·b in their
  /// value already; stabilised traction rows need b itself.
  std::vector<Eigen::Vector3d> body_force;
  /// Extra collocation points: empty for square point collocation (one point per node);
  /// otherwise K has 3(N + M) rows and U is its weighted least-squares solution.
  std::vector<CollocationPoint> extra_points;

  std::size_t size() const { return positions.size(); }
};

}  // namespace touchstone::realtime::mfs
