#pragma once
/// @file
/// The OpenIGTLink haptic device: a TCP server that 3D Slicer or a tracker
/// connects to. The tool pose comes in as TRANSFORM or POSITION messages, the force on the
/// user's hand goes out as a SENSOR message (3 values, newtons) at a fixed rate, and, as a
/// graphics sink, the deformed organ goes out as POLYDATA (plus the tool as a TRANSFORM).
///
/// Threads. One network thread owns the listening and client sockets: it accepts one client at
/// a time, parses what arrives, publishes the latest valid pose through a Seqlock and sends the
/// latest force, which the haptic thread publishes through another Seqlock. read() and
/// write_force() therefore never block, lock or allocate. The graphics thread sends POLYDATA
/// under a mutex that also serializes the network thread's writes (the haptic thread never
/// takes it). libOpenIGTLink (de)serializes messages and checks CRCs; the sockets are plain
/// POSIX ones, because igtl::Socket cannot wait on two descriptors, sends without
/// MSG_NOSIGNAL and loses the bytes of a partial read when a receive timeout fires.
///
/// Headers of version 1 and 2 (3D Slicer's default: an extended header and metadata around the
/// content; libOpenIGTLink 1.11 predates it, so those poses are decoded here) are understood.
///
/// Untrusted input. A message is checked before it can reach read(): header version and type
/// name, announced body size (never allocated or read beyond `max_message_body_bytes`), body
/// size for the type, CRC, finite numbers and a usable rotation. What cannot be re-synchronized
/// (a garbage header, an oversized body, a truncated body) closes the connection; everything
/// else drops only the message. Every case is counted (OpenIgtLinkCounters).

