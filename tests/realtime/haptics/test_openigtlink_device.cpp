// The OpenIGTLink device against a real peer: libOpenIGTLink's own client socket over
// loopback. Each device listens on a port the system picks (settings.port = 0), so parallel
// test runs never collide.

#include "touchstone/realtime/haptics/openigtlink_device.hpp"

#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "support/openigtlink_peer.hpp"

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlPolyDataMessage.h>
#include <igtlPositionMessage.h>
#include <igtlSensorMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <igtlUnit.h>
#include <igtl_header.h>
#include <igtl_util.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <functional>
#include <memory>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

using touchstone::geometry::icosphere;
using touchstone::geometry::TriangleSurface;
using touchstone::realtime::graphics::GraphicsFrame;
using touchstone::realtime::haptics::DeviceSample;
using touchstone::realtime::haptics::OpenIgtLinkDevice;
using touchstone::realtime::haptics::OpenIgtLinkSettings;

using touchstone::testing::Peer;

constexpr double wait_s = 5.0;  // generous bound for events that normally take a millisecond

OpenIgtLinkSettings loopback_settings() {
  OpenIgtLinkSettings settings;
  settings.port = 0;
  settings.bind_address = "127.0.0.1";
  return settings;
}

template <class Predicate>
bool wait_until(Predicate predicate, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!predicate()) {
    if (std::chrono::steady_clock::now() > deadline) return predicate();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

void set_identity(igtl::Matrix4x4& m) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[r][c] = r == c ? 1.0f : 0.0f;
}

/// A matrix rotating by `angle` about a unit `axis` and translating by `t` [mm], in float32.
void make_matrix(igtl::Matrix4x4& m, const Eigen::Vector3d& axis, double angle, const Eigen::Vector3f& t) {
  set_identity(m);
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m[r][c] = static_cast<float>(rotation(r, c));
    m[r][3] = t(r);
  }
}

/// An OpenIGTLink header followed by `body`, built by hand so that the header can lie.
std::vector<unsigned char> raw_message(const char* type, const std::vector<unsigned char>& body,
                                       std::uint64_t announced_body_size, bool correct_crc = true,
                                       std::uint16_t version = 1) {
  igtl_header header;
  std::memset(&header, 0, sizeof header);
  header.version = version;
  // Fixed-size fields, NUL-padded by the memset, not necessarily NUL-terminated.
  std::memcpy(header.name, type, std::min(std::strlen(type), sizeof header.name));
  std::memcpy(header.device_name, "TestPeer", std::min(std::strlen("TestPeer"), sizeof header.device_name));
  header.body_size = announced_body_size;
  std::vector<unsigned char> copy = body;
  header.crc = crc64(copy.data(), copy.size(), crc64(nullptr, 0, 0));
  if (!correct_crc) header.crc ^= 0x1;
  igtl_header_convert_byte_order(&header);
  std::vector<unsigned char> bytes(IGTL_HEADER_SIZE + body.size());
  std::memcpy(bytes.data(), &header, IGTL_HEADER_SIZE);
  std::copy(body.begin(), body.end(), bytes.begin() + IGTL_HEADER_SIZE);
  return bytes;
}

/// float32 values in network byte order, as a message body.
std::vector<unsigned char> big_endian_floats(const std::vector<float>& values) {
  std::vector<unsigned char> bytes;
  for (const float value : values) {
    std::uint32_t word;
    std::memcpy(&word, &value, sizeof word);
    for (int shift = 24; shift >= 0; shift -= 8) bytes.push_back(static_cast<unsigned char>(word >> shift));
  }
  return bytes;
}

