// The enriched MFS: MLS Galerkin plus the punch fields, conditions by multipliers, the KKT solve
// (one concept; its quadratures and Gram assembly live in their own files).
#include "touchstone/realtime/mfs/enriched_galerkin.hpp"

#include "touchstone/realtime/mfs/consistent_gradients.hpp"
#include "touchstone/realtime/mfs/gradient_gram.hpp"
#include "touchstone/realtime/mfs/quadrature_rules.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;

/// The tool axis at the contact: c on the surface, d the push direction, t₁, t₂ ⟂ d.
struct AxisFrame {
  Eigen::Vector3d centre, push, t1, t2;
  Eigen::Vector3d radial(double phi) const { return std::cos(phi) * t1 + std::sin(phi) * t2; }
};

/// Unit directions at polar angle θ from the inward normal −n and azimuth φ about it.
struct PolarDirections {
  Eigen::Vector3d normal, t1, t2;
  explicit PolarDirections(const Eigen::Vector3d& outward_normal) : normal(outward_normal) {
    const Eigen::Vector3d helper = std::abs(normal.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    t1 = normal.cross(helper).normalized();
    t2 = normal.cross(t1);
  }
  /// The unit vector at azimuth φ in the tangent plane, cos φ t₁ + sin φ t₂.
  Eigen::Vector3d radial(double phi) const { return std::cos(phi) * t1 + std::sin(phi) * t2; }
  /// The direction at θ, given radial(φ): computed once per azimuth, so that the searches over
  /// θ do not recompute φ's sine and cosine at every step.
  Eigen::Vector3d at(double theta, const Eigen::Vector3d& radial_direction) const {
    return -std::cos(theta) * normal + std::sin(theta) * radial_direction;
  }
};

/// Rays from the contact point, cut where they leave the organ or reach L; Gauss–Legendre in
/// t with ρ = a (e^{κt} − 1) (graded toward the tool like the node cloud); the polar range per
/// azimuth ends where a short step along the ray already leaves the organ. The reach of a ray,
/// ρ_max(θ) = min(L, distance to the surface), has a kink at θ_cut, where the cut sphere meets
/// the organ surface, and Gauss–Legendre across a kink is only first-order accurate (it
/// over-counted the local ball's volume: docs/enriched_model.md, "The kink in the rays' reach").
/// So the polar range is two Gauss rules, [0, θ_cut] (rays of length L) with three quarters of
/// the polar points and [θ_cut, θ_max] (rays ending on the surface) with the rest, each over a
/// smooth integrand. The shells within
/// volume_coarse_within_tool_radii of the contact point (on a ray of full length L) take half
/// the angular counts: they hold little volume, and the shape functions are smooth across them.
PatchQuadrature enriched_volume_quadrature(const LocalSurface& surface, double tool_radius_m, double length,
                                           const EnrichedSettings& s) {
  const Eigen::Vector3d& centre = surface.centre();
  const PolarDirections direction(surface.normal());
  const auto inside = [&](const Eigen::Vector3d& x) { return surface.inside(x); };
  std::vector<double> xr, wr;
  gauss_legendre(s.volume_radial_points, xr, wr);
  const double coarse_below_t = std::log1p(s.volume_coarse_within_tool_radii) / std::log1p(length / tool_radius_m);
  const double probe = 0.25 * std::min(tool_radius_m, length);
  PatchQuadrature q;
  // At most the full angular product at every radial point (the inner shells take half of it).
  q.reserve(static_cast<std::size_t>(s.volume_radial_points) * static_cast<std::size_t>(s.volume_polar_points) *
            static_cast<std::size_t>(s.volume_azimuth_points));
  // One angular product rule over the shells t ∈ [t_low, t_high).
  const auto add_shells = [&](int azimuth_points, int polar_points, double t_low, double t_high) {
    const int rim_points = std::max(1, (polar_points + 2) / 4);
    std::vector<double> x_whole, w_whole, x_full, w_full, x_rim, w_rim;
    gauss_legendre(polar_points, x_whole, w_whole);
    gauss_legendre(polar_points - rim_points, x_full, w_full);
    gauss_legendre(rim_points, x_rim, w_rim);
    std::vector<std::pair<double, double>> polar;  // θ and its weight
    for (int k = 0; k < azimuth_points; ++k) {
      const double phi = 2 * pi * (k + 0.5) / azimuth_points;
      const Eigen::Vector3d radial = direction.radial(phi);
      const double theta_max = first_exit([&](double theta) { return inside(centre + probe * direction.at(theta, radial)); }, pi, 32);
      if (theta_max <= 0) continue;
      const double theta_cut =
          first_exit([&](double theta) { return inside(centre + length * direction.at(theta, radial)); }, pi, 32);
      polar.clear();
      // A wedge beyond θ_cut thinner than a milliradian (a flat body: both are π/2) holds no volume.
      if (theta_cut > 0 && theta_cut < theta_max - 1e-3) {
        for (std::size_t j = 0; j < x_full.size(); ++j) polar.emplace_back(theta_cut * x_full[j], theta_cut * w_full[j]);
        for (std::size_t j = 0; j < x_rim.size(); ++j)
          polar.emplace_back(theta_cut + (theta_max - theta_cut) * x_rim[j], (theta_max - theta_cut) * w_rim[j]);
      } else {
        for (std::size_t j = 0; j < x_whole.size(); ++j) polar.emplace_back(theta_max * x_whole[j], theta_max * w_whole[j]);
      }
      for (const auto& [theta, theta_weight] : polar) {
        const Eigen::Vector3d d = direction.at(theta, radial);
        const double reach = first_exit([&](double rho) { return inside(centre + rho * d); }, length, 32);
        if (reach <= 0) continue;
        const double scale = tool_radius_m;
        const double kappa = std::log1p(reach / scale);
        for (int i = 0; i < s.volume_radial_points; ++i) {
          if (xr[i] < t_low || xr[i] >= t_high) continue;
          const double rho = scale * std::expm1(kappa * xr[i]);
          const double jacobian = kappa * (rho + scale);
          q.points.push_back(centre + rho * d);
          q.normals.push_back(Eigen::Vector3d::Zero());
          q.weights.push_back(rho * rho * jacobian * wr[i] * std::sin(theta) * theta_weight * 2 * pi / azimuth_points);
        }
      }
    }
  };
  add_shells(std::max(4, s.volume_azimuth_points / 2), std::max(2, s.volume_polar_points / 2), 0, coarse_below_t);
  add_shells(s.volume_azimuth_points, s.volume_polar_points, coarse_below_t, 1);
  return q;
}

/// The cut sphere organ ∩ sphere(c, L) with normals out of the ball: per azimuth about the
/// inward normal, Gauss–Legendre in the polar angle up to where the sphere leaves the organ.
PatchQuadrature enriched_cut_quadrature(const LocalSurface& surface, double length, const EnrichedSettings& s) {
  const Eigen::Vector3d& centre = surface.centre();
  const PolarDirections direction(surface.normal());
  std::vector<double> x, w;
  gauss_legendre(s.cut_polar_points, x, w);
  PatchQuadrature q;
  q.reserve(static_cast<std::size_t>(s.cut_polar_points) * static_cast<std::size_t>(s.cut_azimuth_points));
  for (int k = 0; k < s.cut_azimuth_points; ++k) {
    const double phi = 2 * pi * (k + 0.5) / s.cut_azimuth_points;
    const Eigen::Vector3d radial = direction.radial(phi);
    const double theta_max =
        first_exit([&](double theta) { return surface.inside(centre + length * direction.at(theta, radial)); }, pi, 64);
    for (int i = 0; i < s.cut_polar_points; ++i) {
      const double theta = theta_max * x[i];
      const Eigen::Vector3d d = direction.at(theta, radial);
      q.points.push_back(centre + length * d);
      q.normals.push_back(d);
      q.weights.push_back(length * length * std::sin(theta) * theta_max * w[i] * 2 * pi / s.cut_azimuth_points);
    }
  }
  return q;
}

/// A surface on which the multipliers hold u (or its MLS part) at zero: its quadrature, and
/// whether the constraint includes the enrichment (clamped) or only the MLS part (an exterior).
struct ConstraintSurface {
  const PatchQuadrature* quadrature;
  bool includes_enrichment;
};

/// Values of the raw multiplier functions of a constraint surface at x (3 × count): the
/// monomials of ξ = (x − c)/L up to `degree` per component, then σ(ψ_m)n / scale.
void raw_multipliers(const Eigen::Vector3d& xi, int degree, const std::vector<Eigen::Vector3d>& traction_modes,
                     Eigen::Matrix<double, 3, Eigen::Dynamic>& out) {
  // Each power once (the degree is at most 4, so at most 35 monomials): this runs at every
  // point of the cut's rule, twice.
  constexpr int max_degree = 4;
  double power[3][max_degree + 1];
  for (int c = 0; c < 3; ++c)
    for (int e = 0; e <= degree; ++e) power[c][e] = std::pow(xi(c), e);
  std::array<double, (max_degree + 1) * (max_degree + 2) * (max_degree + 3) / 6> monomials;
  std::size_t found = 0;
  for (int i = 0; i <= degree; ++i)
    for (int j = 0; i + j <= degree; ++j)
      for (int k = 0; i + j + k <= degree; ++k) monomials[found++] = power[0][i] * power[1][j] * power[2][k];
  const Eigen::Index count = static_cast<Eigen::Index>(found);
  out.setZero(3, 3 * count + static_cast<Eigen::Index>(traction_modes.size()));
  for (Eigen::Index k = 0; k < count; ++k)
    for (int i = 0; i < 3; ++i) out(i, 3 * k + i) = monomials[static_cast<std::size_t>(k)];
  for (std::size_t m = 0; m < traction_modes.size(); ++m) out.col(3 * count + static_cast<Eigen::Index>(m)) = traction_modes[m];
}

/// Chebyshev polynomial T_k(t).
double chebyshev(int k, double t) { return std::cos(k * std::acos(std::clamp(t, -1.0, 1.0))); }

}  // namespace

