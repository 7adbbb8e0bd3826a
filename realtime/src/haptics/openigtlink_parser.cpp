// The OpenIGTLink byte-stream parser: an incremental state machine (header, then body) fed by
// the device's network thread in pieces of any size.
#include "touchstone/realtime/haptics/openigtlink_parser.hpp"

#include <igtlMessageHeader.h>
#include <igtlTransformMessage.h>
#include <igtl_header.h>
#include <igtl_util.h>

#include <Eigen/SVD>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <sstream>
#include <utility>
#include <vector>

namespace touchstone::realtime::haptics {

namespace {

constexpr std::size_t header_size = IGTL_HEADER_SIZE;  // 58 bytes
constexpr std::size_t transform_body_size = 48;        // 12 float32: 3×3 rotation columns, then translation
constexpr std::size_t extended_header_size = 12;      // header version 2: sizes and message id before the content
constexpr std::size_t max_v2_pose_body_size = 65536;  // a pose with more metadata than this is not a pose

bool valid_position_size(std::uint64_t size) { return size == 12 || size == 24 || size == 28; }

std::uint32_t big_endian_32(const unsigned char* bytes) {
  return (std::uint32_t{bytes[0]} << 24) | (std::uint32_t{bytes[1]} << 16) | (std::uint32_t{bytes[2]} << 8) |
         std::uint32_t{bytes[3]};
}

float big_endian_float(const unsigned char* bytes) {
  const std::uint32_t word = big_endian_32(bytes);
  float value;
  std::memcpy(&value, &word, sizeof value);
  return value;
}

template <class T>
std::string to_text(const T& value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

/// The header's type name: printable ASCII, NUL-padded to 12 bytes, not empty.
bool valid_type_name(const char (&name)[IGTL_HEADER_TYPE_SIZE]) {
  std::size_t length = 0;
  while (length < IGTL_HEADER_TYPE_SIZE && name[length] != '\0') {
    if (name[length] < 0x20 || name[length] >= 0x7f) return false;
    ++length;
  }
  for (std::size_t i = length; i < IGTL_HEADER_TYPE_SIZE; ++i)
    if (name[i] != '\0') return false;
  return length > 0;
}

/// A device name for messages: printable characters kept, others shown as '?'.
std::string printable_name(const char* name, std::size_t capacity) {
  std::string out(name, strnlen(name, capacity));
  for (char& c : out)
    if (c < 0x20 || c >= 0x7f) c = '?';
  return out;
}

void count(std::atomic<std::uint64_t>& counter) { counter.fetch_add(1, std::memory_order_relaxed); }

}  // namespace

struct OpenIgtLinkParser::State {
  using Verdict = OpenIgtLinkParser::Verdict;
  /// What to do with the body of the message being received.
  enum class BodyUse { discard, transform, position, transform_v2, position_v2 };

  std::uint64_t max_message_body_bytes;
  double length_unit_m;
  PoseHandler on_pose;
  RejectionHandler on_rejection;
  OpenIgtLinkParserCounts counts;

  std::array<unsigned char, header_size> header_bytes{};
  std::size_t header_filled = 0;
  bool in_body = false;
  std::uint64_t body_left = 0;
  BodyUse body_use = BodyUse::discard;
  std::vector<unsigned char> body = std::vector<unsigned char>(max_v2_pose_body_size);  ///< kept bodies only
  std::size_t body_filled = 0;
  std::uint64_t message_crc = 0;  ///< the header's CRC-64 of the body being received
  std::string message_type;
  std::string message_device;
  /// The last accepted orientation: a 12-byte POSITION (no orientation) keeps it.
  Eigen::Quaterniond last_orientation = Eigen::Quaterniond::Identity();

  // libOpenIGTLink messages, reused for every version 1 TRANSFORM.
  igtl::MessageHeader::Pointer header_message = igtl::MessageHeader::New();
  igtl::TransformMessage::Pointer transform_message = igtl::TransformMessage::New();

