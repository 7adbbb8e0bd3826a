#pragma once
/// @file
/// The OpenIGTLink byte-stream parser of the OpenIGTLink device: bytes as they arrive on the
/// socket (in pieces of any size) → tool poses, or a reason to drop a message or close the
/// connection. No sockets and no threads: the device's network thread feeds it, and so can a
/// test or a fuzzer.
///
/// Understood: TRANSFORM (48-byte body) and POSITION (12, 24 or 28 bytes) with header version 1,
/// and both with header version 2 (an extended header and metadata around the content). Every
/// other type is skipped unread. A message is checked before a pose leaves the parser: header
/// version and type name, announced body size (never stored beyond `max_message_body_bytes`),
/// body size for the type, CRC-64, finite numbers and a usable rotation. What cannot be
/// re-synchronized (a garbage header, an oversized body) asks to close the connection; anything
/// else drops only the message. Every outcome is counted.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace touchstone::realtime::haptics {

/// The parser's outcome counts since construction, readable from any thread at any time.
struct OpenIgtLinkParserCounts {
  std::atomic<std::uint64_t> transforms_received{0}, positions_received{0}, messages_skipped{0},
      rejected_bad_header{0}, rejected_oversized{0}, rejected_bad_body_size{0}, rejected_bad_crc{0},
      rejected_non_finite{0}, rejected_bad_rotation{0};
};

class OpenIgtLinkParser {
 public:
  /// What the connection should do after the bytes fed.
  enum class Verdict { keep_connection, close_connection };
  /// Receives every accepted pose: the tool tip [m] and a unit orientation.
  using PoseHandler = std::function<void(const Eigen::Vector3d& position_m, const Eigen::Quaterniond& orientation)>;
  /// Receives a one-line reason for every message dropped or connection to close.
  using RejectionHandler = std::function<void(const std::string& reason)>;

  /// `max_message_body_bytes`: larger announced bodies close the connection;
  /// `length_unit_m`: metres per length unit of the peer (0.001 for millimetres).
  OpenIgtLinkParser(std::uint64_t max_message_body_bytes, double length_unit_m, PoseHandler on_pose,
                    RejectionHandler on_rejection);
  ~OpenIgtLinkParser();
  OpenIgtLinkParser(const OpenIgtLinkParser&) = delete;
  OpenIgtLinkParser& operator=(const OpenIgtLinkParser&) = delete;

  /// Parses the next `size` bytes of the stream; the handlers are called before it returns.
  /// close_connection: framing is lost, feed no more bytes of this stream (reset() first).
  Verdict feed(const unsigned char* data, std::size_t size);
  /// Forgets a partly received message (a new connection starts at a header). The last
  /// orientation, which a 12-byte POSITION keeps, is kept.
  void reset() noexcept;
  /// True when a message is partly received.
  bool inside_message() const noexcept;
  /// What is missing of the partly received message, for "connection lost" notes.
  std::string truncation_note() const;
  const OpenIgtLinkParserCounts& counts() const noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace touchstone::realtime::haptics
