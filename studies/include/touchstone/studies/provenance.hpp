#pragma once
/// @file
/// Provenance of a run (git hash, build type, compiler, machine, config hash), content hashes
/// for caching, and atomic file writes.

#include <nlohmann/json.hpp>

#include <string>

namespace touchstone::studies {

/// Lower-case hex SHA-256 of the bytes of `text`.
std::string sha256_hex(const std::string& text);

/// {"git", "build_type", "compiler", "machine", "config_sha256", "time_utc", "touchstone_version"}.
/// `machine` is "hostname, CPU model, N cores".
nlohmann::json provenance(const std::string& config_text);

/// Writes `text` to `path` through a temporary file in the same folder and a rename, so that a
/// reader never sees half a file. Creates parent folders. Throws std::runtime_error naming path.
void write_file_atomically(const std::string& path, const std::string& text);

/// Reads a whole file; throws std::runtime_error naming the path when it cannot be read.
std::string read_file(const std::string& path);

}  // namespace touchstone::studies
