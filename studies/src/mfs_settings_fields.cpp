// The MFS engine's settings table (see the header). Units: every setting here is a count, a
// ratio or a switch; lengths and moduli of a study (tool radius, L, E) are study keys, read with
// their units by the study readers.
#include "mfs_settings_fields.hpp"

#include <toml++/toml.h>

#include <cstdint>
#include <stdexcept>

namespace touchstone::studies {
namespace mfs = realtime::mfs;
using nlohmann::json;

namespace {

// ---------------------------------------------------------------------------------------------
// Names of the engine's enums, as spelled in configs, results.json and the resolved config.

const std::vector<Named<mfs::Layout>> layouts{{"radial_shells", mfs::Layout::radial_shells},
                                              {"quasi_random", mfs::Layout::quasi_random},
                                              {"lattice", mfs::Layout::lattice}};
const std::vector<Named<mfs::OuterCondition>> outer_conditions{{"clamped", mfs::OuterCondition::clamped},
                                                               {"traction_free", mfs::OuterCondition::traction_free}};
const std::vector<Named<mfs::ExteriorCondition>> exterior_conditions{
    {"body_aware", mfs::ExteriorCondition::body_aware},
    {"half_space", mfs::ExteriorCondition::half_space},
    {"clamped", mfs::ExteriorCondition::clamped}};
const std::vector<Named<mfs::Formulation>> formulations{{"enriched", mfs::Formulation::enriched},
                                                        {"galerkin", mfs::Formulation::galerkin},
                                                        {"collocation", mfs::Formulation::collocation}};
const std::vector<Named<mfs::Constraint>> constraints{{"penalty", mfs::Constraint::penalty},
                                                      {"nitsche", mfs::Constraint::nitsche}};
const std::vector<Named<mfs::Basis>> bases{{"linear", mfs::Basis::linear}, {"quadratic", mfs::Basis::quadratic}};
const std::vector<Named<mfs::Weight>> weights{{"quartic_spline", mfs::Weight::quartic_spline},
                                              {"cubic_spline", mfs::Weight::cubic_spline},
                                              {"truncated_gaussian", mfs::Weight::truncated_gaussian}};
const std::vector<Named<mfs::SolverKind>> solver_kinds{{"dense_lu", mfs::SolverKind::dense_lu},
                                                       {"sparse_lu", mfs::SolverKind::sparse_lu},
                                                       {"gmres_ilut", mfs::SolverKind::gmres_ilut}};
const std::vector<Named<mfs::VolumetricTerm>> volumetric_terms{{"auto", mfs::VolumetricTerm::automatic},
                                                               {"full", mfs::VolumetricTerm::full},
                                                               {"projected", mfs::VolumetricTerm::projected}};
const std::vector<Named<mfs::GradientCorrection>> gradient_corrections{{"auto", mfs::GradientCorrection::automatic},
                                                                       {"none", mfs::GradientCorrection::none},
                                                                       {"linear", mfs::GradientCorrection::linear}};
// "energy" is listed so that ForceSettings::validate() can say why it is not allowed.
const std::vector<Named<mfs::ForceMethod>> force_methods{{"traction_integral", mfs::ForceMethod::traction_integral},
                                                         {"reaction", mfs::ForceMethod::reaction},
                                                         {"energy", mfs::ForceMethod::energy},
                                                         {"paper_partition", mfs::ForceMethod::paper_partition}};

// ---------------------------------------------------------------------------------------------
// The table.

using Settings = mfs::LocalModelSettings;
using Field = SettingField<Settings>;

const auto integer = [](FieldNames n, auto get) { return field::integer<Settings>(n, get); };
const auto real = [](FieldNames n, auto get) { return field::real<Settings>(n, get); };
const auto boolean = [](FieldNames n, auto get) { return field::boolean<Settings>(n, get); };
const auto choice = [](FieldNames n, const auto& choices, auto get) { return field::choice<Settings>(n, choices, get); };

std::vector<Field> make_fields() {
  std::vector<Field> f;
  // Top level. paper_mode picks every other default, so the study readers read it before the
  // table too; here it is read again (same value) so that the table consumes every key it writes.
  f.push_back(boolean({"", "paper_mode", "", "the paper's model: one tool-tip node, linear basis, eqs. 7-9"},
                      [](auto& s) -> auto& { return s.paper_mode; }));
  Field formulation = choice({"", "formulation", "", "enriched (default), galerkin or collocation (the paper's)"},
                                    formulations, [](auto& s) -> auto& { return s.formulation; });
  // The formulation picks the haptic method's default and, for the weak forms, one point per node.
  formulation.read = [](ConfigTable& t, Settings& s) {
    s.formulation = value_of(formulations, t.choice("formulation", names(formulations), name_of(formulations, s.formulation)));
    s.force.haptic_method = mfs::default_haptic_method(s.formulation, s.paper_mode);
    if (s.formulation == mfs::Formulation::galerkin) s.sprinkling.oversampling = 1;
  };
  f.push_back(formulation);

  f.push_back(real({"galerkin", "penalty_factor", "", "penalty of u = 0 on clamped surfaces, times E / h"},
                   [](auto& s) -> auto& { return s.galerkin.penalty_factor; }));
  f.push_back(choice({"galerkin", "constraint", "", "penalty or nitsche"}, constraints,
                     [](auto& s) -> auto& { return s.galerkin.constraint; }));

  f.push_back(choice({"enriched", "exterior", "", "body_aware (organ atlas), half_space or clamped"}, exterior_conditions,
                     [](auto& s) -> auto& { return s.enriched.exterior; }));
  f.push_back(integer({"enriched", "support_neighbours", "nodes", "support radius: distance to this nearest node"},
                      [](auto& s) -> auto& { return s.enriched.support_neighbours; }));
  f.push_back(integer({"enriched", "min_point_neighbours", "nodes", "nodes every quadrature point must see"},
                      [](auto& s) -> auto& { return s.enriched.min_point_neighbours; }));
  f.push_back(integer({"enriched", "volume_radial_points", "points", "MLS-MLS volume quadrature, radial (N <= 40; 0: 6x6x12 with corrected gradients, 8x8x16 without)"},
                      [](auto& s) -> auto& { return s.enriched.volume_radial_points; }));
  f.push_back(integer({"enriched", "volume_polar_points", "points", "MLS-MLS volume quadrature, polar (N <= 40; 0: 6x6x12 with corrected gradients, 8x8x16 without)"},
                      [](auto& s) -> auto& { return s.enriched.volume_polar_points; }));
  f.push_back(integer({"enriched", "volume_azimuth_points", "points", "MLS-MLS volume quadrature, azimuthal (N <= 40; 0: 6x6x12 with corrected gradients, 8x8x16 without)"},
                      [](auto& s) -> auto& { return s.enriched.volume_azimuth_points; }));
  f.push_back(real({"enriched", "volume_coarse_within_tool_radii", "tool radii",
                    "volume shells this close to the contact point take half the angular counts (0: none)"},
                   [](auto& s) -> auto& { return s.enriched.volume_coarse_within_tool_radii; }));
  f.push_back(integer({"enriched", "patch_radial_points", "points", "patch quadrature, radial (r = a sin t)"},
                      [](auto& s) -> auto& { return s.enriched.patch_radial_points; }));
  f.push_back(integer({"enriched", "patch_angular_points", "points", "patch quadrature, angular"},
                      [](auto& s) -> auto& { return s.enriched.patch_angular_points; }));
  f.push_back(integer({"enriched", "free_radial_points", "points", "free-surface quadrature, radial (graded to the rim)"},
                      [](auto& s) -> auto& { return s.enriched.free_radial_points; }));
  f.push_back(integer({"enriched", "free_azimuth_points", "points", "free-surface quadrature, azimuthal"},
                      [](auto& s) -> auto& { return s.enriched.free_azimuth_points; }));
  f.push_back(integer({"enriched", "cut_polar_points", "points", "cut-sphere quadrature, polar (N <= 40; 0: 6 with corrected gradients, 8 without)"},
                      [](auto& s) -> auto& { return s.enriched.cut_polar_points; }));
  f.push_back(integer({"enriched", "cut_azimuth_points", "points", "cut-sphere quadrature, azimuthal (N <= 40; 0: 12 with corrected gradients, 16 without)"},
                      [](auto& s) -> auto& { return s.enriched.cut_azimuth_points; }));
  f.push_back(integer({"enriched", "cut_multiplier_degree", "", "polynomial degree of the cut's multipliers (-1: from N)"},
                      [](auto& s) -> auto& { return s.enriched.cut_multiplier_degree; }));
  f.push_back(integer({"enriched", "bonded_patch_dome_from_nodes", "nodes",
                       "a bonded patch also holds its face's dome (T2 of the normal component) from this many nodes"},
                      [](auto& s) -> auto& { return s.enriched.bonded_patch_dome_from_nodes; }));
  f.push_back(choice({"enriched", "volumetric", "",
                      "auto (projected from nu = 0.475 on), full (the MLS part's lambda term as is) or projected (onto linear polynomials or the nodes' functions, and div psi: no locking as nu -> 0.5)"},
                     volumetric_terms, [](auto& s) -> auto& { return s.enriched.volumetric; }));
  f.push_back(integer({"enriched", "volumetric_linear_space_up_to_nodes", "nodes",
                       "the projected volumetric term's space: linear polynomials and div psi up to this many nodes, the nodes' functions beyond"},
                      [](auto& s) -> auto& { return s.enriched.volumetric_linear_space_up_to_nodes; }));
  f.push_back(choice({"enriched", "gradient_correction", "",
                      "auto (linear while the volumetric term is full, none where it is projected), none or linear: MLS gradients corrected so that the volume rule integrates a linear field's weak form exactly"},
                     gradient_corrections, [](auto& s) -> auto& { return s.enriched.gradient_correction; }));

  f.push_back(choice({"sprinkling", "layout", "", "radial_shells, quasi_random or lattice"}, layouts,
                     [](auto& s) -> auto& { return s.sprinkling.layout; }));
  f.push_back(integer({"sprinkling", "ring_nodes", "nodes", "nodes on the ring around the patch rim"},
                      [](auto& s) -> auto& { return s.sprinkling.ring_nodes; }));
  f.push_back(real({"sprinkling", "radius_factor", "node spacings", "sphere radius of an interior node"},
                   [](auto& s) -> auto& { return s.sprinkling.radius_factor; }));
  f.push_back(real({"sprinkling", "boundary_radius_factor", "node spacings", "sphere radius of a boundary node"},
                   [](auto& s) -> auto& { return s.sprinkling.boundary_radius_factor; }));
  f.push_back(choice({"sprinkling", "outer", "", "the cut sphere: clamped or traction_free"}, outer_conditions,
                     [](auto& s) -> auto& { return s.sprinkling.outer; }));
  f.push_back(real({"sprinkling", "oversampling", "points per node", "collocation points per node (least squares)"},
                   [](auto& s) -> auto& { return s.sprinkling.oversampling; }));
  f.push_back(boolean({"sprinkling", "tip_node_only", "", "the tool acts on one tip node (the paper's point tool)"},
                      [](auto& s) -> auto& { return s.sprinkling.tip_node_only; }));
  f.push_back(field::seed<Settings>({"sprinkling", "seed", "", "seed of the quasi-random layouts (>= 0)"},
                                    [](auto& s) -> auto& { return s.sprinkling.seed; }));

  f.push_back(boolean({"collocation", "scale_rows", "", "scale each collocation row to unit norm"},
                      [](auto& s) -> auto& { return s.collocation.scale_rows; }));
  f.push_back(real({"collocation", "neumann_stabilization", "", "finite-increment stabilisation of traction rows"},
                   [](auto& s) -> auto& { return s.collocation.neumann_stabilization; }));
  f.push_back(real({"collocation", "boundary_row_weight", "", "weight of boundary rows in least squares"},
                   [](auto& s) -> auto& { return s.collocation.boundary_row_weight; }));

  f.push_back(choice({"mls", "basis", "", "linear or quadratic"}, bases, [](auto& s) -> auto& { return s.collocation.mls.basis; }));
  f.push_back(choice({"mls", "weight", "", "quartic_spline, cubic_spline or truncated_gaussian"}, weights,
                     [](auto& s) -> auto& { return s.collocation.mls.weight; }));
  f.push_back(real({"mls", "min_rcond", "", "moment-matrix rcond below which supports grow", "min_rcond_threshold"},
                   [](auto& s) -> auto& { return s.collocation.mls.min_rcond; }));
  f.push_back(real({"mls", "max_support_scale", "", "largest support growth before a point fails"},
                   [](auto& s) -> auto& { return s.collocation.mls.max_support_scale; }));

  f.push_back(choice({"solver", "kind", "", "dense_lu, sparse_lu or gmres_ilut", "solver"}, solver_kinds,
                     [](auto& s) -> auto& { return s.solver.kind; }));
  f.push_back(real({"solver", "gmres_tolerance", "", "GMRES relative residual"}, [](auto& s) -> auto& { return s.solver.gmres_tolerance; }));
  f.push_back(integer({"solver", "gmres_restart", "iterations", "GMRES restart"}, [](auto& s) -> auto& { return s.solver.gmres_restart; }));
  f.push_back(integer({"solver", "gmres_max_iterations", "iterations", "GMRES iteration limit"},
                      [](auto& s) -> auto& { return s.solver.gmres_max_iterations; }));
  f.push_back(real({"solver", "max_relative_residual", "", "largest accepted relative residual of a solve"},
                   [](auto& s) -> auto& { return s.solver.max_relative_residual; }));
  f.push_back(real({"solver", "ilut_drop_tolerance", "", "ILUT drop tolerance"}, [](auto& s) -> auto& { return s.solver.ilut_drop_tolerance; }));
  f.push_back(integer({"solver", "ilut_fill_factor", "", "ILUT fill factor"}, [](auto& s) -> auto& { return s.solver.ilut_fill_factor; }));

  f.push_back(integer({"force", "patch_radial_points", "points", "force quadrature on the patch, radial"},
                      [](auto& s) -> auto& { return s.force.patch_radial_points; }));
  f.push_back(integer({"force", "patch_angular_points", "points", "force quadrature on the patch, angular"},
                      [](auto& s) -> auto& { return s.force.patch_angular_points; }));
  f.push_back(integer({"force", "cut_polar_points", "points", "quadrature of the cut sphere, polar"},
                      [](auto& s) -> auto& { return s.force.cut_polar_points; }));
  f.push_back(integer({"force", "cut_azimuth_points", "points", "quadrature of the cut sphere, azimuthal"},
                      [](auto& s) -> auto& { return s.force.cut_azimuth_points; }));
  f.push_back(integer({"force", "volume_radial_points", "points", "Galerkin volume quadrature, radial"},
                      [](auto& s) -> auto& { return s.force.volume_radial_points; }));
  f.push_back(integer({"force", "volume_polar_points", "points", "Galerkin volume quadrature, polar"},
                      [](auto& s) -> auto& { return s.force.volume_polar_points; }));
  f.push_back(integer({"force", "volume_azimuth_points", "points", "Galerkin volume quadrature, azimuthal"},
                      [](auto& s) -> auto& { return s.force.volume_azimuth_points; }));
  f.push_back(real({"force", "extraction_inner_tool_radii", "tool radii", "inner radius of the energy-extraction shell"},
                   [](auto& s) -> auto& { return s.force.extraction_inner_tool_radii; }));
  f.push_back(real({"force", "extraction_outer_local_radii", "local radii", "outer radius of the energy-extraction shell"},
                   [](auto& s) -> auto& { return s.force.extraction_outer_local_radii; }));
  f.push_back(integer({"force", "extraction_radial_points", "points", "extraction-shell quadrature, radial"},
                      [](auto& s) -> auto& { return s.force.extraction_radial_points; }));
  f.push_back(integer({"force", "extraction_polar_points", "points", "extraction-shell quadrature, polar"},
                      [](auto& s) -> auto& { return s.force.extraction_polar_points; }));
  f.push_back(integer({"force", "extraction_azimuth_points", "points", "extraction-shell quadrature, azimuthal"},
                      [](auto& s) -> auto& { return s.force.extraction_azimuth_points; }));
  // Unset, the haptic method follows the formulation (set when the formulation is read).
  f.push_back(choice({"force", "haptic_method", "", "the force the haptic loop uses (K_t from it)"}, force_methods,
                     [](auto& s) -> auto& { return s.force.haptic_method; }));
  f.push_back(boolean({"force", "reaction", "", "compute the reaction force"}, [](auto& s) -> auto& { return s.force.reaction; }));
  f.push_back(boolean({"force", "energy", "", "compute the energy force"}, [](auto& s) -> auto& { return s.force.energy; }));
  f.push_back(boolean({"force", "traction", "", "compute the traction-integral force"}, [](auto& s) -> auto& { return s.force.traction; }));

  assign_params_keys(f, "MFS");
  return f;
}

}  // namespace

const std::vector<SettingField<Settings>>& local_model_fields() {
  static const std::vector<Field> fields = make_fields();
  return fields;
}

void read_local_model_settings(ConfigTable& config, Settings& settings) {
  read_fields(local_model_fields(), config, settings);
}

void write_local_model_settings(toml::table& document, const Settings& settings) {
  write_fields(local_model_fields(), document, settings);
}

void add_local_model_params(json& params, const Settings& settings) { add_params(local_model_fields(), params, settings); }

}  // namespace touchstone::studies
