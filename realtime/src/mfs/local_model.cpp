// The local model around a contact: sprinkle, build the chosen formulation, condense onto the
// tool (K_t), and the paper's eqs. 7-9 in paper mode (one concept: the formulations' common path).
#include "touchstone/realtime/mfs/local_model.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SparseLU>

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

const char* to_string(MlsStatus status) {
  switch (status) {
    case MlsStatus::ok: return "ok";
    case MlsStatus::too_few_nodes: return "too_few_nodes";
    case MlsStatus::singular_moments: return "singular_moments";
    case MlsStatus::non_finite_input: return "non_finite_input";
  }
  return "unknown";
}

/// The paper's force in newtons (collocation rows are residuals, not forces): each patch node's
/// traction rows scaled by its tributary area — the traction map on a nodal quadrature of the
/// patch.
bool patch_node_map(const NodeCloud& cloud, const geometry::Material& material, const MlsSettings& mls,
                    const PatchQuadrature& patch, Eigen::Matrix<double, 3, Eigen::Dynamic>& map) {
  PatchQuadrature nodes;
  const std::vector<double> area = tributary_areas(cloud, patch);
  for (std::size_t j = 0; j < cloud.size(); ++j)
    if (cloud.kinds[j] == NodeKind::tool_patch) {
      nodes.points.push_back(cloud.positions[j]);
      nodes.normals.push_back(cloud.normals[j]);
      nodes.weights.push_back(area[j]);
    }
  return surface_traction_map(cloud, material, mls, nodes, map);
}

/// The force map that defines K_t (ForceSettings::haptic_method).
const Eigen::Matrix<double, 3, Eigen::Dynamic>& haptic_map(const LocalModel& model) {
  switch (model.settings.force.haptic_method) {
    case ForceMethod::reaction: return model.reaction_map;
    case ForceMethod::paper_partition: return model.paper_map;
    default: return model.traction_map;
  }
}

/// Paper eq. 8 with the tip dofs a = 3t…3t+2: U_b = −K_bb⁻¹ K_ba U_a for U_a = e_x, e_y, e_z.
/// K is square here (paper mode never oversamples).
bool condense_tip(const CollocationSystem& system, int tip, Eigen::MatrixXd& unit_response, std::string& failure) {
  const Eigen::Index n = system.stiffness.cols();
  std::vector<Eigen::Index> other;  // b: every dof but the tip's
  std::vector<Eigen::Index> position(n, -1);
  for (Eigen::Index k = 0; k < n; ++k)
    if (k / 3 != tip) {
      position[k] = static_cast<Eigen::Index>(other.size());
      other.push_back(k);
    }
  const Eigen::Index m = static_cast<Eigen::Index>(other.size());
  std::vector<Eigen::Triplet<double>> bb;
  Eigen::MatrixXd ba = Eigen::MatrixXd::Zero(m, 3);
  for (Eigen::Index r = 0; r < system.stiffness.rows(); ++r) {
    if (r / 3 == tip) continue;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(system.stiffness, r); it; ++it) {
      if (it.col() / 3 == tip)
        ba(position[r], it.col() - 3 * tip) = it.value();
      else
        bb.emplace_back(position[r], position[it.col()], it.value());
    }
  }
  Eigen::SparseMatrix<double> k_bb(m, m);
  k_bb.setFromTriplets(bb.begin(), bb.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(k_bb);
  if (lu.info() != Eigen::Success) {
    failure = "K_bb is singular (paper eq. 7): " + lu.lastErrorMessage();
    return false;
  }
  const Eigen::MatrixXd u_b = -lu.solve(ba);
  const double residual = (k_bb * u_b + ba).norm() / std::max(ba.norm(), 1e-300);
  if (!u_b.allFinite() || !(residual < 1e-6)) {
    failure = "K_bb is singular or too ill-conditioned (paper eq. 7): relative residual " + std::to_string(residual);
    return false;
  }
  unit_response.setZero(n, 3);
  unit_response.block<3, 3>(3 * tip, 0).setIdentity();
  for (Eigen::Index k = 0; k < m; ++k) unit_response.row(other[k]) = u_b.row(k);
  return true;
}

}  // namespace

std::string to_string(Formulation formulation) {
  switch (formulation) {
    case Formulation::collocation: return "collocation";
    case Formulation::galerkin: return "galerkin";
    case Formulation::enriched: return "enriched";
  }
  return "unknown";
}