std::vector<PunchMode> enrichment_modes(const ToolContact& contact, const PunchFrame& frame, double local_radius_m) {
  // A frictionless tool pushing along the patch normal loads only the normal mode; a bonded or
  // oblique one also shears the patch (its constraint traction along d has a tangential part)
  // and tilts its face against it. The tilt the MLS part would hold costs energy that grows as
  // θ²(L/a)³, so the tolerance on θ narrows for a fine tip in a wide ball.
  const Eigen::Vector3d d = contact.direction.normalized(), n = frame.axes.col(2);
  const double off_normal_rad = std::atan2(d.cross(n).norm(), d.dot(n));
  const double reach = local_radius_m / contact.radius_m;
  const bool along_normal = off_normal_rad < 1.0 * 3.14159265358979323846 / 180 &&
                            off_normal_rad * off_normal_rad * reach * reach * reach <= 0.04;
  if (contact.condition == geometry::ContactCondition::frictionless && along_normal) return {PunchMode::normal};
  // The tangential modes neglect their normal coupling, so their u₃ is odd under the disk; the
  // patch holds its tilt, and without the tilt modes the MLS part must, which stiffens it at
  // small N (docs/enriched_model.md, The tilt modes).
  if (contact.condition == geometry::ContactCondition::frictionless)
    return {PunchMode::normal, PunchMode::tangential_1, PunchMode::tangential_2, PunchMode::tilt_1, PunchMode::tilt_2};
  // A bonded patch also holds the radial slip that the normal mode has under the disk; without
  // the radial shear mode the MLS part must cancel it and locks at small N
  // (docs/enriched_model.md, The radial shear mode).
  return {PunchMode::normal, PunchMode::tangential_1, PunchMode::tangential_2, PunchMode::radial, PunchMode::tilt_1, PunchMode::tilt_2};
}

int translation_mode_count(const std::vector<PunchMode>& modes) {
  return static_cast<int>(std::count_if(modes.begin(), modes.end(), [](PunchMode m) {
    return m == PunchMode::normal || m == PunchMode::tangential_1 || m == PunchMode::tangential_2;
  }));
}

int cut_multiplier_degree(const EnrichedSettings& settings, std::size_t node_count) {
  if (settings.cut_multiplier_degree >= 0) return settings.cut_multiplier_degree;
  // Few nodes cannot satisfy many constraints without locking; many nodes would use a poor
  // multiplier space to slip along the cut.
  return node_count < 40 ? 1 : node_count <= 120 ? 2 : 3;
}

std::string to_string(ExteriorCondition exterior) {
  switch (exterior) {
    case ExteriorCondition::clamped: return "clamped";
    case ExteriorCondition::half_space: return "half_space";
    case ExteriorCondition::body_aware: return "body_aware";
  }
  return "unknown";
}

ExteriorCondition exterior_condition_from_string(const std::string& name) {
  if (name == "clamped") return ExteriorCondition::clamped;
  if (name == "half_space") return ExteriorCondition::half_space;
  if (name == "body_aware") return ExteriorCondition::body_aware;
  throw std::invalid_argument("exterior = '" + name + "': expected clamped, half_space or body_aware");
}

void EnrichedSettings::validate() const {
  const auto check = [](const char* field, int value, int low, int high) {
    if (value < low || value > high)
      throw std::invalid_argument(std::string("EnrichedSettings.") + field + " = " + std::to_string(value) +
                                  " must be in [" + std::to_string(low) + ", " + std::to_string(high) + "]");
  };
  check("support_neighbours", support_neighbours, 4, 200);
  check("min_point_neighbours", min_point_neighbours, 10, 200);
  // 0: picked by the gradient correction (settings_for_material).
  const auto check_rule = [&](const char* field, int value, int low, int high) {
    if (value != 0) check(field, value, low, high);
  };
  check_rule("volume_radial_points", volume_radial_points, 2, 64);
  check_rule("volume_polar_points", volume_polar_points, 2, 64);
  check_rule("volume_azimuth_points", volume_azimuth_points, 4, 256);
  if (!(volume_coarse_within_tool_radii >= 0 && volume_coarse_within_tool_radii <= 1e3))
    throw std::invalid_argument("EnrichedSettings.volume_coarse_within_tool_radii = " +
                                std::to_string(volume_coarse_within_tool_radii) + " must be in [0, 1000]");
  check("patch_radial_points", patch_radial_points, 2, 64);
  check("patch_angular_points", patch_angular_points, 4, 256);
  check("free_radial_points", free_radial_points, 2, 64);
  check("free_azimuth_points", free_azimuth_points, 4, 256);
  check_rule("cut_polar_points", cut_polar_points, 2, 64);
  check_rule("cut_azimuth_points", cut_azimuth_points, 4, 256);
  check("cut_multiplier_degree", cut_multiplier_degree, -1, 4);
  check("bonded_patch_dome_from_nodes", bonded_patch_dome_from_nodes, 0, 1000000);
  check("volumetric_linear_space_up_to_nodes", volumetric_linear_space_up_to_nodes, 0, 1000000);
}