  Verdict feed(const unsigned char* data, std::size_t size);
  Verdict on_header();
  Verdict on_body();
  Verdict on_transform();
  Verdict on_v2_pose(bool transform);
  Verdict accept_transform(const igtl::Matrix4x4& matrix);
  Verdict accept_position(const unsigned char* content, std::size_t size);
  void publish(const Eigen::Vector3d& position_m, const Eigen::Quaterniond& orientation);
  void note(const std::string& what) const { on_rejection(what); }
  std::string describe() const { return message_type + " message from '" + message_device + "'"; }
};

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::feed(const unsigned char* data, std::size_t size) {
  while (size > 0) {
    if (!in_body) {
      const std::size_t take = std::min(size, header_size - header_filled);
      std::memcpy(header_bytes.data() + header_filled, data, take);
      header_filled += take;
      data += take;
      size -= take;
      if (header_filled < header_size) break;
      if (on_header() == Verdict::close_connection) return Verdict::close_connection;
      continue;
    }
    const std::size_t take = static_cast<std::size_t>(std::min<std::uint64_t>(size, body_left));
    if (body_use != BodyUse::discard) std::memcpy(body.data() + body_filled, data, take);
    body_filled += take;
    body_left -= take;
    data += take;
    size -= take;
    if (body_left == 0 && on_body() == Verdict::close_connection) return Verdict::close_connection;
  }
  return Verdict::keep_connection;
}

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::on_header() {
  igtl_header header;
  std::memcpy(&header, header_bytes.data(), header_size);
  igtl_header_convert_byte_order(&header);
  message_type.assign(header.name, strnlen(header.name, IGTL_HEADER_TYPE_SIZE));
  message_device = printable_name(header.device_name, IGTL_HEADER_NAME_SIZE);
  message_crc = header.crc;

  // A header that is not one cannot be skipped: nothing after it can be trusted to be framed.
  if ((header.version != 1 && header.version != 2) || !valid_type_name(header.name)) {
    count(counts.rejected_bad_header);
    note("bad OpenIGTLink header (version " + std::to_string(header.version) +
         ", type name not NUL-padded text): closing the connection");
    return Verdict::close_connection;
  }
  // Refuse before reading a byte of the body: skipping 2^40 bytes is no better than storing them.
  if (header.body_size > max_message_body_bytes) {
    count(counts.rejected_oversized);
    note(describe() + ": body of " + std::to_string(header.body_size) + " bytes exceeds max_message_body_bytes = " +
         std::to_string(max_message_body_bytes) + ": closing the connection");
    return Verdict::close_connection;
  }

  in_body = true;
  body_left = header.body_size;
  body_filled = 0;
  body_use = BodyUse::discard;
  const bool is_transform = message_type == "TRANSFORM";
  const bool is_position = message_type == "POSITION";
  if (header.version == 2 && (is_transform || is_position)) {
    // Version 2 (3D Slicer's default): extended header, content, metadata. Sizes checked later.
    if (header.body_size >= extended_header_size && header.body_size <= max_v2_pose_body_size) {
      body_use = is_transform ? BodyUse::transform_v2 : BodyUse::position_v2;
    } else {
      count(counts.rejected_bad_body_size);
      note(describe() + ": header version 2 body of " + std::to_string(header.body_size) +
           " bytes, outside [12, 65536] for a pose");
    }
  } else if (header.version == 2) {
    count(counts.messages_skipped);
  } else if (is_transform) {
    if (header.body_size == transform_body_size) {
      body_use = BodyUse::transform;
    } else {
      count(counts.rejected_bad_body_size);
      note(describe() + ": body of " + std::to_string(header.body_size) + " bytes, a TRANSFORM has 48");
    }
  } else if (is_position) {
    if (valid_position_size(header.body_size)) {
      body_use = BodyUse::position;
    } else {
      count(counts.rejected_bad_body_size);
      note(describe() + ": body of " + std::to_string(header.body_size) + " bytes, a POSITION has 12, 24 or 28");
    }
  } else {
    count(counts.messages_skipped);
  }
  if (body_left == 0) return on_body();
  return Verdict::keep_connection;
}

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::on_body() {
  const BodyUse use = body_use;
  in_body = false;
  header_filled = 0;
  body_use = BodyUse::discard;
  switch (use) {
    case BodyUse::transform:
      return on_transform();
    case BodyUse::transform_v2:
      return on_v2_pose(true);
    case BodyUse::position_v2:
      return on_v2_pose(false);
    case BodyUse::position:
      // Decoded here rather than by igtl::PositionMessage: in libOpenIGTLink 1.11 its
      // SetMessageHeader() takes every body for the 28-byte layout and its byte-order
      // conversion then touches all 28 bytes, past the end of a 12- or 24-byte body.
      if (crc64(body.data(), body_filled, crc64(nullptr, 0, 0)) != message_crc) {
        count(counts.rejected_bad_crc);
        note(describe() + ": CRC-64 of the body does not match the header; message dropped");
        return Verdict::keep_connection;
      }
      return accept_position(body.data(), body_filled);
    case BodyUse::discard:
      break;
  }
  return Verdict::keep_connection;
}

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::on_transform() {
  // libOpenIGTLink unpacks the header, then the body with its CRC-64 check.
  header_message->InitPack();
  std::memcpy(header_message->GetPackPointer(), header_bytes.data(), header_size);
  if (!(header_message->Unpack() & igtl::MessageHeader::UNPACK_HEADER)) {
    count(counts.rejected_bad_header);
    note(describe() + ": libOpenIGTLink could not unpack the header");
    return Verdict::keep_connection;
  }
  transform_message->SetMessageHeader(header_message);
  transform_message->AllocatePack();
  if (static_cast<std::size_t>(transform_message->GetPackBodySize()) != body_filled) {
    count(counts.rejected_bad_body_size);
    note(describe() + ": body size does not match the message type");
    return Verdict::keep_connection;
  }
  std::memcpy(transform_message->GetPackBodyPointer(), body.data(), body_filled);
  if (!(transform_message->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) {
    count(counts.rejected_bad_crc);
    note(describe() + ": CRC-64 of the body does not match the header; message dropped");
    return Verdict::keep_connection;
  }

  igtl::Matrix4x4 matrix;
  transform_message->GetMatrix(matrix);
  return accept_transform(matrix);
}

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::on_v2_pose(bool transform) {
  // libOpenIGTLink 1.11 predates header version 2: check the CRC (over the whole body) and
  // locate the content by hand.
  if (crc64(body.data(), body_filled, crc64(nullptr, 0, 0)) != message_crc) {
    count(counts.rejected_bad_crc);
    note(describe() + ": CRC-64 of the body does not match the header; message dropped");
    return Verdict::keep_connection;
  }
  const std::size_t ext_size = (std::size_t{body[0]} << 8) | body[1];
  const std::size_t metadata_header_size = (std::size_t{body[2]} << 8) | body[3];
  const std::size_t metadata_size = big_endian_32(body.data() + 4);
  const std::size_t framing = ext_size + metadata_header_size + metadata_size;
  const std::size_t content_size = framing <= body_filled ? body_filled - framing : 0;
  const bool sizes_valid = ext_size >= extended_header_size && framing <= body_filled &&
                           (transform ? content_size == transform_body_size : valid_position_size(content_size));
  if (!sizes_valid) {
    count(counts.rejected_bad_body_size);
    note(describe() + ": header version 2 sizes (extended header " + std::to_string(ext_size) + ", metadata " +
         std::to_string(metadata_header_size) + " + " + std::to_string(metadata_size) + ") leave " +
         std::to_string(content_size) + " content bytes of " + std::to_string(body_filled));
    return Verdict::keep_connection;
  }
  const unsigned char* content = body.data() + ext_size;
  if (!transform) return accept_position(content, content_size);
  // TRANSFORM content: the 3×3 part column by column, then the translation (float32).
  igtl::Matrix4x4 matrix;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) matrix[r][c] = r == c ? 1.0f : 0.0f;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) matrix[r][c] = big_endian_float(content + 4 * (3 * c + r));
  return accept_transform(matrix);
}

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::accept_transform(const igtl::Matrix4x4& matrix) {
  Eigen::Matrix3d linear;
  Eigen::Vector3d translation;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) linear(r, c) = matrix[r][c];
    translation(r) = static_cast<double>(matrix[r][3]) * length_unit_m;
  }
  if (!linear.allFinite() || !translation.allFinite()) {
    count(counts.rejected_non_finite);
    note(describe() + ": non-finite matrix element; message dropped");
    return Verdict::keep_connection;
  }
  // The rotation is the orthogonal polar factor U·Vᵀ: a transform with scaling (as 3D Slicer
  // may send) still gives the tool's orientation; singular or reflecting ones give none.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(linear, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sigma = svd.singularValues();
  const Eigen::Matrix3d rotation = svd.matrixU() * svd.matrixV().transpose();
  if (!(sigma(0) > 0) || sigma(2) <= 1e-6 * sigma(0) || rotation.determinant() < 0) {
    count(counts.rejected_bad_rotation);
    note(describe() + ": the 3x3 part is singular or a reflection; message dropped");
    return Verdict::keep_connection;
  }
  count(counts.transforms_received);
  publish(translation, Eigen::Quaterniond(rotation).normalized());
  return Verdict::keep_connection;
}

