// Linear elasticity on a tetrahedral gmsh mesh with deal.II 9.4 simplex elements (one file: one
// solver class whose setup, assembly, solve and output share deal.II's DoF and mesh state).
//
// Why simplices: gmsh grades tetrahedra toward the patch-edge circle (where the contact
// stress is singular) with an exact circle in the geometry; 3-D hexahedral recombination in
// gmsh is not reliable enough for a reference. FE_SimplexP(2) on a linear mapping converges at
// the element's order for smooth solutions (tested), and at first order in the edge size for the
// punch (the r^(1/2) edge singularity), which the convergence study measures.
//
// Near-incompressibility (pure-displacement P2 locks as ν → 0.5): the option
// Formulation::mixed_p0disc adds a discontinuous pressure per cell and eliminates it cell by cell
// (static condensation), so the global system stays SPD in the displacement alone. The pressure is constant per cell (P0),
// not the linear P1disc that suits Q2 hexahedra: on these affine tetrahedra div u of a P2 field
// is already linear on each cell, so projecting it onto P1disc changes nothing and P2–P1disc is
// the displacement formulation, locking included (measured: identical punch forces). P2–P0
// imposes one divergence constraint per cell instead of four.
//
// The parallel layout follows step-40 on a parallel::shared::Triangulation: every rank holds the
// whole mesh (cheap at reference sizes, and it keeps probe evaluation and patch bookkeeping
// simple), assembles its own cells, and the linear algebra is distributed.

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/fem/blas_kernels.hpp"

#include "touchstone/meshes/msh_reader.hpp"

#include <deal.II/base/function.h>
#include <deal.II/base/index_set.h>
#include <deal.II/base/mpi.h>
#include <deal.II/base/quadrature_lib.h>
#include <deal.II/base/timer.h>
#include <deal.II/distributed/shared_tria.h>
#include <deal.II/dofs/dof_handler.h>
#include <deal.II/dofs/dof_tools.h>
#include <deal.II/fe/fe_simplex_p.h>
#include <deal.II/fe/fe_system.h>
#include <deal.II/fe/fe_values.h>
#include <deal.II/fe/mapping_fe.h>
#include <deal.II/grid/grid_in.h>
#include <deal.II/grid/grid_tools.h>
#include <deal.II/grid/grid_tools_cache.h>
#include <deal.II/lac/affine_constraints.h>
#include <deal.II/lac/dynamic_sparsity_pattern.h>
#include <deal.II/lac/generic_linear_algebra.h>
#include <deal.II/lac/petsc_solver.h>
#include <deal.II/lac/solver_control.h>
#include <deal.II/lac/sparsity_tools.h>
#include <deal.II/lac/trilinos_precondition.h>
#include <deal.II/lac/trilinos_solver.h>
#include <deal.II/numerics/data_out.h>
#include <deal.II/numerics/data_postprocessor.h>
#include <deal.II/numerics/vector_tools.h>

#include <petscksp.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace touchstone::fem {
namespace {

using namespace dealii;
constexpr int dim = 3;

Point<dim> to_point(const Eigen::Vector3d& v) { return Point<dim>(v[0], v[1], v[2]); }
Eigen::Vector3d to_eigen(const Point<dim>& p) { return {p[0], p[1], p[2]}; }

/// A VectorField seen as a deal.II Function with three components.
class FieldFunction : public Function<dim> {
 public:
  explicit FieldFunction(VectorField field) : Function<dim>(dim), field_(std::move(field)) {}
  double value(const Point<dim>& p, const unsigned int component) const override {
    return field_(to_eigen(p))[component];
  }
  void vector_value(const Point<dim>& p, Vector<double>& values) const override {
    const Eigen::Vector3d v = field_(to_eigen(p));
    for (int i = 0; i < dim; ++i) values[i] = v[i];
  }

 private:
  VectorField field_;
};

/// Stress (six components, Voigt order xx yy zz yz xz xy) and von Mises. Displacement
/// formulation: σ = λ tr(ε) I + 2μ ε. Mixed: σ = 2μ dev ε + p I with the cell's condensed
/// pressure p = κ Π₀(div u) [Pa], the stress the discrete equations are in equilibrium with
/// (κ tr ε pointwise would bring back the locked, oscillating pressure); p is written as
/// mean_stress_Pa (= tr σ / 3, positive in tension).
class StressPostprocessor : public DataPostprocessor<dim> {
 public:
  /// `cell_pressures`: null for the displacement formulation, else p [Pa] by active cell index.
  StressPostprocessor(double lambda, double mu, const std::vector<double>* cell_pressures = nullptr)
      : lambda_(lambda), mu_(mu), pressures_(cell_pressures) {}

  void evaluate_vector_field(const DataPostprocessorInputs::Vector<dim>& inputs,
                             std::vector<Vector<double>>& computed) const override {
    for (std::size_t q = 0; q < inputs.solution_gradients.size(); ++q) {
      const auto& grad = inputs.solution_gradients[q];
      SymmetricTensor<2, dim> strain;
      for (int i = 0; i < dim; ++i)
        for (int j = i; j < dim; ++j) strain[i][j] = 0.5 * (grad[i][j] + grad[j][i]);
      SymmetricTensor<2, dim> stress;
      if (pressures_) {
        const auto cell = inputs.template get_cell<dim>();
        const double p = (*pressures_)[cell->active_cell_index()];
        stress = 2 * mu_ * deviator(strain) + p * unit_symmetric_tensor<dim>();
        computed[q][7] = p;
      } else {
        stress = lambda_ * trace(strain) * unit_symmetric_tensor<dim>() + 2 * mu_ * strain;
      }
      const SymmetricTensor<2, dim> dev = deviator(stress);
      computed[q][0] = stress[0][0];
      computed[q][1] = stress[1][1];
      computed[q][2] = stress[2][2];
      computed[q][3] = stress[1][2];
      computed[q][4] = stress[0][2];
      computed[q][5] = stress[0][1];
      computed[q][6] = std::sqrt(1.5 * scalar_product(dev, dev));
    }
  }
  std::vector<std::string> get_names() const override {
    std::vector<std::string> names{"stress_xx_Pa", "stress_yy_Pa", "stress_zz_Pa", "stress_yz_Pa",
                                   "stress_xz_Pa", "stress_xy_Pa", "von_mises_Pa"};
    if (pressures_) names.push_back("mean_stress_Pa");
    return names;
  }
  std::vector<DataComponentInterpretation::DataComponentInterpretation>
  get_data_component_interpretation() const override {
    return std::vector<DataComponentInterpretation::DataComponentInterpretation>(
        get_names().size(), DataComponentInterpretation::component_is_scalar);
  }
  UpdateFlags get_needed_update_flags() const override { return update_gradients; }