namespace {
/// Below this many nodes the need-th smallest distance is found by counting: n² comparisons that
/// vectorise and never mispredict, against the insertion's n·need with a branch per node that
/// often does (most of the support radii's time on small clouds).
constexpr std::size_t count_selection_up_to_nodes = 64;

/// The need-th smallest of the values (1 ≤ need ≤ size): the value v with fewer than need values
/// below it and at least need at or below it, so ties give what a sort would.
double nth_smallest_by_counting(const std::vector<double>& values, std::size_t need) {
  const std::size_t n = values.size();
  for (std::size_t j = 0; j < n; ++j) {
    const double v = values[j];
    std::size_t below = 0, at_most = 0;
    for (std::size_t i = 0; i < n; ++i) {
      below += values[i] < v ? 1 : 0;
      at_most += values[i] <= v ? 1 : 0;
    }
    if (below < need && need <= at_most) return v;
  }
  return std::numeric_limits<double>::infinity();  // fewer than need comparable values, as the insertion
}

/// The same by insertion into a short sorted list (most values fail its first comparison).
double nth_smallest_by_insertion(const std::vector<double>& values, std::size_t need, std::vector<double>& nearest) {
  nearest.assign(need, std::numeric_limits<double>::infinity());
  for (const double v : values) {
    if (!(v < nearest[need - 1])) continue;
    std::size_t at = need - 1;
    for (; at > 0 && nearest[at - 1] > v; --at) nearest[at] = nearest[at - 1];
    nearest[at] = v;
  }
  return nearest[need - 1];
}
}  // namespace

std::vector<double> enriched_support_radii(const std::vector<Eigen::Vector3d>& nodes,
                                           const std::vector<const PatchQuadrature*>& points, int support_neighbours,
                                           int min_neighbours) {
  const std::size_t n = nodes.size();
  std::vector<double> radii(n, 0.0), distance(n);
  const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(support_neighbours), n - 1);
  for (std::size_t j = 0; j < n; ++j) {
    for (std::size_t i = 0; i < n; ++i) distance[i] = (nodes[i] - nodes[j]).norm();
    std::nth_element(distance.begin(), distance.begin() + static_cast<std::ptrdiff_t>(k), distance.end());
    radii[j] = distance[k];
  }
  // Grow locally: a point seeing too few nodes reaches its nearest ones, each made to cover it
  // with a margin (W vanishes at the support's edge, so a node just inside adds nothing). Every
  // point is judged against the k-nearest radii, not against the growth of the points before
  // it: the supports must not depend on the order in which the quadrature rules list their
  // points (docs/enriched_model.md, "Supports that do not depend on the point order").
  // Most points see enough nodes: they are counted on squared distances, over coordinates held
  // as separate arrays so that the count vectorises; only the others look for their nearest
  // nodes, and only those pay for a square root.
  const std::size_t need = std::min<std::size_t>(static_cast<std::size_t>(min_neighbours), n);
  std::vector<double> nearest_radii_squared(n), node_x(n), node_y(n), node_z(n), squared(n);
  for (std::size_t j = 0; j < n; ++j) {
    nearest_radii_squared[j] = radii[j] * radii[j];
    node_x[j] = nodes[j].x(), node_y[j] = nodes[j].y(), node_z[j] = nodes[j].z();
  }
  std::vector<double> nearest;  // the insertion's need smallest squared distances, ascending
  for (const PatchQuadrature* set : points)
    for (const Eigen::Vector3d& x : set->points) {
      std::size_t seen = 0;
      for (std::size_t j = 0; j < n; ++j) {
        const double dx = node_x[j] - x.x(), dy = node_y[j] - x.y(), dz = node_z[j] - x.z();
        squared[j] = dx * dx + dy * dy + dz * dz;
        seen += squared[j] < nearest_radii_squared[j] ? 1 : 0;
      }
      if (seen >= need) continue;
      // The need-th smallest squared distance, then every node within it (a tie at that
      // distance grows one node more).
      const double within = n <= count_selection_up_to_nodes ? nth_smallest_by_counting(squared, need)
                                                               : nth_smallest_by_insertion(squared, need, nearest);
      for (std::size_t j = 0; j < n; ++j)
        if (squared[j] <= within) radii[j] = std::max(radii[j], 1.2 * std::sqrt(squared[j]));
    }
  return radii;
}

bool volumetric_term_projected(const EnrichedSettings& settings, const geometry::Material& material) {
  return settings.volumetric == VolumetricTerm::projected ||
         (settings.volumetric == VolumetricTerm::automatic &&
          material.poisson_ratio >= projected_volumetric_from_poisson_ratio);
}

EnrichedSettings settings_for_material(EnrichedSettings s, const geometry::Material& material) {
  const bool projected = volumetric_term_projected(s, material);
  if (s.volumetric == VolumetricTerm::automatic) s.volumetric = projected ? VolumetricTerm::projected : VolumetricTerm::full;
  if (s.gradient_correction == GradientCorrection::automatic)
    s.gradient_correction = projected ? GradientCorrection::none : GradientCorrection::linear;
  const int* rule = s.gradient_correction == GradientCorrection::none ? uncorrected_volume_rule : corrected_volume_rule;
  int* counts[3] = {&s.volume_radial_points, &s.volume_polar_points, &s.volume_azimuth_points};
  for (int i = 0; i < 3; ++i)
    if (*counts[i] == 0) *counts[i] = rule[i];
  const int* cut_rule = s.gradient_correction == GradientCorrection::none ? uncorrected_cut_rule : corrected_cut_rule;
  if (s.cut_polar_points == 0) s.cut_polar_points = cut_rule[0];
  if (s.cut_azimuth_points == 0) s.cut_azimuth_points = cut_rule[1];
  return s;
}

/// From this many nodes the volume rule's radial count grows too: with it fixed the MLS–MLS block
/// and the projected volumetric term were under-integrated along the rays at 100–300 nodes, too
/// soft (docs/enriched_model.md, "The radial count at large N").
constexpr std::size_t radial_growth_from_nodes = 60;

EnrichedSettings quadratures_for_node_count(EnrichedSettings s, std::size_t node_count) {
  const double finer = std::cbrt(static_cast<double>(node_count) / 40.0);
  if (finer <= 1) return s;
  for (int* count : {&s.volume_polar_points, &s.volume_azimuth_points, &s.cut_polar_points, &s.cut_azimuth_points})
    *count = static_cast<int>(std::lround(*count * finer));
  if (node_count > radial_growth_from_nodes) s.volume_radial_points = static_cast<int>(std::lround(s.volume_radial_points * finer));
  return s;
}

namespace {
/// enriched_quadratures() and build_enriched_model() are called with settings_for_material()'s
/// settings; a caller that skips it would build on an empty rule.
void require_chosen(const EnrichedSettings& s, const char* caller) {
  if (s.volume_radial_points == 0 || s.volume_polar_points == 0 || s.volume_azimuth_points == 0 ||
      s.cut_polar_points == 0 || s.cut_azimuth_points == 0 ||
      s.gradient_correction == GradientCorrection::automatic || s.volumetric == VolumetricTerm::automatic)
    throw std::invalid_argument(std::string(caller) + ": the settings' automatic choices are not made (settings_for_material)");
}
}  // namespace