/// A header version 2 message as 3D Slicer sends it: extended header (12 bytes), `content`,
/// then one metadata entry ("Status" = "OK"). `extended_header_size` may lie.
std::vector<unsigned char> v2_message(const char* type, const std::vector<unsigned char>& content,
                                      std::uint16_t extended_header_size = 12, bool correct_crc = true) {
  std::vector<unsigned char> body;
  const auto put16 = [&](std::uint16_t v) {
    body.push_back(static_cast<unsigned char>(v >> 8));
    body.push_back(static_cast<unsigned char>(v));
  };
  const auto put32 = [&](std::uint32_t v) {
    put16(static_cast<std::uint16_t>(v >> 16));
    put16(static_cast<std::uint16_t>(v));
  };
  const std::string key = "Status", value = "OK";
  put16(extended_header_size);
  put16(2 + 8);  // metadata header: entry count, then key size, value encoding, value size per entry
  put32(static_cast<std::uint32_t>(key.size() + value.size()));
  put32(7);  // message id
  body.insert(body.end(), content.begin(), content.end());
  put16(1);
  put16(static_cast<std::uint16_t>(key.size()));
  put16(3);  // US-ASCII
  put32(static_cast<std::uint32_t>(value.size()));
  body.insert(body.end(), key.begin(), key.end());
  body.insert(body.end(), value.begin(), value.end());
  return raw_message(type, body, body.size(), correct_crc, 2);
}

/// A started device on a free loopback port.
class OpenIgtLinkDeviceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    device_ = std::make_unique<OpenIgtLinkDevice>(loopback_settings());
    device_->start();
    ASSERT_GT(device_->bound_port(), 0);
  }
  void TearDown() override { device_->stop(); }

  /// A connected peer, once the device has accepted it.
  std::unique_ptr<Peer> connect() {
    auto peer = std::make_unique<Peer>(device_->bound_port());
    EXPECT_TRUE(peer->connected());
    EXPECT_TRUE(wait_until([&] { return device_->client_connected(); }, wait_s));
    return peer;
  }
  /// Reads until a fresh pose arrives (or the wait ends); the last sample read.
  DeviceSample wait_for_fresh_pose() {
    DeviceSample sample;
    EXPECT_TRUE(wait_until(
        [&] {
          sample = device_->read(0.0);
          return sample.fresh;
        },
        wait_s));
    return sample;
  }
  /// Sends a valid pose and checks that it arrives: the connection is still served.
  void expect_still_served(Peer& peer) {
    igtl::Matrix4x4 matrix;
    make_matrix(matrix, Eigen::Vector3d::UnitX(), 0.25, Eigen::Vector3f(7.0f, 8.0f, 9.0f));
    peer.send_transform(matrix);
    const DeviceSample sample = wait_for_fresh_pose();
    EXPECT_TRUE(sample.connected);
    EXPECT_NEAR(sample.tip_position_m.x(), 0.007, 1e-12);
  }
  static void expect_finite(const DeviceSample& sample) {
    EXPECT_TRUE(sample.tip_position_m.allFinite());
    EXPECT_TRUE(sample.orientation.coeffs().allFinite());
  }

  std::unique_ptr<OpenIgtLinkDevice> device_;
};

void expect_rejected_field(const std::function<void(OpenIgtLinkSettings&)>& change, const std::string& field) {
  OpenIgtLinkSettings settings;
  change(settings);
  try {
    settings.validate();
    ADD_FAILURE() << "validate() accepted an invalid " << field;
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find(field), std::string::npos) << error.what();
  }
}

// --- settings and start --------------------------------------------------------------------------

TEST(OpenIgtLinkSettings, DefaultsAreValid) {
  const OpenIgtLinkSettings settings;
  EXPECT_NO_THROW(settings.validate());
  EXPECT_EQ(settings.port, 18944);
  EXPECT_EQ(settings.length_unit_m, 0.001);
}

