#pragma once
/// @file
/// The fuzz input as a file, for the readers that take a path: one scratch directory per
/// process (libFuzzer's -fork and -jobs run several), the file rewritten for every input.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace touchstone::fuzz {

/// The process's scratch directory, created on first use.
inline const std::filesystem::path& scratch_directory() {
  static const std::filesystem::path directory = [] {
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("touchstone_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(path);
    return path;
  }();
  return directory;
}

/// Writes the input to `name` in the scratch directory and returns the file's path; aborts when
/// the file cannot be written (a broken setup, not a finding in the reader).
inline std::string write_input_file(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const std::string path = (scratch_directory() / name).string();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) std::abort();
  return path;
}

}  // namespace touchstone::fuzz
