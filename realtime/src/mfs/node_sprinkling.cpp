#include "touchstone/realtime/mfs/node_sprinkling.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;

/// Unit tangents (t1, t2) completing n to a right-handed frame.
std::pair<Eigen::Vector3d, Eigen::Vector3d> tangents(const Eigen::Vector3d& n) {
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d t1 = n.cross(helper).normalized();
  return {t1, n.cross(t1)};
}

/// Points on the unit sphere, evenly spread (Fibonacci lattice), rotated by `rotation`.
std::vector<Eigen::Vector3d> fibonacci_sphere(int count, const Eigen::Matrix3d& rotation) {
  std::vector<Eigen::Vector3d> points;
  const double golden = pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / count;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    points.push_back(rotation * Eigen::Vector3d(r * std::cos(golden * i), r * std::sin(golden * i), z));
  }
  return points;
}

double halton(int index, int base) {
  double f = 1, r = 0;
  for (int i = index; i > 0; i /= base) {
    f /= base;
    r += f * (i % base);
  }
  return r;
}

/// The graded spacing s(ρ) = max(s_min, g ρ): fine at the tool, coarse toward the cut.
/// s_min = g a, so refining (smaller g) refines the patch and its singular edge too.
struct Spacing {
  double minimum, growth;
  double operator()(double rho) const { return std::max(minimum, growth * rho); }
};

class Sprinkler {
 public:
  Sprinkler(const geometry::TriangleSurface& organ, const ToolContact& contact, const SprinklingSettings& settings,
            Spacing spacing)
      : organ_(organ), contact_(contact), settings_(settings), spacing_(spacing), random_(settings.seed) {}

  NodeCloud run() {
    const geometry::SurfaceProjection at_contact = organ_.project(contact_.point);
    centre_ = at_contact.point;
    normal_ = at_contact.normal;
    place_patch();
    if (settings_.layout == Layout::lattice) {
      place_lattice();
    } else {
      place_surface();
      place_cut();
      place_interior();
    }
    return finish();
  }

 private:
  struct Candidate {
    Eigen::Vector3d x;
    NodeKind kind;
    Eigen::Vector3d normal;
  };

  double rho(const Eigen::Vector3d& x) const { return (x - centre_).norm(); }

  bool far_from_accepted(const Eigen::Vector3d& x, double min_distance) const {
    for (const auto& node : nodes_)
      if ((node.x - x).squaredNorm() < min_distance * min_distance) return false;
    return true;
  }

  void accept(const Eigen::Vector3d& x, NodeKind kind, const Eigen::Vector3d& normal) { nodes_.push_back({x, kind, normal}); }

  /// Tip node and rings on the tangent plane, projected onto the surface: n_r = max(2, ⌈a/s⌉)
  /// rings at radii a k/n_r (the last on the patch edge), each with at least `ring_nodes` nodes
  /// and about one per spacing s = s(a) along it, staggered ring to ring.
  void place_patch() {
    const double a = contact_.radius_m, s = patch_spacing();
    accept(centre_, NodeKind::tool_patch, normal_);
    if (settings_.tip_node_only) return;
    const auto [t1, t2] = tangents(normal_);
    const int ring_count = std::max(2, static_cast<int>(std::ceil(a / s - 1e-9)));
    for (int k = 1; k <= ring_count; ++k) {
      const double ring = a * k / ring_count;
      const int count = std::max(settings_.ring_nodes, static_cast<int>(std::lround(2 * pi * ring / s)));
      const double offset = (k % 2) * pi / count;
      for (int j = 0; j < count; ++j) {
        const double angle = 2 * pi * j / count + offset;
        const geometry::SurfaceProjection p =
            organ_.project(centre_ + ring * (std::cos(angle) * t1 + std::sin(angle) * t2));
        accept(p.point, NodeKind::tool_patch, p.normal);
      }
    }
  }

  double patch_spacing() const {
    return settings_.layout == Layout::lattice ? spacing_.minimum : spacing_(contact_.radius_m);
  }

