#include "touchstone/realtime/haptics/palpation_trajectory.hpp"

#include "touchstone/realtime/hand_motion/approach_trajectory.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::haptics {

namespace {

void require_non_negative(double value, const char* field) {
  if (!std::isfinite(value) || value < 0)
    throw std::invalid_argument(std::string("PalpationSettings.") + field + " = " + std::to_string(value) +
                                " must be finite and >= 0");
}
void require_positive(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0)
    throw std::invalid_argument(std::string("PalpationSettings.") + field + " = " + std::to_string(value) +
                                " must be finite and > 0");
}

/// A unit vector orthogonal to n: the projection of x (or y when x is nearly along n).
Eigen::Vector3d tangent_of(const Eigen::Vector3d& n) {
  Eigen::Vector3d t = Eigen::Vector3d::UnitX() - n.x() * n;
  if (t.norm() < 0.3) t = Eigen::Vector3d::UnitY() - n.y() * n;
  return t.normalized();
}

/// Appends moves to a script; last() is the smooth position of the last sample so far, exactly
/// as sample_palpation_script() will compute it.
class Builder {
 public:
  Builder(const PalpationSettings& settings, PalpationScript& out) : settings_(settings), out_(out) {}

  void rest(const Eigen::Vector3d& at, double seconds, int site, const Eigen::Vector3d& axis) {
    move(at, at, seconds, PalpationPhase::rest, site, axis);
  }
  /// A minimum-jerk segment from → to lasting `seconds`.
  void move(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double seconds, PalpationPhase phase, int site,
            const Eigen::Vector3d& axis) {
    PalpationMove m;
    m.from_m = from;
    m.to_m = to;
    m.tool_axis = axis;
    m.begin = out_.sample_count;
    m.samples = std::max(1, static_cast<int>(std::lround(seconds * settings_.sample_rate_hz)));
    out_.moves.push_back(m);
    out_.sample_count += m.samples;
    out_.segments.push_back({phase, site, m.begin, out_.sample_count});
    last_ = palpation_sample(m, out_.sample_count - 1);
  }
  const Eigen::Vector3d& last() const { return last_; }
  const Eigen::Vector3d& last_axis() const { return out_.moves.back().tool_axis; }
  double seconds() const { return static_cast<double>(out_.sample_count) / settings_.sample_rate_hz; }

 private:
  const PalpationSettings& settings_;
  PalpationScript& out_;
  Eigen::Vector3d last_ = Eigen::Vector3d::Zero();
};

}  // namespace

const char* to_string(PalpationPhase phase) {
  switch (phase) {
    case PalpationPhase::rest: return "rest";
    case PalpationPhase::approach: return "approach";
    case PalpationPhase::hold: return "hold";
    case PalpationPhase::slide: return "slide";
    case PalpationPhase::release: return "release";
    case PalpationPhase::transfer: return "transfer";
  }
  return "?";
}

void PalpationSettings::validate() const {
  for (std::size_t i = 0; i < sites.size(); ++i)
    if (!sites[i].allFinite())
      throw std::invalid_argument("PalpationSettings.sites[" + std::to_string(i) + "] is not finite");
  if (sites.empty() && generated_sites < 1)
    throw std::invalid_argument("PalpationSettings.generated_sites = " + std::to_string(generated_sites) +
                                " must be >= 1");
  require_non_negative(site_spread_m, "site_spread_m");
  require_positive(duration_s, "duration_s");
  require_positive(hover_m, "hover_m");
  require_positive(press_depth_m, "press_depth_m");
  require_non_negative(slide_m, "slide_m");
  require_positive(approach_s, "approach_s");
  require_non_negative(hold_s, "hold_s");
  require_positive(slide_s, "slide_s");
  require_positive(release_s, "release_s");
  require_non_negative(rest_s, "rest_s");
  require_non_negative(lift_m, "lift_m");
  require_positive(transfer_s, "transfer_s");
  require_positive(sample_rate_hz, "sample_rate_hz");
  tremor.validate();
  if (!(duration_s >= first_palpation_s()))
    throw std::invalid_argument("PalpationSettings.duration_s = " + std::to_string(duration_s) +
                                " s is shorter than one palpation (" + std::to_string(first_palpation_s()) + " s)");
}

double PalpationSettings::palpation_s() const noexcept {
  return approach_s + 2 * hold_s + (slide_m > 0 ? slide_s : 0) + release_s + rest_s;
}

double PalpationSettings::first_palpation_s() const noexcept { return palpation_s() + rest_s; }

Eigen::Vector3d palpation_sample(const PalpationMove& move, long long k) noexcept {
  const double s = hand_motion::minimum_jerk(static_cast<double>(k - move.begin + 1) / move.samples);
  return move.from_m + s * (move.to_m - move.from_m);
}

