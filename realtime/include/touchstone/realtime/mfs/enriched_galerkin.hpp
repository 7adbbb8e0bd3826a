#pragma once
/// @file
/// The enriched local model: MLS Galerkin plus the punch's own singular fields with free
/// amplitudes (the singular-function method: Fix, Gulati & Wakoff 1973; Olson, Georgiou &
/// Schultz 1991),
///
///   u_h = Σ_I N_I(x) u_I + Σ_m c_m ψ_m(x),
///
/// ψ_m the half-space punch fields of punch_field.hpp (normal; for a bonded tool also the two
/// tangential modes) in a frame on the rim plane of the actual patch. Smooth MLS functions
/// cannot carry the √ρ displacement and ρ^(−½) traction at the punch rim; the ψ_m carry them
/// exactly, and the MLS part is left with a smooth remainder that a few dozen nodes resolve.
///
/// The patch and the outer boundary are held by Lagrange multipliers, so the tool force is part
/// of the solution (the patch multiplier's resultant), not a post-processed traction:
/// - patch: λ = (λ₀ + λ₁ (r/a) cos φ + λ₂ (r/a) sin φ) / √(a² − r²), the normal component
///   only for a frictionless tool, all three for a bonded one;
/// - cut (and any clamped surface inside the ball): polynomials of degree ≤ 2 per component
///   plus σ(ψ_m)n, which the multiplier space must contain for the half-space solution to be
///   reproduced exactly.
///
/// The outer condition on the cut sphere (ExteriorCondition):
/// - clamped: u_h = 0, the paper's (the identical-domain benchmark);
/// - half_space: the exterior is the ψ part continued into the half-space: the MLS part vanishes
///   on the cut and the exterior energy ½ cᵀ K_ext c is added, K_ext,mn = −∮_cut ψ_m·σ(ψ_n)n dA
///   (n out of the ball). Exact for a half-space;
/// - body_aware: as half_space with K_ext from the actual organ (computed offline by the FEM,
///   read from an organ atlas).
///
/// Every ψ term is a boundary integral, because div σ(ψ) = 0: ∫_Ω ε(v):σ(ψ) dV = ∮_∂Ω v·σ(ψ)n dA
/// over the patch, the free surface, the cut and any clamped part. Only the MLS–MLS block needs
/// a volume quadrature (graded Gauss rules on rays from the contact, EnrichedSettings; it is
/// assembled through the gradient Gram matrix, gradient_gram.hpp), and the KKT system is solved
/// through a Cholesky factorisation of the augmented stiffness and a small Schur complement.

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/consistent_gradients.hpp"
#include "touchstone/realtime/mfs/local_surface.hpp"
#include "touchstone/geometry/material.hpp"
#include "touchstone/realtime/mfs/mls_shape_functions.hpp"
#include "touchstone/realtime/mfs/node_cloud.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/mfs/punch_field.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace touchstone::realtime::mfs {

/// What holds the local domain's cut sphere |x − c| = L.
enum class ExteriorCondition : std::uint8_t {
  clamped,     ///< u_h = 0 on the cut (the paper's local model)
  half_space,  ///< the exterior is the punch field continued into a half-space
  body_aware,  ///< the exterior stiffness of the actual organ, from an organ atlas (default)
};

std::string to_string(ExteriorCondition exterior);
/// "clamped" | "half_space" | "body_aware"; throws std::invalid_argument listing them.
ExteriorCondition exterior_condition_from_string(const std::string& name);

/// How the MLS part's volumetric energy λ ∫ (div u)² is integrated.
enum class VolumetricTerm : std::uint8_t {
  /// projected from ν = projected_volumetric_from_poisson_ratio on, full below (the default)
  automatic,
  full,  ///< as is, on the volume rule
  /// div of the MLS part projected (L2, on the volume rule) onto P ⊕ span{div ψ_m}, P the linear
  /// polynomials up to EnrichedSettings::volumetric_linear_space_up_to_nodes nodes and span{N_I}
  /// beyond: a few volumetric constraints instead of one per volume point, so the MLS part does
  /// not lock as ν → 0.5. With div ψ_m in the space the projection leaves the ψ–MLS coupling as
  /// it is, so the model's energy stays a sum of squares and half-space exactness holds.
  projected,
};