std::string to_string(ForceMethod method) {
  switch (method) {
    case ForceMethod::traction_integral: return "traction_integral";
    case ForceMethod::reaction: return "reaction";
    case ForceMethod::energy: return "energy";
    case ForceMethod::paper_partition: return "paper_partition";
  }
  return "unknown";
}

void ForceSettings::validate() const {
  const auto check = [](const char* field, int value, int low, int high) {
    if (value < low || value > high)
      throw std::invalid_argument(std::string("ForceSettings.") + field + " = " + std::to_string(value) + " must be in [" +
                                  std::to_string(low) + ", " + std::to_string(high) + "]");
  };
  check("patch_radial_points", patch_radial_points, 2, 128);
  check("patch_angular_points", patch_angular_points, 4, 512);
  check("cut_polar_points", cut_polar_points, 2, 256);
  check("cut_azimuth_points", cut_azimuth_points, 4, 512);
  check("volume_radial_points", volume_radial_points, 2, 128);
  check("volume_polar_points", volume_polar_points, 2, 256);
  check("volume_azimuth_points", volume_azimuth_points, 4, 512);
  check("extraction_radial_points", extraction_radial_points, 2, 64);
  check("extraction_polar_points", extraction_polar_points, 2, 256);
  check("extraction_azimuth_points", extraction_azimuth_points, 4, 512);
  if (!(extraction_inner_tool_radii > 1) || !std::isfinite(extraction_inner_tool_radii))
    throw std::invalid_argument("ForceSettings.extraction_inner_tool_radii = " + std::to_string(extraction_inner_tool_radii) +
                                " must be > 1 (the cutoff must be 1 on the whole tool patch)");
  if (!(extraction_outer_local_radii > 0 && extraction_outer_local_radii < 1))
    throw std::invalid_argument("ForceSettings.extraction_outer_local_radii = " +
                                std::to_string(extraction_outer_local_radii) +
                                " must be in (0, 1) (the cutoff must vanish before the cut)");
  if (haptic_method == ForceMethod::energy)
    throw std::invalid_argument("ForceSettings.haptic_method = energy: the energy force is not linear in U_tool");
  if (haptic_method == ForceMethod::reaction && !reaction)
    throw std::invalid_argument("ForceSettings.haptic_method = reaction needs ForceSettings.reaction = true");
  if (haptic_method == ForceMethod::traction_integral && !traction)
    throw std::invalid_argument("ForceSettings.haptic_method = traction_integral needs ForceSettings.traction = true");
}

void LocalModelSettings::validate() const {
  if (formulation == Formulation::enriched) {
    // The enriched model places its own nodes and quadratures; its force is the patch
    // multiplier's resultant, so the extraction settings do not apply.
    if (paper_mode) throw std::invalid_argument("paper_mode with formulation = enriched: the paper's model is point collocation");
    if (sprinkling.node_count < 10 || sprinkling.node_count > 5000)
      throw std::invalid_argument("SprinklingSettings.node_count = " + std::to_string(sprinkling.node_count) +
                                  " must be in [10, 5000] for formulation = enriched");
    if (!(sprinkling.local_radius_m > 0) || !std::isfinite(sprinkling.local_radius_m))
      throw std::invalid_argument("SprinklingSettings.local_radius_m = " + std::to_string(sprinkling.local_radius_m) +
                                  " must be finite and > 0");
    if (!(collocation.mls.max_support_scale >= 1 && collocation.mls.max_support_scale <= 4))
      throw std::invalid_argument("MlsSettings.max_support_scale = " + std::to_string(collocation.mls.max_support_scale) +
                                  " must be in [1, 4]");
    enriched.validate();
    // Its haptic force is always the patch multiplier's resultant; the energy never is a force map.
    if (force.haptic_method == ForceMethod::energy)
      throw std::invalid_argument("ForceSettings.haptic_method = energy: the energy force is not linear in U_tool");
    return;
  }
  sprinkling.validate();
  force.validate();
  const auto finite_non_negative = [](const char* field, double value) {
    if (!std::isfinite(value) || value < 0)
      throw std::invalid_argument(std::string("CollocationSettings.") + field + " = " + std::to_string(value) +
                                  " must be finite and >= 0");
  };
  finite_non_negative("neumann_stabilization", collocation.neumann_stabilization);
  finite_non_negative("boundary_row_weight", collocation.boundary_row_weight);
  if (!(collocation.boundary_row_weight > 0))
    throw std::invalid_argument("CollocationSettings.boundary_row_weight = 0: boundary rows would vanish");
  if (!(collocation.mls.max_support_scale >= 1 && collocation.mls.max_support_scale <= 4))
    throw std::invalid_argument("MlsSettings.max_support_scale = " + std::to_string(collocation.mls.max_support_scale) +
                                " must be in [1, 4]");
  galerkin.validate();
  if (paper_mode && formulation == Formulation::galerkin)
    throw std::invalid_argument("paper_mode with formulation = galerkin: the paper's model is point collocation");
  if (formulation == Formulation::galerkin && sprinkling.outer == OuterCondition::traction_free)
    throw std::invalid_argument(
        "SprinklingSettings.outer = traction_free with formulation = galerkin: the weak form clamps the cut (u = 0); "
        "use formulation = collocation for a traction-free cut");
  if (formulation == Formulation::galerkin && !force.reaction)
    throw std::invalid_argument("ForceSettings.reaction = false with formulation = galerkin: the tool force is the reaction");
  if (paper_mode && sprinkling.oversampling > 1)
    throw std::invalid_argument("paper_mode with sprinkling.oversampling = " + std::to_string(sprinkling.oversampling) +
                                ": the paper's partition (eq. 7) needs square collocation");
}