PalpationScript make_palpation_script(const geometry::TriangleSurface& organ, const PalpationSettings& settings) {
  settings.validate();
  PalpationScript out;
  out.sample_period_s = 1.0 / settings.sample_rate_hz;
  hand_motion::RandomStream random(settings.seed);

  // Sites: the given points projected, or the top of the organ and random points around it.
  std::vector<Eigen::Vector3d> queries = settings.sites;
  if (queries.empty()) {
    const auto& vertices = organ.vertices();
    const Eigen::Vector3d top = *std::max_element(vertices.begin(), vertices.end(),
                                                  [](const auto& a, const auto& b) { return a.z() < b.z(); });
    queries.push_back(top);
    const Eigen::Vector3d n = organ.project(top).normal;
    const Eigen::Vector3d t1 = tangent_of(n), t2 = n.cross(t1);
    for (int i = 1; i < settings.generated_sites; ++i) {
      const double radius = settings.site_spread_m * std::sqrt(random.uniform());
      const double angle = 6.283185307179586 * random.uniform();
      queries.push_back(top + radius * (std::cos(angle) * t1 + std::sin(angle) * t2));
    }
  }
  for (const auto& q : queries) {
    const auto projection = organ.project(q);
    out.site_points.push_back(projection.point);
    out.site_normals.push_back(projection.normal.normalized());
  }

  // One palpation: approach from the hover point, press, hold, slide, hold, release.
  const double palpation_seconds = settings.palpation_s();
  const auto transfer_seconds = 3 * settings.transfer_s;
  Builder builder(settings, out);
  const int site_count = static_cast<int>(out.site_points.size());
  int site = 0;
  while (true) {
    const Eigen::Vector3d p = out.site_points[site], n = out.site_normals[site];
    const Eigen::Vector3d hover = p + settings.hover_m * n;
    const double needed = palpation_seconds + (out.palpations == 0 ? settings.rest_s : transfer_seconds);
    if (builder.seconds() + needed > settings.duration_s) break;
    if (out.palpations == 0) {
      builder.rest(hover, settings.rest_s, site, n);
    } else {
      // Lift above the previous site, move over, descend: the straight path between the lift
      // points is checked against the organ below.
      const int previous = (site + site_count - 1) % site_count;
      const Eigen::Vector3d from = builder.last();
      const Eigen::Vector3d lift_from = out.site_points[previous] + (settings.hover_m + settings.lift_m) * out.site_normals[previous];
      const Eigen::Vector3d lift_to = p + (settings.hover_m + settings.lift_m) * n;
      for (int k = 0; k <= 20; ++k) {
        const Eigen::Vector3d x = lift_from + (k / 20.0) * (lift_to - lift_from);
        if (organ.signed_distance(x) < settings.hover_m / 2)
          throw std::runtime_error("palpation: the transfer from site " + std::to_string(previous) + " to site " +
                                   std::to_string(site) + " passes within hover_m/2 of the organ; raise lift_m (" +
                                   std::to_string(settings.lift_m) + " m) or bring the sites closer");
      }
      builder.move(from, lift_from, settings.transfer_s, PalpationPhase::transfer, site, n);
      builder.move(lift_from, lift_to, settings.transfer_s, PalpationPhase::transfer, site, n);
      builder.move(lift_to, hover, settings.transfer_s, PalpationPhase::transfer, site, n);
    }
    const Eigen::Vector3d pressed = p - settings.press_depth_m * n;
    builder.move(hover, pressed, settings.approach_s, PalpationPhase::approach, site, n);
    builder.rest(pressed, settings.hold_s, site, n);
    out.segments.back().phase = PalpationPhase::hold;
    Eigen::Vector3d last = pressed;
    if (settings.slide_m > 0) {
      const double angle = 6.283185307179586 * random.uniform();
      const Eigen::Vector3d t1 = tangent_of(n), t2 = n.cross(t1);
      last = pressed + settings.slide_m * (std::cos(angle) * t1 + std::sin(angle) * t2);
      builder.move(pressed, last, settings.slide_s, PalpationPhase::slide, site, n);
      builder.rest(last, settings.hold_s, site, n);
      out.segments.back().phase = PalpationPhase::hold;
    }
    builder.move(last, last + (settings.press_depth_m + settings.hover_m) * n, settings.release_s,
                 PalpationPhase::release, site, n);
    builder.rest(builder.last(), settings.rest_s, site, n);
    ++out.palpations;
    site = (site + 1) % site_count;
  }
  const double remaining = settings.duration_s - builder.seconds();
  if (remaining * settings.sample_rate_hz >= 1)
    builder.rest(builder.last(), remaining, site == 0 ? site_count - 1 : site - 1, builder.last_axis());

  // Tremor on top of the hand motion.
  out.tremor = settings.tremor;
  out.tremor.sample_rate_hz = settings.sample_rate_hz;
  out.tremor.seed = settings.seed * 0x9e3779b97f4a7c15ULL + 17;
  return out;
}

PalpationTrajectory sample_palpation_script(const PalpationScript& script) {
  PalpationTrajectory out;
  out.site_points = script.site_points;
  out.site_normals = script.site_normals;
  out.segments = script.segments;
  out.sample_period_s = script.sample_period_s;
  out.palpations = script.palpations;
  const auto count = static_cast<std::size_t>(script.sample_count);
  out.smooth.reserve(count);
  out.tool_axis.reserve(count);
  for (const PalpationMove& move : script.moves)
    for (long long k = move.begin; k < move.begin + move.samples; ++k) {
      out.smooth.push_back(palpation_sample(move, k));
      out.tool_axis.push_back(move.tool_axis);
    }
  out.tip = out.smooth;
  if (script.tremor.rms_per_axis_m > 0) {
    hand_motion::TremorGenerator generator(script.tremor);
    for (auto& x : out.tip) x += generator.next();
  }
  return out;
}

PalpationTrajectory make_palpation_trajectory(const geometry::TriangleSurface& organ,
                                              const PalpationSettings& settings) {
  return sample_palpation_script(make_palpation_script(organ, settings));
}

}  // namespace touchstone::realtime::haptics
