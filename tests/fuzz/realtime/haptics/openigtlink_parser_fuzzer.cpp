// libFuzzer harness of the OpenIGTLink byte-stream parser (what a peer sends the OpenIGTLink
// device over TCP). The first byte's low 7 bits set the size of the pieces the rest arrives in,
// as recv() splits a stream anywhere; after a close_connection verdict the parser is reset and
// fed the remaining bytes, as the next connection would be. With the first byte's high bit set
// the harness first writes the right CRC-64 into every header it can frame: a fuzzer cannot
// forge a checksum, and without this nothing past the CRC check would be reached. Every pose it lets through must be finite
// with a unit orientation (the haptic loop takes it on trust) and every rejection must say why:
// anything else is a finding, as is an exception, a sanitizer report or a hang.
#include "touchstone/realtime/haptics/openigtlink_parser.hpp"

#include <igtl_util.h>

#include <algorithm>
#include <cmath>
#include <vector>
#include <cstdio>
#include <cstdlib>

namespace {

namespace haptics = touchstone::realtime::haptics;

void require_usable_pose(const Eigen::Vector3d& position_m, const Eigen::Quaterniond& orientation) {
  if (position_m.allFinite() && orientation.coeffs().allFinite() && std::abs(orientation.norm() - 1.0) < 1e-6)
    return;
  std::fprintf(stderr, "parser published position (%g, %g, %g) m, orientation norm %g\n", position_m.x(),
               position_m.y(), position_m.z(), orientation.norm());
  std::abort();
}

void require_reason(const std::string& reason) {
  if (!reason.empty()) return;
  std::fprintf(stderr, "parser rejected a message without a reason\n");
  std::abort();
}

/// Walks the stream as a sequence of version 1/2 messages (58-byte header, then the body its
/// big-endian size field announces) and writes each complete body's CRC-64 into its header.
void fix_checksums(std::vector<unsigned char>& stream) {
  constexpr std::size_t header_size = 58, body_size_offset = 42, crc_offset = 50;
  std::size_t at = 0;
  while (stream.size() - at >= header_size) {
    std::uint64_t body_size = 0;
    for (std::size_t i = 0; i < 8; ++i) body_size = (body_size << 8) | stream[at + body_size_offset + i];
    if (body_size > stream.size() - at - header_size) return;
    unsigned char* body = stream.data() + at + header_size;
    const std::uint64_t crc = crc64(body, body_size, crc64(nullptr, 0, 0));
    for (std::size_t i = 0; i < 8; ++i) stream[at + crc_offset + i] = static_cast<unsigned char>(crc >> (56 - 8 * i));
    at += header_size + body_size;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t piece_size = std::size_t{data[0] & 0x7fu} + 1;
  std::vector<unsigned char> stream(data + 1, data + size);
  if (data[0] & 0x80u) fix_checksums(stream);
  const unsigned char* bytes = stream.data();
  size = stream.size();
  // The device's defaults: 1 MiB bodies at most, peer lengths in millimetres.
  haptics::OpenIgtLinkParser parser(std::uint64_t{1} << 20, 1e-3, require_usable_pose, require_reason);
  while (size > 0) {
    const std::size_t take = std::min(size, piece_size);
    if (parser.feed(bytes, take) == haptics::OpenIgtLinkParser::Verdict::close_connection) parser.reset();
    bytes += take;
    size -= take;
  }
  if (parser.inside_message()) require_reason(parser.truncation_note());
  return 0;
}