OpenIgtLinkParser::Verdict OpenIgtLinkParser::State::accept_position(const unsigned char* content,
                                                                      std::size_t size) {
  // Big-endian float32: x, y, z, then ox, oy, oz (and w in the 28-byte form).
  float values[7] = {0, 0, 0, 0, 0, 0, 1};
  const std::size_t count_read = std::min<std::size_t>(size / 4, 7);  // 3, 6 or 7 (checked with the header)
  for (std::size_t i = 0; i < count_read; ++i) values[i] = big_endian_float(content + 4 * i);
  const Eigen::Vector3d translation = Eigen::Vector3d(values[0], values[1], values[2]) * length_unit_m;
  Eigen::Quaterniond orientation = last_orientation;
  if (count_read >= 6) {
    const Eigen::Vector3d vector(values[3], values[4], values[5]);
    // The 24-byte form leaves w ≥ 0 implicit; a vector part beyond unit length has none.
    const double w =
        count_read == 7 ? static_cast<double>(values[6]) : std::sqrt(std::max(0.0, 1.0 - vector.squaredNorm()));
    orientation = Eigen::Quaterniond(w, vector.x(), vector.y(), vector.z());
  }
  if (!translation.allFinite() || !orientation.coeffs().allFinite()) {
    count(counts.rejected_non_finite);
    note(describe() + ": non-finite position or quaternion; message dropped");
    return Verdict::keep_connection;
  }
  // float32 quaternions are unit to ~1e-7; far from unit means a sender bug, not rounding.
  if (std::abs(orientation.norm() - 1.0) > 1e-2) {
    count(counts.rejected_bad_rotation);
    note(describe() + ": quaternion norm " + to_text(orientation.norm()) + " is not 1; message dropped");
    return Verdict::keep_connection;
  }
  count(counts.positions_received);
  publish(translation, orientation.normalized());
  return Verdict::keep_connection;
}