 private:
  double lambda_, mu_;
  const std::vector<double>* pressures_;
};

double elapsed(Timer& timer) {
  timer.stop();
  const double t = timer.wall_time();
  timer.reset();
  timer.start();
  return t;
}

/// The two linear-algebra backends (step-40's LinearAlgebra namespaces as types).
struct TrilinosAlgebra {
  using SparseMatrix = TrilinosWrappers::SparseMatrix;
  using Vector = TrilinosWrappers::MPI::Vector;
};
struct PetscAlgebra {
  using SparseMatrix = PETScWrappers::MPI::SparseMatrix;
  using Vector = PETScWrappers::MPI::Vector;
};

/// The whole solve, templated on the linear-algebra backend.
template <typename LA>
class ElasticitySolver {
 public:
  ElasticitySolver(const ElasticityProblem& problem, MPI_Comm communicator)
      : problem_(problem),
        comm_(communicator),
        triangulation_(comm_),
        fe_(FE_SimplexP<dim>(problem.solver.degree), dim),
        mapping_(FE_SimplexP<dim>(1)),
        dof_handler_(triangulation_),
        stiffness_quadrature_(problem.solver.degree),
        quadrature_(problem.solver.degree + 1),
        face_quadrature_(problem.solver.degree + 1),
        lambda_(problem.material.lame_lambda_Pa()),
        mu_(problem.material.shear_modulus_Pa()),
        kappa_(lambda_ + 2 * mu_ / 3),
        mixed_(problem.solver.formulation == Formulation::mixed_p0disc) {
    for (unsigned int i = 0; i < fe_.n_dofs_per_cell(); ++i) component_.push_back(fe_.system_to_component_index(i).first);
  }

  ElasticitySolution run() {
    Timer timer(comm_);
    timer.start();
    read_mesh();
    result_.read_mesh_s = elapsed(timer);
    setup();
    result_.setup_s = elapsed(timer);
    assemble();
    result_.assembly_s = elapsed(timer);
    solve();
    check_solution_is_finite();
    // The solver name is what the study JSON records about the numerics: name the formulation.
    if (mixed_) result_.solver_name += ", mixed P2-P0 (pressure condensed per cell)";
    result_.solve_s = elapsed(timer);
    postprocess();
    result_.postprocess_s = elapsed(timer);
    if (!problem_.vtu_directory.empty()) write_vtu();
    result_.output_s = elapsed(timer);
    return result_;
  }

 private:
  void read_mesh() {
    read_physical_names();
    std::ifstream in(problem_.mesh_path);
    if (!in) throw std::runtime_error(problem_.mesh_path + ": cannot open mesh file");
    GridIn<dim> grid_in;
    grid_in.attach_triangulation(triangulation_);
    try {
      grid_in.read_msh(in);
    } catch (const std::exception& e) {
      throw std::runtime_error(problem_.mesh_path + ": deal.II could not read the mesh: " + e.what());
    }
    if (!triangulation_.all_reference_cells_are_simplex())
      throw std::runtime_error(problem_.mesh_path + ": expected a tetrahedral mesh");

    // A boundary face gmsh did not put into any physical group comes back with id 0: it would
    // silently become traction-free, so refuse it.
    for (const auto& cell : triangulation_.active_cell_iterators())
      for (const auto f : cell->face_indices())
        if (cell->face(f)->at_boundary() && cell->face(f)->boundary_id() == 0)
          throw std::runtime_error(problem_.mesh_path +
                                   ": boundary faces without a physical group (every boundary "
                                   "surface must be named)");
  }

  /// The names of the surface groups, which deal.II's GridIn drops (it keeps the numeric tags
  /// as boundary ids). An unreadable file is a runtime_error here, as GridIn's failures are.
  void read_physical_names() {
    std::vector<touchstone::meshes::MshPhysicalName> names;
    try {
      names = touchstone::meshes::read_msh_physical_names(problem_.mesh_path);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(e.what());
    }
    if (names.empty())
      throw std::runtime_error(problem_.mesh_path +
                               ": no $PhysicalNames section (name the boundaries with gmsh physical groups)");
    for (const touchstone::meshes::MshPhysicalName& name : names)
      if (name.dimension == 2) surface_tags_[name.name] = name.tag;
  }

  types::boundary_id boundary_id(const std::string& name, bool required) const {
    const auto it = surface_tags_.find(name);
    if (it == surface_tags_.end()) {
      if (required) {
        std::string list;
        for (const auto& [known, tag] : surface_tags_) list += (list.empty() ? "" : ", ") + known;
        throw std::runtime_error(problem_.mesh_path + ": no surface physical group named '" + name +
                                 "' (has: " + (list.empty() ? std::string("none") : list) + ")");
      }
      return numbers::invalid_boundary_id;
    }
    return static_cast<types::boundary_id>(it->second);
  }