/// VolumetricTerm::automatic projects from this Poisson's ratio on: close to incompressibility the
/// full term locks the MLS part, while further from it the projection changes the force by less
/// than the model's own error and costs build time (figures: docs/enriched_model.md).
constexpr double projected_volumetric_from_poisson_ratio = 0.475;

struct EnrichedSettings {
  ExteriorCondition exterior = ExteriorCondition::body_aware;
  /// Support radius r_J = the distance to the node's support_neighbours-th nearest node.
  int support_neighbours = 12;
  /// Then each quadrature point must see this many nodes: the supports of its nearest nodes are
  /// grown just enough (locally; a global growth would couple far nodes and lock).
  int min_point_neighbours = 14;
  /// Quadrature of the MLS–MLS block (rays from the contact point, graded toward the tool).
  /// These counts and the cut's are for N ≤ 40: build_local_model grows their angular counts as
  /// ∛(N/40) beyond, and the radial count in the same proportion beyond 60 nodes (finer shape
  /// functions need finer quadratures). 0 picks the count by the gradient correction
  /// (settings_for_material()): 6 × 6 × 12 with corrected gradients, 8 × 8 × 16 without.
  int volume_radial_points = 0, volume_polar_points = 0, volume_azimuth_points = 0;
  /// The volume rule's shells within this many tool radii of the contact point (on a ray of
  /// full length L) take half the polar and azimuthal counts; 0: every shell takes the full
  /// counts. Coarsening further out costs accuracy (docs/enriched_model.md, "The inner shells
  /// of the volume rule").
  double volume_coarse_within_tool_radii = 1.25;
  /// Boundary quadratures of every ψ term and of the multipliers.
  int patch_radial_points = 6, patch_angular_points = 12;
  int free_radial_points = 6, free_azimuth_points = 16;
  /// The cut sphere's rule (polar, azimuthal; N ≤ 40). 0 picks it like the volume rule: 6 × 12
  /// with corrected gradients, 8 × 16 without (near incompressibility the coarser cut rule
  /// softens the projected model past the force target; docs/enriched_model.md, "The cut rule").
  int cut_polar_points = 0, cut_azimuth_points = 0;
  /// Degree of the polynomial multipliers on the cut (per component, plus σ(ψ_m)n); −1 picks it
  /// from N (cut_multiplier_degree()).
  int cut_multiplier_degree = -1;
  /// A bonded patch holds the normal displacement's even Chebyshev mode T₂(r/a)/√(a² − r²) too
  /// (a dome of the face) from this many nodes on; fewer nodes cannot hold it without locking.
  int bonded_patch_dome_from_nodes = 50;
  /// The MLS part's volumetric term λ ∫ (div u)² (VolumetricTerm).
  VolumetricTerm volumetric = VolumetricTerm::automatic;
  /// The projected term's space holds the linear polynomials (4 constraints) up to this many
  /// nodes and the nodes' own functions (N constraints) beyond: few nodes make nearly global
  /// shape functions, which N constraints lock; many nodes make local ones, whose divergence a
  /// global polynomial cannot hold, so they come out too soft.
  int volumetric_linear_space_up_to_nodes = 60;
  /// Correct the MLS gradients on the volume rule to its integration constraints
  /// (consistent_gradients.hpp), so that a coarser volume rule keeps the model's accuracy.
  /// automatic: linear while the MLS part's volumetric term is integrated in full, none where it
  /// is projected (near incompressibility the coarse corrected rule misses the displacement
  /// target, and the finer uncorrected one meets it; docs/enriched_model.md).
  GradientCorrection gradient_correction = GradientCorrection::automatic;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// The volume rule's counts (radial, polar, azimuthal) and the cut's (polar, azimuthal), for
/// N ≤ 40, that a count of 0 picks.
constexpr int corrected_volume_rule[3] = {6, 6, 12};
constexpr int uncorrected_volume_rule[3] = {8, 8, 16};
constexpr int corrected_cut_rule[2] = {6, 12};
constexpr int uncorrected_cut_rule[2] = {8, 16};

/// Whether the MLS part's volumetric term is projected for this material (VolumetricTerm).
bool volumetric_term_projected(const EnrichedSettings& settings, const geometry::Material& material);

/// The settings a build uses for `material`: the automatic choices made (the volumetric term,
/// the gradient correction, and the volume and cut rules' counts left at 0). enriched_quadratures() and
/// build_enriched_model() take only settings made this way.
EnrichedSettings settings_for_material(EnrichedSettings settings, const geometry::Material& material);

/// The quadrature counts for a cloud of node_count nodes: finer shape functions need finer
/// quadratures (under-integrating the MLS–MLS block, or the cut's multipliers, makes the model
/// too soft as N grows with the counts fixed), so the volume rule's and the cut's angular counts
/// grow as ∛(N/40) beyond 40 nodes, and the volume rule's radial count beyond 60.
EnrichedSettings quadratures_for_node_count(EnrichedSettings settings, std::size_t node_count);

/// The boundary pieces of the local domain Ω = organ ∩ ball(c, L), with per-point data the
/// multipliers need. Patch and free surface are parametrised by the distance r from the tool
/// axis, so the rim r = a is exactly where ψ is singular.
struct EnrichedQuadratures {
  PatchQuadrature volume, patch, free_surface, cut, clamped;
  std::vector<double> patch_radius_m, patch_azimuth_rad;  ///< r and φ of each patch point in the punch frame
  double local_radius_m = 0;  ///< L, the radius of the ball the rules cover
};

/// The assembled and solved enriched model for the three unit tool translations.
struct EnrichedModel {
  PunchFrame frame;
  std::vector<PunchMode> modes;  ///< the enrichment fields (enrichment_modes())
  ExteriorCondition exterior = ExteriorCondition::clamped;
  /// K_ext [N/m] in mode order, then the cut's shift if any: the exterior energy ½ cᵀ K_ext c
  /// (zero for clamped).
  Eigen::MatrixXd exterior_stiffness_N_per_m;
  /// The cut carries a rigid shift t (three unknowns after the amplitudes, along the frame's
  /// e₃, e₁, e₂ [m per m of tool displacement]): an organ atlas with cut translations.
  bool cut_translations = false;
  /// The MLS part's volumetric term was projected (VolumetricTerm), onto which space: "linear"
  /// or "nodal" ("" when not projected).
  bool volumetric_projected = false;
  std::string volumetric_space;
  /// The response to U_tool = e_x, e_y, e_z: nodal parameters, amplitudes, then the cut's shift
  /// ((3N + m (+ 3)) × 3), and the tool force on the tissue (the patch multiplier's resultant) [N/m].
  Eigen::MatrixXd unit_response;
  Eigen::Matrix3d tool_stiffness_N_per_m = Eigen::Matrix3d::Zero();
  /// The resultant of the cut's (and clamped surfaces') multipliers per unit U_tool [N/m]:
  /// balances the tool force when the cut is clamped.
  Eigen::Matrix3d cut_reaction_N_per_m = Eigen::Matrix3d::Zero();
  /// The full stiffness over (u_I, c_m, t) including K_ext: the energy is ½ xᵀ K x.
  Eigen::MatrixXd stiffness;
  /// Diagnostics: counts, conditioning, and what the enrichment carries.
  int volume_points = 0, boundary_points = 0, mls_evaluations = 0, multipliers = 0;
  /// Nodes seen per volume point, averaged over the volume rule. Near N the MLS part is dense
  /// and its assembly costs (volume points) × N², whatever is done per point.
  double mean_volume_point_nodes = 0;
  /// The MLS–MLS block's dense products over what the points' own node sets need
  /// (GradientGram::product_overhead): the price of batching nearby points over the union of
  /// their nodes, small where every point sees nearly every node, large on big clouds.
  double gram_product_overhead = 0;
  double min_rcond = 1, max_support_scale = 1;
  double kkt_relative_residual = 0;
  /// The part of the integration-constraint residuals the gradient correction could not remove,
  /// relative to their largest (correct_gradients(); 0 without a correction).
  double gradient_correction_left = 0;
  /// The correction the build applied (none or linear), and its volume and cut rules' counts
  /// for N ≤ 40.
  GradientCorrection gradient_correction = GradientCorrection::none;
  int volume_rule[3] = {0, 0, 0};
  int cut_rule[2] = {0, 0};
  /// Where the build's time went [s]: the supports and the volume rule (MLS gradients, their
  /// correction, the MLS–MLS block and the projected volumetric term), the boundary rules with
  /// the ψ blocks and the constraint rows, and the KKT solve.
  double volume_s = 0, boundary_s = 0, solve_s = 0;
  std::string status = "ok";
  bool ok() const { return status == "ok"; }
};

/// The enrichment fields for a contact: the normal mode alone for a frictionless tool pushing
/// along the patch normal; otherwise the three translations and the two tilts, and for a bonded
/// tool the radial mode (shear with a flat face) too. "Along the normal" is within an angle θ
/// with θ ≤ 1° and θ²(L/a)³ ≤ 0.04 (what 1° gives at L = 5a): a tool pushed θ off the normal
/// tilts its face against the patch, and without the tilt modes the MLS part must hold that
/// tilt, which stiffens the model as θ²(L/a)³ (a fine tip in a ball of the usual size).
std::vector<PunchMode> enrichment_modes(const ToolContact& contact, const PunchFrame& frame, double local_radius_m);

/// How many of `modes` are punch translations (they come first; an organ atlas holds their
/// exterior stiffness).
int translation_mode_count(const std::vector<PunchMode>& modes);

/// The cut multipliers' polynomial degree for a cloud of node_count nodes: the setting, or for
/// −1: 1 below 40 nodes, 2 up to 120, 3 beyond.
int cut_multiplier_degree(const EnrichedSettings& settings, std::size_t node_count);

/// Support radii for the enriched model: r_J = distance to the k-th nearest node, then grown
/// locally so that every point of `points` sees at least min_neighbours nodes: a point that sees
/// fewer under the k-nearest radii grows its min_neighbours nearest nodes to cover it. The
/// result does not depend on the order of the points.
std::vector<double> enriched_support_radii(const std::vector<Eigen::Vector3d>& nodes,
                                           const std::vector<const PatchQuadrature*>& points,
                                           int support_neighbours, int min_neighbours);

/// The quadratures of the enriched model on the organ near the contact (patch and free surface
/// found along the tool axis; the cut sphere and the volume by rays from the contact, graded
/// toward the tool; clamped parts inside the ball from `clamped`, which may be empty). Also sets the punch frame: origin at the centre of
/// the patch's rim circle, e₃ = the organ's inward normal at the contact (not the push direction). Fails (status) when the tool axis misses the
/// organ near the contact, e.g. at an organ edge.
bool enriched_quadratures(const LocalSurface& surface, const ToolContact& contact, double local_radius_m,
                          const EnrichedSettings& settings, const PatchQuadrature& clamped, EnrichedQuadratures& out,
                          PunchFrame& frame, std::string& failure);

/// Assembles and solves the model. `cloud` supplies positions (its radii are replaced by
/// enriched_support_radii); `exterior_stiffness_N_per_m` is required for body_aware (t × t in
/// mode order over the t = translation_mode_count() translations; the radial and tilt modes'
/// exterior terms are the half-space's) and ignored otherwise. A (t + 3) × (t + 3) matrix also
/// holds the cut translations (organ_atlas.hpp): the model then gains three unknowns, a rigid
/// shift of the trace on the cut along the frame's e₃, e₁, e₂, which the MLS part takes on there
/// and the exterior's energy prices (they follow the mode amplitudes in the unknowns).
EnrichedModel build_enriched_model(NodeCloud& cloud, const geometry::Material& material, const ToolContact& contact,
                                   const EnrichedQuadratures& quadratures, const PunchFrame& frame,
                                   const EnrichedSettings& settings, const MlsSettings& mls,
                                   const Eigen::MatrixXd* exterior_stiffness_N_per_m = nullptr);

/// The half-space exterior stiffness −∮_cut ψ_m·σ(ψ_n)n dA [N/m] on a cut quadrature (n out
/// of the ball), symmetrised.
Eigen::MatrixXd half_space_exterior_stiffness(const std::vector<PunchMode>& modes, const PunchFrame& frame,
                                              double radius_m, const geometry::Material& material, const PatchQuadrature& cut);

/// u_h at x from the parameters (3N nodal values, then the m amplitudes). Returns the MLS status.
MlsStatus enriched_displacement(const NodeCloud& cloud, const EnrichedModel& model, double radius_m,
                                const geometry::Material& material, const MlsSettings& mls, const Eigen::VectorXd& parameters,
                                const Eigen::Vector3d& x, MlsEvaluation& scratch, Eigen::Vector3d& u) noexcept;

}  // namespace touchstone::realtime::mfs