LocalModelSettings paper_settings() {
  LocalModelSettings s;
  s.formulation = Formulation::collocation;
  s.paper_mode = true;
  s.sprinkling.node_count = 34;
  s.sprinkling.oversampling = 1;
  s.collocation.mls.basis = Basis::linear;
  s.solver.kind = SolverKind::dense_lu;
  s.force.haptic_method = default_haptic_method(s.formulation, s.paper_mode);
  return s;
}

ForceMethod default_haptic_method(Formulation formulation, bool paper_mode) {
  if (paper_mode) return ForceMethod::paper_partition;
  // The enriched model's patch multiplier is the contact traction: its resultant is (a).
  if (formulation == Formulation::enriched) return ForceMethod::traction_integral;
  return formulation == Formulation::galerkin ? ForceMethod::reaction : ForceMethod::paper_partition;
}

namespace {

/// The shell of the traction integral's domain form (ForceSettings::extraction_*).
PatchQuadrature force_extraction_shell(const geometry::TriangleSurface& organ, const ToolContact& contact,
                                       const LocalModelSettings& settings) {
  const ForceSettings& f = settings.force;
  const double inner = f.extraction_inner_tool_radii * contact.radius_m,
               outer = f.extraction_outer_local_radii * settings.sprinkling.local_radius_m;
  return extraction_quadrature(organ, contact, inner, outer, f.extraction_radial_points, f.extraction_polar_points,
                               f.extraction_azimuth_points);
}

/// The clamped surface inside the ball, resolved to a sixteenth of L.
PatchQuadrature clamped_inside_ball(const geometry::TriangleSurface& organ, const ToolContact& contact,
                                    const LocalModelSettings& settings, const ClampedSurface& clamped) {
  if (clamped.empty()) return {};
  const double length = settings.sprinkling.local_radius_m;
  return clamped_quadrature(clamped, organ.project(contact.point).point, length, length / 16);
}

/// The traction integral's cutoff must vanish on every fixed boundary but the patch: false when
/// a clamped point lies inside the shell's outer radius.
bool shell_clear_of(const PatchQuadrature& clamped, const geometry::TriangleSurface& organ, const ToolContact& contact,
                    const LocalModelSettings& settings) {
  const Eigen::Vector3d centre = organ.project(contact.point).point;
  const double outer = settings.force.extraction_outer_local_radii * settings.sprinkling.local_radius_m;
  for (const Eigen::Vector3d& x : clamped.points)
    if ((x - centre).norm() < outer) return false;
  return true;
}

const char* const traction_failure = "a point of the traction integral's extraction shell is outside every support";

/// The traction integral's map (zero when unavailable: switched off, or the shell would reach a
/// clamped surface). False when a shell point is outside every support.
bool traction_map(const geometry::TriangleSurface& organ, LocalModel& model) {
  if (!model.traction_available) {
    model.traction_map.setZero(3, 3 * static_cast<Eigen::Index>(model.cloud.size()));
    return true;
  }
  return surface_traction_map(model.cloud, model.material, model.settings.collocation.mls,
                              force_extraction_shell(organ, model.contact, model.settings), model.traction_map);
}

/// The traction integral as a diagnostic, after the model is ready: timed apart, and a failure
/// marks it unavailable instead of failing the model.
void diagnostic_traction_map(const geometry::TriangleSurface& organ, LocalModel& model) {
  const auto start = std::chrono::steady_clock::now();
  if (!traction_map(organ, model)) {
    model.traction_available = false;
    model.traction_map.setZero(3, 3 * static_cast<Eigen::Index>(model.cloud.size()));
  }
  model.times.diagnostics_s = seconds_since(start);
}

/// The Galerkin branch of build_local_model: quadratures first (the stiffness is an integral),
/// then K, LDLT, the unit responses and the penalty force maps.
LocalModel build_galerkin(const geometry::TriangleSurface& organ, LocalModel model, const ClampedSurface& clamped,
                          std::chrono::steady_clock::time_point start) {
  const LocalModelSettings& settings = model.settings;
  const ForceSettings& f = settings.force;
  const auto fail = [&](std::string why) {
    model.status = std::move(why);
    model.times.total_s = seconds_since(start);
    return std::move(model);
  };
  auto step = std::chrono::steady_clock::now();
  const double length = settings.sprinkling.local_radius_m;
  model.volume = volume_quadrature(organ, model.contact, length, f.volume_radial_points, f.volume_polar_points,
                                   f.volume_azimuth_points);
  const PatchQuadrature patch = patch_quadrature(organ, model.contact, f.patch_radial_points, f.patch_angular_points);
  // The clamped surface is held like the cut (u = 0): one constraint, one reaction.
  PatchQuadrature cut = cut_quadrature(organ, model.contact, length, f.cut_polar_points, f.cut_azimuth_points);
  const PatchQuadrature base = clamped_inside_ball(organ, model.contact, settings, clamped);
  model.clamped_points = static_cast<int>(base.points.size());
  cut.points.insert(cut.points.end(), base.points.begin(), base.points.end());
  cut.normals.insert(cut.normals.end(), base.normals.begin(), base.normals.end());
  cut.weights.insert(cut.weights.end(), base.weights.begin(), base.weights.end());
  model.traction_available = f.traction && shell_clear_of(base, organ, model.contact, settings);
  if (f.haptic_method == ForceMethod::traction_integral && !model.traction_available)
    return fail("the traction integral's shell reaches a clamped surface: use haptic_method = reaction");
  GalerkinSettings galerkin = settings.galerkin;
  galerkin.mls = settings.collocation.mls;
  model.galerkin = assemble_galerkin(model.cloud, model.material, model.contact, model.volume, patch, cut, galerkin);
  model.times.assembly_s = seconds_since(step);
  if (model.galerkin.status != MlsStatus::ok)
    return fail(std::string("shape functions failed (") + to_string(model.galerkin.status) + ") at quadrature point " +
                std::to_string(model.galerkin.failed_point));

  step = std::chrono::steady_clock::now();
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(model.galerkin.stiffness);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return fail("the Galerkin stiffness is not positive definite");
  model.unit_response = ldlt.solve(Eigen::MatrixXd(model.galerkin.tool_rhs));
  const double residual = (model.galerkin.stiffness * model.unit_response - model.galerkin.tool_rhs).norm() /
                          model.galerkin.tool_rhs.norm();
  if (!model.unit_response.allFinite() || !(residual <= settings.solver.max_relative_residual))
    return fail("the Galerkin stiffness is singular or too ill-conditioned: relative residual " + std::to_string(residual));
  model.load_response.setZero(model.unit_response.rows());
  model.times.factorize_s = seconds_since(step);

  step = std::chrono::steady_clock::now();
  const MlsSettings& mls = settings.collocation.mls;
  if (!surface_traction_map(model.cloud, model.material, mls, patch, model.traction_surface_map))
    return fail("a tool-patch quadrature point is outside every support");
  const bool traction_is_haptic = f.haptic_method == ForceMethod::traction_integral;
  if (traction_is_haptic && !traction_map(organ, model)) return fail(traction_failure);
  model.reaction_map = model.galerkin.cut_map;  // minus the penalty force of the cut and the clamped surface
  // Eq. 9 in the weak form: the patch nodes' elastic rows (K_el U)_a = ∫_patch h_a λ dA, each
  // weighted by s_a, the patch nodes' share of the patch: Σ_a s_a h_a ≈ 1 on it in least squares
  // (M s = b, M_ab = ∫ h_a h_b dA, b_a = ∫ h_a dA), so Σ_a s_a (K_el U)_a ≈ ∫_patch λ dA. With
  // interpolating (FEM) shape functions s_a = 1 and this is the FEM's reaction from the
  // unconstrained residual; weighting by tributary area / ∫ h_a dA instead stays low on B3 as N
  // grows (the singular edge traction averaged over each support).
  const GalerkinSystem& g = model.galerkin;
  model.paper_map.setZero(3, 3 * static_cast<Eigen::Index>(model.cloud.size()));
  if (!g.patch_nodes.empty()) {
    const Eigen::VectorXd shape_integral_m2 =
        Eigen::Map<const Eigen::VectorXd>(g.patch_node_shape_integral_m2.data(), g.patch_node_mass_m2.rows());
    // Neighbouring shape functions are nearly alike on the patch: M is near-singular and the
    // minimum-norm solution is the meaningful one.
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> mass(g.patch_node_mass_m2);
    mass.setThreshold(1e-10);
    const Eigen::VectorXd share = mass.solve(shape_integral_m2);
    for (std::size_t i = 0; i < g.patch_nodes.size(); ++i)
      model.paper_map += share[static_cast<Eigen::Index>(i)] * g.patch_node_rows.middleRows<3>(3 * static_cast<Eigen::Index>(i));
  }
  model.tool_stiffness_N_per_m = haptic_map(model) * model.unit_response;
  if (!model.tool_stiffness_N_per_m.allFinite()) return fail("the tool stiffness is not finite");
  if (!f.energy) model.volume = PatchQuadrature{};
  model.times.condense_s = seconds_since(step);
  model.times.total_s = seconds_since(start);
  if (!traction_is_haptic) diagnostic_traction_map(organ, model);
  return model;
}

/// The enriched branch of build_local_model: its own even cloud, boundary quadratures, the
/// exterior stiffness (body-aware from `exterior`, else the half-space's), one KKT solve.
LocalModel build_enriched(const geometry::TriangleSurface& organ, LocalModel model, const ClampedSurface& clamped,
                          const ExteriorStiffnessSource& exterior, std::chrono::steady_clock::time_point start) {
  const LocalModelSettings& settings = model.settings;
  const auto fail = [&](std::string why) {
    model.status = std::move(why);
    model.times.total_s = seconds_since(start);
    return std::move(model);
  };
  const double length = settings.sprinkling.local_radius_m;
  auto step = std::chrono::steady_clock::now();
  const LocalSurface surface(organ, model.contact.point, enriched_surface_reach_local_radii * length);
  model.cloud = sprinkle_even_nodes(surface, model.contact, settings.sprinkling.node_count, length, settings.sprinkling.seed);
  // The quadratures grow with N; the assembly takes the settings for N ≤ 40.
  EnrichedSettings enriched = settings_for_material(settings.enriched, model.material);
  const EnrichedSettings quadrature_settings = quadratures_for_node_count(enriched, model.cloud.size());
  EnrichedQuadratures quadratures;
  PunchFrame frame;
  std::string failure;
  if (!enriched_quadratures(surface, model.contact, length, quadrature_settings,
                            clamped_inside_ball(organ, model.contact, settings, clamped), quadratures, frame, failure))
    return fail(failure);
  model.clamped_points = static_cast<int>(quadratures.clamped.points.size());
  Eigen::MatrixXd exterior_stiffness;
  model.exterior_used = to_string(enriched.exterior);
  if (enriched.exterior == ExteriorCondition::body_aware) {
    // The exterior's stiffness is in the modes of the patch frame: ask for it along the patch
    // normal, not along the tool.
    ToolContact along_patch = model.contact;
    along_patch.direction = frame.axes.col(2);
    // The atlas holds the punch translations; a bonded tool's radial mode takes the
    // half-space's exterior terms (build_enriched_model).
    const int modes = translation_mode_count(enrichment_modes(model.contact, frame, length));
    std::string why_not = "no organ atlas was given";
    if (!exterior || !exterior(along_patch, length, model.material, modes, exterior_stiffness, why_not)) {
      enriched.exterior = ExteriorCondition::half_space;
      model.exterior_used = to_string(enriched.exterior);
      model.exterior_note = why_not;
    }
  }
  model.times.sprinkle_s = seconds_since(step);
  step = std::chrono::steady_clock::now();
  // Where a quadrature point's moment matrix is singular the supports may grow up to 2× there.
  MlsSettings mls = settings.collocation.mls;
  mls.max_support_scale = std::max(mls.max_support_scale, 2.0);
  model.enriched = build_enriched_model(model.cloud, model.material, model.contact, quadratures, frame, enriched, mls,
                                        exterior_stiffness.size() ? &exterior_stiffness : nullptr);
  model.times.assembly_s = model.enriched.volume_s + model.enriched.boundary_s;
  model.times.factorize_s = model.enriched.solve_s;
  if (!model.enriched.ok()) return fail(model.enriched.status);
  const Eigen::Index n = model.enriched.unit_response.rows();
  model.unit_response = model.enriched.unit_response;
  model.load_response.setZero(n);
  model.traction_map.setZero(3, n);
  model.traction_surface_map.setZero(3, n);
  model.reaction_map.setZero(3, n);
  model.paper_map.setZero(3, n);
  model.traction_available = true;
  model.tool_stiffness_N_per_m = model.enriched.tool_stiffness_N_per_m;
  model.times.total_s = seconds_since(start);
  return model;
}

}  // namespace