  void setup() {
    dof_handler_.distribute_dofs(fe_);
    locally_owned_ = dof_handler_.locally_owned_dofs();
    DoFTools::extract_locally_relevant_dofs(dof_handler_, locally_relevant_);

    constraints_.clear();
    for (const auto& name : problem_.clamped_boundaries) {
      const auto id = boundary_id(name, false);
      if (id != numbers::invalid_boundary_id)
        VectorTools::interpolate_boundary_values(mapping_, dof_handler_, id,
                                                 Functions::ZeroFunction<dim>(dim), constraints_);
    }
    for (const auto& condition : problem_.conditions) {
      if (condition.kind != BoundaryCondition::Kind::displacement) continue;
      VectorTools::interpolate_boundary_values(mapping_, dof_handler_,
                                               boundary_id(condition.boundary, true),
                                               FieldFunction(condition.value), constraints_);
    }
    if (problem_.punch) add_punch_constraints(*problem_.punch);
    constraints_.close();

    DynamicSparsityPattern dsp(locally_relevant_);
    DoFTools::make_sparsity_pattern(dof_handler_, dsp, constraints_, false);
    SparsityTools::distribute_sparsity_pattern(dsp, locally_owned_, comm_, locally_relevant_);
    system_matrix_.reinit(locally_owned_, locally_owned_, dsp, comm_);
    system_rhs_.reinit(locally_owned_, comm_);
    solution_.reinit(locally_owned_, comm_);
    ghosted_solution_.reinit(locally_owned_, locally_relevant_, comm_);

    result_.dof_count = dof_handler_.n_dofs();
    result_.node_count = dof_handler_.n_dofs() / dim;
    result_.cell_count = triangulation_.n_active_cells();
    result_.mpi_processes = Utilities::MPI::n_mpi_processes(comm_);
  }

  /// Bonded: u = δ d. Frictionless: the single linear constraint u·d = δ per patch node,
  /// written on the component where |d_k| is largest (so any direction works, not only −z).
  void add_punch_constraints(const RigidPunch& punch) {
    const types::boundary_id patch = boundary_id("tool_patch", true);
    const Eigen::Vector3d d = punch.direction.normalized();
    if (punch.contact == touchstone::geometry::ContactCondition::bonded) {
      const Eigen::Vector3d u = punch.depth_m * d;
      VectorTools::interpolate_boundary_values(
          mapping_, dof_handler_, patch,
          Functions::ConstantFunction<dim>(std::vector<double>{u[0], u[1], u[2]}), constraints_);
      return;
    }
    int k = 0;
    d.cwiseAbs().maxCoeff(&k);
    std::vector<types::global_dof_index> face_dofs;
    for (const auto& cell : dof_handler_.active_cell_iterators()) {
      if (cell->is_artificial()) continue;
      for (const auto f : cell->face_indices()) {
        if (!cell->face(f)->at_boundary() || cell->face(f)->boundary_id() != patch) continue;
        // The face's own dofs: FiniteElement::has_support_on_face cannot select them, since
        // deal.II 9.4's simplex elements keep its default "true" for every dof of the cell (which
        // would constrain the nodes one layer under the patch too). Group them by support point:
        // the base index is shared by the three components of one node.
        face_dofs.resize(fe_.n_dofs_per_face(f));
        cell->face(f)->get_dof_indices(face_dofs);
        std::map<unsigned int, std::array<types::global_dof_index, dim>> nodes;
        for (unsigned int i = 0; i < face_dofs.size(); ++i) {
          const auto [component, base_index] = fe_.face_system_to_component_index(i, f);
          nodes[base_index][component] = face_dofs[i];
        }
        for (const auto& [base_index, node] : nodes) {
          const auto line = node[k];
          if (constraints_.is_constrained(line)) continue;
          constraints_.add_line(line);
          for (int j = 0; j < dim; ++j)
            if (j != k && std::abs(d[j]) > 1e-14) constraints_.add_entry(line, node[j], -d[j] / d[k]);
          constraints_.set_inhomogeneity(line, punch.depth_m / d[k]);
        }
      }
    }
  }

  /// Displacement formulation: K_c = ∫ (2μ ε(φ_i):ε(φ_j) + λ div φ_i div φ_j) dx.
  /// Mixed: K_c = ∫ 2μ dev ε(φ_i):dev ε(φ_j) dx + κ G_i G_j / |K| with G_j = ∫_K div φ_j dx, the
  /// general κ Gᵀ M⁻¹ G of a condensed discontinuous pressure with M = |K| for P0: the pressure
  /// p = κ Π₀(div u) = κ G·u_c / |K| is eliminated. `pressure`, when given, receives the row
  /// κ G / |K| [Pa/m] that recovers p from the cell's displacement.
  /// (With Π = identity the two agree: ε:ε = dev ε:dev ε + (tr ε)²/3 and λ = κ − 2μ/3.)
  void cell_matrix(const FEValues<dim>& fe_values, FullMatrix<double>& matrix,
                   Vector<double>* pressure = nullptr) const {
    if (mixed_) {
      mixed_cell_matrix(fe_values, matrix, pressure);
      return;
    }
    // Every shape function of the FESystem is primitive: φ_i = ψ_k e_a with a = component_[i].
    // With g_i = ∇ψ_k, ε(φ_i):ε(φ_j) = ½ (δ_ab g_i·g_j + g_i[b] g_j[a]) and div φ_i = g_i[a], so
    // K_ij = ∫ μ (δ_ab g_i·g_j + g_i[b] g_j[a]) + λ g_i[a] g_j[b]: the same integrand as
    // 2μ ε:ε + λ div div, without forming a strain tensor per shape function.
    const unsigned int n = fe_.n_dofs_per_cell();
    gradients_.resize(n);
    matrix = 0;
    for (const unsigned int q : fe_values.quadrature_point_indices()) {
      for (unsigned int i = 0; i < n; ++i) gradients_[i] = fe_values.shape_grad(i, q);
      const double jxw = fe_values.JxW(q);
      const double mu = mu_ * jxw, lambda = lambda_ * jxw;
      for (unsigned int i = 0; i < n; ++i) {
        const unsigned int a = component_[i];
        const Tensor<1, dim>& gi = gradients_[i];
        for (unsigned int j = i; j < n; ++j) {
          const unsigned int b = component_[j];
          const Tensor<1, dim>& gj = gradients_[j];
          double v = mu * gi[b] * gj[a] + lambda * gi[a] * gj[b];
          if (a == b) v += mu * (gi * gj);
          matrix(i, j) += v;
        }
      }
    }
    for (unsigned int i = 0; i < n; ++i)
      for (unsigned int j = 0; j < i; ++j) matrix(i, j) = matrix(j, i);
  }

