#pragma once
/// @file
/// The OpenHaptics backend: a 3D Systems Touch / Phantom device through the HD
/// API. 3D Systems' SDK is not in Debian, so the backend is compiled only when CMake finds it
/// (TOUCHSTONE_HAVE_OPENHAPTICS). This header includes nothing from the SDK: without it, it
/// declares only `openhaptics_available = false` and is harmless to include.
///
/// Threads. The HD scheduler's servo thread (≈1 kHz) owns the device: each of its ticks reads
/// the pose and renders the force inside hdBeginFrame/hdEndFrame. Our haptic thread exchanges
/// values with it through two Seqlocks (pose: scheduler → haptic thread; force: haptic thread →
/// scheduler), never by hdScheduleSynchronous, which would make the haptic thread wait for a
/// servo tick. The price is at most one servo tick (≈1 ms) of added latency each way: a force
/// written just after a servo tick is rendered at the next one, and read() returns the pose of
/// the latest completed tick.

#include "touchstone/realtime/haptics/haptic_device.hpp"

namespace touchstone::realtime::haptics {

#if defined(TOUCHSTONE_HAVE_OPENHAPTICS)
inline constexpr bool openhaptics_available = true;
#else
inline constexpr bool openhaptics_available = false;
#endif

}  // namespace touchstone::realtime::haptics

#if defined(TOUCHSTONE_HAVE_OPENHAPTICS)

#include "touchstone/realtime/concurrency/plain_types.hpp"
#include "touchstone/realtime/concurrency/seqlock.hpp"

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

namespace touchstone::realtime::haptics {

/// Settings of the OpenHaptics device. Plain values; validate() before use.
struct OpenHapticsSettings {
  /// Device name as configured in 3D Systems' Touch Setup; "Default Device" is its default.
  std::string device_name = "Default Device";
  /// World position of the device's origin [m]: tip_world = origin + length_unit_m · tip_device.
  std::array<double, 3> origin_m{0.0, 0.0, 0.0};
  /// Length unit of the HD API [m per unit]: positions come in millimetres.
  double length_unit_m = 0.001;
  /// Force clamp [N], (0, ∞). The device's own nominal maximum (HD_NOMINAL_MAX_FORCE, about
  /// 3.3 N for a Touch) lowers it further at start().
  double max_force_N = 3.0;

  /// Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

/// A device on the HD API. start() and stop() from a control thread; read() and
/// write_force() from the haptic thread.
class OpenHapticsDevice final : public HapticDevice {
 public:
  /// Validates the settings (std::invalid_argument naming the field).
  explicit OpenHapticsDevice(OpenHapticsSettings settings);
  /// Calls stop().
  ~OpenHapticsDevice() override;
  OpenHapticsDevice(const OpenHapticsDevice&) = delete;
  OpenHapticsDevice& operator=(const OpenHapticsDevice&) = delete;

  /// "openhaptics".
  std::string name() const override;
  /// hdInitDevice, force output on, the servo callback scheduled, the scheduler started.
  /// Throws std::runtime_error naming the device and the HD error; std::logic_error when
  /// already started.
  void start() override;
  /// The pose of the latest servo tick, in the world frame [m]. `connected` turns false for
  /// good when the servo callback met a device error (e.g. an amplifier fault or overheating).
  /// Haptic thread: noexcept, no allocation, lock or wait.
  DeviceSample read(double time_s) noexcept override;
  /// The force [N] the next servo tick renders (non-finite → zero, clamped to max_force_N()).
  void write_force(const Eigen::Vector3d& force_N, double time_s) noexcept override;
  /// Zero force, scheduler stopped, device released. Idempotent.
  void stop() noexcept override;
  /// The smaller of settings.max_force_N and the device's nominal maximum [N].
  double max_force_N() const noexcept override;

  /// The servo tick, run by the HD scheduler thread only (public for the C callback).
  bool servo_tick() noexcept;

 private:
  struct ServoPose {
    concurrency::PlainVector3 position_m{};
    std::array<double, 4> orientation_wxyz{1.0, 0.0, 0.0, 0.0};
    std::uint64_t tick = 0;
  };
  struct Handles;  // HHD and HDSchedulerHandle, kept out of this header

  OpenHapticsSettings settings_;
  std::unique_ptr<Handles> handles_;
  concurrency::Seqlock<ServoPose> pose_;               ///< servo thread → haptic thread
  concurrency::Seqlock<concurrency::PlainVector3> force_;  ///< haptic thread → servo thread [N]
  std::atomic<bool> render_zero_{false};           ///< stop(): the servo renders zero from now on
  std::atomic<bool> device_fault_{false};
  std::atomic<double> max_force_N_{0.0};
  // Servo-thread state.
  concurrency::PlainVector3 servo_force_N_{};
  ServoPose servo_pose_{};
  // Haptic-thread state of read().
  ServoPose last_pose_{};
  std::uint64_t last_read_tick_ = 0;
  bool started_ = false;
};

}  // namespace touchstone::realtime::haptics

#endif  // TOUCHSTONE_HAVE_OPENHAPTICS