NodeCloud sprinkle_local_nodes(const geometry::TriangleSurface& organ, const ToolContact& contact,
                               const LocalModelSettings& settings) {
  SprinklingSettings sprinkling = settings.sprinkling;
  if (settings.formulation == Formulation::enriched)
    return sprinkle_even_nodes(organ, contact, sprinkling.node_count, sprinkling.local_radius_m, sprinkling.seed);
  if (settings.paper_mode) sprinkling.tip_node_only = true;
  // Extra collocation points mean nothing to the weak form: do not sprinkle them.
  if (settings.formulation == Formulation::galerkin) sprinkling.oversampling = 1;
  return sprinkle_nodes(organ, contact, sprinkling);
}

ExteriorStiffnessSource exterior_from_atlas(std::shared_ptr<const OrganAtlas> atlas) {
  if (!atlas) return {};
  return [atlas](const ToolContact& contact, double local_radius_m, const geometry::Material& material, int modes,
                 Eigen::MatrixXd& stiffness, std::string& why_not) {
    OrganAtlasQuery query;
    query.contact_point_m = contact.point;
    query.direction = contact.direction;
    query.tool_radius_m = contact.radius_m;
    query.local_radius_m = local_radius_m;
    query.material = material;
    const OrganAtlasLookup found = lookup_exterior_stiffness(*atlas, query);
    if (found.status != OrganAtlasStatus::ok) {
      why_not = "organ atlas: " + found.message;
      return false;
    }
    if (found.mode_count < modes) {
      why_not = "organ atlas has the normal mode only; this contact loads the tangential modes too (a bonded tool, or a push "
                "more than 1 degree off the patch normal): make the atlas with modes = \"all\"";
      return false;
    }
    // The model's modes, then the atlas's cut translations if it has them.
    std::vector<int> keep;
    for (int i = 0; i < modes; ++i) keep.push_back(i);
    if (found.cut_translations)
      for (int i = 0; i < 3; ++i) keep.push_back(found.mode_count + i);
    const Eigen::Index size = static_cast<Eigen::Index>(keep.size());
    stiffness.resize(size, size);
    for (Eigen::Index i = 0; i < size; ++i)
      for (Eigen::Index j = 0; j < size; ++j) stiffness(i, j) = found.stiffness_N_per_m(keep[i], keep[j]);
    return true;
  };
}