TEST(OpenIgtLinkSettings, ValidationErrorsNameTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  expect_rejected_field([](auto& s) { s.port = -1; }, "port");
  expect_rejected_field([](auto& s) { s.port = 65536; }, "port");
  expect_rejected_field([](auto& s) { s.bind_address = "localhost:1"; }, "bind_address");
  expect_rejected_field([](auto& s) { s.length_unit_m = 0; }, "length_unit_m");
  expect_rejected_field([&](auto& s) { s.length_unit_m = nan; }, "length_unit_m");
  expect_rejected_field([](auto& s) { s.max_message_body_bytes = 10; }, "max_message_body_bytes");
  expect_rejected_field([](auto& s) { s.max_force_N = -1; }, "max_force_N");
  expect_rejected_field([](auto& s) { s.force_send_rate_hz = 0; }, "force_send_rate_hz");
  expect_rejected_field([](auto& s) { s.force_device_name = "a-name-longer-than-twenty"; }, "force_device_name");
  expect_rejected_field([](auto& s) { s.organ_device_name = ""; }, "organ_device_name");
  expect_rejected_field([](auto& s) { s.tool_device_name = "tab\there"; }, "tool_device_name");
  expect_rejected_field([](auto& s) { s.accept_poll_s = 0; }, "accept_poll_s");
  expect_rejected_field([](auto& s) { s.send_timeout_s = 100; }, "send_timeout_s");
  OpenIgtLinkSettings bad;
  bad.max_force_N = 0;
  EXPECT_THROW(OpenIgtLinkDevice{bad}, std::invalid_argument);
}

TEST(OpenIgtLinkDevice, StartOnAPortInUseThrowsNamingThePort) {
  OpenIgtLinkDevice first(loopback_settings());
  first.start();
  OpenIgtLinkSettings settings = loopback_settings();
  settings.port = first.bound_port();
  OpenIgtLinkDevice second(settings);
  try {
    second.start();
    ADD_FAILURE() << "a second server bound port " << settings.port;
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(std::to_string(settings.port)), std::string::npos) << error.what();
  }
  second.stop();  // harmless when never started
  first.stop();
  first.stop();  // idempotent
  EXPECT_EQ(first.bound_port(), 0);
}

TEST_F(OpenIgtLinkDeviceTest, NotConnectedBeforeAClientSendsAPose) {
  const DeviceSample before = device_->read(0.0);
  EXPECT_FALSE(before.connected);
  EXPECT_FALSE(before.fresh);
  EXPECT_FALSE(before.finished);
  expect_finite(before);
  EXPECT_EQ(device_->name(), "openigtlink");
  EXPECT_EQ(device_->max_force_N(), 10.0);
  EXPECT_THROW(device_->start(), std::logic_error);

  auto peer = connect();
  EXPECT_FALSE(device_->read(0.0).connected);  // a client, but no pose yet
  EXPECT_EQ(device_->counters().connections, 1u);
}

// --- poses in --------------------------------------------------------------------------------------

TEST_F(OpenIgtLinkDeviceTest, TransformGivesThePoseInMetres) {
  auto peer = connect();
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized();
  const Eigen::Vector3f translation_mm(12.5f, -40.25f, 103.1f);
  igtl::Matrix4x4 matrix;
  make_matrix(matrix, axis, 0.7, translation_mm);
  peer->send_transform(matrix);

  const DeviceSample sample = wait_for_fresh_pose();
  EXPECT_TRUE(sample.connected);
  for (int i = 0; i < 3; ++i) {
    const double expected = static_cast<double>(translation_mm(i)) * 0.001;
    EXPECT_NEAR(sample.tip_position_m(i), expected, 1e-12 * std::abs(expected)) << "component " << i;
  }
  const Eigen::Matrix3d expected_rotation = Eigen::AngleAxisd(0.7, axis).toRotationMatrix();
  EXPECT_LT((sample.orientation.toRotationMatrix() - expected_rotation).norm(), 1e-6);

  // The same pose read again is no longer fresh.
  const DeviceSample again = device_->read(0.001);
  EXPECT_FALSE(again.fresh);
  EXPECT_TRUE(again.connected);
  EXPECT_EQ(again.tip_position_m, sample.tip_position_m);
  EXPECT_EQ(device_->counters().transforms_received, 1u);

  // A transform with scaling still gives the rotation (its orthogonal polar factor).
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) matrix[r][c] *= 2.5f;
  peer->send_transform(matrix);
  const DeviceSample scaled = wait_for_fresh_pose();
  EXPECT_LT((scaled.orientation.toRotationMatrix() - expected_rotation).norm(), 1e-6);
}

