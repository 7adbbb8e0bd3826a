#pragma once
/// @file
/// The check every reader of a user's file makes before it opens it: a folder, a device such as
/// /dev/zero, or a named pipe opens as a stream and then fails obscurely, never ends, or blocks
/// until a writer comes.

#include <filesystem>
#include <string>
#include <system_error>

namespace touchstone::geometry {

/// Why `path` (symbolic links followed) is not a regular file: "it is a folder" or "it is a
/// device, pipe or socket, not a regular file"; empty when it is one or does not exist (opening
/// it then names the error).
inline std::string non_regular_file_reason(const std::string& path) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (error || !std::filesystem::exists(status) || std::filesystem::is_regular_file(status)) return {};
  if (std::filesystem::is_directory(status)) return "it is a folder";
  return "it is a device, pipe or socket, not a regular file";
}

}  // namespace touchstone::geometry
