#include "touchstone/realtime/hand_motion/approach_trajectory.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::hand_motion {

namespace {

using Eigen::Vector3d;

constexpr double pi = 3.14159265358979323846;
constexpr int max_attempts = 1000;
/// Sphere tracing stops this close to the target [m]: a crossing closer than this to the
/// target is the target's own contact.
constexpr double trace_tolerance_m = 1e-5;

}  // namespace

double minimum_jerk(double tau) noexcept {
  const double t = std::clamp(tau, 0.0, 1.0);
  return t * t * t * (10 + t * (-15 + 6 * t));
}

void ApproachSettings::validate() const {
  const auto reject = [](const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("ApproachSettings." + field + " = " + std::to_string(value) + " " + rule);
  };
  const auto positive = [&](const std::string& field, double value) {
    if (!(value > 0) || !std::isfinite(value)) reject(field, value, "must be finite and > 0");
  };
  const auto non_negative = [&](const std::string& field, double value) {
    if (!(value >= 0) || !std::isfinite(value)) reject(field, value, "must be finite and >= 0");
  };
  positive("start_distance_min_m", start_distance_min_m);
  if (!(start_distance_max_m >= start_distance_min_m) || !std::isfinite(start_distance_max_m))
    reject("start_distance_max_m", start_distance_max_m, "must be >= start_distance_min_m");
  if (!(max_approach_angle_rad >= 0 && max_approach_angle_rad < 0.5 * pi))
    reject("max_approach_angle_rad", max_approach_angle_rad, "must be in [0, pi/2)");
  positive("speed_min_m_per_s", speed_min_m_per_s);
  if (!(speed_max_m_per_s >= speed_min_m_per_s) || !std::isfinite(speed_max_m_per_s))
    reject("speed_max_m_per_s", speed_max_m_per_s, "must be >= speed_min_m_per_s");
  non_negative("press_depth_min_m", press_depth_min_m);
  if (!(press_depth_max_m >= press_depth_min_m) || !std::isfinite(press_depth_max_m))
    reject("press_depth_max_m", press_depth_max_m, "must be >= press_depth_min_m");
  non_negative("rest_s", rest_s);
  non_negative("hold_s", hold_s);
  non_negative("final_rest_s", final_rest_s);
  positive("min_segment_s", min_segment_s);
  positive("sample_rate_hz", sample_rate_hz);
  TremorSettings tremor_at_rate = tremor;
  tremor_at_rate.sample_rate_hz = sample_rate_hz;
  tremor_at_rate.validate();
}

ApproachTrajectoryGenerator::ApproachTrajectoryGenerator(const geometry::TriangleSurface& surface,
                                                         const ApproachSettings& settings)
    : surface_(surface), settings_(settings) {
  settings_.validate();
  settings_.tremor.sample_rate_hz = settings_.sample_rate_hz;
  double total = 0;
  for (const Eigen::Vector3i& t : surface_.triangles()) {
    const Vector3d& a = surface_.vertices()[t[0]];
    total += 0.5 * (surface_.vertices()[t[1]] - a).cross(surface_.vertices()[t[2]] - a).norm();
    cumulative_area_.push_back(total);
  }
}

bool ApproachTrajectoryGenerator::clear_path(const Vector3d& start, const Vector3d& target) const {
  // Sphere tracing: the ball of radius |signed distance| around x holds no surface point, so
  // stepping by it never jumps over a crossing.
  const double length = (target - start).norm();
  const Vector3d direction = (target - start) / length;
  double travelled = 0;
  for (int step = 0; step < 10000; ++step) {
    const double remaining = length - travelled;
    if (remaining < trace_tolerance_m) return true;
    const double distance = surface_.signed_distance(start + travelled * direction);
    if (distance <= 0) return false;
    if (distance >= remaining) return true;
    travelled += distance;
  }
  return false;
}