TEST_F(OpenIgtLinkDeviceTest, PositionGivesThePoseInMetres) {
  auto peer = connect();
  const Eigen::Quaternionf q = Eigen::Quaternionf(Eigen::AngleAxisf(1.1f, Eigen::Vector3f(0, 1, 1).normalized()));
  igtl::PositionMessage::Pointer message = igtl::PositionMessage::New();
  message->SetDeviceName("Tracker");
  message->SetPackType(igtl::PositionMessage::ALL);
  message->SetPosition(1.5f, -2.5f, 300.75f);
  message->SetQuaternion(q.x(), q.y(), q.z(), q.w());
  peer->send(message);

  const DeviceSample sample = wait_for_fresh_pose();
  EXPECT_TRUE(sample.connected);
  const Eigen::Vector3d expected = Eigen::Vector3d(1.5, -2.5, 300.75) * 0.001;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(sample.tip_position_m(i), expected(i), 1e-12 * std::abs(expected(i)));
  EXPECT_LT(sample.orientation.angularDistance(q.cast<double>()), 1e-6);
  EXPECT_FALSE(device_->read(0.001).fresh);

  // The short forms are built by hand: libOpenIGTLink 1.11 packs them past the end of its
  // buffer. Position only (12 bytes): the orientation stays.
  peer->send_bytes(raw_message("POSITION", big_endian_floats({4.0f, 5.0f, 6.0f}), 12));
  const DeviceSample moved = wait_for_fresh_pose();
  EXPECT_NEAR(moved.tip_position_m.z(), 0.006, 1e-15);
  EXPECT_LT(moved.orientation.angularDistance(q.cast<double>()), 1e-6);

  // Three quaternion components (24 bytes): w = sqrt(1 - |v|²).
  peer->send_bytes(raw_message("POSITION", big_endian_floats({0.0f, 0.0f, 1.0f, 0.0f, 0.6f, 0.0f}), 24));
  const DeviceSample turned = wait_for_fresh_pose();
  EXPECT_LT(turned.orientation.angularDistance(Eigen::Quaterniond(0.8, 0.0, 0.6, 0.0)), 1e-6);
  EXPECT_EQ(device_->counters().positions_received, 3u);
}

TEST_F(OpenIgtLinkDeviceTest, HeaderVersion2PosesAreDecodedAndOtherV2TypesSkipped) {
  auto peer = connect();
  // 3D Slicer opens with a version 2 STATUS: skipped, the connection stays.
  peer->send_bytes(v2_message("STATUS", std::vector<unsigned char>(30, 0)));

  igtl::Matrix4x4 matrix;
  const Eigen::Vector3d axis = Eigen::Vector3d(-1, 0.5, 2).normalized();
  make_matrix(matrix, axis, 2.0, Eigen::Vector3f(-20.5f, 33.0f, 7.25f));
  std::vector<float> content;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) content.push_back(matrix[r][c]);  // columns, then translation
  peer->send_bytes(v2_message("TRANSFORM", big_endian_floats(content)));
  const DeviceSample sample = wait_for_fresh_pose();
  EXPECT_TRUE(sample.connected);
  EXPECT_NEAR(sample.tip_position_m.x(), static_cast<double>(-20.5f) * 0.001, 1e-15);
  EXPECT_NEAR(sample.tip_position_m.z(), static_cast<double>(7.25f) * 0.001, 1e-15);
  EXPECT_LT((sample.orientation.toRotationMatrix() - Eigen::AngleAxisd(2.0, axis).toRotationMatrix()).norm(), 1e-6);

  peer->send_bytes(v2_message("POSITION", big_endian_floats({1.0f, 2.0f, 3.0f, 0.0f, 0.0f, 0.6f, 0.8f})));
  const DeviceSample position = wait_for_fresh_pose();
  EXPECT_NEAR(position.tip_position_m.y(), 0.002, 1e-15);
  EXPECT_LT(position.orientation.angularDistance(Eigen::Quaterniond(0.8, 0.0, 0.0, 0.6)), 1e-6);

  // Extended header sizes that do not add up, and a bad CRC: dropped, connection kept.
  peer->send_bytes(v2_message("TRANSFORM", big_endian_floats(content), 40));
  peer->send_bytes(v2_message("TRANSFORM", big_endian_floats(content), 12, /*correct_crc=*/false));
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_bad_body_size == 1; }, wait_s));
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_bad_crc == 1; }, wait_s));
  expect_still_served(*peer);
  const auto counts = device_->counters();
  EXPECT_EQ(counts.messages_skipped, 1u);
  EXPECT_EQ(counts.transforms_received, 2u);
  EXPECT_EQ(counts.positions_received, 1u);
  EXPECT_EQ(counts.disconnects, 0u);
}

