// Compiled only when CMake finds 3D Systems' OpenHaptics SDK (TOUCHSTONE_HAVE_OPENHAPTICS).
#include "touchstone/realtime/haptics/openhaptics_device.hpp"

#include <HD/hd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>

namespace touchstone::realtime::haptics {

namespace {

template <class T>
std::string to_text(const T& value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

/// "HD_<name> (0x…)" for the latest HD error, or an empty string when there is none.
std::string hd_error_text() {
  const HDErrorInfo error = hdGetError();
  if (!HD_DEVICE_ERROR(error)) return {};
  std::ostringstream out;
  out << hdGetErrorString(error.errorCode) << " (HD error 0x" << std::hex << error.errorCode << ", internal 0x"
      << error.internalErrorCode << ")";
  return out.str();
}

HDCallbackCode HDCALLBACK servo_callback(void* user_data) {
  return static_cast<OpenHapticsDevice*>(user_data)->servo_tick() ? HD_CALLBACK_CONTINUE : HD_CALLBACK_DONE;
}

}  // namespace

struct OpenHapticsDevice::Handles {
  HHD device = HD_INVALID_HANDLE;
  HDSchedulerHandle callback = HD_INVALID_HANDLE;
  bool scheduler_running = false;
};

void OpenHapticsSettings::validate() const {
  if (device_name.empty())
    throw std::invalid_argument(
        "OpenHapticsSettings.device_name is empty (Touch Setup's default is \"Default Device\")");
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(origin_m[static_cast<std::size_t>(i)]))
      throw std::invalid_argument("OpenHapticsSettings.origin_m[" + std::to_string(i) + "] is not finite");
  if (!(std::isfinite(length_unit_m) && length_unit_m > 0))
    throw std::invalid_argument("OpenHapticsSettings.length_unit_m = " + to_text(length_unit_m) +
                                ": must be finite and positive [m per unit]");
  if (!(std::isfinite(max_force_N) && max_force_N > 0))
    throw std::invalid_argument("OpenHapticsSettings.max_force_N = " + to_text(max_force_N) +
                                ": must be finite and positive [N]");
}

OpenHapticsDevice::OpenHapticsDevice(OpenHapticsSettings settings)
    : settings_(std::move(settings)), handles_(std::make_unique<Handles>()) {
  settings_.validate();
  max_force_N_.store(settings_.max_force_N, std::memory_order_relaxed);
}

OpenHapticsDevice::~OpenHapticsDevice() { stop(); }

std::string OpenHapticsDevice::name() const { return "openhaptics"; }

void OpenHapticsDevice::start() {
  if (started_) throw std::logic_error("OpenHaptics device '" + settings_.device_name + "': already started");
  Handles& h = *handles_;
  // hdGetError() pops the error it reports: read it once per step.
  const auto check = [&](bool failed, const std::string& step) {
    const std::string error = hd_error_text();
    if (!failed && error.empty()) return;
    if (h.scheduler_running) hdStopScheduler();
    if (h.callback != HD_INVALID_HANDLE) hdUnschedule(h.callback);
    if (h.device != HD_INVALID_HANDLE) hdDisableDevice(h.device);
    h = Handles{};
    throw std::runtime_error("OpenHaptics device '" + settings_.device_name + "': " + step +
                             " failed: " + (error.empty() ? std::string("no HD error reported") : error));
  };

  const HHD device = hdInitDevice(settings_.device_name.c_str());
  check(device == HD_INVALID_HANDLE, "hdInitDevice");
  h.device = device;
  hdMakeCurrentDevice(h.device);
  HDdouble nominal_max_force_N = 0;
  hdGetDoublev(HD_NOMINAL_MAX_FORCE, &nominal_max_force_N);
  check(false, "hdGetDoublev(HD_NOMINAL_MAX_FORCE)");
  if (nominal_max_force_N > 0)
    max_force_N_.store(std::min(settings_.max_force_N, static_cast<double>(nominal_max_force_N)),
                       std::memory_order_relaxed);

  // Start with zero force and a pose read by the first tick, not a stale one.
  render_zero_.store(false, std::memory_order_release);
  device_fault_.store(false, std::memory_order_release);
  servo_force_N_ = {};
  force_.store(concurrency::PlainVector3{});
  hdEnable(HD_FORCE_OUTPUT);
  check(false, "hdEnable(HD_FORCE_OUTPUT)");
  const HDSchedulerHandle callback = hdScheduleAsynchronous(&servo_callback, this, HD_MAX_SCHEDULER_PRIORITY);
  check(callback == HD_INVALID_HANDLE, "hdScheduleAsynchronous");
  h.callback = callback;
  hdStartScheduler();
  h.scheduler_running = true;
  check(false, "hdStartScheduler");
  started_ = true;
}

bool OpenHapticsDevice::servo_tick() noexcept {
  Handles& h = *handles_;
  hdBeginFrame(h.device);
  HDdouble position_mm[3] = {0, 0, 0};
  HDdouble transform[16];  // column-major 4×4, translation in millimetres
  hdGetDoublev(HD_CURRENT_POSITION, position_mm);
  hdGetDoublev(HD_CURRENT_TRANSFORM, transform);

  // A force write in flight keeps the previous force for this tick (≤ 1 tick late).
  concurrency::PlainVector3 force{};
  if (force_.try_load(force)) servo_force_N_ = force;
  HDdouble out[3] = {0, 0, 0};
  if (!render_zero_.load(std::memory_order_acquire))
    for (int i = 0; i < 3; ++i) out[i] = servo_force_N_[static_cast<std::size_t>(i)];
  hdSetDoublev(HD_CURRENT_FORCE, out);
  hdEndFrame(h.device);

  if (!hd_error_text().empty()) {
    // A device fault (amplifier, temperature, communication): stop rendering for good; read()
    // reports the device as disconnected and the runtime outputs zero force from then on.
    device_fault_.store(true, std::memory_order_release);
    return false;
  }

  Eigen::Matrix3d rotation;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) rotation(r, c) = transform[4 * c + r];
  const Eigen::Vector3d position =
      concurrency::eigen(settings_.origin_m) +
      settings_.length_unit_m * Eigen::Vector3d(position_mm[0], position_mm[1], position_mm[2]);
  if (position.allFinite() && rotation.allFinite()) {
    // The stylus runs along the gimbal frame's +z from the tip, as DeviceSample::orientation.
    const Eigen::Quaterniond orientation = Eigen::Quaterniond(rotation).normalized();
    servo_pose_.position_m = concurrency::plain(position);
    servo_pose_.orientation_wxyz = {orientation.w(), orientation.x(), orientation.y(), orientation.z()};
    servo_pose_.tick += 1;
    pose_.store(servo_pose_);
  }
  return true;
}

