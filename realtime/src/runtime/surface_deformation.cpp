#include "touchstone/realtime/runtime/surface_deformation.hpp"

namespace touchstone::realtime::runtime {

DeformationMap make_deformation_map(const mfs::LocalModel& model, const geometry::TriangleSurface& organ,
                                    std::uint64_t model_id) {
  DeformationMap map;
  map.model_id = model_id;
  map.contact_point_m = model.contact.point;
  map.direction = model.contact.direction;
  const double radius = model.settings.sprinkling.local_radius_m;
  std::vector<Eigen::Vector3d> points;
  const auto& vertices = organ.vertices();
  for (int v = 0; v < static_cast<int>(vertices.size()); ++v)
    if ((vertices[v] - model.contact.point).norm() < radius) {
      map.vertices.push_back(v);
      points.push_back(vertices[v]);
    }
  map.unit_maps.assign(points.size(), Eigen::Matrix3d::Zero());
  map.load_offsets.assign(points.size(), Eigen::Vector3d::Zero());
  if (!model.ok() || points.empty()) return map;

  // u_h at the vertices for U = e_x, e_y, e_z and for the loads alone. A vertex outside every
  // support (possible right at the cut) keeps zero: it stays at rest.
  std::vector<Eigen::Vector3d> displacement;
  std::vector<bool> covered(points.size(), true);
  for (int column = 0; column < 3; ++column) {
    displacement_at(model, model.unit_response.col(column), points, displacement);
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!displacement[i].allFinite()) covered[i] = false;
      else map.unit_maps[i].col(column) = displacement[i];
    }
  }
  if (model.load_response.size() == model.unit_response.rows()) {
    displacement_at(model, model.load_response, points, displacement);
    for (std::size_t i = 0; i < points.size(); ++i)
      if (displacement[i].allFinite()) map.load_offsets[i] = displacement[i];
  }
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!covered[i] || (map.unit_maps[i].isZero(0) && map.load_offsets[i].isZero(0))) {
      map.unit_maps[i].setZero();
      map.load_offsets[i].setZero();
      ++map.outside_supports;
    }
  return map;
}

DeformedSurface::DeformedSurface(const geometry::TriangleSurface& organ)
    : organ_(organ), vertices_(organ.vertices()), displacement_(organ.vertices().size(), Eigen::Vector3d::Zero()) {}

int DeformedSurface::update(const DeformationMap* map, const Eigen::Vector3d& tool_displacement_m, bool apply) {
  int written = 0;
  for (const int v : moved_) {
    vertices_[v] = organ_.vertices()[v];
    displacement_[v].setZero();
    ++written;
  }
  moved_.clear();
  if (map == nullptr || !apply) return written;
  for (std::size_t i = 0; i < map->vertices.size(); ++i) {
    const int v = map->vertices[i];
    const Eigen::Vector3d u = map->unit_maps[i] * tool_displacement_m + map->load_offsets[i];
    displacement_[v] = u;
    vertices_[v] = organ_.vertices()[v] + u;
    moved_.push_back(v);
    ++written;
  }
  return written;
}

}  // namespace touchstone::realtime::runtime
