// The OpenIGTLink device: connection, pose and force exchange with a peer such as 3D Slicer
// (one file: the socket's state shared by the network and graphics threads). The bytes → pose
// parsing is openigtlink_parser.cpp.
#include "touchstone/realtime/haptics/openigtlink_device.hpp"

#include "touchstone/realtime/haptics/openigtlink_parser.hpp"

#include "touchstone/geometry/triangle_surface.hpp"

#include <igtlPolyDataMessage.h>
#include <igtlSensorMessage.h>
#include <igtlTransformMessage.h>
#include <igtlUnit.h>
#include <igtl_header.h>
#include <igtl_util.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <vector>

namespace touchstone::realtime::haptics {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t max_device_name_length = IGTL_HEADER_NAME_SIZE;

std::string errno_text(int error) { return std::error_code(error, std::system_category()).message(); }

template <class T>
std::string to_text(const T& value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

void require(bool ok, const char* field, const std::string& value, const char* rule) {
  if (!ok) throw std::invalid_argument(std::string("OpenIgtLinkSettings.") + field + " = " + value + ": " + rule);
}

void require_device_name(const std::string& name, const char* field) {
  const bool printable = std::all_of(name.begin(), name.end(), [](char c) { return c >= 0x20 && c < 0x7f; });
  require(!name.empty() && name.size() <= max_device_name_length && printable, field, "'" + name + "'",
          "must be 1 to 20 printable ASCII characters (the OpenIGTLink header's device name field)");
}

/// Message time stamp: seconds and 2^-32 fractions of a second since the Unix epoch.
void stamp_now(igtl::MessageBase* message) {
  const auto since_epoch = std::chrono::system_clock::now().time_since_epoch();
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(since_epoch);
  const auto nanoseconds = std::chrono::duration_cast<std::chrono::nanoseconds>(since_epoch - seconds);
  message->SetTimeStamp(static_cast<unsigned int>(seconds.count()),
                        igtl_nanosec_to_frac(static_cast<igtl_uint32>(nanoseconds.count())));
}

/// Writes all `size` bytes to a non-blocking socket, waiting for room at most until
/// `deadline`. False on error or timeout; the stream's framing is then broken.
bool send_all(int fd, const void* data, std::size_t size, Clock::time_point deadline) noexcept {
  const auto* bytes = static_cast<const unsigned char*>(data);
  while (size > 0) {
    const ssize_t sent = ::send(fd, bytes, size, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (sent > 0) {
      bytes += sent;
      size -= static_cast<std::size_t>(sent);
      continue;
    }
    if (sent < 0 && errno == EINTR) continue;
    if (sent < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) return false;
      pollfd writable{fd, POLLOUT, 0};
      if (::poll(&writable, 1, static_cast<int>(left)) < 0 && errno != EINTR) return false;
      continue;
    }
    return false;
  }
  return true;
}

}  // namespace

void OpenIgtLinkSettings::validate() const {
  require(port >= 0 && port <= 65535, "port", std::to_string(port), "must be in [0, 65535] (0: any free port)");
  in_addr address{};
  require(::inet_pton(AF_INET, bind_address.c_str(), &address) == 1, "bind_address", "'" + bind_address + "'",
          "must be an IPv4 address such as 0.0.0.0 or 127.0.0.1");
  require(std::isfinite(length_unit_m) && length_unit_m > 0 && length_unit_m <= 1e3, "length_unit_m",
          to_text(length_unit_m), "must be in (0, 1000] m per unit (0.001 for millimetres)");
  require(max_message_body_bytes >= 64 &&
              max_message_body_bytes <= static_cast<std::size_t>(std::numeric_limits<int>::max()),
          "max_message_body_bytes", std::to_string(max_message_body_bytes), "must be in [64, 2^31 - 1] bytes");
  require(std::isfinite(max_force_N) && max_force_N > 0, "max_force_N", to_text(max_force_N),
          "must be finite and positive [N]");
  require(std::isfinite(force_send_rate_hz) && force_send_rate_hz > 0 && force_send_rate_hz <= 10000,
          "force_send_rate_hz", to_text(force_send_rate_hz), "must be in (0, 10000] Hz");
  require_device_name(force_device_name, "force_device_name");
  require_device_name(organ_device_name, "organ_device_name");
  require_device_name(tool_device_name, "tool_device_name");
  require(std::isfinite(accept_poll_s) && accept_poll_s > 0 && accept_poll_s <= 1, "accept_poll_s",
          to_text(accept_poll_s), "must be in (0, 1] s");
  require(std::isfinite(send_timeout_s) && send_timeout_s > 0 && send_timeout_s <= 10, "send_timeout_s",
          to_text(send_timeout_s), "must be in (0, 10] s");
}

// ---------------------------------------------------------------------------------------------
// The network thread: sockets, the message parser and the force stream.

struct OpenIgtLinkDevice::Network {
  /// The connection's counts; the parser counts its own outcomes.
  struct Counters {
    std::atomic<std::uint64_t> rejected_truncated{0}, forces_sent{0}, forces_dropped{0}, polydata_sent{0},
        tool_transforms_sent{0}, send_failures{0}, connections{0}, disconnects{0};
  };

