#pragma once
/// @file
/// A solution field on a mesh's points, read from and written to VTK XML unstructured grids
/// (.vtu, or the .pvtu + pieces deal.II writes under MPI): how the study runner puts the MFS
/// field on the FEM reference's points and writes both, and their difference, for ParaView.

#include <Eigen/Core>

#include <string>
#include <utility>
#include <vector>

namespace touchstone::meshes {

/// The points of a grid [m] and one 3-component point array on them.
struct PointField {
  std::vector<Eigen::Vector3d> points_m;
  std::vector<Eigen::Vector3d> values;
};

/// Reads the points and the 3-component point array `array_name` of a .vtu or .pvtu. Throws
/// std::runtime_error naming the file (unreadable, no points) or the array (missing, not 3
/// components).
PointField read_point_field(const std::string& path, const std::string& array_name);

/// Writes `reference_path`'s grid (cells and every array, pieces merged) to `output_vtu` with
/// extra point arrays: 3-component `vectors` and 1-component `scalars`, one value per point of
/// the reference. Throws std::invalid_argument when a size differs from the point count, and
/// std::runtime_error naming a file that cannot be read or written.
void write_with_point_arrays(const std::string& reference_path, const std::string& output_vtu,
                             const std::vector<std::pair<std::string, std::vector<Eigen::Vector3d>>>& vectors,
                             const std::vector<std::pair<std::string, std::vector<double>>>& scalars);

}  // namespace touchstone::meshes
