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

}  // namespace touchstone::meshes::internal