// --- force out -------------------------------------------------------------------------------------

TEST_F(OpenIgtLinkDeviceTest, ForceGoesOutAsSensorInNewtonsAndZeroAfterStop) {
  auto peer = connect();
  const auto receive_force = [&](const Eigen::Vector3d& expected) {
    return wait_until(
        [&] {
          igtl::SensorMessage::Pointer sensor = peer->receive<igtl::SensorMessage>("SENSOR");
          if (!sensor) return false;
          EXPECT_EQ(sensor->GetLength(), 3u);
          EXPECT_STREQ(sensor->GetDeviceName(), "TouchstoneForce");
          return Eigen::Vector3d(sensor->GetValue(0), sensor->GetValue(1), sensor->GetValue(2)) == expected;
        },
        wait_s);
  };

  const Eigen::Vector3d force(1.5, -2.0, 0.25);
  device_->write_force(force, 0.0);
  EXPECT_TRUE(receive_force(force));

  // The unit field says newton.
  igtl::SensorMessage::Pointer sensor = peer->receive<igtl::SensorMessage>("SENSOR");
  ASSERT_TRUE(sensor);
  igtl::Unit::Pointer newton = igtl::Unit::New();
  newton->Init();
  newton->Append(igtl::Unit::SI_DERIVED_NEWTON, 1);
  EXPECT_EQ(sensor->GetUnit(), newton->Pack());

  // The device clamps to max_force_N and never sends a non-finite force.
  device_->write_force(Eigen::Vector3d(100.0, 0.0, 0.0), 0.001);
  EXPECT_TRUE(receive_force(Eigen::Vector3d(10.0, 0.0, 0.0)));
  device_->write_force(Eigen::Vector3d(std::nan(""), 1.0, 1.0), 0.002);
  EXPECT_TRUE(receive_force(Eigen::Vector3d::Zero()));
  device_->write_force(force, 0.003);
  EXPECT_TRUE(receive_force(force));

  // stop(): the last SENSOR before the stream ends is zero.
  device_->stop();
  Eigen::Vector3d last = force;
  int after_stop = 0;
  while (igtl::SensorMessage::Pointer message = peer->receive<igtl::SensorMessage>("SENSOR")) {
    last = Eigen::Vector3d(message->GetValue(0), message->GetValue(1), message->GetValue(2));
    ++after_stop;
  }
  EXPECT_GT(after_stop, 0);
  EXPECT_EQ(last, Eigen::Vector3d::Zero());
  EXPECT_GT(device_->counters().forces_sent, 0u);
  EXPECT_FALSE(device_->read(0.004).connected);
}

// --- POLYDATA out ----------------------------------------------------------------------------------