void OpenIgtLinkParser::State::publish(const Eigen::Vector3d& position_m, const Eigen::Quaterniond& orientation) {
  last_orientation = orientation;
  on_pose(position_m, orientation);
}

OpenIgtLinkParser::OpenIgtLinkParser(std::uint64_t max_message_body_bytes, double length_unit_m, PoseHandler on_pose,
                                     RejectionHandler on_rejection)
    : state_(std::make_unique<State>()) {
  state_->max_message_body_bytes = max_message_body_bytes;
  state_->length_unit_m = length_unit_m;
  state_->on_pose = std::move(on_pose);
  state_->on_rejection = std::move(on_rejection);
}

OpenIgtLinkParser::~OpenIgtLinkParser() = default;

OpenIgtLinkParser::Verdict OpenIgtLinkParser::feed(const unsigned char* data, std::size_t size) {
  return state_->feed(data, size);
}

void OpenIgtLinkParser::reset() noexcept {
  State& s = *state_;
  s.header_filled = 0;
  s.in_body = false;
  s.body_left = 0;
  s.body_filled = 0;
  s.body_use = State::BodyUse::discard;
}

bool OpenIgtLinkParser::inside_message() const noexcept { return state_->in_body || state_->header_filled > 0; }

std::string OpenIgtLinkParser::truncation_note() const {
  const State& s = *state_;
  return s.in_body ? s.describe() + ": connection lost with " + std::to_string(s.body_left) + " body bytes missing"
                   : "connection lost inside a message header (" + std::to_string(s.header_filled) + " of 58 bytes)";
}

const OpenIgtLinkParserCounts& OpenIgtLinkParser::counts() const noexcept { return state_->counts; }

}  // namespace touchstone::realtime::haptics
