#include "gmsh_session.hpp"

#include <gmsh.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace touchstone::meshes::internal {

namespace {

std::mutex& gmsh_mutex() {
  static std::mutex mutex;
  return mutex;
}

}  // namespace

GmshSession::GmshSession(const std::string& model_name) : lock_(gmsh_mutex()) {
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::model::add(model_name);
}

GmshSession::~GmshSession() {
  try {
    gmsh::finalize();
  } catch (...) {
    // Nothing useful can be done about a failed teardown while unwinding.
  }
}

/// gmsh::write reports no failed write: a full disk or a file-size limit leaves a truncated file
/// that a later reader would take for a bad mesh. The file is written beside its path, checked
/// to end with a section's $End line, and renamed into place (readers never see a partial file).
void write_msh_whole(const std::string& msh_path) {
  const std::string partial = msh_path + ".partial.msh";
  gmsh::write(partial);
  std::ifstream in(partial, std::ios::binary | std::ios::ate);
  const std::streamoff size = in ? static_cast<std::streamoff>(in.tellg()) : -1;
  std::string tail(static_cast<std::size_t>(std::max<std::streamoff>(0, std::min<std::streamoff>(size, 64))), '\0');
  if (size > 0) {
    in.seekg(size - static_cast<std::streamoff>(tail.size()));
    in.read(tail.data(), static_cast<std::streamsize>(tail.size()));
  }
  while (!tail.empty() && (tail.back() == '\n' || tail.back() == '\r')) tail.pop_back();
  const std::size_t line = tail.rfind('\n');
  const std::string last_line = line == std::string::npos ? tail : tail.substr(line + 1);
  if (last_line.rfind("$End", 0) != 0) {
    std::remove(partial.c_str());
    throw std::runtime_error("cannot write '" + msh_path + "': gmsh wrote an incomplete file (" +
                             std::to_string(std::max<std::streamoff>(size, 0)) +
                             " bytes; is the disk full, or a file-size limit reached?)");
  }
  std::error_code error;
  std::filesystem::rename(partial, msh_path, error);
  if (error) throw std::runtime_error("cannot write '" + msh_path + "': " + error.message());
}

void require_writable(const std::string& path) {
  if (path.empty()) throw std::runtime_error("the output path is empty");
  const bool existed = std::ifstream(path).good();
  const bool writable = std::ofstream(path, std::ios::out | std::ios::app).good();
  if (!existed) std::remove(path.c_str());
  if (!writable) throw std::runtime_error("cannot open the output file for writing");
}

}  // namespace touchstone::meshes::internal