TEST_F(OpenIgtLinkDeviceTest, FrameSendsTheDeformedOrganAsPolyDataInMillimetres) {
  const auto mesh = icosphere(1, 0.05);
  const TriangleSurface organ(mesh.vertices, mesh.triangles, "icosphere");
  device_->begin(organ);

  std::vector<Eigen::Vector3d> deformed = organ.vertices();
  std::vector<Eigen::Vector3d> displacement(deformed.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < deformed.size(); ++i) {
    displacement[i] = Eigen::Vector3d(0.0, 0.0, -0.0001 * static_cast<double>(i % 7));
    deformed[i] += displacement[i];
  }
  GraphicsFrame frame;
  frame.index = 0;
  frame.organ_vertices_m = &deformed;
  frame.organ_displacement_m = &displacement;
  frame.tool_tip_m = Eigen::Vector3d(0.01, 0.02, 0.06);
  frame.tool_axis = Eigen::Vector3d::UnitX();

  device_->frame(frame);  // nobody connected: nothing sent
  EXPECT_EQ(device_->counters().polydata_sent, 0u);

  auto peer = connect();
  frame.index = 1;
  device_->frame(frame);
  EXPECT_EQ(device_->counters().polydata_sent, 1u);

  igtl::PolyDataMessage::Pointer polydata = peer->receive<igtl::PolyDataMessage>("POLYDATA");
  ASSERT_TRUE(polydata);
  EXPECT_STREQ(polydata->GetDeviceName(), "TouchstoneOrgan");
  ASSERT_TRUE(polydata->GetPoints());
  ASSERT_TRUE(polydata->GetPolygons());
  ASSERT_EQ(static_cast<std::size_t>(polydata->GetPoints()->GetNumberOfPoints()), deformed.size());
  ASSERT_EQ(polydata->GetPolygons()->GetNumberOfCells(), organ.triangles().size());
  for (std::size_t i = 0; i < deformed.size(); ++i) {
    igtlFloat32 point[3];
    polydata->GetPoints()->GetPoint(static_cast<unsigned int>(i), point);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(point[k], deformed[i](k) * 1000.0, 1e-6 * 50.0) << "vertex " << i << " component " << k;
  }
  for (std::size_t t = 0; t < organ.triangles().size(); ++t) {
    ASSERT_EQ(polydata->GetPolygons()->GetCellSize(static_cast<unsigned int>(t)), 3u);
    igtlUint32 cell[3];
    polydata->GetPolygons()->GetCell(static_cast<unsigned int>(t), cell);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(cell[k], static_cast<igtlUint32>(organ.triangles()[t](k)));
  }

  igtl::TransformMessage::Pointer tool = peer->receive<igtl::TransformMessage>("TRANSFORM");
  ASSERT_TRUE(tool);
  EXPECT_STREQ(tool->GetDeviceName(), "TouchstoneTool");
  igtl::Matrix4x4 matrix;
  tool->GetMatrix(matrix);
  EXPECT_NEAR(matrix[0][3], 10.0f, 1e-5);
  EXPECT_NEAR(matrix[1][3], 20.0f, 1e-5);
  EXPECT_NEAR(matrix[2][3], 60.0f, 1e-5);
  EXPECT_NEAR(matrix[0][2], 1.0f, 1e-6);  // the shaft (local z) along the tool axis
  EXPECT_EQ(device_->counters().tool_transforms_sent, 1u);

  // A frame that does not match the organ is an error naming it.
  std::vector<Eigen::Vector3d> too_few(3, Eigen::Vector3d::Zero());
  frame.organ_vertices_m = &too_few;
  EXPECT_THROW(device_->frame(frame), std::invalid_argument);
  device_->end();
}

// --- disconnect and reconnect ----------------------------------------------------------------------

TEST_F(OpenIgtLinkDeviceTest, DisconnectIsSeenPromptlyAndANewClientIsServed) {
  auto first = connect();
  expect_still_served(*first);
  first->close();
  // Disconnect detection is event-driven (poll wakes on the FIN), so 200 ms is a wide margin.
  EXPECT_TRUE(wait_until([&] { return !device_->read(0.0).connected; }, 0.2));
  EXPECT_TRUE(wait_until([&] { return device_->counters().disconnects == 1; }, wait_s));
  expect_finite(device_->read(0.0));

  auto second = connect();
  igtl::Matrix4x4 matrix;
  make_matrix(matrix, Eigen::Vector3d::UnitZ(), 0.0, Eigen::Vector3f(-1.0f, -2.0f, -3.0f));
  second->send_transform(matrix);
  const DeviceSample sample = wait_for_fresh_pose();
  EXPECT_TRUE(sample.connected);
  EXPECT_NEAR(sample.tip_position_m.z(), -0.003, 1e-15);
  EXPECT_EQ(device_->counters().connections, 2u);
}

