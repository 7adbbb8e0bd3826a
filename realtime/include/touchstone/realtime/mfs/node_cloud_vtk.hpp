#pragma once
/// @file
/// The MFS node cloud as a VTK XML UnstructuredGrid (.vtu, ASCII) for ParaView. Written by
/// hand, like deal.II's DataOut, so that touchstone::realtime needs no VTK library.

#include "touchstone/realtime/mfs/node_cloud.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace touchstone::realtime::mfs {

/// Optional per-node fields written next to the cloud (empty = not written).
struct NodeCloudFields {
  Eigen::VectorXd displacement_m;  ///< u_h at each node (3N: x, y, z per node) [m]
  Eigen::VectorXd parameters_m;    ///< nodal parameters u_J (3N) [m]; MLS does not interpolate, so ≠ u_h
  std::vector<double> rcond;       ///< reciprocal condition number of the moment matrix at each node [-]
};

/// Writes the nodes as VTK_VERTEX cells in a .vtu (ASCII XML, opens in ParaView). Point data:
///   sphere_radius_m                  support radius [m]
///   spacing_m                        local node spacing [m]
///   kind                             int: 0 interior, 1 free_surface, 2 tool_patch, 3 cut (NodeKind)
///   normal                           outward unit normal (zero on interior nodes)
///   row_type                         3 ints per node, one per row: 0 navier, 1 traction, 2 dirichlet
///   body_force_N_per_m3              b [N/m³], when the cloud has one
///   displacement_m, parameters_m,
///   rcond                            the non-empty members of `fields`
/// Extra collocation points (if any) go to a second file, collocation_points_vtu_path(path),
/// with kind, normal, row_type and spacing_m; with none, no second file is written (an older
/// one is left alone).
/// Doubles are written with max_digits10 digits, so they read back bit for bit. Each file is
/// written to `<file>.tmp` and renamed, so a reader never sees a half-written file.
/// Throws std::invalid_argument naming the field when a cloud member or a field has the wrong
/// size, or holds a NaN/inf (VTK's ASCII reader does not read those back reliably); nothing is
/// written then.
/// Throws std::runtime_error naming the path when a file cannot be written.
void write_node_cloud_vtu(const NodeCloud& cloud, const NodeCloudFields& fields, const std::string& path);

/// Where write_node_cloud_vtu puts the extra collocation points: `<stem>_collocation_points.vtu`,
/// with `<stem>` = `path` less a trailing ".vtu".
std::string collocation_points_vtu_path(const std::string& path);

}  // namespace touchstone::realtime::mfs