  /// Area-weighted random points of the triangles inside the ball, nearest first, thinned to
  /// the graded spacing.
  void place_surface() {
    const double length = settings_.local_radius_m;
    const auto& v = organ_.vertices();
    std::vector<std::pair<int, double>> triangles;  // index, cumulative area
    double total = 0;
    for (int t = 0; t < static_cast<int>(organ_.triangles().size()); ++t) {
      const Eigen::Vector3i& tri = organ_.triangles()[t];
      const double nearest = std::min({rho(v[tri[0]]), rho(v[tri[1]]), rho(v[tri[2]])});
      const double longest = std::max({(v[tri[0]] - v[tri[1]]).norm(), (v[tri[1]] - v[tri[2]]).norm(),
                                       (v[tri[2]] - v[tri[0]]).norm()});
      if (nearest > length + longest) continue;
      total += 0.5 * (v[tri[1]] - v[tri[0]]).cross(v[tri[2]] - v[tri[0]]).norm();
      triangles.push_back({t, total});
    }
    if (triangles.empty()) return;
    // Enough samples that the finest spacing near the patch is resolved.
    const double finest = spacing_(contact_.radius_m);
    const int samples = static_cast<int>(std::min(2.0e5, 8 * total / (finest * finest) + 100));
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<Candidate> candidates;
    for (int s = 0; s < samples; ++s) {
      const double pick = unit(random_) * total;
      const auto it = std::lower_bound(triangles.begin(), triangles.end(), pick,
                                       [](const auto& entry, double value) { return entry.second < value; });
      const Eigen::Vector3i& tri = organ_.triangles()[it->first];
      double b1 = unit(random_), b2 = unit(random_);
      if (b1 + b2 > 1) b1 = 1 - b1, b2 = 1 - b2;
      const Eigen::Vector3d x = v[tri[0]] + b1 * (v[tri[1]] - v[tri[0]]) + b2 * (v[tri[2]] - v[tri[0]]);
      const double r = rho(x);
      const double patch = settings_.tip_node_only ? 0.0 : contact_.radius_m;
      if (r <= patch + 0.5 * spacing_(r) || r >= length - 0.5 * spacing_(length)) continue;
      const geometry::SurfaceProjection p = organ_.project(x);
      candidates.push_back({p.point, NodeKind::free_surface, p.normal});
    }
    thin_nearest_first(candidates, 0.8);
  }

  /// The cut sphere |x − c| = L inside the organ, away from the surface.
  void place_cut() {
    const double length = settings_.local_radius_m, s = spacing_(length);
    const int count = static_cast<int>(std::ceil(4 * pi * length * length / (s * s)));
    std::vector<Candidate> candidates;
    for (const Eigen::Vector3d& direction : fibonacci_sphere(count, random_rotation())) {
      const Eigen::Vector3d x = centre_ + length * direction;
      if (organ_.signed_distance(x) > -0.5 * s) continue;
      candidates.push_back({x, NodeKind::cut, direction});
    }
    thin_nearest_first(candidates, 0.8);
  }

  /// Shells (or Halton points) strictly inside Ω, away from the surface and the cut.
  void place_interior() {
    const double length = settings_.local_radius_m;
    std::vector<Candidate> candidates;
    const auto consider = [&](const Eigen::Vector3d& x) {
      const double r = rho(x), s = spacing_(r);
      if (r > length - 0.5 * s) return;
      if (organ_.signed_distance(x) > -0.5 * s) return;
      candidates.push_back({x, NodeKind::interior, Eigen::Vector3d::Zero()});
    };
    if (settings_.layout == Layout::radial_shells) {
      for (double r = 0.5 * spacing_(0.0); r < length;) {
        const double s = spacing_(r);
        const int count = std::max(4, static_cast<int>(std::ceil(4 * pi * r * r / (s * s))));
        for (const Eigen::Vector3d& direction : fibonacci_sphere(count, random_rotation())) consider(centre_ + r * direction);
        r += spacing_(r + 0.5 * s);
      }
    } else {
      const int count = 40 * settings_.node_count;
      for (int i = 1; i <= count; ++i) {
        const Eigen::Vector3d u(halton(i, 2), halton(i, 3), halton(i, 5));
        consider(centre_ + length * (2 * u - Eigen::Vector3d::Ones()));
      }
    }
    thin_nearest_first(candidates, 0.8);
  }

