#pragma once
/// @file
/// The force at haptic rate from what the model loop publishes.
///
/// The local MFS model is linear in the tool displacement U = tip − c (c the contact point the
/// model was built at), so the haptic loop evaluates the model's force exactly every tick:
/// F = K_t U + F_loads, nine multiply-adds (`ForceMode::stiffness`, the default). The paper
/// instead extrapolated linearly from the forces the 200 Hz model loop computed
/// (`ForceMode::extrapolation`); both are here so that a run can measure what the paper's
/// scheme costs in force error and in force steps at model updates.
///
/// Tissue pushes, it does not pull: a force whose component along the push direction d is
/// negative (the tool is outside the undeformed surface) is zero.

#include "touchstone/realtime/concurrency/plain_types.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace touchstone::realtime::runtime {

// The loops hand these plain values to each other (concurrency/plain_types.hpp).
using concurrency::eigen;
using concurrency::plain;
using concurrency::PlainMatrix3;
using concurrency::PlainVector3;

enum class ForceMode : std::uint8_t {
  stiffness,      ///< F = K_t U every haptic tick: exact for the linear model (default)
  extrapolation,  ///< the paper: linear extrapolation of the model loop's last two forces
};
const char* to_string(ForceMode mode);

/// What the model loop publishes for the haptic loop (a Seqlock payload: plain values only).
struct ModelSnapshot {
  std::uint64_t model_id = 0;  ///< 0: no model yet; increments with every new local model
  bool valid = false;          ///< a usable model (built, status ok)
  PlainMatrix3 tool_stiffness_N_per_m{};  ///< K_t: force on the tissue per tool displacement
  PlainVector3 load_force_N{};            ///< F_loads (zero without body loads)
  PlainVector3 contact_point_m{};         ///< c
  PlainVector3 direction{};               ///< d, unit, into the organ
  double local_radius_m = 0;              ///< L
  /// Time of this publish on the run's clock [s]: the model loop's heartbeat (every step).
  double heartbeat_s = 0;
  /// The model loop's last two forces on the tissue [N] and their times [s] (extrapolation);
  /// times < 0 when not available.
  PlainVector3 force_N{}, previous_force_N{};
  double force_time_s = -1, previous_force_time_s = -1;
  std::uint64_t force_sequence = 0;  ///< increments with each new force
};

/// Penetration of the tip along the model's push direction [m] (negative: outside).
double penetration_depth_m(const ModelSnapshot& model, const Eigen::Vector3d& tip_m) noexcept;

/// Distance of the tip from the model's contact point across d [m] (how far it has slid).
double tangential_offset_m(const ModelSnapshot& model, const Eigen::Vector3d& tip_m) noexcept;

/// F = K_t (tip − c) + F_loads on the tissue [N], zero when it would pull.
Eigen::Vector3d stiffness_force_N(const ModelSnapshot& model, const Eigen::Vector3d& tip_m) noexcept;

/// The paper's scheme: F(t) = F_k + (F_k − F_{k−1}) (t − t_k)/(t_k − t_{k−1}), with t − t_k
/// capped at `horizon_s` (beyond it the force is held: extrapolating stale forces is how a
/// device starts to shake); F_k alone when only one force exists; zero when none or when it
/// would pull.
Eigen::Vector3d extrapolated_force_N(const ModelSnapshot& model, double time_s, double horizon_s) noexcept;

/// Unilateral contact: zero when the force on the tissue has a negative component along d.
Eigen::Vector3d push_only(const Eigen::Vector3d& force_N, const Eigen::Vector3d& direction) noexcept;

}  // namespace touchstone::realtime::runtime