  explicit Network(OpenIgtLinkDevice& owner)
      : device(owner),
        parser(
            owner.settings_.max_message_body_bytes, owner.settings_.length_unit_m,
            [this](const Eigen::Vector3d& position_m, const Eigen::Quaterniond& orientation) {
              publish_pose(position_m, orientation);
            },
            [this](const std::string& reason) { note(reason); }) {}

  OpenIgtLinkDevice& device;
  Counters counts;
  OpenIgtLinkParser parser;  ///< network thread only
  std::thread thread;
  std::atomic<bool> stop_requested{false};
  std::atomic<int> bound_port{0};
  std::atomic<bool> client_open{false};
  int listen_fd = -1;
  int wake_fd = -1;  ///< eventfd: stop() writes it so that a waiting poll returns at once

  /// Serializes every write to the client socket (network and graphics threads) and every
  /// change of client_fd. The network thread, the only one to change client_fd, reads it
  /// without the lock.
  std::mutex send_mutex;
  int client_fd = -1;

  mutable std::mutex rejection_mutex;
  std::string last_rejection;

  std::vector<unsigned char> receive_buffer = std::vector<unsigned char>(std::size_t{1} << 16);

  // Published pose (network thread's copy) and the force stream.
  PoseRecord published{};
  Clock::time_point next_force_time{};
  concurrency::PlainVector3 last_force_N{};

  // libOpenIGTLink messages, created by start() (before the thread runs) and reused.
  igtl::SensorMessage::Pointer sensor_message;

  void create_messages();
  void run() noexcept;
  void wait_for_client();
  void serve_client();
  void open_client(int fd);
  void close_client(bool send_zero_force);
  void receive_available();
  void publish_pose(const Eigen::Vector3d& position_m, const Eigen::Quaterniond& orientation);
  void send_force(bool zero, bool wait_for_lock);
  void note(const std::string& what);
  Clock::duration force_period() const {
    return std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / device.settings_.force_send_rate_hz));
  }
};

void OpenIgtLinkDevice::Network::create_messages() {
  if (sensor_message) return;
  sensor_message = igtl::SensorMessage::New();
  sensor_message->SetDeviceName(device.settings_.force_device_name.c_str());
  sensor_message->SetLength(3);
  igtl::Unit::Pointer newton = igtl::Unit::New();
  newton->Init();
  newton->SetPrefix(igtl::Unit::SI_PREFIX_NONE);
  newton->Append(igtl::Unit::SI_DERIVED_NEWTON, 1);
  sensor_message->SetUnit(newton);
}

void OpenIgtLinkDevice::Network::note(const std::string& what) {
  std::lock_guard<std::mutex> lock(rejection_mutex);
  last_rejection = what;
}

void OpenIgtLinkDevice::Network::run() noexcept {
  try {
    while (!stop_requested.load(std::memory_order_acquire)) {
      if (client_fd < 0)
        wait_for_client();
      else
        serve_client();
    }
    close_client(/*send_zero_force=*/true);
  } catch (const std::exception& error) {
    // Only allocation inside libOpenIGTLink can throw here: end the connection, keep the
    // device in a defined (disconnected) state.
    note(std::string("network thread stopped: ") + error.what());
    close_client(false);
  }
}

