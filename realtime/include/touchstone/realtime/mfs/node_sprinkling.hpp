#pragma once
/// @file
/// Local node sprinkling (paper §4): when the tool touches the organ, nodes are
/// placed in the local domain Ω = organ ∩ ball(contact, L), each with a sphere of finite
/// radius, and each node gets its collocation rows. Works on any closed triangle surface.

#include "touchstone/geometry/contact_condition.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/local_surface.hpp"
#include "touchstone/realtime/mfs/node_cloud.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace touchstone::realtime::mfs {

enum class Layout : std::uint8_t {
  radial_shells,  ///< shells around the contact, spacing graded with distance (default)
  quasi_random,   ///< Halton points, same graded spacing
  lattice,        ///< a cubic lattice of uniform spacing
};

/// What holds the cut surface |x − c| = L.
enum class OuterCondition : std::uint8_t {
  clamped,         ///< u = 0 (default)
  traction_free,   ///< σn = 0 (a floating local domain; needs the tool to hold it)
};

/// The tool where it touches: a rigid flat punch of radius a pressed along d.
struct ToolContact {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< on the organ surface [m]
  Eigen::Vector3d direction{0.0, 0.0, -1.0};        ///< unit push direction
  double radius_m = 0.0025;                         ///< a
  geometry::ContactCondition condition = geometry::ContactCondition::frictionless;
};

struct SprinklingSettings {
  int node_count = 100;             ///< target N (the result is within a few per cent)
  double local_radius_m = 0.0125;   ///< L
  Layout layout = Layout::radial_shells;
  int ring_nodes = 8;               ///< nodes on each patch ring (a/2 and a); plus the tip node
  double radius_factor = 2.5;       ///< r_J = radius_factor × local spacing (interior)
  double boundary_radius_factor = 3.0;  ///< r_J on the surface and the cut (one-sided supports)
  OuterCondition outer = OuterCondition::clamped;
  /// Collocation points per node (about): 1 = square point collocation; > 1 adds extra points
  /// (the same sprinkling, denser) and K U = f is solved in the least-squares sense, which
  /// stabilises the traction rows (square collocation flips the sign of the tool stiffness as N
  /// changes, least squares does not).
  double oversampling = 3.0;
  /// The paper's tool (B4): one tool-tip node and no patch rings. The tip node carries the
  /// natural traction rows of a surface node; the model prescribes its parameters (eq. 7).
  bool tip_node_only = false;
  std::uint64_t seed = 1;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Places the nodes and their rows. Deterministic for a seed. Throws std::invalid_argument on
/// invalid settings or a contact point off the surface (by more than a/10).
NodeCloud sprinkle_nodes(const geometry::TriangleSurface& organ, const ToolContact& contact,
                         const SprinklingSettings& settings);

/// The enriched model's cloud: its MLS part carries only a smooth remainder (the punch fields
/// carry the rim), so the nodes are spread evenly instead of graded toward the patch edge, and
/// placed in one pass (no search for the spacing): a sunflower spiral on the organ surface
/// around the contact (the tip node first), a Fibonacci lattice on the cut sphere and Halton
/// points inside, each kept where it lies in the organ. Up to 25 % of the nodes on the surface
/// and 20 % on the cut; the interior points make up what those lose, so the cloud has exactly
/// `node_count` nodes unless the ball holds too little organ for them (the Halton sequence is
/// tried for 8× the interior count).
/// Throws std::invalid_argument for node_count outside [10, 5000] and for the contact
/// problems sprinkle_nodes names.
NodeCloud sprinkle_even_nodes(const geometry::TriangleSurface& organ, const ToolContact& contact, int node_count,
                              double local_radius_m, std::uint64_t seed = 1);
/// The same on a LocalSurface already made for this contact (reach ≥ L).
NodeCloud sprinkle_even_nodes(const LocalSurface& surface, const ToolContact& contact, int node_count,
                              double local_radius_m, std::uint64_t seed = 1);

}  // namespace touchstone::realtime::mfs