#include "touchstone/realtime/graphics/graphics_sink.hpp"
#include "touchstone/realtime/haptics/haptic_device.hpp"
#include "touchstone/realtime/concurrency/plain_types.hpp"
#include "touchstone/realtime/concurrency/seqlock.hpp"

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace touchstone::realtime::haptics {

/// Settings of the OpenIGTLink server. Plain values; validate() before use.
struct OpenIgtLinkSettings {
  /// TCP port [0, 65535]; 18944 is the OpenIGTLink default. 0 lets the system pick a free port
  /// (see OpenIgtLinkDevice::bound_port()), for tests.
  int port = 18944;
  /// IPv4 address of the interface to listen on: "0.0.0.0" for every interface, "127.0.0.1"
  /// for this machine only.
  std::string bind_address = "0.0.0.0";
  /// Length unit of the peer [m per unit]: incoming positions are multiplied by it, outgoing
  /// POLYDATA points and tool translations divided by it. 3D Slicer works in millimetres.
  double length_unit_m = 0.001;
  /// Largest message body accepted [bytes]. A header announcing more is rejected and the
  /// connection closed (the body is never allocated or read). At least 64.
  std::size_t max_message_body_bytes = std::size_t{1} << 20;
  /// Largest force the device renders [N]: write_force() clamps the magnitude to it.
  double max_force_N = 10.0;
  /// Rate of outgoing SENSOR (force) messages while a client is connected [Hz], (0, 10000].
  double force_send_rate_hz = 1000.0;
  /// Device names of outgoing messages (at most 20 characters: the header's name field).
  std::string force_device_name = "TouchstoneForce";
  std::string organ_device_name = "TouchstoneOrgan";
  std::string tool_device_name = "TouchstoneTool";
  /// Send the tool tip pose as a TRANSFORM with every graphics frame.
  bool send_tool_transform = true;
  /// How long the network thread sleeps in one wait while no client is connected [s]
  /// (stop() wakes it at once regardless), (0, 1].
  double accept_poll_s = 0.01;
  /// Longest a send may stay blocked by a peer that does not read [s], (0, 10]. A message that
  /// cannot be completed in time breaks the stream's framing, so the connection is closed.
  double send_timeout_s = 0.25;

  /// Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

/// Event counts since construction, readable from any thread at any time.
struct OpenIgtLinkCounters {
  std::uint64_t transforms_received = 0;     ///< valid TRANSFORM poses published
  std::uint64_t positions_received = 0;      ///< valid POSITION poses published
  std::uint64_t messages_skipped = 0;        ///< well-formed messages of other types, ignored
  std::uint64_t rejected_bad_header = 0;     ///< unknown header version or a type name that is not text: closes
  std::uint64_t rejected_oversized = 0;      ///< body larger than max_message_body_bytes: closes
  std::uint64_t rejected_truncated = 0;      ///< connection lost in the middle of a message
  std::uint64_t rejected_bad_body_size = 0;  ///< body size impossible for the type (TRANSFORM ≠ 48 bytes, ...)
  std::uint64_t rejected_bad_crc = 0;        ///< CRC-64 of the body does not match the header
  std::uint64_t rejected_non_finite = 0;     ///< NaN or infinite position, matrix or quaternion
  std::uint64_t rejected_bad_rotation = 0;   ///< singular or reflecting matrix, quaternion far from unit
  std::uint64_t forces_sent = 0;             ///< SENSOR messages sent
  std::uint64_t forces_dropped = 0;          ///< force ticks skipped while the socket or the graphics thread was busy
  std::uint64_t polydata_sent = 0;           ///< POLYDATA messages sent
  std::uint64_t tool_transforms_sent = 0;    ///< tool TRANSFORM messages sent
  std::uint64_t send_failures = 0;           ///< sends that failed or timed out (the connection is then closed)
  std::uint64_t connections = 0;             ///< clients accepted
  std::uint64_t disconnects = 0;             ///< client connections ended (by the peer, an error or a rejection)

  /// Sum of every rejected_* count.
  std::uint64_t rejected_total() const noexcept {
    return rejected_bad_header + rejected_oversized + rejected_truncated + rejected_bad_body_size + rejected_bad_crc +
           rejected_non_finite + rejected_bad_rotation;
  }
};

/// The OpenIGTLink device and POLYDATA sink. start() and stop() from a control thread,
/// read()/write_force() from the haptic thread, begin()/frame()/end() from the graphics thread.
class OpenIgtLinkDevice final : public HapticDevice, public graphics::GraphicsSink {
 public:
  /// Validates the settings (std::invalid_argument naming the field).
  explicit OpenIgtLinkDevice(OpenIgtLinkSettings settings);
  /// Calls stop().
  ~OpenIgtLinkDevice() override;
  OpenIgtLinkDevice(const OpenIgtLinkDevice&) = delete;
  OpenIgtLinkDevice& operator=(const OpenIgtLinkDevice&) = delete;

  /// "openigtlink" (both as a device and as a graphics sink).
  std::string name() const override;

  /// Binds the server socket and launches the network thread. Throws std::runtime_error naming
  /// the address and port when the socket cannot be created or bound, std::logic_error when
  /// already started. May be called again after stop().
  void start() override;
  /// The latest valid pose [m]. `connected` is true while a client is connected and has sent
  /// at least one valid pose on this connection (before that there is no pose to render at);
  /// `fresh` is true when a pose arrived since the previous read(). When the network thread is
  /// mid-publication, returns the previous sample (a fresh copy comes one tick later).
  /// Haptic thread only: noexcept, no allocation, lock or I/O.
  DeviceSample read(double time_s) noexcept override;
  /// Publishes the force on the user's hand [N] for the network thread to send. Non-finite
  /// forces become zero, larger ones are clamped to max_force_N. Haptic thread only.
  void write_force(const Eigen::Vector3d& force_N, double time_s) noexcept override;
  /// Sends a zero force to a connected client, closes the sockets and joins the network
  /// thread. Idempotent.
  void stop() noexcept override;
  /// settings.max_force_N [N].
  double max_force_N() const noexcept override;

  /// Stores the organ's connectivity and rest vertex count (graphics thread, before frames).
  /// Throws std::invalid_argument when the surface has more vertices than POLYDATA addresses.
  void begin(const geometry::TriangleSurface& organ) override;
  /// Sends the deformed organ as POLYDATA [length units] and, when enabled, the tool tip pose
  /// as a TRANSFORM, if a client is connected; returns at once otherwise. Throws
  /// std::invalid_argument when the frame's vertices do not match the organ or are not finite.
  void frame(const graphics::GraphicsFrame& frame) override;
  /// Forgets the organ. noexcept.
  void end() noexcept override;

  /// The port actually listened on (the system's choice when settings.port is 0); 0 before
  /// start().
  int bound_port() const noexcept;
  /// True while a client socket is open (whether or not it has sent a pose).
  bool client_connected() const noexcept;
  /// Snapshot of the event counts (relaxed loads: each count is exact, the set is not atomic).
  OpenIgtLinkCounters counters() const noexcept;
  /// Description of the latest rejected or skipped message, naming its type, device name and
  /// what was wrong (empty when none). Not for the haptic thread (takes a mutex).
  std::string last_rejection() const;
  const OpenIgtLinkSettings& settings() const noexcept { return settings_; }

 private:
  /// What the network thread publishes to the haptic thread.
  struct PoseRecord {
    concurrency::PlainVector3 position_m{};
    std::array<double, 4> orientation_wxyz{{1.0, 0.0, 0.0, 0.0}};
    std::uint64_t pose_count = 0;  ///< valid poses since start(); changes mean "fresh"
    bool connected = false;
  };
  struct Network;   // sockets, parser and libOpenIGTLink messages of the network thread
  struct Graphics;  // the organ's POLYDATA message of the graphics thread

  OpenIgtLinkSettings settings_;
  concurrency::Seqlock<PoseRecord> pose_;              ///< network thread → haptic thread
  concurrency::Seqlock<concurrency::PlainVector3> force_;  ///< haptic thread → network thread [N]
  // Haptic-thread state of read().
  PoseRecord last_pose_{};
  std::uint64_t last_read_pose_count_ = 0;

  std::unique_ptr<Network> network_;
  std::unique_ptr<Graphics> graphics_;
};

}  // namespace touchstone::realtime::haptics
