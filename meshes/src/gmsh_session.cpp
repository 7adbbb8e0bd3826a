#include "gmsh_session.hpp"

#include <gmsh.h>

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

}  // namespace touchstone::meshes::internal
