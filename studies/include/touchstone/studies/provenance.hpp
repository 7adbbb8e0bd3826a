#pragma once
/// @file
/// Provenance of a run (git hash, build type, compiler, machine, config hash), content hashes
/// for caching.

#include <nlohmann/json.hpp>

#include <string>

namespace touchstone::studies {

/// Lower-case hex SHA-256 of the bytes of `text`.
std::string sha256_hex(const std::string& text);

/// {"git", "build_type", "compiler", "machine", "blas", "heap_huge_pages", "config_sha256", "time_utc",
/// "touchstone_version"}.
/// `machine` is "hostname, CPU model, N cores".
nlohmann::json provenance(const std::string& config_text);

}  // namespace touchstone::studies