  void mixed_cell_matrix(const FEValues<dim>& fe_values, FullMatrix<double>& matrix,
                         Vector<double>* pressure) const {
    const FEValuesExtractors::Vector u(0);
    const unsigned int n = fe_.n_dofs_per_cell();
    std::vector<SymmetricTensor<2, dim>> deviatoric(n);
    Vector<double> divergence_integral(n);  // G_j [m²]
    double volume = 0;                      // |K| [m³]
    matrix = 0;
    for (const unsigned int q : fe_values.quadrature_point_indices()) {
      const double jxw = fe_values.JxW(q);
      for (unsigned int i = 0; i < n; ++i) {
        const SymmetricTensor<2, dim> strain = fe_values[u].symmetric_gradient(i, q);
        divergence_integral(i) += trace(strain) * jxw;
        deviatoric[i] = deviator(strain);
      }
      volume += jxw;
      for (unsigned int i = 0; i < n; ++i)
        for (unsigned int j = i; j < n; ++j) matrix(i, j) += 2 * mu_ * (deviatoric[i] * deviatoric[j]) * jxw;
    }
    for (unsigned int i = 0; i < n; ++i)
      for (unsigned int j = i; j < n; ++j)
        matrix(i, j) += kappa_ * divergence_integral(i) * divergence_integral(j) / volume;
    for (unsigned int i = 0; i < n; ++i)
      for (unsigned int j = 0; j < i; ++j) matrix(i, j) = matrix(j, i);
    if (pressure) {
      *pressure = divergence_integral;
      *pressure *= kappa_ / volume;
    }
  }

  /// f_c = ∫ φ_i·b dx + ∫_Γt φ_i·t̄ ds.
  void cell_load(const typename DoFHandler<dim>::active_cell_iterator& cell,
                 const FEValues<dim>& fe_values, FEFaceValues<dim>& face_values,
                 Vector<double>& load) const {
    const FEValuesExtractors::Vector u(0);
    load = 0;
    if (problem_.body_force) {
      for (const unsigned int q : fe_values.quadrature_point_indices()) {
        const Eigen::Vector3d b = problem_.body_force(to_eigen(fe_values.quadrature_point(q)));
        const Tensor<1, dim> bt({b[0], b[1], b[2]});
        for (unsigned int i = 0; i < fe_.n_dofs_per_cell(); ++i)
          load(i) += fe_values[u].value(i, q) * bt * fe_values.JxW(q);
      }
    }
    for (const auto& condition : problem_.conditions) {
      if (condition.kind != BoundaryCondition::Kind::traction) continue;
      const auto id = boundary_id(condition.boundary, true);
      for (const auto f : cell->face_indices()) {
        if (!cell->face(f)->at_boundary() || cell->face(f)->boundary_id() != id) continue;
        face_values.reinit(cell, f);
        for (const unsigned int q : face_values.quadrature_point_indices()) {
          const Eigen::Vector3d t = condition.value(to_eigen(face_values.quadrature_point(q)));
          const Tensor<1, dim> tt({t[0], t[1], t[2]});
          for (unsigned int i = 0; i < fe_.n_dofs_per_cell(); ++i)
            load(i) += face_values[u].value(i, q) * tt * face_values.JxW(q);
        }
      }
    }
  }

  bool has_load() const {
    if (problem_.body_force) return true;
    return std::any_of(problem_.conditions.begin(), problem_.conditions.end(), [](const auto& c) {
      return c.kind == BoundaryCondition::Kind::traction;
    });
  }

  void assemble() {
    FEValues<dim> fe_values(mapping_, fe_, stiffness_quadrature_, update_gradients | update_JxW_values);
    FEValues<dim> load_values(mapping_, fe_, quadrature_,
                              update_values | update_quadrature_points | update_JxW_values);
    FEFaceValues<dim> face_values(mapping_, fe_, face_quadrature_,
                                  update_values | update_quadrature_points | update_JxW_values);
    const unsigned int n = fe_.n_dofs_per_cell();
    FullMatrix<double> matrix(n, n);
    Vector<double> load(n);
    std::vector<types::global_dof_index> dofs(n);
    const bool loaded = has_load();
    for (const auto& cell : dof_handler_.active_cell_iterators()) {
      if (!cell->is_locally_owned()) continue;
      fe_values.reinit(cell);
      cell_matrix(fe_values, matrix);
      if (loaded) {
        load_values.reinit(cell);
        cell_load(cell, load_values, face_values, load);
      }
      cell->get_dof_indices(dofs);
      constraints_.distribute_local_to_global(matrix, load, dofs, system_matrix_, system_rhs_);
    }
    system_matrix_.compress(VectorOperation::add);
    system_rhs_.compress(VectorOperation::add);
  }

  void solve();
  void solve_with_mumps();
  void check_solution_is_finite() const;

  /// Reaction force from the unconstrained residual r = K u − f on the patch dofs, strain
  /// energy, probe values and (optionally) the L2 error. Each cell is owned by one rank, so the
  /// cell-wise sums add up over ranks without double counting.
  /// Which dofs belong to the faces of boundary `id` (the faces' own dofs, not
  /// has_support_on_face: see add_punch_constraints).
  std::vector<bool> dofs_on_boundary(types::boundary_id id) const {
    std::vector<bool> on(dof_handler_.n_dofs(), false);
    std::vector<types::global_dof_index> face_dofs;
    for (const auto& cell : dof_handler_.active_cell_iterators()) {
      if (cell->is_artificial()) continue;
      for (const auto f : cell->face_indices()) {
        if (!cell->face(f)->at_boundary() || cell->face(f)->boundary_id() != id) continue;
        face_dofs.resize(fe_.n_dofs_per_face(f));
        cell->face(f)->get_dof_indices(face_dofs);
        for (const auto dof : face_dofs) on[dof] = true;
      }
    }
    return on;
  }

