#pragma once
/// @file
/// The probe points where both models report displacement: the axis below the tool and a
/// surface meridian out to 8a, placed from the benchmark geometry so that the MFS engine and the
/// FEM reference are sampled at identical points.

#include "touchstone/meshes/benchmark_geometry.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace touchstone::studies {

struct Probe {
  std::string name;           ///< "axis_2a", "meridian_1.5a", …
  Eigen::Vector3d position_m;
};

/// Contact point (centre of the tool patch) [m] and the outward surface normal there: R n on
/// the hemisphere benchmarks; the origin and e_z on B1 (the centre of the cylinder's top face).
Eigen::Vector3d contact_point(const meshes::MeshParameters& geometry);
Eigen::Vector3d outward_normal(const meshes::MeshParameters& geometry);

/// Axis points c + s·d for s/a ∈ {0.25, 0.5, 1, 2, 4, 8} (tool direction d), and surface points
/// at distance ρ/a ∈ {0, 0.5, 1.5, 2, 3, 4, 6, 8} from the contact point along the meridian
/// (the patch edge ρ = a, where the stress is singular, is left out). On B1's flat top the
/// "meridian" points are the radial line c + ρ e_x (same names, so results compare across
/// benchmarks). Points that would fall outside the domain (B3 with a small L) are dropped.
std::vector<Probe> indentation_probes(const meshes::MeshParameters& geometry,
                                      const Eigen::Vector3d& tool_direction);

}  // namespace touchstone::studies