void OpenIgtLinkDevice::Network::wait_for_client() {
  pollfd fds[2] = {{listen_fd, POLLIN, 0}, {wake_fd, POLLIN, 0}};
  const int timeout_ms = std::max(1, static_cast<int>(std::lround(device.settings_.accept_poll_s * 1e3)));
  if (::poll(fds, 2, timeout_ms) <= 0 || !(fds[0].revents & POLLIN)) return;
  const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
  if (fd < 0) return;  // the client gave up already, or a transient error: keep listening
  open_client(fd);
}

void OpenIgtLinkDevice::Network::open_client(int fd) {
  // Forces are small and latency matters: no Nagle batching.
  int on = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  {
    std::lock_guard<std::mutex> lock(send_mutex);
    client_fd = fd;
  }
  client_open.store(true, std::memory_order_release);
  counts.connections.fetch_add(1, std::memory_order_relaxed);
  parser.reset();
  next_force_time = Clock::now();
}

void OpenIgtLinkDevice::Network::close_client(bool send_zero_force) {
  if (client_fd < 0) return;
  if (send_zero_force) {
    send_force(/*zero=*/true, /*wait_for_lock=*/true);
    if (client_fd < 0) return;  // that send failed and closed the connection already
  }
  // Connected goes false first: the haptic thread stops rendering this peer at once.
  published.connected = false;
  device.pose_.store(published);
  {
    std::lock_guard<std::mutex> lock(send_mutex);
    ::close(client_fd);
    client_fd = -1;
  }
  client_open.store(false, std::memory_order_release);
  counts.disconnects.fetch_add(1, std::memory_order_relaxed);
  parser.reset();
}

void OpenIgtLinkDevice::Network::serve_client() {
  // Force stream: one SENSOR per period; after a stall, resume the cadence rather than burst.
  auto now = Clock::now();
  if (now >= next_force_time) {
    send_force(/*zero=*/false, /*wait_for_lock=*/false);
    if (client_fd < 0) return;
    next_force_time += force_period();
    if (next_force_time < now) next_force_time = now + force_period();
    now = Clock::now();
  }
  const auto wait = std::max(Clock::duration::zero(), next_force_time - now);
  const auto wait_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count();
  timespec timeout{static_cast<time_t>(wait_ns / 1000000000), static_cast<long>(wait_ns % 1000000000)};
  pollfd fds[2] = {{client_fd, POLLIN, 0}, {wake_fd, POLLIN, 0}};
  if (::ppoll(fds, 2, &timeout, nullptr) <= 0) return;
  if (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) receive_available();
}