  void postprocess() {
    const std::vector<bool> on_patch = problem_.punch ? dofs_on_boundary(boundary_id("tool_patch", true))
                                                      : std::vector<bool>(dof_handler_.n_dofs(), false);
    const unsigned int n = fe_.n_dofs_per_cell();
    std::vector<types::global_dof_index> dofs(n);

    // Boundary works: which dofs lie on each boundary, and the support points of a cell's dofs
    // to evaluate the virtual displacement at.
    const std::size_t work_count = problem_.boundary_works.size();
    std::vector<std::vector<bool>> on_work_boundary;
    for (const BoundaryWork& work : problem_.boundary_works)
      on_work_boundary.push_back(dofs_on_boundary(boundary_id(work.boundary, true)));
    std::vector<double> works(work_count, 0.0);
    FEValues<dim> support_values(mapping_, fe_, Quadrature<dim>(fe_.get_unit_support_points()),
                                 update_quadrature_points);

    FEValues<dim> fe_values(mapping_, fe_, stiffness_quadrature_, update_gradients | update_JxW_values);
    FEValues<dim> load_values(mapping_, fe_, quadrature_,
                              update_values | update_quadrature_points | update_JxW_values);
    FEFaceValues<dim> face_values(mapping_, fe_, face_quadrature_,
                                  update_values | update_quadrature_points | update_JxW_values);
    FullMatrix<double> matrix(n, n);
    Vector<double> load(n), u(n), ku(n);
    const bool loaded = has_load();
    double energy = 0;
    Tensor<1, dim> force;
    Vector<double> pressure_row(n);
    if (mixed_) cell_pressures_.assign(triangulation_.n_active_cells(), 0.0);
    for (const auto& cell : dof_handler_.active_cell_iterators()) {
      if (!cell->is_locally_owned()) continue;
      fe_values.reinit(cell);
      cell_matrix(fe_values, matrix, mixed_ ? &pressure_row : nullptr);
      cell->get_dof_values(ghosted_solution_, u);
      matrix.vmult(ku, u);
      energy += 0.5 * (u * ku);
      if (mixed_) cell_pressures_[cell->active_cell_index()] = pressure_row * u;
      if (!problem_.punch && work_count == 0) continue;
      if (loaded) {
        load_values.reinit(cell);
        cell_load(cell, load_values, face_values, load);
      }
      cell->get_dof_indices(dofs);
      if (problem_.punch)
        for (unsigned int i = 0; i < n; ++i)
          if (on_patch[dofs[i]])
            force[fe_.system_to_component_index(i).first] += ku(i) - (loaded ? load(i) : 0.0);
      if (work_count == 0) continue;
      support_values.reinit(cell);
      for (std::size_t w = 0; w < work_count; ++w)
        for (unsigned int i = 0; i < n; ++i) {
          if (!on_work_boundary[w][dofs[i]]) continue;
          const Point<dim>& x = support_values.quadrature_point(i);
          const Eigen::Vector3d g = problem_.boundary_works[w].field(Eigen::Vector3d(x[0], x[1], x[2]));
          works[w] += (ku(i) - (loaded ? load(i) : 0.0)) * g[fe_.system_to_component_index(i).first];
        }
    }
    energy = Utilities::MPI::sum(energy, comm_);
    force = Utilities::MPI::sum(force, comm_);
    if (work_count > 0) Utilities::MPI::sum(works, comm_, works);
    result_.boundary_work_J = works;
    result_.energy_J = energy;
    result_.force_N = to_eigen(Point<dim>(force));
    if (problem_.punch) result_.energy_force_N = 2 * energy / problem_.punch->depth_m;

    evaluate_probes();

    if (problem_.exact_displacement) {
      Vector<float> cellwise(triangulation_.n_active_cells());
      VectorTools::integrate_difference(mapping_, dof_handler_, ghosted_solution_,
                                        FieldFunction(problem_.exact_displacement), cellwise,
                                        QGaussSimplex<dim>(problem_.solver.degree + 2),
                                        VectorTools::L2_norm);
      result_.l2_error_m =
          VectorTools::compute_global_error(triangulation_, cellwise, VectorTools::L2_norm);
    }
  }

  /// Every rank holds the whole mesh, so every rank can find the cell; only its owner has the
  /// values, and a sum over ranks delivers them everywhere. Points a little outside the faceted
  /// surface (a probe on the exact sphere) are accepted within a tolerance in cell coordinates.
  void evaluate_probes() {
    const std::size_t count = problem_.probes.size();
    std::vector<double> values(3 * count, 0.0), found(count, 0.0);
    GridTools::Cache<dim> cache(triangulation_, mapping_);
    for (std::size_t p = 0; p < count; ++p) {
      const Point<dim> point = to_point(problem_.probes[p]);
      std::pair<typename Triangulation<dim>::active_cell_iterator, Point<dim>> located;
      try {
        located = GridTools::find_active_cell_around_point(cache, point, {}, {}, 1e-2);
      } catch (const std::exception&) {
        continue;
      }
      if (located.first.state() != IteratorState::valid || !located.first->is_locally_owned())
        continue;
      const typename DoFHandler<dim>::active_cell_iterator cell(&triangulation_, located.first->level(),
                                                                 located.first->index(), &dof_handler_);
      FEValues<dim> fe_values(mapping_, fe_, Quadrature<dim>(located.second), update_values);
      fe_values.reinit(cell);
      std::vector<Vector<double>> value(1, Vector<double>(dim));
      fe_values.get_function_values(ghosted_solution_, value);
      for (int c = 0; c < dim; ++c) values[3 * p + c] = value[0][c];
      found[p] = 1.0;
    }
    // A probe exactly on a partition boundary is found by two ranks: average over finders.
    Utilities::MPI::sum(values, comm_, values);
    Utilities::MPI::sum(found, comm_, found);
    result_.probe_displacements_m.assign(count, Eigen::Vector3d::Zero());
    result_.probe_found.assign(count, false);
    for (std::size_t p = 0; p < count; ++p) {
      if (found[p] < 0.5) continue;
      result_.probe_found[p] = true;
      for (int c = 0; c < dim; ++c) result_.probe_displacements_m[p][c] = values[3 * p + c] / found[p];
    }
  }