// --- malformed input -------------------------------------------------------------------------------

TEST_F(OpenIgtLinkDeviceTest, BadCrcDropsTheMessageAndKeepsTheConnection) {
  auto peer = connect();
  igtl::TransformMessage::Pointer message = igtl::TransformMessage::New();
  igtl::Matrix4x4 matrix;
  make_matrix(matrix, Eigen::Vector3d::UnitY(), 0.3, Eigen::Vector3f(1.0f, 2.0f, 3.0f));
  message->SetMatrix(matrix);
  std::vector<unsigned char> bytes = Peer::packed(message);
  bytes[IGTL_HEADER_SIZE + 5] ^= 0x40;  // corrupt the body, keep the header's CRC
  peer->send_bytes(bytes);
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_bad_crc == 1; }, wait_s));
  EXPECT_FALSE(device_->read(0.0).connected);  // no valid pose yet
  expect_still_served(*peer);
  EXPECT_NE(device_->last_rejection().find("CRC"), std::string::npos) << device_->last_rejection();
}

TEST_F(OpenIgtLinkDeviceTest, OversizedBodyClosesTheConnectionWithoutReadingIt) {
  auto peer = connect();
  expect_still_served(*peer);
  peer->send_bytes(raw_message("IMAGE", {}, std::uint64_t{1} << 40));
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_oversized == 1; }, wait_s));
  EXPECT_TRUE(wait_until([&] { return !device_->client_connected(); }, wait_s));
  const DeviceSample sample = device_->read(0.0);
  EXPECT_FALSE(sample.connected);
  expect_finite(sample);
  EXPECT_NE(device_->last_rejection().find("IMAGE"), std::string::npos) << device_->last_rejection();

  auto next = connect();
  expect_still_served(*next);
}

TEST_F(OpenIgtLinkDeviceTest, TruncatedBodyThenDisconnectIsCounted) {
  auto peer = connect();
  std::vector<unsigned char> body(48, 0);
  std::vector<unsigned char> bytes = raw_message("TRANSFORM", body, 48);
  bytes.resize(IGTL_HEADER_SIZE + 20);  // header and 20 of 48 body bytes
  peer->send_bytes(bytes);
  peer->close();
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_truncated == 1; }, wait_s));
  EXPECT_TRUE(wait_until([&] { return !device_->client_connected(); }, wait_s));
  EXPECT_EQ(device_->counters().transforms_received, 0u);
  auto next = connect();
  expect_still_served(*next);
}

TEST_F(OpenIgtLinkDeviceTest, GarbageBytesCloseTheConnection) {
  auto peer = connect();
  expect_still_served(*peer);
  std::mt19937 random(12345);
  std::vector<unsigned char> garbage(4096);
  for (auto& byte : garbage) byte = static_cast<unsigned char>(random());
  garbage[0] = 0xA5;  // a version field that is neither 1 nor 2, whatever the seed gives
  peer->send_bytes(garbage);
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_bad_header == 1; }, wait_s));
  EXPECT_TRUE(wait_until([&] { return !device_->client_connected(); }, wait_s));
  const DeviceSample sample = device_->read(0.0);
  EXPECT_FALSE(sample.connected);
  expect_finite(sample);
  EXPECT_NEAR(sample.tip_position_m.x(), 0.007, 1e-12);  // the last valid pose is kept

  auto next = connect();
  expect_still_served(*next);
}