bool enriched_quadratures(const LocalSurface& surface, const ToolContact& contact, double local_radius_m,
                          const EnrichedSettings& settings, const PatchQuadrature& clamped, EnrichedQuadratures& out,
                          PunchFrame& frame, std::string& failure) {
  require_chosen(settings, "enriched_quadratures");
  out = EnrichedQuadratures{};
  out.patch.reserve(static_cast<std::size_t>(settings.patch_radial_points) *
                    static_cast<std::size_t>(settings.patch_angular_points));
  out.free_surface.reserve(static_cast<std::size_t>(settings.free_radial_points) *
                           static_cast<std::size_t>(settings.free_azimuth_points));
  out.local_radius_m = local_radius_m;
  const double a = contact.radius_m, length = local_radius_m;
  // The patch is the disk of radius a about the contact on the organ, centred on its normal: the
  // punch fields live in its frame (e₃ the inward normal), whatever direction the tool pushes.
  AxisFrame f;
  f.centre = surface.centre();
  f.push = -surface.normal();
  const PunchFrame axes = PunchFrame::along(f.centre, f.push);
  f.t1 = axes.axes.col(0);
  f.t2 = axes.axes.col(1);

  // The patch: r = a sin(πx/2) absorbs the (a² − r²)^(−½) of the contact traction; the rim
  // circle's centre, the punch frame's origin, is the mean axial position of the rim.
  std::vector<double> x, w;
  gauss_legendre(settings.patch_radial_points, x, w);
  const int angular = settings.patch_angular_points;
  struct {
    Eigen::Vector3d point, normal;
  } p;
  const auto on_axis_line = [&](double r, double phi) {
    return surface.on_line(f.centre + r * f.radial(phi), f.push, p.point, p.normal);
  };
  double rim_axial = 0;
  for (int k = 0; k < angular; ++k) {
    const double phi = 2 * pi * (k + 0.5) / angular;
    if (!on_axis_line(a, phi)) {
      failure = "the tool axis misses the organ at the patch rim (contact at an organ edge?)";
      return false;
    }
    rim_axial += f.push.dot(p.point - f.centre) / angular;
  }
  frame = axes;
  frame.origin = f.centre + rim_axial * f.push;
  // r = a sin t absorbs the rim's (a² − r²)^(−½); the radial mode adds a log-singular pressure
  // (its dome), which t = (π/2)(1 − (1 − x)²) grades toward as well.
  const std::vector<PunchMode> modes = enrichment_modes(contact, frame, local_radius_m);
  const bool graded_twice = std::find(modes.begin(), modes.end(), PunchMode::radial) != modes.end();
  for (int i = 0; i < settings.patch_radial_points; ++i) {
    const double t = graded_twice ? 0.5 * pi * (1 - (1 - x[i]) * (1 - x[i])) : 0.5 * pi * x[i], r = a * std::sin(t);
    const double dt_dx = graded_twice ? pi * (1 - x[i]) : 0.5 * pi;
    const double radial_weight = w[i] * dt_dx * a * a * std::sin(t) * std::cos(t);
    for (int k = 0; k < angular; ++k) {
      const double phi = 2 * pi * (k + 0.5 * (i % 2)) / angular;
      if (!on_axis_line(r, phi)) {
        failure = "the tool axis misses the organ under the patch (contact at an organ edge?)";
        return false;
      }
      out.patch.points.push_back(p.point);
      out.patch.normals.push_back(p.normal);
      // Area on the surface = area across the axis / |n·d|.
      out.patch.weights.push_back(radial_weight * 2 * pi / angular / std::max(0.2, std::abs(p.normal.dot(f.push))));
      out.patch_radius_m.push_back(r);
      out.patch_azimuth_rad.push_back(phi);
    }
  }

  // The free surface a < r < r_edge(φ), where the surface leaves the ball; r = a + (r_edge − a)t²
  // absorbs the ρ^(−½) of σ(ψ)n at the rim of a curved surface.
  gauss_legendre(settings.free_radial_points, x, w);
  for (int k = 0; k < settings.free_azimuth_points; ++k) {
    const double phi = 2 * pi * (k + 0.5) / settings.free_azimuth_points;
    // Regula falsi (Illinois) on g(r) = |X(r) − c| − L over [a, L].
    const auto g = [&](double r, bool& ok) {
      ok = on_axis_line(r, phi);
      return (p.point - f.centre).norm() - length;
    };
    bool ok_low = true, ok_high = true;
    double low = a, high = length, g_low = g(low, ok_low), g_high = g(high, ok_high);
    if (!ok_low || !(g_low < 0)) {
      failure = "the free surface around the patch leaves the local ball at once (L too close to a?)";
      return false;
    }
    if (!ok_high) {
      // The axis leaves the organ before L (an edge): march inward to the last good radius.
      double good = low;
      for (int step = 1; step <= 32; ++step) {
        bool ok = true;
        const double r = low + (length - low) * step / 32.0;
        const double value = g(r, ok);
        if (!ok) break;
        good = r;
        if (value >= 0) break;
      }
      bool ok = true;
      high = good;
      g_high = g(high, ok);
      if (!(g_high >= 0)) {
        failure = "the organ surface folds away from the tool axis inside the local ball (contact near an organ edge)";
        return false;
      }
    }
    // The edge is the root where g vanishes to rounding, else the middle of the final bracket:
    // Illinois may keep one end of the bracket far from the root (on a flat surface g(L) = 0 at
    // the start), so the bracket's middle is not the root when the loop stops on g.
    int side = 0;
    double edge = std::abs(g_high) < 1e-12 * length ? high : std::numeric_limits<double>::quiet_NaN();
    for (int iteration = 0; iteration < 60 && std::isnan(edge) && high - low > 1e-10 * length; ++iteration) {
      const double r = (low * g_high - high * g_low) / (g_high - g_low);
      bool ok = true;
      const double value = g(r, ok);
      if (!ok) {
        failure = "the tool axis misses the organ inside the local ball";
        return false;
      }
      if (value < 0) {
        low = r, g_low = value;
        if (side == -1) g_high *= 0.5;
        side = -1;
      } else {
        high = r, g_high = value;
        if (side == 1) g_low *= 0.5;
        side = 1;
      }
      if (std::abs(value) < 1e-12 * length) edge = r;
    }
    if (std::isnan(edge)) edge = 0.5 * (low + high);
    const double span = edge - a;
    for (int i = 0; i < settings.free_radial_points; ++i) {
      const double r = a + span * x[i] * x[i];
      if (!on_axis_line(r, phi)) {
        failure = "the tool axis misses the organ inside the local ball";
        return false;
      }
      out.free_surface.points.push_back(p.point);
      out.free_surface.normals.push_back(p.normal);
      out.free_surface.weights.push_back(w[i] * 2 * span * x[i] * r * 2 * pi / settings.free_azimuth_points /
                                         std::max(0.2, std::abs(p.normal.dot(f.push))));
    }
  }

  out.cut = enriched_cut_quadrature(surface, length, settings);
  out.volume = enriched_volume_quadrature(surface, a, length, settings);
  out.clamped = clamped;
  if (out.volume.points.empty() || out.cut.points.empty()) {
    failure = "the local ball holds no organ volume or no cut surface";
    return false;
  }
  return true;
}

Eigen::MatrixXd half_space_exterior_stiffness(const std::vector<PunchMode>& modes, const PunchFrame& frame,
                                              double radius_m, const geometry::Material& material, const PatchQuadrature& cut) {
  const Eigen::Index m = static_cast<Eigen::Index>(modes.size());
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(m, m);
  std::vector<PunchFieldSample> samples(modes.size());
  for (std::size_t q = 0; q < cut.points.size(); ++q) {
    for (std::size_t i = 0; i < modes.size(); ++i)
      samples[i] = punch_field(modes[i], frame, radius_m, material, cut.points[q]);
    for (Eigen::Index i = 0; i < m; ++i)
      for (Eigen::Index j = 0; j < m; ++j)
        k(i, j) -= cut.weights[q] * samples[i].displacement.dot(samples[j].stress_Pa_per_m * cut.normals[q]);
  }
  return 0.5 * (k + k.transpose());
}