  void write_vtu() {
    DataOut<dim> data_out;
    data_out.attach_dof_handler(dof_handler_);
    const std::vector<DataComponentInterpretation::DataComponentInterpretation> vector_field(
        dim, DataComponentInterpretation::component_is_part_of_vector);
    data_out.add_data_vector(ghosted_solution_, std::vector<std::string>(dim, "displacement_m"),
                             DataOut<dim>::type_dof_data, vector_field);
    const StressPostprocessor stress(lambda_, mu_, mixed_ ? &cell_pressures_ : nullptr);
    data_out.add_data_vector(ghosted_solution_, stress);
    Vector<float> subdomain(triangulation_.n_active_cells());
    for (auto& s : subdomain) s = static_cast<float>(triangulation_.locally_owned_subdomain());
    data_out.add_data_vector(subdomain, "subdomain");
    data_out.build_patches(mapping_);
    std::string directory = problem_.vtu_directory;
    if (directory.back() != '/') directory += '/';
    result_.vtu_file = directory + data_out.write_vtu_with_pvtu_record(
                                       directory, problem_.vtu_basename, 0, comm_, 2);
  }

  const ElasticityProblem& problem_;
  MPI_Comm comm_;
  parallel::shared::Triangulation<dim> triangulation_;
  FESystem<dim> fe_;
  MappingFE<dim> mapping_;
  DoFHandler<dim> dof_handler_;
  /// Exact for the stiffness: on the affine cells the integrand is a polynomial of degree
  /// 2(degree − 1), which QGaussSimplex(degree) integrates exactly (1 point for P1, 6 for P2,
  /// against the 14 of QGaussSimplex(3): the same matrix to rounding for less than half the
  /// cell work).
  QGaussSimplex<dim> stiffness_quadrature_;
  QGaussSimplex<dim> quadrature_;  ///< loads (body forces of any smoothness): one degree more
  QGaussSimplex<dim - 1> face_quadrature_;
  double lambda_, mu_;
  double kappa_;                 ///< bulk modulus κ = λ + 2μ/3 [Pa]
  bool mixed_;                   ///< Formulation::mixed_p0disc
  std::vector<double> cell_pressures_;  ///< p = κ Π₀(div u) [Pa] of the locally owned cells
  std::vector<unsigned int> component_;  ///< the vector component of each cell shape function
  mutable std::vector<Tensor<1, dim>> gradients_;  ///< cell_matrix's scratch: ∇ψ of each shape function [1/m]
  std::map<std::string, int> surface_tags_;  ///< surface group name → physical tag (boundary id)

  IndexSet locally_owned_, locally_relevant_;
  AffineConstraints<double> constraints_;
  typename LA::SparseMatrix system_matrix_;
  typename LA::Vector system_rhs_, solution_, ghosted_solution_;
  ElasticitySolution result_;
};

/// CG + Trilinos ML. ML gets the three translations as near-null space (9.4 accepts only
/// constant modes), with settings for higher-order elliptic problems.
template <>
void ElasticitySolver<TrilinosAlgebra>::solve() {
  TrilinosWrappers::PreconditionAMG::AdditionalData data;
  data.elliptic = true;
  data.higher_order_elements = problem_.solver.degree > 1;
  data.smoother_sweeps = 2;
  data.aggregation_threshold = 0.02;
  DoFTools::extract_constant_modes(dof_handler_, ComponentMask(), data.constant_modes);
  TrilinosWrappers::PreconditionAMG amg;
  amg.initialize(system_matrix_, data);

  SolverControl control(problem_.solver.max_iterations,
                        problem_.solver.relative_tolerance * system_rhs_.l2_norm());
  TrilinosWrappers::SolverCG cg(control);
  try {
    cg.solve(system_matrix_, solution_, system_rhs_, amg);
  } catch (const std::exception& e) {
    throw std::runtime_error("CG + Trilinos ML did not converge in " +
                             std::to_string(control.last_step()) + " iterations: " + e.what());
  }
  constraints_.distribute(solution_);
  ghosted_solution_ = solution_;
  result_.solver_name = "CG + Trilinos ML AMG (translation near-null space)";
  result_.solver_iterations = control.last_step();
  result_.solver_residual = control.last_value();
}

void check_petsc(PetscErrorCode code, const char* what) {
  if (code != 0) throw std::runtime_error(std::string("PETSc error in ") + what + ", code " + std::to_string(code));
}

/// A PETSc option set for the lifetime of this object, unless the user's options (command line,
/// PETSC_OPTIONS) already give it; the database is left as it was found.
class PetscDefaultOption {
 public:
  PetscDefaultOption(const char* name, const char* value) : name_(name) {
    PetscBool given = PETSC_FALSE;
    check_petsc(PetscOptionsHasName(nullptr, nullptr, name, &given), "PetscOptionsHasName");
    if (given) return;
    check_petsc(PetscOptionsSetValue(nullptr, name, value), "PetscOptionsSetValue");
    set_ = true;
  }
  ~PetscDefaultOption() {
    if (set_) PetscOptionsClearValue(nullptr, name_);
  }
  PetscDefaultOption(const PetscDefaultOption&) = delete;
  PetscDefaultOption& operator=(const PetscDefaultOption&) = delete;

 private:
  const char* name_;
  bool set_ = false;
};

/// A PETSc option set to `value` for the lifetime of this object, whatever the database held;
/// the previous value (or its absence) is put back afterwards.
class PetscScopedOption {
 public:
  PetscScopedOption(const char* name, const std::string& value) : name_(name) {
    char previous[256] = {0};
    PetscBool found = PETSC_FALSE;
    check_petsc(PetscOptionsGetString(nullptr, nullptr, name, previous, sizeof previous, &found), "PetscOptionsGetString");
    if (found) previous_ = std::string(previous);
    check_petsc(PetscOptionsSetValue(nullptr, name, value.c_str()), "PetscOptionsSetValue");
  }
  ~PetscScopedOption() {
    if (previous_)
      PetscOptionsSetValue(nullptr, name_, previous_->c_str());
    else
      PetscOptionsClearValue(nullptr, name_);
  }
  PetscScopedOption(const PetscScopedOption&) = delete;
  PetscScopedOption& operator=(const PetscScopedOption&) = delete;

