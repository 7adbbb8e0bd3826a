#pragma once
// A directory of its own per test and process (ctest -j runs test processes in parallel),
// removed with everything in it when the test ends.

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace touchstone::testing {

class TemporaryDirectory {
 public:
  /// <temp>/touchstone_<prefix>_<pid>_<count>
  explicit TemporaryDirectory(const std::string& prefix)
      : path_(std::filesystem::temp_directory_path() /
              ("touchstone_" + prefix + "_" + std::to_string(::getpid()) + "_" + std::to_string(count_++))) {
    std::filesystem::create_directories(path_);
  }
  ~TemporaryDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;

  /// Writes `content` (bytes as given) to a file of this directory and returns its path.
  std::string file(const std::string& name, const std::string& content) const {
    const std::string path = (path_ / name).string();
    std::ofstream(path, std::ios::binary) << content;
    return path;
  }
  std::string path(const std::string& name) const { return (path_ / name).string(); }

 private:
  static inline int count_ = 0;
  std::filesystem::path path_;
};

}  // namespace touchstone::testing
