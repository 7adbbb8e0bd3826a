#pragma once
/// @file
/// The deformed organ for graphics: the local MFS field applied to the surface
/// vertices inside the local domain — and only to them. The field is linear in the tool
/// displacement, so the model loop precomputes, once per local model, a 3×3 map per vertex
/// (u_v = G_v U + g_v); a graphics frame is then one 3×3 product per local vertex.

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace touchstone::realtime::runtime {

struct DeformationMap {
  std::uint64_t model_id = 0;
  Eigen::Vector3d contact_point_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  std::vector<int> vertices;                  ///< surface vertices inside the local domain
  std::vector<Eigen::Matrix3d> unit_maps;     ///< G_v: displacement per unit tool displacement
  std::vector<Eigen::Vector3d> load_offsets;  ///< g_v: displacement under the loads alone [m]
  int outside_supports = 0;                   ///< vertices of the ball no MLS support covers (left still)
};

/// The map of every organ vertex within the local radius of the model's contact point.
DeformationMap make_deformation_map(const mfs::LocalModel& model, const geometry::TriangleSurface& organ,
                                    std::uint64_t model_id);

/// The deformed organ: a buffer of vertex positions that starts at the rest positions and is
/// updated in place, touching only the local vertices of the current and the previous frame.
class DeformedSurface {
 public:
  explicit DeformedSurface(const geometry::TriangleSurface& organ);
  /// Applies `map` for the tool displacement U [m] (nullptr or !apply: back to rest). Returns
  /// the number of vertices written (restored + moved).
  int update(const DeformationMap* map, const Eigen::Vector3d& tool_displacement_m, bool apply);
  const std::vector<Eigen::Vector3d>& vertices_m() const noexcept { return vertices_; }
  const std::vector<Eigen::Vector3d>& displacement_m() const noexcept { return displacement_; }
  int moved_vertices() const noexcept { return static_cast<int>(moved_.size()); }

 private:
  const geometry::TriangleSurface& organ_;
  std::vector<Eigen::Vector3d> vertices_, displacement_;
  std::vector<int> moved_;
};

}  // namespace touchstone::realtime::runtime