 private:
  const char* name_;
  std::optional<std::string> previous_;
};

/// MUMPS' errors whose remedy, in its user guide, is a larger ICNTL(14): a workspace sized from
/// the analysis's estimate that the factorisation or the solution outgrew.
bool mumps_workspace_too_small(PetscInt infog1) {
  return infog1 == -8 || infog1 == -9 || infog1 == -11 || infog1 == -12 || infog1 == -14 || infog1 == -15;
}

/// MUMPS' names for the orderings of ICNTL(7) and INFOG(7).
std::string mumps_ordering_name(PetscInt ordering) {
  switch (ordering) {
    case 0: return "AMD";
    case 1: return "user-given";
    case 2: return "AMF";
    case 3: return "SCOTCH";
    case 4: return "PORD";
    case 5: return "METIS";
    case 6: return "QAMD";
    default: return "unknown (" + std::to_string(ordering) + ")";
  }
}

/// MUMPS' sparse LDLᵀ through PETSc's Cholesky factor interface, told that the matrix is
/// positive definite (the constrained rows keep a positive diagonal), so that it factorises
/// without pivoting, and ordered by approximate minimum degree: at the sizes a direct solve is
/// chosen for (the paper's Table 2 mesh, the tests' meshes) AMD's analysis is a quarter of that of
/// MUMPS' automatic choice here, nested dissection (PORD), whose smaller factor does not win
/// back the difference (the README's Table 2 section has the phase times). A workspace that the
/// factorisation outgrows is enlarged and the factorisation repeated; any other failed analysis
/// or factorisation (MUMPS' INFOG(1) < 0) is an error naming MUMPS' codes, not a solution of
/// NaNs. The solver name records the ordering MUMPS used (INFOG(7)), not the one asked for.
template <>
void ElasticitySolver<PetscAlgebra>::solve_with_mumps() {
  // PETSc 3.18 initialises MUMPS at the analysis and then sets its controls from the options
  // database, so an ICNTL set on the factor matrix before (MatMumpsSetIcntl) is lost: the
  // ordering and the workspace go through the database.
  const PetscDefaultOption ordering("-mat_mumps_icntl_7", "0");  // 0: approximate minimum degree
  Mat A = system_matrix_.petsc_matrix();
  check_petsc(MatSetOption(A, MAT_SPD, PETSC_TRUE), "MatSetOption");
  // MUMPS sizes its workspace from the analysis's estimate plus ICNTL(14) percent. With several
  // processes its dynamic scheduling can outgrow that (INFOG(1) = -9, seen on a B2 mesh of the
  // paper's size under two ranks, for one of its partitions): the factorisation is then repeated
  // with the relaxation doubled, a few times, before it is reported as a failure.
  constexpr int max_workspace_retries = 4;
  std::optional<PetscScopedOption> workspace;  // emplacing a new value first restores the previous one
  PetscInt relaxation_percent = -1;  // -1: MUMPS' own (or the user's) ICNTL(14)
  for (int attempt = 0;; ++attempt) {
    KSP ksp;
    PC pc;
    Mat factor;
    check_petsc(KSPCreate(comm_, &ksp), "KSPCreate");
    // Destroyed on every way out, a thrown PETSc error included.
    const std::unique_ptr<KSP, void (*)(KSP*)> destroy_ksp(&ksp, [](KSP* k) { KSPDestroy(k); });
    check_petsc(KSPSetOperators(ksp, A, A), "KSPSetOperators");
    check_petsc(KSPSetType(ksp, KSPPREONLY), "KSPSetType");
    check_petsc(KSPGetPC(ksp, &pc), "KSPGetPC");
    check_petsc(PCSetType(pc, PCCHOLESKY), "PCSetType");
    check_petsc(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS), "PCFactorSetMatSolverType");
    check_petsc(PCFactorSetUpMatSolverType(pc), "PCFactorSetUpMatSolverType");
    check_petsc(PCFactorGetMatrix(pc, &factor), "PCFactorGetMatrix");
    check_petsc(KSPSetFromOptions(ksp), "KSPSetFromOptions");
    check_petsc(KSPSolve(ksp, system_rhs_, solution_), "KSPSolve");
    KSPConvergedReason reason;
    KSPGetConvergedReason(ksp, &reason);
    PetscInt infog1 = 0, infog2 = 0, used_percent = 0;
    MatMumpsGetInfog(factor, 1, &infog1);
    MatMumpsGetInfog(factor, 2, &infog2);
    MatMumpsGetIcntl(factor, 14, &used_percent);
    if (mumps_workspace_too_small(infog1) && attempt < max_workspace_retries) {
      relaxation_percent = 2 * std::max<PetscInt>(used_percent, 10);
      workspace.emplace("-mat_mumps_icntl_14", std::to_string(relaxation_percent));
      continue;
    }
    if (reason < 0 || infog1 < 0)
      throw std::runtime_error("MUMPS LDLT failed on the " + std::to_string(dof_handler_.n_dofs()) + "-dof system of " +
                               problem_.mesh_path + ": INFOG(1) = " + std::to_string(infog1) + ", INFOG(2) = " +
                               std::to_string(infog2) + ", PETSc reason " + std::to_string(reason) + ", ICNTL(14) = " +
                               std::to_string(used_percent) + " % after " + std::to_string(attempt + 1) +
                               (attempt == 0 ? " attempt" : " attempts") + " (the MUMPS user guide lists the codes)");
    constraints_.distribute(solution_);
    ghosted_solution_ = solution_;
    PetscInt ordering_used = -1;
    MatMumpsGetInfog(factor, 7, &ordering_used);
    result_.solver_name = "PETSc MUMPS sparse LDLT (SPD, " + mumps_ordering_name(ordering_used) + " ordering" +
                          (relaxation_percent > 0 ? ", workspace ICNTL(14) = " + std::to_string(relaxation_percent) + " %"
                                                  : std::string()) +
                          ")";
    result_.solver_iterations = 1;
    return;
  }
}

/// Every linear solver's answer is checked before anything is derived from it: a NaN or an
/// infinity would otherwise become the force of a report (and null in its JSON).
template <typename LA>
void ElasticitySolver<LA>::check_solution_is_finite() const {
  // A NaN or an infinity anywhere makes the (collective) 2-norm NaN or infinite.
  const double norm = solution_.l2_norm();
  if (!std::isfinite(norm))
    throw std::runtime_error(result_.solver_name + " returned a solution that is not finite on " + problem_.mesh_path +
                             " (its 2-norm is " + std::to_string(norm) + ", over " +
                             std::to_string(dof_handler_.n_dofs()) + " dofs)");
}