EnrichedModel build_enriched_model(NodeCloud& cloud, const geometry::Material& material, const ToolContact& contact,
                                   const EnrichedQuadratures& quad, const PunchFrame& frame,
                                   const EnrichedSettings& settings, const MlsSettings& mls,
                                   const Eigen::MatrixXd* exterior_stiffness_N_per_m) {
  require_chosen(settings, "build_enriched_model");
  EnrichedModel model;
  model.frame = frame;
  model.exterior = settings.exterior;
  model.gradient_correction = settings.gradient_correction;
  model.volume_rule[0] = settings.volume_radial_points;
  model.volume_rule[1] = settings.volume_polar_points;
  model.volume_rule[2] = settings.volume_azimuth_points;
  model.cut_rule[0] = settings.cut_polar_points;
  model.cut_rule[1] = settings.cut_azimuth_points;
  model.modes = enrichment_modes(contact, frame, quad.local_radius_m);
  const bool bonded = contact.condition == geometry::ContactCondition::bonded;
  const Eigen::Index n_nodes = static_cast<Eigen::Index>(cloud.size());
  const Eigen::Index m = static_cast<Eigen::Index>(model.modes.size());
  const double a = contact.radius_m;
  const auto fail = [&](std::string why) {
    model.status = std::move(why);
    return model;
  };
  const Eigen::Index translations = translation_mode_count(model.modes);
  bool cut_shift = false;
  if (settings.exterior == ExteriorCondition::body_aware) {
    const Eigen::Index size = exterior_stiffness_N_per_m ? exterior_stiffness_N_per_m->rows() : -1;
    if (!exterior_stiffness_N_per_m || exterior_stiffness_N_per_m->cols() != size ||
        (size != translations && size != translations + 3))
      return fail("body_aware exterior without an exterior stiffness of the right size");
    cut_shift = size == translations + 3;
  }
  model.cut_translations = cut_shift;
  // Unknowns: the nodes' 3-vectors, the mode amplitudes, and the cut's rigid shift if any.
  const Eigen::Index modes_at = 3 * n_nodes, shift_at = modes_at + m;
  const Eigen::Index n = shift_at + (cut_shift ? 3 : 0);

  using clock = std::chrono::steady_clock;
  const auto seconds_since = [](clock::time_point t) { return std::chrono::duration<double>(clock::now() - t).count(); };
  auto step = clock::now();  // the supports are grown for the volume rule's points too: count them in volume_s
  cloud.radii = enriched_support_radii(cloud.positions, {&quad.volume, &quad.patch, &quad.free_surface, &quad.cut, &quad.clamped},
                                       settings.support_neighbours, settings.min_point_neighbours);
  const double supports_s = seconds_since(step);
  step = clock::now();
  // The shape functions at the points of a rule, a batch at a time (evaluate_mls_batch runs
  // mls_batch_size nearby points side by side), handed to `use` in the order given; false at the
  // first point where they fail, whose index and evaluation are left in failed_point and `failed`.
  MlsEvaluation batch[mls_batch_size];
  const MlsEvaluation* failed = nullptr;
  int failed_point = -1;
  const auto evaluate_in_batches = [&](const std::vector<Eigen::Vector3d>& points, const std::vector<int>& order,
                                       Derivatives what, const auto& use) {
    Eigen::Vector3d x[mls_batch_size];
    for (std::size_t first = 0; first < order.size(); first += mls_batch_size) {
      const int count = static_cast<int>(std::min<std::size_t>(mls_batch_size, order.size() - first));
      for (int k = 0; k < count; ++k) x[k] = points[static_cast<std::size_t>(order[first + static_cast<std::size_t>(k)])];
      evaluate_mls_batch(x, count, cloud.positions, cloud.radii, mls, what, batch);
      for (int k = 0; k < count; ++k) {
        const MlsEvaluation& eval = batch[k];
        ++model.mls_evaluations;
        if (eval.status != MlsStatus::ok) {
          failed = &eval;
          failed_point = order[first + static_cast<std::size_t>(k)];
          return false;
        }
        model.min_rcond = std::min(model.min_rcond, eval.rcond);
        model.max_support_scale = std::max(model.max_support_scale, eval.support_scale);
        use(order[first + static_cast<std::size_t>(k)], eval);
      }
    }
    return true;
  };

  // Every boundary point: the MLS values and the ψ samples, shared by the ψ blocks and the
  // multipliers. ψ blocks as boundary forms: K_Jm = ∮ N_J σ(ψ_m)n, K_mn = ∮ ψ_m·σ(ψ_n)n. The
  // values are stored once, as the whole boundary's samples that the gradient correction reads
  // (its integration constraints); each rule's points are views into them.
  struct BoundaryPoint {
    const int* nodes;
    const double* values;
    std::size_t count;
    const PunchFieldSample* psi;  ///< one per mode
    Eigen::Vector3d x, normal;
    double weight;
  };
  const std::size_t boundary_total =
      quad.patch.points.size() + quad.free_surface.points.size() + quad.cut.points.size() + quad.clamped.points.size();
  ShapeSamples boundary;
  boundary.reserve(boundary_total, boundary_total * std::min<std::size_t>(static_cast<std::size_t>(n_nodes), 64), false);
  const std::size_t mode_count = model.modes.size();
  std::vector<PunchFieldSample> psi_samples(boundary_total * mode_count);
  const auto sample_set = [&](const PatchQuadrature& set, const char* name) {
    std::vector<int> in_order(set.points.size());
    std::iota(in_order.begin(), in_order.end(), 0);
    const bool sampled = evaluate_in_batches(set.points, in_order, Derivatives::values, [&](int q, const MlsEvaluation& eval) {
      const std::size_t at = boundary.size();  // the points come in order
      const Eigen::Vector3d& x = set.points[static_cast<std::size_t>(q)];
      boundary.add(x, set.normals[static_cast<std::size_t>(q)], set.weights[static_cast<std::size_t>(q)],
                   eval.neighbours.data(), eval.value.data(), nullptr, eval.neighbours.size());
      for (std::size_t i = 0; i < mode_count; ++i)
        psi_samples[at * mode_count + i] = punch_field(model.modes[i], frame, a, material, x);
    });
    if (!sampled)
      throw std::runtime_error(std::string("shape functions failed at ") + name + " quadrature point " + std::to_string(failed_point));
  };
  try {
    sample_set(quad.patch, "patch");
    sample_set(quad.free_surface, "free-surface");
    sample_set(quad.cut, "cut");
    sample_set(quad.clamped, "clamped-surface");
  } catch (const std::runtime_error& e) {
    return fail(e.what());
  }
  // Each rule's points as views, taken once every sample is stored (until then it may move).
  std::size_t first = 0;
  const auto views = [&](std::size_t count) {
    std::vector<BoundaryPoint> points(count);
    for (std::size_t q = 0; q < count; ++q, ++first) {
      const auto entry = static_cast<std::size_t>(boundary.offset[first]);
      points[q] = {boundary.node.data() + entry,
                   boundary.value.data() + entry,
                   static_cast<std::size_t>(boundary.offset[first + 1]) - entry,
                   psi_samples.data() + first * mode_count,
                   boundary.points[first],
                   boundary.normals[first],
                   boundary.weights[first]};
    }
    return points;
  };
  const std::vector<BoundaryPoint> patch = views(quad.patch.points.size());
  const std::vector<BoundaryPoint> free_surface = views(quad.free_surface.points.size());
  const std::vector<BoundaryPoint> cut = views(quad.cut.points.size());
  const std::vector<BoundaryPoint> clamped = views(quad.clamped.points.size());
  model.boundary_points = static_cast<int>(boundary_total);
  const double boundary_sampling_s = seconds_since(step);
  step = clock::now();

  // MLS–MLS: ∫ ε(N_a):C:ε(N_b) dV on the volume points, through the gradient Gram matrix fed
  // in a spatially coherent order (dense products over small node sets).
  Eigen::MatrixXd& K = model.stiffness;
  K.setZero(n, n);
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
  const double mean_radius = std::accumulate(cloud.radii.begin(), cloud.radii.end(), 0.0) / static_cast<double>(n_nodes);
  GradientGram gram(static_cast<int>(n_nodes));
  // The projected volumetric term (VolumetricTerm::projected): Q = P ⊕ span{div ψ_m}, P the
  // linear polynomials in (x − c)/L on small clouds and span{N_I} on larger ones;
  // G = ∫ q q' and D = ∫ q ∂_i N_J on the volume rule, and λ ∫ (Π div u)² = λ (T D u)ᵀ (T D u)
  // with G⁻¹ = Tᵀ T. div ψ = tr σ(ψ) / (3λ + 2μ), scaled by L to the size of the N_I.
  const bool projected = volumetric_term_projected(settings, material);
  model.volumetric_projected = projected;
  const bool linear_space = n_nodes <= settings.volumetric_linear_space_up_to_nodes;
  model.volumetric_space = !projected ? "" : linear_space ? "linear" : "nodal";
  const Eigen::Index space_functions = linear_space ? 4 : n_nodes;  // 1, ξ_x, ξ_y, ξ_z, or the N_I
  const Eigen::Index space_size = projected ? space_functions + m : 0;
  const double cut_distance = quad.cut.points.empty() ? a : (quad.cut.points.front() - contact.point).norm();
  const double divergence_scale = cut_distance / (3 * lambda + 2 * mu);
  Eigen::MatrixXd space_gram = Eigen::MatrixXd::Zero(space_size, space_size);            // G [m³]
  Eigen::MatrixXd divergence_moments_t = Eigen::MatrixXd::Zero(3 * n_nodes, space_size);  // Dᵀ [m²], columns contiguous
  std::vector<double> psi_divergence(static_cast<std::size_t>(m));
  std::vector<int> space_at_point;
  std::vector<double> space_values;
  // The shape functions at every volume point (in a spatially coherent order), corrected to the
  // integration constraints if asked; then the MLS–MLS block and the volumetric term from them.
  // Without a correction each point is used as soon as it is evaluated (nothing is stored);
  // with one, every point is stored, corrected, and then used.
  const auto use_point = [&](const Eigen::Vector3d& x, double w, const int* nodes, const double* values,
                             const Eigen::Vector3d* gradients, int count) {
    gram.add(nodes, gradients, count, w);
    model.mean_volume_point_nodes += count;
    if (projected) {
      for (Eigen::Index i = 0; i < m; ++i)
        psi_divergence[static_cast<std::size_t>(i)] =
            divergence_scale * punch_field(model.modes[static_cast<std::size_t>(i)], frame, a, material, x).stress_Pa_per_m.trace();
      // The space's functions that are non-zero here: the four monomials, or the nodes in reach
      // with their MLS values.
      if (linear_space) {
        const Eigen::Vector3d xi = (x - contact.point) / cut_distance;
        space_at_point.assign({0, 1, 2, 3});
        space_values.assign({1.0, xi.x(), xi.y(), xi.z()});
      } else {
        space_at_point.assign(nodes, nodes + count);
        space_values.assign(values, values + count);
      }
      for (std::size_t k = 0; k < space_at_point.size(); ++k) {
        const double wq = w * space_values[k];
        for (std::size_t l = 0; l < space_at_point.size(); ++l) space_gram(space_at_point[k], space_at_point[l]) += wq * space_values[l];
        for (int l = 0; l < count; ++l) divergence_moments_t.block<3, 1>(3 * nodes[l], space_at_point[k]) += wq * gradients[l];
        for (Eigen::Index i = 0; i < m; ++i)
          space_gram(space_functions + i, space_at_point[k]) += wq * psi_divergence[static_cast<std::size_t>(i)];
      }
      for (Eigen::Index i = 0; i < m; ++i) {
        const double d = w * psi_divergence[static_cast<std::size_t>(i)];
        for (int l = 0; l < count; ++l) divergence_moments_t.block<3, 1>(3 * nodes[l], space_functions + i) += d * gradients[l];
      }
      for (Eigen::Index i = 0; i < m; ++i)
        for (Eigen::Index j = 0; j <= i; ++j)
          space_gram(space_functions + i, space_functions + j) +=
              w * psi_divergence[static_cast<std::size_t>(i)] * psi_divergence[static_cast<std::size_t>(j)];
    }
  };
  const bool corrected = settings.gradient_correction != GradientCorrection::none;
  ShapeSamples volume;
  // Room for what the points see (every node of a small cloud, a few dozen of a large one), so
  // that storing them rarely copies.
  constexpr std::size_t reserved_nodes_per_point = 64;
  if (corrected)
    volume.reserve(quad.volume.points.size(), quad.volume.points.size() * std::min(cloud.size(), reserved_nodes_per_point), true);
  const bool volume_sampled = evaluate_in_batches(
      quad.volume.points, sort_points_spatially(quad.volume.points, 0.5 * mean_radius), Derivatives::gradients,
      [&](int q, const MlsEvaluation& eval) {
        const Eigen::Vector3d& x = quad.volume.points[static_cast<std::size_t>(q)];
        const double w = quad.volume.weights[static_cast<std::size_t>(q)];
        if (corrected)
          volume.add(x, Eigen::Vector3d::Zero(), w, eval.neighbours, eval.value, &eval.gradient);
        else
          use_point(x, w, eval.neighbours.data(), eval.value.data(), eval.gradient.data(), static_cast<int>(eval.neighbours.size()));
      });
  if (!volume_sampled)
    return fail("shape functions failed (" + std::string(failed->status == MlsStatus::too_few_nodes ? "too few nodes"
                                                         : failed->status == MlsStatus::singular_moments
                                                             ? "singular moment matrix"
                                                             : "non-finite input") +
                ", " + std::to_string(failed->neighbours.size()) + " nodes in reach) at volume quadrature point " +
                std::to_string(failed_point));
  if (corrected) {
    try {
      model.gradient_correction_left = correct_gradients(cloud.positions, boundary, settings.gradient_correction, volume);
    } catch (const std::invalid_argument& e) {
      return fail(std::string("the gradient correction failed: ") + e.what());
    }
    for (std::size_t q = 0; q < volume.size(); ++q) {
      const int first = volume.offset[q];
      use_point(volume.points[q], volume.weights[q], volume.node.data() + first, volume.value.data() + first,
                volume.gradient.data() + first, volume.offset[q + 1] - first);
    }
  }
  gram.add_isotropic_stiffness(projected ? 0.0 : lambda, mu, K);
  model.gram_product_overhead = gram.product_overhead();
  if (projected) {
    // The ψ rows of G were summed below the diagonal only.
    space_gram.triangularView<Eigen::StrictlyUpper>() = space_gram.transpose().triangularView<Eigen::StrictlyUpper>();
    // T D with G⁻¹ = Tᵀ T: by Cholesky (T = L⁻¹); if the rule cannot tell div ψ from the span of
    // the N_I (G singular to rounding), by the eigen-decomposition with that direction dropped.
    Eigen::MatrixXd projected_moments;
    const Eigen::LLT<Eigen::MatrixXd> cholesky(space_gram);
    const Eigen::VectorXd diagonal = space_gram.diagonal();
    bool well_posed = cholesky.info() == Eigen::Success;
    if (well_posed) {
      const Eigen::VectorXd pivots = cholesky.matrixLLT().diagonal();
      for (Eigen::Index j = 0; j < space_size && well_posed; ++j) well_posed = pivots[j] * pivots[j] > 1e-12 * diagonal[j];
    }
    if (well_posed) {
      projected_moments = cholesky.matrixL().solve(divergence_moments_t.transpose());
    } else {
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(space_gram);
      const double largest = eigen.eigenvalues().maxCoeff();
      Eigen::Index kept = 0;
      projected_moments.resize(space_size, 3 * n_nodes);
      for (Eigen::Index j = 0; j < space_size; ++j)
        if (eigen.eigenvalues()[j] > 1e-12 * largest)
          projected_moments.row(kept++) =
              (divergence_moments_t * eigen.eigenvectors().col(j)).transpose() / std::sqrt(eigen.eigenvalues()[j]);
      projected_moments.conservativeResize(kept, Eigen::NoChange);
    }
    Eigen::MatrixXd volumetric = Eigen::MatrixXd::Zero(3 * n_nodes, 3 * n_nodes);
    volumetric.selfadjointView<Eigen::Lower>().rankUpdate(projected_moments.transpose(), lambda);
    K.topLeftCorner(3 * n_nodes, 3 * n_nodes) += volumetric.selfadjointView<Eigen::Lower>();
  }
  model.volume_points = static_cast<int>(quad.volume.points.size());
  model.mean_volume_point_nodes /= static_cast<double>(std::max(model.volume_points, 1));
  model.volume_s = supports_s + seconds_since(step);
  step = clock::now();

  for (const std::vector<BoundaryPoint>* set : {&patch, &free_surface, &cut, &clamped})
    for (const BoundaryPoint& b : *set)
      for (Eigen::Index i = 0; i < m; ++i) {
        const Eigen::Vector3d traction = b.psi[i].stress_Pa_per_m * b.normal;
        for (std::size_t k = 0; k < b.count; ++k)
          K.block<3, 1>(3 * b.nodes[k], 3 * n_nodes + i) += b.weight * b.values[k] * traction;
        for (Eigen::Index j = 0; j < m; ++j) K(3 * n_nodes + j, 3 * n_nodes + i) += b.weight * b.psi[j].displacement.dot(traction);
      }
  K.block(modes_at, 0, m, modes_at) = K.block(0, modes_at, modes_at, m).transpose();
  const Eigen::MatrixXd psi_block = K.block(modes_at, modes_at, m, m);
  K.block(modes_at, modes_at, m, m) = 0.5 * (psi_block + psi_block.transpose());

  // The exterior energy, over the amplitudes and the cut's shift.
  model.exterior_stiffness_N_per_m.setZero(m, m);
  if (settings.exterior == ExteriorCondition::half_space)
    model.exterior_stiffness_N_per_m = half_space_exterior_stiffness(model.modes, frame, a, material, quad.cut);
  else if (settings.exterior == ExteriorCondition::body_aware) {
    // The organ's exterior for the punch translations; the radial and tilt modes couple with it
    // through the half-space's terms (the tilt modes carry no resultant force, the radial mode's
    // dome a small normal one; docs/enriched_model.md, The atlas and the extra modes).
    if (translations < m)
      model.exterior_stiffness_N_per_m = half_space_exterior_stiffness(model.modes, frame, a, material, quad.cut);
    const Eigen::MatrixXd& atlas = *exterior_stiffness_N_per_m;
    model.exterior_stiffness_N_per_m.topLeftCorner(translations, translations) = atlas.topLeftCorner(translations, translations);
    if (cut_shift) {
      // The shift's rows: its own block and its coupling with the translation modes; the
      // radial and tilt modes' coupling with it is not in the atlas (zero).
      model.exterior_stiffness_N_per_m.conservativeResize(m + 3, m + 3);
      model.exterior_stiffness_N_per_m.rightCols<3>().setZero();
      model.exterior_stiffness_N_per_m.bottomRows<3>().setZero();
      model.exterior_stiffness_N_per_m.bottomRightCorner<3, 3>() = atlas.bottomRightCorner<3, 3>();
      model.exterior_stiffness_N_per_m.block(0, m, translations, 3) = atlas.topRightCorner(translations, 3);
      model.exterior_stiffness_N_per_m.block(m, 0, 3, translations) = atlas.bottomLeftCorner(3, translations);
    }
  }
  K.bottomRightCorner(n - modes_at, n - modes_at) += model.exterior_stiffness_N_per_m;
  // The shift's directions in the global frame, in the atlas's order e₃, e₁, e₂.
  Eigen::Matrix3d shift_axes;
  shift_axes << frame.axes.col(2), frame.axes.col(0), frame.axes.col(1);

  // Constraint rows B (and their right-hand sides per unit U_tool, G) and each row's resultant
  // per unit multiplier (3-vector), to turn multipliers into forces.
  std::vector<Eigen::RowVectorXd> rows;
  std::vector<Eigen::RowVector3d> rhs;
  std::vector<Eigen::Vector3d> resultant;
  std::vector<bool> on_patch;
  // Patch: T_k(r/a)/√(1 − (r/a)²), made dimensionless; the normal component (frictionless) or
  // all three (bonded).
  const Eigen::Vector3d d = contact.direction.normalized();
  // T₀ and the two tilt modes: the higher even modes T₂, T₄ over-constrain the MLS part near the
  // patch and lock it below ~45 nodes (measured on B3: +5 … +16 % with them, ≤ 0.3 % without).
  const int patch_functions = 3;
  const auto patch_function = [&](int k, std::size_t q) {
    const double t = quad.patch_radius_m[q] / a, phi = quad.patch_azimuth_rad[q];
    const double inverse_root = 1 / std::sqrt(std::max(1 - t * t, 1e-300));
    switch (k) {
      case 0: return chebyshev(0, t) * inverse_root;
      case 1: return t * std::cos(phi) * inverse_root;
      case 2: return t * std::sin(phi) * inverse_root;
      case 3: return chebyshev(2, t) * inverse_root;
      default: return chebyshev(4, t) * inverse_root;
    }
  };
  const int components = bonded ? 3 : 1;
  // The dome: with enough nodes the MLS part of a bonded patch bulges its face under the mean
  // condition alone; few nodes lock under the extra condition (docs/enriched_model.md, The dome
  // that flattens it).
  const bool hold_dome = bonded && n_nodes >= settings.bonded_patch_dome_from_nodes;
  const Eigen::Vector3d patch_normal = frame.axes.col(2);
  for (int k = 0; k < patch_functions + (hold_dome ? 1 : 0); ++k)
    for (int c = 0; c < (k < patch_functions ? components : 1); ++c) {
      const Eigen::Vector3d e = k == patch_functions ? patch_normal : bonded ? Eigen::Vector3d::Unit(c) : d;
      Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(n);
      double integral = 0;
      for (std::size_t q = 0; q < patch.size(); ++q) {
        const BoundaryPoint& b = patch[q];
        const double mu = patch_function(k, q) * b.weight;
        integral += mu;
        for (std::size_t j = 0; j < b.count; ++j) row.segment<3>(3 * b.nodes[j]) += mu * b.values[j] * e.transpose();
        for (Eigen::Index i = 0; i < m; ++i) row(3 * n_nodes + i) += mu * e.dot(b.psi[i].displacement);
      }
      rows.push_back(row);
      rhs.push_back(integral * e.transpose());
      resultant.push_back(integral * e);
      on_patch.push_back(true);
    }

  // Cut and clamped surfaces: orthonormal (in L2 of the surface) combinations of the raw
  // functions, so that dependent ones (1 and |ξ|² on a sphere) drop out.
  const ConstraintSurface surfaces[] = {{&quad.cut, settings.exterior == ExteriorCondition::clamped},
                                        {&quad.clamped, true}};
  const std::vector<BoundaryPoint>* samples[] = {&cut, &clamped};
  Eigen::Matrix<double, 3, Eigen::Dynamic> raw;
  const Eigen::Vector3d centre = quad.cut.points.empty() ? frame.origin : contact.point;
  const double length = quad.cut.points.empty() ? a : (quad.cut.points.front() - contact.point).norm();
  for (int s = 0; s < 2; ++s) {
    const std::vector<BoundaryPoint>& points = *samples[s];
    if (points.empty()) continue;
    // Scale σ(ψ)n to O(1) like the polynomials.
    const int degree = cut_multiplier_degree(settings, cloud.size());
    std::vector<double> scale(model.modes.size(), 0.0);
    for (const BoundaryPoint& b : points)
      for (std::size_t i = 0; i < model.modes.size(); ++i)
        scale[i] = std::max(scale[i], (b.psi[i].stress_Pa_per_m * b.normal).norm());
    std::vector<Eigen::Vector3d> modes(model.modes.size());
    const auto raw_at = [&](const BoundaryPoint& b) {
      for (std::size_t i = 0; i < model.modes.size(); ++i)
        modes[i] = scale[i] > 0 ? Eigen::Vector3d(b.psi[i].stress_Pa_per_m * b.normal / scale[i]) : Eigen::Vector3d::Zero();
      raw_multipliers((b.x - centre) / length, degree, modes, raw);
    };
    const Eigen::Index count = 3 * (degree + 1) * (degree + 2) * (degree + 3) / 6 + m;
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(count, count);
    for (const BoundaryPoint& b : points) {
      raw_at(b);
      gram.noalias() += b.weight * raw.transpose() * raw;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram);
    const double largest = eigen.eigenvalues().maxCoeff();
    std::vector<Eigen::Index> kept;
    for (Eigen::Index j = 0; j < count; ++j)
      if (eigen.eigenvalues()[j] > 1e-10 * largest) kept.push_back(j);
    Eigen::MatrixXd transform(count, static_cast<Eigen::Index>(kept.size()));
    for (std::size_t j = 0; j < kept.size(); ++j)
      transform.col(static_cast<Eigen::Index>(j)) = eigen.eigenvectors().col(kept[j]) / std::sqrt(eigen.eigenvalues()[kept[j]]);
    const Eigen::Index first = static_cast<Eigen::Index>(rows.size()), added = transform.cols();
    for (Eigen::Index j = 0; j < added; ++j) {
      rows.push_back(Eigen::RowVectorXd::Zero(n));
      rhs.push_back(Eigen::RowVector3d::Zero());
      resultant.push_back(Eigen::Vector3d::Zero());
      on_patch.push_back(false);
    }
    Eigen::Matrix<double, 3, Eigen::Dynamic> basis;
    for (const BoundaryPoint& b : points) {
      raw_at(b);
      basis.noalias() = raw * transform;  // 3 × added
      for (Eigen::Index j = 0; j < added; ++j) {
        const Eigen::Vector3d mu = b.weight * basis.col(j);
        Eigen::RowVectorXd& row = rows[static_cast<std::size_t>(first + j)];
        for (std::size_t k = 0; k < b.count; ++k) row.segment<3>(3 * b.nodes[k]) += b.values[k] * mu.transpose();
        if (surfaces[s].includes_enrichment)
          for (Eigen::Index i = 0; i < m; ++i) row(3 * n_nodes + i) += mu.dot(b.psi[i].displacement);
        // On the cut the MLS part equals the shift: ∮ μ·(Σ N_J u_J − t) = 0.
        if (cut_shift && s == 0) row.segment<3>(shift_at) -= mu.transpose() * shift_axes;
        resultant[static_cast<std::size_t>(first + j)] += mu;
      }
    }
  }

  // KKT [K Bᵀ; B 0] [x; y] = [0; G U], multipliers λ = −y, rows scaled to K's magnitude.
  // Solved through the augmented stiffness K_ρ = K + ρ BᵀB (the same solution, since Bx = G),
  // which is positive definite exactly when the KKT solution is unique: one Cholesky K_ρ = L Lᵀ
  // of the n × n K_ρ and a c × c Schur complement S = B K_ρ⁻¹ Bᵀ = Wᵀ W with W = L⁻¹ Bᵀ (one
  // triangular solve per multiplier, not two), instead of an LU of the indefinite (n + c) × (n + c)
  // system: x = L⁻ᵀ W S⁻¹ G, y = ρ G − S⁻¹ G.
  model.boundary_s = boundary_sampling_s + seconds_since(step);
  step = clock::now();
  const Eigen::Index c = static_cast<Eigen::Index>(rows.size());
  model.multipliers = static_cast<int>(c);
  const double k_scale = K.diagonal().head(3 * n_nodes).cwiseAbs().maxCoeff();
  Eigen::MatrixXd constraints(c, n), targets(c, 3);
  std::vector<double> row_scale(static_cast<std::size_t>(c));
  for (Eigen::Index r = 0; r < c; ++r) {
    const double norm = rows[static_cast<std::size_t>(r)].norm();
    const double s = norm > 0 ? k_scale / norm : 1.0;
    row_scale[static_cast<std::size_t>(r)] = s;
    constraints.row(r) = s * rows[static_cast<std::size_t>(r)];
    targets.row(r) = s * rhs[static_cast<std::size_t>(r)];
  }
  const double rho = k_scale > 0 ? 1 / k_scale : 1.0;
  Eigen::MatrixXd augmented = K;
  augmented.selfadjointView<Eigen::Lower>().rankUpdate(constraints.transpose(), rho);
  // Factorised in place from its lower triangle (no symmetric copy of the n × n matrix).
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> cholesky(augmented);
  if (cholesky.info() != Eigen::Success)
    return fail("the enriched system is singular: the constraints leave a zero-energy mode free");
  Eigen::MatrixXd w = constraints.transpose();
  cholesky.matrixL().solveInPlace(w);
  const Eigen::MatrixXd schur = w.transpose() * w;
  const Eigen::MatrixXd s_inverse_g = schur.ldlt().solve(targets);
  Eigen::MatrixXd solution(n + c, 3);
  Eigen::MatrixXd x = w * s_inverse_g;
  cholesky.matrixU().solveInPlace(x);
  solution.topRows(n) = x;
  solution.bottomRows(c) = rho * targets - s_inverse_g;
  const double residual = std::sqrt((K * solution.topRows(n) + constraints.transpose() * solution.bottomRows(c)).squaredNorm() +
                                    (constraints * solution.topRows(n) - targets).squaredNorm());
  model.kkt_relative_residual = residual / targets.norm();
  if (!solution.allFinite() || !(model.kkt_relative_residual < 1e-8))
    return fail("the enriched system is singular or too ill-conditioned: relative residual " +
                std::to_string(model.kkt_relative_residual));
  model.unit_response = solution.topRows(n);
  for (Eigen::Index r = 0; r < c; ++r) {
    const Eigen::RowVector3d lambda = -row_scale[static_cast<std::size_t>(r)] * solution.row(n + r);
    const Eigen::Matrix3d force = resultant[static_cast<std::size_t>(r)] * lambda;
    (on_patch[static_cast<std::size_t>(r)] ? model.tool_stiffness_N_per_m : model.cut_reaction_N_per_m) += force;
  }
  if (!model.tool_stiffness_N_per_m.allFinite()) return fail("the tool stiffness is not finite");
  model.solve_s = seconds_since(step);
  return model;
}

MlsStatus enriched_displacement(const NodeCloud& cloud, const EnrichedModel& model, double radius_m,
                                const geometry::Material& material, const MlsSettings& mls, const Eigen::VectorXd& parameters,
                                const Eigen::Vector3d& x, MlsEvaluation& scratch, Eigen::Vector3d& u) noexcept {
  static const std::vector<int> all_nodes;
  u.setZero();
  evaluate_mls(x, cloud.positions, cloud.radii, all_nodes, mls, Derivatives::values, scratch);
  if (scratch.status != MlsStatus::ok) return scratch.status;
  for (std::size_t k = 0; k < scratch.neighbours.size(); ++k)
    u += scratch.value[k] * parameters.segment<3>(3 * scratch.neighbours[k]);
  const Eigen::Index base = 3 * static_cast<Eigen::Index>(cloud.size());
  for (std::size_t i = 0; i < model.modes.size(); ++i)
    u += parameters[base + static_cast<Eigen::Index>(i)] *
         punch_field(model.modes[i], model.frame, radius_m, material, x).displacement;
  return MlsStatus::ok;
}

}  // namespace touchstone::realtime::mfs