DeviceSample OpenHapticsDevice::read(double /*time_s*/) noexcept {
  ServoPose pose;
  if (pose_.try_load(pose)) last_pose_ = pose;
  DeviceSample sample;
  sample.tip_position_m = concurrency::eigen(last_pose_.position_m);
  sample.orientation = Eigen::Quaterniond(last_pose_.orientation_wxyz[0], last_pose_.orientation_wxyz[1],
                                          last_pose_.orientation_wxyz[2], last_pose_.orientation_wxyz[3]);
  // No pose before the first servo tick: not connected yet.
  sample.connected = last_pose_.tick > 0 && !device_fault_.load(std::memory_order_acquire);
  sample.finished = false;
  sample.fresh = last_pose_.tick != last_read_tick_;
  last_read_tick_ = last_pose_.tick;
  return sample;
}

void OpenHapticsDevice::write_force(const Eigen::Vector3d& force_N, double /*time_s*/) noexcept {
  force_.store(concurrency::plain(bounded_force_N(force_N, max_force_N_.load(std::memory_order_relaxed))));
}

void OpenHapticsDevice::stop() noexcept {
  if (!started_) return;
  Handles& h = *handles_;
  // The servo renders zero from its next tick; give it a few ticks before the scheduler stops
  // (hdStopScheduler ends the servo loop; the last commanded force must be zero).
  render_zero_.store(true, std::memory_order_release);
  const std::uint64_t tick = pose_.load().tick;
  for (int wait = 0; wait < 100 && pose_.load().tick < tick + 2 && !device_fault_.load(std::memory_order_acquire);
       ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  hdMakeCurrentDevice(h.device);
  hdStopScheduler();
  hdUnschedule(h.callback);
  hdDisable(HD_FORCE_OUTPUT);
  hdDisableDevice(h.device);
  h = Handles{};
  started_ = false;
}

double OpenHapticsDevice::max_force_N() const noexcept { return max_force_N_.load(std::memory_order_relaxed); }

}  // namespace touchstone::realtime::haptics