  /// A uniform lattice aligned with the contact frame: surface and cut nodes by projection.
  void place_lattice() {
    const double length = settings_.local_radius_m, h = spacing_.minimum;
    const auto [t1, t2] = tangents(normal_);
    const int n = static_cast<int>(std::ceil(length / h));
    std::vector<Candidate> candidates;
    for (int i = -n; i <= n; ++i)
      for (int j = -n; j <= n; ++j)
        for (int k = -n; k <= 0; ++k) {
          const Eigen::Vector3d x = centre_ + h * (i * t1 + j * t2 + k * normal_);
          const double r = rho(x), distance = organ_.signed_distance(x);
          if (r > length + 0.5 * h || distance > 0.5 * h) continue;
          if (r > length - 0.5 * h) {
            if (distance < -0.5 * h) candidates.push_back({centre_ + length * (x - centre_).normalized(), NodeKind::cut, (x - centre_).normalized()});
          } else if (distance > -0.5 * h) {
            const geometry::SurfaceProjection p = organ_.project(x);
            if (rho(p.point) > (settings_.tip_node_only ? 0.0 : contact_.radius_m) + 0.5 * h) candidates.push_back({p.point, NodeKind::free_surface, p.normal});
          } else {
            candidates.push_back({x, NodeKind::interior, Eigen::Vector3d::Zero()});
          }
        }
    thin_nearest_first(candidates, 0.7);
  }

  void thin_nearest_first(std::vector<Candidate>& candidates, double fraction) {
    std::stable_sort(candidates.begin(), candidates.end(),
                     [&](const Candidate& a, const Candidate& b) { return rho(a.x) < rho(b.x); });
    for (const Candidate& c : candidates) {
      const double s = settings_.layout == Layout::lattice ? spacing_.minimum : spacing_(rho(c.x));
      if (far_from_accepted(c.x, fraction * s)) accept(c.x, c.kind, c.normal);
    }
  }

  Eigen::Matrix3d random_rotation() {
    std::normal_distribution<double> gauss;
    Eigen::Quaterniond q(gauss(random_), gauss(random_), gauss(random_), gauss(random_));
    return q.normalized().toRotationMatrix();
  }

  NodeCloud finish() const {
    NodeCloud cloud;
    const Eigen::Vector3d d = contact_.direction.normalized();
    for (const Candidate& node : nodes_) {
      const double s = settings_.layout == Layout::lattice ? spacing_.minimum : spacing_(rho(node.x));
      const bool boundary = node.kind != NodeKind::interior;
      cloud.positions.push_back(node.x);
      cloud.kinds.push_back(node.kind);
      cloud.normals.push_back(node.normal);
      cloud.spacing.push_back(s);
      cloud.radii.push_back((boundary ? settings_.boundary_radius_factor : settings_.radius_factor) * s);
      cloud.rows.push_back(rows_for(node, d));
    }
    return cloud;
  }

  std::array<CollocationRow, 3> rows_for(const Candidate& node, const Eigen::Vector3d& d) const {
    using Type = CollocationRow::Type;
    std::array<CollocationRow, 3> rows;
    const auto along_axes = [&](Type type, bool tool) {
      for (int k = 0; k < 3; ++k) {
        rows[k].type = type;
        rows[k].direction = Eigen::Vector3d::Unit(k);
        if (tool) rows[k].tool = Eigen::Vector3d::Unit(k);
      }
    };
    switch (node.kind) {
      case NodeKind::interior: along_axes(Type::navier, false); break;
      case NodeKind::free_surface: along_axes(Type::traction, false); break;
      case NodeKind::cut:
        along_axes(settings_.outer == OuterCondition::clamped ? Type::dirichlet : Type::traction, false);
        break;
      case NodeKind::tool_patch:
        if (settings_.tip_node_only) {
          along_axes(Type::traction, false);
        } else if (contact_.condition == geometry::ContactCondition::bonded) {
          along_axes(Type::dirichlet, true);
        } else {
          const auto [t1, t2] = tangents(d);
          rows[0] = {Type::dirichlet, d, 0.0, d};
          rows[1] = {Type::traction, t1, 0.0, Eigen::Vector3d::Zero()};
          rows[2] = {Type::traction, t2, 0.0, Eigen::Vector3d::Zero()};
        }
        break;
    }
    return rows;
  }

  const geometry::TriangleSurface& organ_;
  const ToolContact& contact_;
  const SprinklingSettings& settings_;
  Spacing spacing_;
  std::mt19937_64 random_;
  Eigen::Vector3d centre_, normal_;
  std::vector<Candidate> nodes_;
};

}  // namespace

