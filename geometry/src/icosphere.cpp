#include "touchstone/geometry/icosphere.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

namespace touchstone::geometry {

TriangleMeshData icosphere(int level, double radius_m) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  TriangleMeshData mesh;
  mesh.vertices = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                   {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                    {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < level; ++l) {
    // Each edge is split once: its midpoint is shared by the two triangles on it.
    std::map<std::pair<int, int>, int> midpoints;
    const auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto found = midpoints.find(key);
      if (found != midpoints.end()) return found->second;
      mesh.vertices.push_back(0.5 * (mesh.vertices[a] + mesh.vertices[b]));
      return midpoints[key] = static_cast<int>(mesh.vertices.size()) - 1;
    };
    std::vector<Eigen::Vector3i> finer;
    for (const Eigen::Vector3i& t : mesh.triangles) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      finer.insert(finer.end(), {{t[0], ab, ca}, {t[1], bc, ab}, {t[2], ca, bc}, {ab, bc, ca}});
    }
    mesh.triangles = std::move(finer);
  }
  for (Eigen::Vector3d& v : mesh.vertices) v *= radius_m / v.norm();
  return mesh;
}

}  // namespace touchstone::geometry