LocalModel build_local_model(const geometry::TriangleSurface& organ, const ToolContact& contact, const geometry::Material& material,
                             const LocalModelSettings& settings, const ClampedSurface& clamped,
                             const ExteriorStiffnessSource& exterior) {
  material.validate();
  settings.validate();
  clamped.validate();
  // The shell depends on the tool radius as well as the settings: checked here, before any work.
  const ForceSettings& f = settings.force;
  if (settings.formulation != Formulation::enriched && f.traction && !(f.extraction_inner_tool_radii * contact.radius_m <
                      f.extraction_outer_local_radii * settings.sprinkling.local_radius_m))
    throw std::invalid_argument(
        "ForceSettings: the extraction shell is empty: inner radius extraction_inner_tool_radii × a = " +
        std::to_string(f.extraction_inner_tool_radii * contact.radius_m) +
        " m must be < extraction_outer_local_radii × L = " +
        std::to_string(f.extraction_outer_local_radii * settings.sprinkling.local_radius_m) + " m");
  const auto start = std::chrono::steady_clock::now();
  LocalModel model;
  model.material = material;
  model.settings = settings;
  model.contact = contact;
  if (settings.formulation == Formulation::enriched)
    return build_enriched(organ, std::move(model), clamped, exterior, start);
  model.cloud = sprinkle_local_nodes(organ, contact, settings);
  model.times.sprinkle_s = seconds_since(start);

  if (settings.formulation == Formulation::galerkin) return build_galerkin(organ, std::move(model), clamped, start);
  model.clamped_points = static_cast<int>(clamped_inside_ball(organ, contact, settings, clamped).points.size());

  auto step = std::chrono::steady_clock::now();
  assemble_collocation(model.cloud, material, settings.collocation, model.system);
  model.times.assembly_s = seconds_since(step);
  const auto fail = [&](std::string why) {
    model.status = std::move(why);
    model.times.total_s = seconds_since(start);
    return std::move(model);
  };
  if (model.clamped_points > 0)
    return fail("the local ball reaches a clamped surface, which collocation cannot hold: use formulation = galerkin");
  if (!model.system.status.ok())
    return fail(std::string("shape functions failed (") + to_string(model.system.status.mls) + ") at collocation point " +
                std::to_string(model.system.status.node));

  const int n = static_cast<int>(model.cloud.size());
  step = std::chrono::steady_clock::now();
  if (settings.paper_mode) {
    model.tip_node = 0;  // the sprinkler places the tip first
    std::string failure;
    if (!condense_tip(model.system, model.tip_node, model.unit_response, failure)) return fail(failure);
    model.load_response.setZero(3 * n);
  } else {
    model.solver = CollocationSolver(settings.solver);
    const SolveReport factorised = model.solver.factorize(model.system.stiffness);
    if (!factorised.ok) return fail("factorisation: " + factorised.failure);
    model.times.factorize_s = seconds_since(step);
    step = std::chrono::steady_clock::now();
    Eigen::MatrixXd rhs(model.system.tool_rhs.rows(), 4), response;
    rhs << model.system.tool_rhs, model.system.constant_rhs;
    const SolveReport solved = model.solver.solve(rhs, response);
    if (!solved.ok) return fail("solve: " + solved.failure);
    model.unit_response = response.leftCols<3>();
    model.load_response = response.col(3);
  }

  // Force maps: each is U ↦ F, so K_t = map · unit_response is the condensation.
  const MlsSettings& mls = settings.collocation.mls;
  const PatchQuadrature patch = patch_quadrature(organ, contact, f.patch_radial_points, f.patch_angular_points);
  if (!surface_traction_map(model.cloud, material, mls, patch, model.traction_surface_map))
    return fail("a tool-patch quadrature point is outside every support");
  model.traction_available = f.traction;
  const bool traction_is_haptic = f.haptic_method == ForceMethod::traction_integral;
  if (traction_is_haptic && !traction_map(organ, model)) return fail(traction_failure);
  if (f.reaction) {
    const PatchQuadrature cut =
        cut_quadrature(organ, contact, settings.sprinkling.local_radius_m, f.cut_polar_points, f.cut_azimuth_points);
    if (!surface_traction_map(model.cloud, material, mls, cut, model.reaction_map))
      return fail("a cut-surface quadrature point is outside every support");
    model.reaction_map = -model.reaction_map;  // the tool balances what the cut surface holds
  } else {
    model.reaction_map.setZero(3, 3 * n);
  }
  if (settings.paper_mode) {
    // Eq. 9 literally: the tip's rows applied to U, in the rows' own units (traction [Pa]),
    // then times a tributary area π s² (B4: the FEM patch radius equals the node spacing).
    const double s = model.cloud.spacing[model.tip_node];
    model.tip_tributary_area_m2 = pi * s * s;
    model.paper_map.setZero(3, 3 * n);
    for (int r = 0; r < 3; ++r) {
      const int row = 3 * model.tip_node + r;
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(model.system.stiffness, row); it; ++it)
        model.paper_map(r, it.col()) = it.value() / model.system.row_scale[row];
    }
    // The tip's rows are along the axes: the residual is already a traction vector.
    model.paper_map *= model.tip_tributary_area_m2;
  } else {
    if (!patch_node_map(model.cloud, material, mls, patch, model.paper_map))
      return fail("a tool-patch node is outside every support");
  }
  if (f.energy)
    model.volume = volume_quadrature(organ, contact, settings.sprinkling.local_radius_m, f.volume_radial_points,
                                     f.volume_polar_points, f.volume_azimuth_points);
  model.tool_stiffness_N_per_m = haptic_map(model) * model.unit_response;
  model.load_force_N = haptic_map(model) * model.load_response;
  if (!model.tool_stiffness_N_per_m.allFinite() || !model.load_force_N.allFinite())
    return fail("the tool stiffness is not finite");
  model.times.condense_s = seconds_since(step);
  model.times.total_s = seconds_since(start);
  if (!traction_is_haptic) diagnostic_traction_map(organ, model);
  return model;
}

