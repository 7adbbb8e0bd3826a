#pragma once
/// @file
/// The local MFS model of one contact (paper §4): sprinkle the nodes, assemble the collocation
/// system, factorise it once, and condense it to the 3×3 tool stiffness K_t. The model is
/// linear in the tool displacement U_tool, so one build serves every
/// U_tool until the contact moves: F = K_t U_tool is exact for the model, nine multiply-adds.
///
/// Model/data split: LocalModel is built once per contact and then only read; LocalSolution is
/// what one tool displacement produces.

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/clamped_surface.hpp"
#include "touchstone/realtime/mfs/collocation.hpp"
#include "touchstone/realtime/mfs/enriched_galerkin.hpp"
#include "touchstone/realtime/mfs/galerkin.hpp"
#include "touchstone/realtime/mfs/linear_solvers.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/mfs/organ_atlas.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace touchstone::realtime::mfs {

/// The four force extractions. They differ at finite N and must agree as N grows.
enum class ForceMethod : std::uint8_t {
  /// (a) ∫_patch σ(u_h) n dA, evaluated in its domain form ∫_Ω σ(u_h) ∇w dV (w = 1 on the
  /// patch, 0 on the cut: extraction_quadrature). The surface form is reported too
  /// (ToolForces::traction_surface_N); it does not converge at the singular punch edge.
  traction_integral,
  reaction,           ///< (b) −∫_cut σ(u_h) n dA: equilibrium of the local domain
  energy,             ///< (c) F·U_tool = 2U, U = ½∫_Ω σ:ε dV: the component along U_tool only
  /// (d) the paper's partition force, eq. 9, rows scaled by the patch nodes' shares: collocation —
  /// each patch node's traction row × its tributary area; Galerkin — each patch node's elastic
  /// row (K_el U)_a = ∫_patch h_a λ dA (a force already) × s_a, where Σ_a s_a h_a ≈ 1 on the
  /// patch (least squares; s_a = 1 for interpolating shape functions: the FEM's reaction).
  paper_partition,
};

std::string to_string(ForceMethod method);