/// PETSc: MUMPS LDLᵀ, or CG + GAMG with the six rigid-body modes as near-null space. GAMG needs
/// the nodal block size 3, which holds when deal.II numbers the three components of every
/// support point consecutively (checked; otherwise the block size is left at 1).
template <>
void ElasticitySolver<PetscAlgebra>::solve() {
  if (problem_.solver.solver == LinearSolver::direct_mumps) {
    solve_with_mumps();
    return;
  }

  const std::vector<types::global_dof_index> owned = [&] {
    std::vector<types::global_dof_index> v;
    for (const auto i : locally_owned_) v.push_back(i);
    return v;
  }();
  std::map<types::global_dof_index, Point<dim>> support_points;
  DoFTools::map_dofs_to_support_points(mapping_, dof_handler_, support_points);
  const ComponentMask all(dim, true);
  std::vector<IndexSet> component_dofs = DoFTools::locally_owned_dofs_per_component(dof_handler_, all);
  bool blocked = owned.size() % dim == 0 && !owned.empty() && owned.front() % dim == 0;
  for (std::size_t i = 0; blocked && i < owned.size(); ++i) {
    const auto dof = owned[i];
    blocked = component_dofs[dof % dim].is_element(dof) &&
              support_points.at(dof).distance(support_points.at(dof - dof % dim)) < 1e-14;
  }
  blocked = Utilities::MPI::min(blocked ? 1 : 0, comm_) == 1;

  Mat A = system_matrix_.petsc_matrix();
  KSP ksp;
  PC pc;
  check_petsc(KSPCreate(comm_, &ksp), "KSPCreate");
  check_petsc(KSPSetOperators(ksp, A, A), "KSPSetOperators");
  check_petsc(KSPSetType(ksp, KSPCG), "KSPSetType");
  check_petsc(KSPGetPC(ksp, &pc), "KSPGetPC");
  check_petsc(PCSetType(pc, PCGAMG), "PCSetType");
  MatNullSpace near_null_space = nullptr;
  if (blocked) {
    check_petsc(MatSetBlockSize(A, dim), "MatSetBlockSize");
    Vec coordinates;
    check_petsc(VecCreateMPI(comm_, owned.size(), dof_handler_.n_dofs(), &coordinates), "VecCreateMPI");
    check_petsc(VecSetBlockSize(coordinates, dim), "VecSetBlockSize");
    PetscScalar* x;
    check_petsc(VecGetArray(coordinates, &x), "VecGetArray");
    for (std::size_t i = 0; i < owned.size(); ++i) x[i] = support_points.at(owned[i])[owned[i] % dim];
    check_petsc(VecRestoreArray(coordinates, &x), "VecRestoreArray");
    check_petsc(MatNullSpaceCreateRigidBody(coordinates, &near_null_space), "MatNullSpaceCreateRigidBody");
    check_petsc(MatSetNearNullSpace(A, near_null_space), "MatSetNearNullSpace");
    check_petsc(VecDestroy(&coordinates), "VecDestroy");
  }
  const double bnorm = system_rhs_.l2_norm();
  check_petsc(KSPSetTolerances(ksp, problem_.solver.relative_tolerance, 0.0, PETSC_DEFAULT,
                               problem_.solver.max_iterations),
              "KSPSetTolerances");
  check_petsc(KSPSetFromOptions(ksp), "KSPSetFromOptions");
  check_petsc(KSPSolve(ksp, system_rhs_, solution_), "KSPSolve");
  KSPConvergedReason reason;
  PetscInt iterations;
  PetscReal residual;
  KSPGetConvergedReason(ksp, &reason);
  KSPGetIterationNumber(ksp, &iterations);
  KSPGetResidualNorm(ksp, &residual);
  if (near_null_space) MatNullSpaceDestroy(&near_null_space);
  KSPDestroy(&ksp);
  if (reason < 0)
    throw std::runtime_error("CG + PETSc GAMG did not converge (reason " + std::to_string(reason) +
                             ") after " + std::to_string(iterations) + " iterations, residual " +
                             std::to_string(residual / std::max(bnorm, 1e-300)));
  constraints_.distribute(solution_);
  ghosted_solution_ = solution_;
  result_.solver_name = std::string("CG + PETSc GAMG (") +
                        (blocked ? "rigid-body near-null space, block size 3" : "scalar, no near-null space") + ")";
  result_.solver_iterations = static_cast<unsigned int>(iterations);
  result_.solver_residual = residual;
}

}  // namespace

ElasticitySolution solve_elasticity(const ElasticityProblem& problem, MPI_Comm communicator) {
  problem.validate();
  if (problem.solver.solver == LinearSolver::cg_amg_trilinos)
    return ElasticitySolver<TrilinosAlgebra>(problem, communicator).run();
  return ElasticitySolver<PetscAlgebra>(problem, communicator).run();
}

struct MpiSession::Impl {
  Impl(int& argc, char**& argv) : mpi(argc, argv, 1) {}
  Utilities::MPI::MPI_InitFinalize mpi;
};

MpiSession::MpiSession(int& argc, char**& argv) {
  restart_with_native_blas_kernels(argv);  // before MPI starts: an MPI process cannot restart
  impl_ = new Impl(argc, argv);
}
MpiSession::~MpiSession() { delete impl_; }
unsigned int MpiSession::rank() { return Utilities::MPI::this_mpi_process(MPI_COMM_WORLD); }
unsigned int MpiSession::size() { return Utilities::MPI::n_mpi_processes(MPI_COMM_WORLD); }
void MpiSession::barrier() { MPI_Barrier(MPI_COMM_WORLD); }
void MpiSession::broadcast_from_root(std::vector<double>& values) {
  values = Utilities::MPI::broadcast(MPI_COMM_WORLD, values, 0);
}
void MpiSession::sum_over_ranks(std::vector<double>& values) {
  const std::vector<double> mine = values;
  Utilities::MPI::sum(mine, MPI_COMM_WORLD, values);
}

}  // namespace touchstone::fem