ApproachTrajectory ApproachTrajectoryGenerator::generate(std::uint64_t seed) const {
  RandomStream random(seed);
  const auto between = [&](double low, double high) { return low + (high - low) * random.uniform(); };
  const auto& vertices = surface_.vertices();

  for (int attempt = 0; attempt < max_attempts; ++attempt) {
    // A target uniform over the area: a triangle by area, a point uniform in it.
    const double pick = random.uniform() * cumulative_area_.back();
    const auto found = std::upper_bound(cumulative_area_.begin(), cumulative_area_.end(), pick);
    const std::size_t index = std::min<std::size_t>(found - cumulative_area_.begin(), cumulative_area_.size() - 1);
    const Eigen::Vector3i& t = surface_.triangles()[index];
    const Vector3d& a = vertices[t[0]];
    const Vector3d& b = vertices[t[1]];
    const Vector3d& c = vertices[t[2]];
    const double r1 = std::sqrt(random.uniform());
    const double r2 = random.uniform();
    const Vector3d target = (1 - r1) * a + r1 * (1 - r2) * b + r1 * r2 * c;
    const Vector3d normal = (b - a).cross(c - a).normalized();

    // An outward direction uniform in the cone about the normal (uniform in cos θ).
    const double cos_theta = between(std::cos(settings_.max_approach_angle_rad), 1.0);
    const double sin_theta = std::sqrt(std::max(0.0, 1 - cos_theta * cos_theta));
    const double azimuth = 2 * pi * random.uniform();
    const Vector3d u = normal.unitOrthogonal();
    const Vector3d v = normal.cross(u);
    const Vector3d outward = cos_theta * normal + sin_theta * (std::cos(azimuth) * u + std::sin(azimuth) * v);
    const double distance = between(settings_.start_distance_min_m, settings_.start_distance_max_m);
    const Vector3d start = target + distance * outward;
    const double speed = between(settings_.speed_min_m_per_s, settings_.speed_max_m_per_s);
    const double press = between(settings_.press_depth_min_m, settings_.press_depth_max_m);
    if (surface_.signed_distance(start) <= 0 || !clear_path(start, target)) continue;

    ApproachTrajectory trajectory;
    trajectory.start = start;
    trajectory.target = target;
    trajectory.target_normal = normal;
    trajectory.direction = -outward;
    trajectory.press_point = target + press * trajectory.direction;
    trajectory.sample_period_s = 1.0 / settings_.sample_rate_hz;

    const double rate = settings_.sample_rate_hz;
    const double travel_s = std::max(settings_.min_segment_s, (distance + press) / speed);
    const int rest = static_cast<int>(std::lround(settings_.rest_s * rate));
    const int travel = std::max(1, static_cast<int>(std::lround(travel_s * rate)));
    const int hold = static_cast<int>(std::lround(settings_.hold_s * rate));
    const int final_rest = static_cast<int>(std::lround(settings_.final_rest_s * rate));
    std::vector<Vector3d>& smooth = trajectory.smooth;
    smooth.reserve(rest + 2 * travel + hold + final_rest + 1);
    for (int k = 0; k < rest; ++k) smooth.push_back(start);
    trajectory.approach_begin = static_cast<int>(smooth.size());
    for (int k = 0; k <= travel; ++k)
      smooth.push_back(start + minimum_jerk(static_cast<double>(k) / travel) * (trajectory.press_point - start));
    trajectory.approach_end = static_cast<int>(smooth.size()) - 1;
    for (int k = 0; k < hold; ++k) smooth.push_back(trajectory.press_point);
    trajectory.release_begin = static_cast<int>(smooth.size()) - 1;
    for (int k = 1; k <= travel; ++k)
      smooth.push_back(trajectory.press_point +
                       minimum_jerk(static_cast<double>(k) / travel) * (start - trajectory.press_point));
    trajectory.release_end = static_cast<int>(smooth.size()) - 1;
    for (int k = 0; k < final_rest; ++k) smooth.push_back(start);

    trajectory.tip = smooth;
    if (settings_.tremor.rms_per_axis_m > 0) {
      TremorSettings tremor = settings_.tremor;
      tremor.seed = random.next_u64() ^ settings_.tremor.seed;
      TremorGenerator generator(tremor);
      for (Vector3d& x : trajectory.tip) x += generator.next();
    }
    return trajectory;
  }
  throw std::runtime_error("ApproachTrajectoryGenerator: no start outside the surface with a clear path to the "
                           "target in " + std::to_string(max_attempts) + " attempts (seed " +
                           std::to_string(seed) + ")");
}

}  // namespace touchstone::realtime::hand_motion