double stiffness_ratio_to_half_space(const LocalModel& model) {
  const Eigen::Vector3d d = model.contact.direction.normalized();
  const double nu = model.material.poisson_ratio;
  const double half_space_N_per_m = 2 * model.material.youngs_modulus_Pa * model.contact.radius_m / (1 - nu * nu);
  const double ratio = d.dot(model.tool_stiffness_N_per_m * d) / half_space_N_per_m;
  return std::isfinite(ratio) ? ratio : std::numeric_limits<double>::quiet_NaN();
}

LocalSolution solve_local_model(const LocalModel& model, const Eigen::Vector3d& tool_displacement_m) {
  LocalSolution solution;
  if (!model.ok()) {
    solution.status = "model not usable: " + model.status;
    return solution;
  }
  if (!tool_displacement_m.allFinite()) {
    solution.status = "tool displacement is not finite";
    return solution;
  }
  auto start = std::chrono::steady_clock::now();
  solution.parameters = model.unit_response * tool_displacement_m + model.load_response;
  solution.solve_s = seconds_since(start);
  start = std::chrono::steady_clock::now();
  ToolForces& f = solution.forces;
  if (model.settings.formulation == Formulation::enriched) {
    // The patch multiplier is the contact traction (a); the cut's balances it when the cut is
    // clamped (b); the energy includes the exterior's (c).
    f.haptic_N = model.tool_stiffness_N_per_m * tool_displacement_m;
    f.traction_integral_N = f.haptic_N;
    f.traction_surface_N = f.haptic_N;
    f.reaction_N = -model.enriched.cut_reaction_N_per_m * tool_displacement_m;
    f.energy_J = 0.5 * solution.parameters.dot(model.enriched.stiffness * solution.parameters);
    if (tool_displacement_m.norm() > 0) f.energy_force_N = 2 * f.energy_J / tool_displacement_m.norm();
    solution.force_s = seconds_since(start);
    return solution;
  }
  f.traction_integral_N = model.traction_map * solution.parameters;
  f.traction_surface_N = model.traction_surface_map * solution.parameters;
  f.reaction_N = model.reaction_map * solution.parameters;
  f.paper_partition_N = model.paper_map * solution.parameters;
  if (model.settings.paper_mode) f.paper_tip_residual_Pa = f.paper_partition_N / model.tip_tributary_area_m2;
  f.haptic_N = model.tool_stiffness_N_per_m * tool_displacement_m + model.load_force_N;
  if (!model.volume.points.empty()) {
    if (!strain_energy(model.cloud, model.material, model.settings.collocation.mls, model.volume, solution.parameters,
                       f.energy_J)) {
      solution.status = "a volume quadrature point is outside every support";
    } else if (tool_displacement_m.norm() > 0) {
      f.energy_force_N = 2 * f.energy_J / tool_displacement_m.norm();
    }
  }
  solution.force_s = seconds_since(start);
  return solution;
}

bool displacement_at(const LocalModel& model, const Eigen::VectorXd& parameters, const std::vector<Eigen::Vector3d>& points,
                     std::vector<Eigen::Vector3d>& displacement_m) {
  displacement_m.assign(points.size(), Eigen::Vector3d::Zero());
  MlsEvaluation scratch;
  bool all = true;
  if (model.settings.formulation == Formulation::enriched) {
    MlsSettings mls = model.settings.collocation.mls;  // as build_enriched evaluated them
    mls.max_support_scale = std::max(mls.max_support_scale, 2.0);
    for (std::size_t p = 0; p < points.size(); ++p)
      all = enriched_displacement(model.cloud, model.enriched, model.contact.radius_m, model.material, mls, parameters,
                                  points[p], scratch, displacement_m[p]) ==
                MlsStatus::ok &&
            all;
    return all;
  }
  for (std::size_t p = 0; p < points.size(); ++p)
    all = evaluate_displacement(model.cloud, parameters, points[p], model.settings.collocation.mls, scratch,
                                displacement_m[p]) == MlsStatus::ok &&
          all;
  return all;
}

}  // namespace touchstone::realtime::mfs