void SprinklingSettings::validate() const {
  const auto reject = [](const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("SprinklingSettings." + field + " = " + std::to_string(value) + " " + rule);
  };
  if (node_count < 20 || node_count > 20000) reject("node_count", node_count, "must be in [20, 20000]");
  if (!(local_radius_m > 0) || !std::isfinite(local_radius_m)) reject("local_radius_m", local_radius_m, "must be > 0");
  if (ring_nodes < 3 || ring_nodes > 64) reject("ring_nodes", ring_nodes, "must be in [3, 64]");
  if (!(radius_factor >= 1.2 && radius_factor <= 6)) reject("radius_factor", radius_factor, "must be in [1.2, 6]");
  if (!(oversampling >= 1 && oversampling <= 16)) reject("oversampling", oversampling, "must be in [1, 16]");
  if (!(boundary_radius_factor >= 1.2 && boundary_radius_factor <= 8))
    reject("boundary_radius_factor", boundary_radius_factor, "must be in [1.2, 8]");
}

NodeCloud sprinkle_nodes(const geometry::TriangleSurface& organ, const ToolContact& contact,
                         const SprinklingSettings& settings) {
  settings.validate();
  if (!contact.point.allFinite() || !contact.direction.allFinite() || contact.direction.norm() < 1e-12)
    throw std::invalid_argument("ToolContact: point and direction must be finite, direction non-zero");
  if (!(contact.radius_m > 0) || !(contact.radius_m < 0.5 * settings.local_radius_m))
    throw std::invalid_argument("ToolContact.radius_m = " + std::to_string(contact.radius_m) +
                                " must be in (0, L/2) with L = " + std::to_string(settings.local_radius_m));
  if (organ.project(contact.point).distance_m > 0.1 * contact.radius_m)
    throw std::invalid_argument("ToolContact.point is not on the organ surface (distance " +
                                std::to_string(organ.project(contact.point).distance_m) + " m)");

  // The growth g of the spacing decides N: bisect on it (the count falls as g grows).
  const auto spacing_for = [&](double growth) {
    // The lattice has one spacing h = 0.2 g L; the graded layouts s(ρ) = g max(a, ρ).
    return settings.layout == Layout::lattice ? Spacing{0.2 * growth * settings.local_radius_m, 0.0}
                                              : Spacing{growth * contact.radius_m, growth};
  };
  double low = 0.05, high = 2.0, best_growth = high;
  NodeCloud best;
  for (int iteration = 0; iteration < 24; ++iteration) {
    const double growth = std::sqrt(low * high);
    NodeCloud cloud = Sprinkler(organ, contact, settings, spacing_for(growth)).run();
    const int count = static_cast<int>(cloud.size());
    if (best.size() == 0 || std::abs(count - settings.node_count) < std::abs(static_cast<int>(best.size()) - settings.node_count)) {
      best = std::move(cloud);
      best_growth = growth;
    }
    if (std::abs(count - settings.node_count) <= settings.node_count / 20) break;
    (count > settings.node_count ? low : high) = growth;
  }
  if (settings.oversampling > 1) {
    // Least-squares collocation: the same sprinkling at spacing s / oversampling^(1/3) gives
    // about `oversampling` times as many points; those that do not sit on a node are extra
    // collocation points.
    const double shrink = std::cbrt(settings.oversampling);
    Spacing dense = spacing_for(best_growth);
    dense.minimum /= shrink;
    dense.growth /= shrink;
    SprinklingSettings dense_settings = settings;
    dense_settings.seed = settings.seed + 1;
    const NodeCloud points = Sprinkler(organ, contact, dense_settings, dense).run();
    for (std::size_t p = 0; p < points.size(); ++p) {
      const bool on_a_node = std::any_of(best.positions.begin(), best.positions.end(), [&](const Eigen::Vector3d& x) {
        return (x - points.positions[p]).norm() < 0.35 * points.spacing[p];
      });
      if (on_a_node) continue;
      best.extra_points.push_back({points.positions[p], points.kinds[p], points.normals[p], points.spacing[p],
                                   Eigen::Vector3d::Zero(), points.rows[p]});
    }
  }
  return best;
}

NodeCloud sprinkle_even_nodes(const geometry::TriangleSurface& organ, const ToolContact& contact, int node_count,
                              double local_radius_m, std::uint64_t seed) {
  const LocalSurface surface(organ, contact.point, enriched_surface_reach_local_radii * local_radius_m);
  return sprinkle_even_nodes(surface, contact, node_count, local_radius_m, seed);
}

