#include "touchstone/realtime/runtime/contact_model.hpp"

#include <algorithm>

namespace touchstone::realtime::runtime {

const char* to_string(ForceMode mode) {
  switch (mode) {
    case ForceMode::stiffness: return "stiffness";
    case ForceMode::extrapolation: return "extrapolation";
  }
  return "?";
}

double penetration_depth_m(const ModelSnapshot& model, const Eigen::Vector3d& tip_m) noexcept {
  return (tip_m - eigen(model.contact_point_m)).dot(eigen(model.direction));
}

double tangential_offset_m(const ModelSnapshot& model, const Eigen::Vector3d& tip_m) noexcept {
  const Eigen::Vector3d d = eigen(model.direction);
  const Eigen::Vector3d u = tip_m - eigen(model.contact_point_m);
  return (u - u.dot(d) * d).norm();
}

Eigen::Vector3d push_only(const Eigen::Vector3d& force_N, const Eigen::Vector3d& direction) noexcept {
  return force_N.dot(direction) > 0 ? force_N : Eigen::Vector3d::Zero();
}

Eigen::Vector3d stiffness_force_N(const ModelSnapshot& model, const Eigen::Vector3d& tip_m) noexcept {
  const Eigen::Vector3d u = tip_m - eigen(model.contact_point_m);
  return push_only(eigen(model.tool_stiffness_N_per_m) * u + eigen(model.load_force_N), eigen(model.direction));
}

Eigen::Vector3d extrapolated_force_N(const ModelSnapshot& model, double time_s, double horizon_s) noexcept {
  if (model.force_time_s < 0) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d latest = eigen(model.force_N);
  const double interval = model.force_time_s - model.previous_force_time_s;
  if (model.previous_force_time_s < 0 || !(interval > 0)) return push_only(latest, eigen(model.direction));
  const double ahead = std::clamp(time_s - model.force_time_s, 0.0, horizon_s);
  const Eigen::Vector3d slope = (latest - eigen(model.previous_force_N)) / interval;
  return push_only(latest + slope * ahead, eigen(model.direction));
}

}  // namespace touchstone::realtime::runtime
