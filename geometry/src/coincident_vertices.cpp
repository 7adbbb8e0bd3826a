// The welding map: each vertex to the lowest-numbered earlier vertex within a tolerance, found
// through a uniform grid.
#include "touchstone/geometry/triangle_surface.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <numeric>
#include <unordered_map>
#include <vector>

namespace touchstone::geometry {

using Eigen::Vector3d;

std::vector<int> coincident_vertices(const std::vector<Vector3d>& vertices, double tolerance_m,
                                     const std::vector<char>& used) {
  const int count = static_cast<int>(vertices.size());
  std::vector<int> representative(vertices.size());
  std::iota(representative.begin(), representative.end(), 0);
  const auto active = [&](int v) {
    return vertices[v].allFinite() && (used.empty() || (static_cast<std::size_t>(v) < used.size() && used[v]));
  };
  Vector3d lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
  Vector3d upper = -lower;
  for (int v = 0; v < count; ++v) {
    if (!active(v)) continue;
    lower = lower.cwiseMin(vertices[v]);
    upper = upper.cwiseMax(vertices[v]);
  }
  if (!(lower[0] <= upper[0])) return representative;
  const double tolerance = tolerance_m > 0 ? tolerance_m : 0.0;  // NaN and negative: exact
  // Grid cells at least as wide as the tolerance: points within reach lie in the 27 cells
  // around. The floor on the width keeps cell indices well inside 64 bits.
  const double width = std::max({tolerance, 1e-15 * (upper - lower).norm(), std::numeric_limits<double>::min()});
  using Cell = std::array<long long, 3>;
  struct CellHash {
    std::size_t operator()(const Cell& c) const {
      std::size_t h = std::hash<long long>()(c[0]);
      h = h * 1000003u ^ std::hash<long long>()(c[1]);
      return h * 1000003u ^ std::hash<long long>()(c[2]);
    }
  };
  std::unordered_map<Cell, std::vector<int>, CellHash> cells;
  for (int v = 0; v < count; ++v) {
    if (!active(v)) continue;
    Cell cell;
    for (int i = 0; i < 3; ++i) cell[i] = static_cast<long long>(std::floor((vertices[v][i] - lower[i]) / width));
    int best = -1;
    for (long long dx = -1; dx <= 1; ++dx) {
      for (long long dy = -1; dy <= 1; ++dy) {
        for (long long dz = -1; dz <= 1; ++dz) {
          const auto found = cells.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (found == cells.end()) continue;
          for (const int r : found->second) {
            if ((best < 0 || r < best) && (vertices[r] - vertices[v]).norm() <= tolerance) best = r;
          }
        }
      }
    }
    if (best >= 0) {
      representative[v] = best;
    } else {
      cells[cell].push_back(v);
    }
  }
  return representative;
}

}  // namespace touchstone::geometry