NodeCloud sprinkle_even_nodes(const LocalSurface& surface, const ToolContact& contact, int node_count,
                              double local_radius_m, std::uint64_t seed) {
  if (node_count < 10 || node_count > 5000)
    throw std::invalid_argument("node_count = " + std::to_string(node_count) + " must be in [10, 5000]");
  const double length = local_radius_m, a = contact.radius_m;
  if (!(length > 0) || !std::isfinite(length))
    throw std::invalid_argument("local_radius_m = " + std::to_string(length) + " must be finite and > 0");
  if (!contact.point.allFinite() || !contact.direction.allFinite() || contact.direction.norm() < 1e-12)
    throw std::invalid_argument("ToolContact: point and direction must be finite, direction non-zero");
  if (!(a > 0) || !(a < 0.5 * length))
    throw std::invalid_argument("ToolContact.radius_m = " + std::to_string(a) + " must be in (0, L/2) with L = " +
                                std::to_string(length));
  // Against the triangles, not the fitted centre: the fit smooths a faceted organ by up to its
  // residual, which a fine tip's a/10 does not allow for.
  const double off_surface = surface.contact_offset_m();
  if (off_surface > 0.1 * a)
    throw std::invalid_argument("ToolContact.point is not on the organ surface (distance " + std::to_string(off_surface) +
                                " m)");
  const Eigen::Vector3d centre = surface.centre(), normal = surface.normal();
  const auto [t1, t2] = tangents(normal);
  // Spacing of N nodes in a half ball; nodes keep half a spacing off the cut and the surface
  // (those on them are placed there).
  const double spacing = std::cbrt(2.0 / 3.0 * pi * length * length * length / node_count);
  const int surface_count = std::max(4, static_cast<int>(std::lround(0.25 * node_count)));
  const int cut_count = std::max(3, static_cast<int>(std::lround(0.2 * node_count)));

  NodeCloud cloud;
  const auto add = [&](const Eigen::Vector3d& x, NodeKind kind, const Eigen::Vector3d& n) {
    cloud.positions.push_back(x);
    cloud.kinds.push_back(kind);
    cloud.normals.push_back(n);
    cloud.spacing.push_back(spacing);
    cloud.radii.push_back(2.5 * spacing);
    std::array<CollocationRow, 3> rows;
    for (int i = 0; i < 3; ++i) rows[i].direction = Eigen::Vector3d::Unit(i);
    cloud.rows.push_back(rows);
  };
  // Surface: a sunflower spiral of equal areas in the tangent plane, projected; the tip first.
  const double golden = pi * (3.0 - std::sqrt(5.0));
  const double phase = 2 * pi * halton(static_cast<int>(seed % 1000) + 1, 2);
  for (int k = 0; k < surface_count; ++k) {
    const double r = 0.97 * length * std::sqrt(static_cast<double>(k) / surface_count);
    const double phi = phase + golden * k;
    Eigen::Vector3d point, n;
    if (!surface.on_line(centre + r * (std::cos(phi) * t1 + std::sin(phi) * t2), -normal, point, n)) continue;
    if ((point - centre).norm() > length - 0.5 * spacing) continue;
    add(point, r < a ? NodeKind::tool_patch : NodeKind::free_surface, n);
  }
  // Cut: a Fibonacci lattice on the sphere, twice the count (about half of it lies in a
  // locally flat organ), kept half a spacing inside the organ surface.
  Eigen::Matrix3d rotation;
  rotation << t1, t2, normal;
  for (const Eigen::Vector3d& d : fibonacci_sphere(2 * cut_count, rotation)) {
    const Eigen::Vector3d x = centre + length * d;
    if (surface.inside(x, 0.5 * spacing)) add(x, NodeKind::cut, d);
  }
  // Inside: Halton points in the ball, uniform in volume, off the surface and the cut. They make
  // up the count: the spiral's outer ring and the cut lattice lose the nodes that fall outside
  // the organ or within half a spacing of the cut (about a tenth of N on a flat organ).
  const int inner_count = std::max(3, node_count - static_cast<int>(cloud.size()));
  const int start = 1 + static_cast<int>(seed % 997) * 64;
  for (int k = 0, kept = 0; kept < inner_count && k < 8 * inner_count; ++k) {
    const double rho = (length - 0.5 * spacing) * std::cbrt(halton(start + k, 2));
    const double z = 1 - 2 * halton(start + k, 3), phi = 2 * pi * halton(start + k, 5);
    const double s = std::sqrt(std::max(0.0, 1 - z * z));
    const Eigen::Vector3d x = centre + rho * (rotation * Eigen::Vector3d(s * std::cos(phi), s * std::sin(phi), z));
    if (surface.inside(x, 0.5 * spacing)) {
      add(x, NodeKind::interior, Eigen::Vector3d::Zero());
      ++kept;
    }
  }
  return cloud;
}

}  // namespace touchstone::realtime::mfs