void OpenIgtLinkDevice::Network::receive_available() {
  // At most a few buffers per wake-up, so that a flooding peer cannot starve the force stream.
  for (int round = 0; round < 4; ++round) {
    const ssize_t received = ::recv(client_fd, receive_buffer.data(), receive_buffer.size(), MSG_DONTWAIT);
    if (received > 0) {
      if (parser.feed(receive_buffer.data(), static_cast<std::size_t>(received)) ==
          OpenIgtLinkParser::Verdict::close_connection) {
        close_client(false);
        return;
      }
      continue;
    }
    if (received < 0 && errno == EINTR) continue;
    if (received < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
    // End of stream (0) or a socket error: the peer is gone.
    if (parser.inside_message()) {
      counts.rejected_truncated.fetch_add(1, std::memory_order_relaxed);
      note(parser.truncation_note());
    }
    close_client(false);
    return;
  }
}

void OpenIgtLinkDevice::Network::publish_pose(const Eigen::Vector3d& position_m,
                                              const Eigen::Quaterniond& orientation) {
  published.position_m = concurrency::plain(position_m);
  published.orientation_wxyz = {orientation.w(), orientation.x(), orientation.y(), orientation.z()};
  published.pose_count += 1;
  published.connected = true;
  device.pose_.store(published);
}

void OpenIgtLinkDevice::Network::send_force(bool zero, bool wait_for_lock) {
  concurrency::PlainVector3 force{};
  if (!zero) {
    // A write in flight keeps the previous force: the next period brings the new one.
    if (device.force_.try_load(force)) last_force_N = force;
    force = last_force_N;
  }
  std::unique_lock<std::mutex> lock(send_mutex, std::defer_lock);
  if (wait_for_lock)
    lock.lock();
  else if (!lock.try_lock()) {
    counts.forces_dropped.fetch_add(1, std::memory_order_relaxed);  // the graphics thread is sending
    return;
  }
  if (client_fd < 0) return;
  if (!wait_for_lock) {
    // A peer that stops reading fills the socket: drop this tick rather than stall the thread.
    pollfd writable{client_fd, POLLOUT, 0};
    if (::poll(&writable, 1, 0) <= 0 || !(writable.revents & POLLOUT)) {
      counts.forces_dropped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
  }
  for (unsigned int i = 0; i < 3; ++i) sensor_message->SetValue(i, force[i]);
  stamp_now(sensor_message);
  sensor_message->Pack();
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(device.settings_.send_timeout_s));
  if (send_all(client_fd, sensor_message->GetPackPointer(), static_cast<std::size_t>(sensor_message->GetPackSize()),
               deadline)) {
    counts.forces_sent.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  counts.send_failures.fetch_add(1, std::memory_order_relaxed);
  note("SENSOR to the client: send failed or timed out; closing the connection");
  lock.unlock();
  close_client(false);
}

// ---------------------------------------------------------------------------------------------
// The graphics thread's POLYDATA message.

struct OpenIgtLinkDevice::Graphics {
  bool begun = false;
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  igtl::PolyDataMessage::Pointer polydata;
  igtl::PolyDataPointArray::Pointer points;
  igtl::TransformMessage::Pointer tool;
};

// ---------------------------------------------------------------------------------------------

OpenIgtLinkDevice::OpenIgtLinkDevice(OpenIgtLinkSettings settings)
    : settings_(std::move(settings)),
      network_(std::make_unique<Network>(*this)),
      graphics_(std::make_unique<Graphics>()) {
  settings_.validate();
}

OpenIgtLinkDevice::~OpenIgtLinkDevice() { stop(); }

std::string OpenIgtLinkDevice::name() const { return "openigtlink"; }

void OpenIgtLinkDevice::start() {
  Network& net = *network_;
  if (net.thread.joinable()) throw std::logic_error("OpenIGTLink device: start() called while already running");
  const std::string where = settings_.bind_address + ":" + std::to_string(settings_.port);
  const auto fail = [&](const std::string& what, int error) {
    if (net.listen_fd >= 0) ::close(net.listen_fd);
    if (net.wake_fd >= 0) ::close(net.wake_fd);
    net.listen_fd = net.wake_fd = -1;
    throw std::runtime_error("OpenIGTLink device: cannot " + what + " on port " + std::to_string(settings_.port) +
                             " (" + where + "): " + errno_text(error));
  };

  net.listen_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (net.listen_fd < 0) fail("create a TCP socket", errno);
  // Rebinding while an earlier connection lingers in TIME_WAIT is fine; a second listener on
  // the same port still fails (that takes SO_REUSEPORT).
  int on = 1;
  ::setsockopt(net.listen_fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(settings_.port));
  ::inet_pton(AF_INET, settings_.bind_address.c_str(), &address.sin_addr);
  if (::bind(net.listen_fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) fail("bind", errno);
  // Backlog 1: one client is served at a time; the next waits in the queue until it leaves.
  if (::listen(net.listen_fd, 1) != 0) fail("listen", errno);
  sockaddr_in bound{};
  socklen_t bound_size = sizeof bound;
  if (::getsockname(net.listen_fd, reinterpret_cast<sockaddr*>(&bound), &bound_size) != 0)
    fail("query the port", errno);
  net.wake_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (net.wake_fd < 0) fail("create the wake-up eventfd", errno);

  net.create_messages();
  net.stop_requested.store(false, std::memory_order_release);
  net.bound_port.store(ntohs(bound.sin_port), std::memory_order_release);
  try {
    net.thread = std::thread([&net] { net.run(); });
  } catch (const std::system_error& error) {
    net.bound_port.store(0, std::memory_order_release);
    fail("start the network thread", error.code().value());
  }
}

DeviceSample OpenIgtLinkDevice::read(double /*time_s*/) noexcept {
  PoseRecord record;
  if (pose_.try_load(record)) last_pose_ = record;
  DeviceSample sample;
  sample.tip_position_m = concurrency::eigen(last_pose_.position_m);
  sample.orientation = Eigen::Quaterniond(last_pose_.orientation_wxyz[0], last_pose_.orientation_wxyz[1],
                                          last_pose_.orientation_wxyz[2], last_pose_.orientation_wxyz[3]);
  sample.connected = last_pose_.connected;
  sample.finished = false;
  sample.fresh = last_pose_.pose_count != last_read_pose_count_;
  last_read_pose_count_ = last_pose_.pose_count;
  return sample;
}

void OpenIgtLinkDevice::write_force(const Eigen::Vector3d& force_N, double /*time_s*/) noexcept {
  force_.store(concurrency::plain(bounded_force_N(force_N, settings_.max_force_N)));
}

void OpenIgtLinkDevice::stop() noexcept {
  Network& net = *network_;
  if (!net.thread.joinable()) return;
  net.stop_requested.store(true, std::memory_order_release);
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t written = ::write(net.wake_fd, &one, sizeof one);
  try {
    net.thread.join();
  } catch (const std::system_error&) {
    // join() fails only on a non-joinable thread or a deadlock, both excluded above.
  }
  ::close(net.listen_fd);
  ::close(net.wake_fd);
  net.listen_fd = net.wake_fd = -1;
  net.bound_port.store(0, std::memory_order_release);
}

double OpenIgtLinkDevice::max_force_N() const noexcept { return settings_.max_force_N; }

void OpenIgtLinkDevice::begin(const geometry::TriangleSurface& organ) {
  const auto& triangles = organ.triangles();
  const std::size_t vertex_count = organ.vertices().size();
  if (vertex_count > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
      triangles.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw std::invalid_argument("OpenIGTLink POLYDATA '" + settings_.organ_device_name + "': the organ has " +
                                std::to_string(vertex_count) + " vertices and " + std::to_string(triangles.size()) +
                                " triangles, more than a POLYDATA message addresses");
  Graphics& g = *graphics_;
  g.polydata = igtl::PolyDataMessage::New();
  g.points = igtl::PolyDataPointArray::New();
  g.points->SetNumberOfPoints(static_cast<int>(vertex_count));
  igtl::PolyDataCellArray::Pointer polygons = igtl::PolyDataCellArray::New();
  for (const Eigen::Vector3i& triangle : triangles) {
    igtlUint32 cell[3] = {static_cast<igtlUint32>(triangle(0)), static_cast<igtlUint32>(triangle(1)),
                          static_cast<igtlUint32>(triangle(2))};
    polygons->AddCell(3, cell);
  }
  g.polydata->SetPoints(g.points);
  g.polydata->SetPolygons(polygons);
  g.polydata->SetDeviceName(settings_.organ_device_name.c_str());
  g.tool = igtl::TransformMessage::New();
  g.tool->SetDeviceName(settings_.tool_device_name.c_str());
  g.vertex_count = vertex_count;
  g.triangle_count = triangles.size();
  g.begun = true;
}

void OpenIgtLinkDevice::frame(const graphics::GraphicsFrame& frame) {
  Graphics& g = *graphics_;
  if (!g.begun) throw std::logic_error("OpenIGTLink POLYDATA: frame() before begin()");
  Network& net = *network_;
  if (!net.client_open.load(std::memory_order_acquire)) return;  // nobody to send to: skip the packing too

  const std::string what =
      "OpenIGTLink POLYDATA '" + settings_.organ_device_name + "', frame " + std::to_string(frame.index);
  if (frame.organ_vertices_m == nullptr || frame.organ_vertices_m->size() != g.vertex_count)
    throw std::invalid_argument(what + ": " +
                                std::to_string(frame.organ_vertices_m ? frame.organ_vertices_m->size() : 0) +
                                " vertices, the organ given to begin() has " + std::to_string(g.vertex_count));
  const double per_unit = 1.0 / settings_.length_unit_m;
  const auto& vertices = *frame.organ_vertices_m;
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const Eigen::Vector3f point = (vertices[i] * per_unit).cast<float>();
    if (!point.allFinite())
      throw std::invalid_argument(what + ": vertex " + std::to_string(i) + " is not finite in length units");
    g.points->SetPoint(static_cast<unsigned int>(i), point.x(), point.y(), point.z());
  }
  stamp_now(g.polydata);
  g.polydata->Pack();

  bool send_tool = settings_.send_tool_transform;
  if (send_tool) {
    const Eigen::Vector3d axis = frame.tool_axis.allFinite() && frame.tool_axis.norm() > 0
                                     ? frame.tool_axis.normalized()
                                     : Eigen::Vector3d::UnitZ();
    // The tool's frame: z along the shaft (as DeviceSample::orientation), origin at the tip.
    const Eigen::Matrix3d rotation =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis).toRotationMatrix();
    const Eigen::Vector3d tip = frame.tool_tip_m * per_unit;
    send_tool = tip.allFinite();
    igtl::Matrix4x4 matrix;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) matrix[r][c] = r == c ? 1.0f : 0.0f;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) matrix[r][c] = static_cast<float>(rotation(r, c));
      matrix[r][3] = static_cast<float>(tip(r));
    }
    g.tool->SetMatrix(matrix);
    stamp_now(g.tool);
    g.tool->Pack();
  }

  std::lock_guard<std::mutex> lock(net.send_mutex);
  if (net.client_fd < 0) return;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(settings_.send_timeout_s));
  bool ok = send_all(net.client_fd, g.polydata->GetPackPointer(), static_cast<std::size_t>(g.polydata->GetPackSize()),
                     deadline);
  if (ok) net.counts.polydata_sent.fetch_add(1, std::memory_order_relaxed);
  if (ok && send_tool) {
    ok = send_all(net.client_fd, g.tool->GetPackPointer(), static_cast<std::size_t>(g.tool->GetPackSize()), deadline);
    if (ok) net.counts.tool_transforms_sent.fetch_add(1, std::memory_order_relaxed);
  }
  if (!ok) {
    // Framing is broken mid-message: end the stream; the network thread sees it and cleans up.
    net.counts.send_failures.fetch_add(1, std::memory_order_relaxed);
    net.note(what + ": send failed or timed out; closing the connection");
    ::shutdown(net.client_fd, SHUT_RDWR);
  }
}

