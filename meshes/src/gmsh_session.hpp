#pragma once
// Internal to touchstone::meshes: one gmsh session at a time for the whole library.

#include <mutex>
#include <string>

namespace touchstone::meshes::internal {

/// gmsh is one global state: every use in this library (benchmark meshes, organ surfaces) holds
/// this session, which serialises them on one mutex and runs each between initialize and
/// finalize, so options and models never leak from one call into the next.
class GmshSession {
 public:
  explicit GmshSession(const std::string& model_name);
  ~GmshSession();
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

 private:
  std::lock_guard<std::mutex> lock_;
};

/// Writes the current gmsh model's mesh to msh_path whole or not at all: gmsh::write reports no
/// failed write, so the file is written beside its path, checked to end with an $End line and
/// renamed into place. Throws std::runtime_error naming the path.
void write_msh_whole(const std::string& msh_path);

/// Throws std::runtime_error when `path` cannot be opened for writing (before any meshing work).
void require_writable(const std::string& path);

}  // namespace touchstone::meshes::internal