/// Quadrature resolution of the force extractions.
struct ForceSettings {
  int patch_radial_points = 16, patch_angular_points = 32;
  int cut_polar_points = 24, cut_azimuth_points = 48;
  int volume_radial_points = 32, volume_polar_points = 24, volume_azimuth_points = 32;
  /// The method that defines K_t (the haptic force). Energy is not linear in U_tool: not allowed;
  /// reaction needs `reaction` on, traction_integral needs `traction` on.
  ForceMethod haptic_method = ForceMethod::reaction;
  /// Compute the reaction (a cut-surface quadrature) and the energy force (a volume
  /// quadrature): tens of milliseconds, for studies, not for the model loop.
  bool reaction = true;
  bool energy = true;
  /// Compute the traction integral's domain form (a shell of ~9k quadrature points); a scene
  /// whose haptic force is the reaction can skip it. Off, its map is zero.
  bool traction = true;
  /// The shell of the traction integral's domain form: inner = extraction_inner_tool_radii × a,
  /// outer = extraction_outer_local_radii × L; w goes from 1 to 0 across it. Inner > 1 keeps the
  /// shell off the punch edge; outer < 1 keeps it off the cut.
  double extraction_inner_tool_radii = 1.5, extraction_outer_local_radii = 0.8;
  int extraction_radial_points = 8, extraction_polar_points = 24, extraction_azimuth_points = 48;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// How the equations are written on the nodes.
enum class Formulation : std::uint8_t {
  collocation,  ///< strong form at points (the paper; square or least squares): fast, not convergent on the punch
  galerkin,     ///< weak form with penalty or Nitsche constraints (De & Bathe's MFS): converges from above, slowly
  /// weak form enriched with the punch's singular fields, multipliers on the patch and the cut,
  /// and an exterior condition (enriched_galerkin.hpp): the default
  enriched,
};

std::string to_string(Formulation formulation);

struct LocalModelSettings {
  /// The enriched weak form by default: the punch's own singular fields carry the rim, so a few
  /// dozen nodes suffice; Galerkin and collocation (the paper's) stay selectable.
  Formulation formulation = Formulation::enriched;
  SprinklingSettings sprinkling;
  CollocationSettings collocation;
  /// Galerkin only: penalty; its MLS settings are collocation.mls. K is dense and factorised by
  /// LDLT (the solver settings apply to collocation).
  GalerkinSettings galerkin;
  /// Enriched only: its exterior condition, supports and quadratures (its MLS settings are
  /// collocation.mls; sprinkling.node_count, local_radius_m and seed place its nodes).
  EnrichedSettings enriched;
  SolverSettings solver;
  ForceSettings force;
  /// The paper's model (B4, paper eqs. 7–9 literally): one tool-tip node whose nodal parameters
  /// are set to U_tool (MLS does not interpolate: this is not u_h = U_tool), the natural
  /// traction rows of the tip as the "force", square collocation. Overrides tip_node_only.
  bool paper_mode = false;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// The paper-faithful setup of B4: 34 nodes, linear basis, one tip node, LU.
LocalModelSettings paper_settings();

/// The haptic force method that suits a formulation: the reaction for the weak form (its
/// constraint force, which balances the cut exactly); for collocation (whose reaction on the cut
/// is off by hundreds of per cent) and the paper's model, the paper's partition force (eq. 9) —
/// cheap, where the traction integral's domain form costs a shell quadrature of thousands of
/// points.
ForceMethod default_haptic_method(Formulation formulation, bool paper_mode);

/// Wall times of a build [s].
struct BuildTimes {
  double sprinkle_s = 0, assembly_s = 0, factorize_s = 0, condense_s = 0, total_s = 0;
  /// The traction integral's shell when it is only a diagnostic (not the haptic method):
  /// computed after the model is ready and not part of total_s.
  double diagnostics_s = 0;
};

/// Where the body-aware exterior stiffness comes from: given the contact, L and the material,
/// fills K_ext [N/m] (m × m in the enrichment's mode order, or (m + 3) × (m + 3) with the cut's
/// rigid shift after them: build_enriched_model) or says why it cannot (e.g. no organ
/// atlas sample near the contact). An organ atlas provides one.
using ExteriorStiffnessSource =
    std::function<bool(const ToolContact& contact, double local_radius_m, const geometry::Material& material, int modes,
                       Eigen::MatrixXd& exterior_stiffness_N_per_m, std::string& why_not)>;

/// The exterior stiffness an organ atlas gives: lookup_exterior_stiffness at the contact (its
/// point, push direction, a, L and material); no answer (no sample nearby, other parameters, the
/// normal mode only for a bonded tool) says why, and the model falls back to the half-space.
/// A null atlas gives an empty source.
ExteriorStiffnessSource exterior_from_atlas(std::shared_ptr<const OrganAtlas> atlas);

struct LocalModel {
  geometry::Material material;
  LocalModelSettings settings;
  ToolContact contact;
  NodeCloud cloud;
  CollocationSystem system;   ///< collocation only
  CollocationSolver solver;   ///< collocation only
  GalerkinSystem galerkin;    ///< Galerkin only
  EnrichedModel enriched;     ///< enriched only; unit_response rows are then 3N nodal values and the m amplitudes
  /// Enriched only: the exterior the model used (body_aware falls back to half_space when its
  /// source has no answer for this contact) and, then, why.
  std::string exterior_used, exterior_note;
  /// Nodal parameters for U_tool = e_x, e_y, e_z (3N × 3) and for the loads alone (3N).
  Eigen::MatrixXd unit_response;
  Eigen::VectorXd load_response;
  /// Force maps U ↦ F (3 × 3N) of the linear methods: traction integral (domain form), its
  /// surface form ∫_patch σ(u_h) n dA, reaction, paper.
  Eigen::Matrix<double, 3, Eigen::Dynamic> traction_map, traction_surface_map, reaction_map, paper_map;
  PatchQuadrature volume;  ///< energy quadrature (empty when ForceSettings::energy is off)
  /// Quadrature points of the clamped surface inside the ball (0: none reached, or none given).
  int clamped_points = 0;
  /// False when the traction integral's shell would reach a clamped surface (its cutoff must
  /// vanish on every fixed boundary but the patch): traction_map is then zero, not a force.
  bool traction_available = true;
  /// K_t [N/m]: F = K_t U_tool + F_loads, by the haptic method.
  Eigen::Matrix3d tool_stiffness_N_per_m = Eigen::Matrix3d::Zero();
  Eigen::Vector3d load_force_N = Eigen::Vector3d::Zero();
  /// Paper mode: the tip node and its raw eq. 9 "force" map (traction rows, [Pa] per m).
  int tip_node = -1;
  double tip_tributary_area_m2 = 0;
  BuildTimes times;
  /// "ok", or why the model cannot be used (shape functions, singular K, a quadrature point
  /// outside every support). Never NaN forces: a failed model has status != "ok".
  std::string status = "ok";
  bool ok() const { return status == "ok"; }
};

/// A local model's normal stiffness d·K_t·d along its push direction d, as a multiple of the
/// frictionless flat punch's on a half-space, 2Ea/(1 − ν²). A rigid flat punch on a body whose
/// clamped or free boundaries lie at least 2a away is within a small factor of it (of the
/// benchmark bodies the ball clamped at L = 5a is the stiffest, and it stays under 2×; bonded
/// tools are about as stiff as frictionless ones): outside
/// [plausible_stiffness_ratio_min, plausible_stiffness_ratio_max] it is the model that is wrong,
/// not the tissue. NaN for a model without a stiffness.
double stiffness_ratio_to_half_space(const LocalModel& model);
constexpr double plausible_stiffness_ratio_min = 0.25, plausible_stiffness_ratio_max = 4.0;

/// The node cloud build_local_model places for `settings` (paper mode: the tip node, first,
/// and no patch rings; Galerkin: no extra collocation points), without building anything else:
/// milliseconds. The paper's tip spacing cloud.spacing[0] is eq. 9's tributary radius s.
NodeCloud sprinkle_local_nodes(const geometry::TriangleSurface& organ, const ToolContact& contact,
                               const LocalModelSettings& settings);

/// Builds the local model of `contact` on `organ`. `clamped`: parts of the organ surface held
/// at u = 0 (Galerkin only; a collocation model whose ball reaches them fails with a status).
/// Throws std::invalid_argument for invalid settings, material, contact or clamped surface
/// (naming the field); numerical failures end in `status`.
LocalModel build_local_model(const geometry::TriangleSurface& organ, const ToolContact& contact,
                             const geometry::Material& material, const LocalModelSettings& settings,
                             const ClampedSurface& clamped = {}, const ExteriorStiffnessSource& exterior = {});

/// Forces on the tissue from the tool [N] (the tool feels the opposite).
struct ToolForces {
  Eigen::Vector3d traction_integral_N = Eigen::Vector3d::Zero();  ///< (a), domain form
  /// (a) in its surface form, ∫_patch σ(u_h) n dA on the patch quadrature: a diagnostic of how
  /// much of the edge stress the field resolves.
  Eigen::Vector3d traction_surface_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d reaction_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d paper_partition_N = Eigen::Vector3d::Zero();
  double energy_J = 0;
  /// 2U/|U_tool| [N]: the force component along U_tool by energy (NaN-free: 0 if U_tool = 0).
  double energy_force_N = 0;
  /// Paper mode only: eq. 9's f_tip in the units of the tip's rows (traction, [Pa]).
  Eigen::Vector3d paper_tip_residual_Pa = Eigen::Vector3d::Zero();
  Eigen::Vector3d haptic_N = Eigen::Vector3d::Zero();  ///< K_t U_tool + F_loads
};

struct LocalSolution {
  Eigen::VectorXd parameters;  ///< u_J (3N) [m]
  ToolForces forces;
  double solve_s = 0, force_s = 0;
  std::string status = "ok";
};

/// The response to a tool displacement U_tool [m] (a combination of the stored unit responses:
/// no new solve).
LocalSolution solve_local_model(const LocalModel& model, const Eigen::Vector3d& tool_displacement_m);

/// u_h at arbitrary points (probes, surface vertices) [m]; false if a point is outside every
/// support (its u is left zero).
bool displacement_at(const LocalModel& model, const Eigen::VectorXd& parameters,
                     const std::vector<Eigen::Vector3d>& points, std::vector<Eigen::Vector3d>& displacement_m);

}  // namespace touchstone::realtime::mfs