void OpenIgtLinkDevice::end() noexcept {
  Graphics& g = *graphics_;
  g.begun = false;
  g.polydata = nullptr;
  g.points = nullptr;
  g.tool = nullptr;
}

int OpenIgtLinkDevice::bound_port() const noexcept { return network_->bound_port.load(std::memory_order_acquire); }

bool OpenIgtLinkDevice::client_connected() const noexcept {
  return network_->client_open.load(std::memory_order_acquire);
}

OpenIgtLinkCounters OpenIgtLinkDevice::counters() const noexcept {
  const Network::Counters& c = network_->counts;
  const OpenIgtLinkParserCounts& p = network_->parser.counts();
  const auto get = [](const std::atomic<std::uint64_t>& value) { return value.load(std::memory_order_relaxed); };
  OpenIgtLinkCounters out;
  out.transforms_received = get(p.transforms_received);
  out.positions_received = get(p.positions_received);
  out.messages_skipped = get(p.messages_skipped);
  out.rejected_bad_header = get(p.rejected_bad_header);
  out.rejected_oversized = get(p.rejected_oversized);
  out.rejected_truncated = get(c.rejected_truncated);
  out.rejected_bad_body_size = get(p.rejected_bad_body_size);
  out.rejected_bad_crc = get(p.rejected_bad_crc);
  out.rejected_non_finite = get(p.rejected_non_finite);
  out.rejected_bad_rotation = get(p.rejected_bad_rotation);
  out.forces_sent = get(c.forces_sent);
  out.forces_dropped = get(c.forces_dropped);
  out.polydata_sent = get(c.polydata_sent);
  out.tool_transforms_sent = get(c.tool_transforms_sent);
  out.send_failures = get(c.send_failures);
  out.connections = get(c.connections);
  out.disconnects = get(c.disconnects);
  return out;
}

std::string OpenIgtLinkDevice::last_rejection() const {
  std::lock_guard<std::mutex> lock(network_->rejection_mutex);
  return network_->last_rejection;
}

}  // namespace touchstone::realtime::haptics