TEST_F(OpenIgtLinkDeviceTest, NonFiniteAndSingularTransformsNeverReachRead) {
  auto peer = connect();
  expect_still_served(*peer);
  igtl::Matrix4x4 matrix;
  make_matrix(matrix, Eigen::Vector3d::UnitZ(), 0.1, Eigen::Vector3f(1.0f, 1.0f, 1.0f));
  matrix[1][3] = std::numeric_limits<float>::quiet_NaN();
  peer->send_transform(matrix);
  make_matrix(matrix, Eigen::Vector3d::UnitZ(), 0.1, Eigen::Vector3f(1.0f, 1.0f, 1.0f));
  matrix[0][1] = std::numeric_limits<float>::infinity();
  peer->send_transform(matrix);
  make_matrix(matrix, Eigen::Vector3d::UnitZ(), 0.1, Eigen::Vector3f(1.0f, 1.0f, 1.0f));
  for (int r = 0; r < 3; ++r) matrix[r][2] = 0.0f;  // singular 3×3 part
  peer->send_transform(matrix);
  igtl::PositionMessage::Pointer position = igtl::PositionMessage::New();
  position->SetPackType(igtl::PositionMessage::ALL);
  position->SetPosition(1.0f, std::numeric_limits<float>::quiet_NaN(), 1.0f);
  position->SetQuaternion(0.0f, 0.0f, 0.0f, 1.0f);
  peer->send(position);

  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_non_finite == 3; }, wait_s));
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_bad_rotation == 1; }, wait_s));
  const DeviceSample sample = device_->read(0.0);
  EXPECT_FALSE(sample.fresh);
  EXPECT_TRUE(sample.connected);
  expect_finite(sample);
  EXPECT_NEAR(sample.tip_position_m.x(), 0.007, 1e-12);
  expect_still_served(*peer);
}

TEST_F(OpenIgtLinkDeviceTest, OtherTypesAreSkippedAndWrongSizesRejected) {
  auto peer = connect();
  igtl::StringMessage::Pointer text = igtl::StringMessage::New();
  text->SetDeviceName("Slicer");
  text->SetString("hello");
  peer->send(text);
  peer->send_bytes(raw_message("GET_TRANS", {}, 0));                                  // header-only query
  peer->send_bytes(raw_message("TRANSFORM", std::vector<unsigned char>(40, 0), 40));  // 40 ≠ 48 bytes
  peer->send_bytes(raw_message("POSITION", std::vector<unsigned char>(20, 0), 20));   // not 12, 24 or 28
  EXPECT_TRUE(wait_until([&] { return device_->counters().messages_skipped == 2; }, wait_s));
  EXPECT_TRUE(wait_until([&] { return device_->counters().rejected_bad_body_size == 2; }, wait_s));
  expect_still_served(*peer);
  EXPECT_EQ(device_->counters().disconnects, 0u);
}

TEST_F(OpenIgtLinkDeviceTest, EveryKindOfBadInputInARowLeavesTheDeviceServing) {
  // Each connection ends in a different way; read() stays finite throughout.
  const auto check_read = [&] { expect_finite(device_->read(0.0)); };
  {
    auto peer = connect();
    peer->send_bytes(raw_message("TRANSFORM", std::vector<unsigned char>(48, 0x7f), 48, /*correct_crc=*/false));
    peer->send_bytes(raw_message("TRANSFORM", std::vector<unsigned char>(48, 0xff), 48));  // NaN floats
    peer->send_bytes(raw_message("POINT", std::vector<unsigned char>(100, 1), 100));
    peer->send_bytes(raw_message("TRANSFORM", {}, std::uint64_t{1} << 40));
    EXPECT_TRUE(wait_until([&] { return !device_->client_connected(); }, wait_s));
    check_read();
  }
  {
    auto peer = connect();
    std::vector<unsigned char> half_header(30, 0);
    peer->send_bytes(half_header);
    peer->close();
    EXPECT_TRUE(wait_until([&] { return !device_->client_connected(); }, wait_s));
    check_read();
  }
  const auto counts = device_->counters();
  EXPECT_EQ(counts.rejected_bad_crc, 1u);
  EXPECT_EQ(counts.rejected_non_finite, 1u);
  EXPECT_EQ(counts.messages_skipped, 1u);
  EXPECT_EQ(counts.rejected_oversized, 1u);
  EXPECT_EQ(counts.rejected_truncated, 1u);
  EXPECT_EQ(counts.rejected_total(), 4u);
  EXPECT_EQ(counts.disconnects, 2u);
  auto last = connect();
  expect_still_served(*last);
}

}  // namespace
