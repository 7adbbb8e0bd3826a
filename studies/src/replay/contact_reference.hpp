#pragma once
/// @file
/// Private to the palpation replay: one contact of the real-time run, verified against the
/// reference FEM of the whole organ (its mesh levels, Richardson's extrapolation, and the
/// real-time model rebuilt at the same contact). replay_run.cpp spreads the contacts over the
/// MPI ranks and compares the forces tick by tick.

#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/studies/palpation_replay.hpp"
#include "touchstone/studies/sim_scene.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace touchstone::studies::replay {

/// A contact to verify: the model's frame, as every rank needs it.
struct Contact {
  std::uint64_t model_id = 0;
  Eigen::Vector3d point_m = Eigen::Vector3d::Zero(), direction = -Eigen::Vector3d::UnitZ();
  std::string label() const { return "model" + std::to_string(model_id); }
};

/// Contacts as 7 numbers each (id, point [m], direction), for an MPI broadcast, and back.
std::vector<double> pack(const std::vector<Contact>& contacts);
std::vector<Contact> unpack(const std::vector<double>& values);

/// The reference's organ problem of the study and the scene, its contact not yet set.
meshes::MeshParameters reference_geometry(const PalpationReplayStudy& study,
                                          const realtime::runtime::SceneSettings& scene,
                                          const std::string& organ_file, double organ_unit_scale);

/// One contact's reference (levels, Richardson) and the real-time model rebuilt at the same
/// contact: K_t again (the run's must be reproduced exactly) and its surface deformation map.
/// Solved on this rank alone; finished levels come from the cache.
nlohmann::json verify_contact(const Contact& contact, const PalpationReplayStudy& study, const SimScene& scene,
                              const geometry::TriangleSurface& organ, const std::string& organ_file,
                              double organ_unit_scale, const ReplayRunOptions& options);

}  // namespace touchstone::studies::replay
