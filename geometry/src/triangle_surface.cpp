// The TriangleSurface: its normals (face, edge and angle-weighted vertex pseudo-normals) and the
// AABB tree behind closest point, inside/outside and signed distance. Validation is in
// surface_validation.cpp.
#include "touchstone/geometry/triangle_surface.hpp"

#include "surface_analysis.hpp"
#include "touchstone/geometry/closest_point_on_triangle.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::geometry {

namespace {

using Eigen::Vector3d;
using Eigen::Vector3i;

constexpr int leaf_size = 4;
// Median splits halve the triangle count per level, so the depth is at most log2(n) + 1 and the
// traversal stack (one deferred child per level) never exceeds 64 entries.
constexpr int max_stack = 64;

inline double box_distance_squared(const Vector3d& lower, const Vector3d& upper, const Vector3d& x) {
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    const double below = lower[i] - x[i];
    const double above = x[i] - upper[i];
    const double gap = std::max({below, above, 0.0});
    sum += gap * gap;
  }
  return sum;
}

}  // namespace

TriangleSurface::TriangleSurface(std::vector<Vector3d> vertices, std::vector<Vector3i> triangles,
                                 const std::string& source)
    : TriangleSurface(std::move(vertices), std::move(triangles), source, SurfaceLabels{}) {}

TriangleSurface::TriangleSurface(std::vector<Vector3d> vertices, std::vector<Vector3i> triangles,
                                 const std::string& source, const SurfaceLabels& labels)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
  const detail::SurfaceAnalysis analysis = detail::analyse_surface(vertices_, triangles_, source, labels);
  if (!analysis.defects.empty()) {
    std::string message = analysis.defects.front().message;
    if (analysis.defects.size() > 1) {
      message += " (further defects:";
      for (std::size_t i = 1; i < analysis.defects.size(); ++i) {
        message += std::string(i == 1 ? " " : ", ") + to_string(analysis.defects[i].kind);
      }
      message += ")";
    }
    throw std::invalid_argument(message);
  }
  const std::vector<int>& neighbours = analysis.neighbours;
  volume_m3_ = analysis.volume_m3;

  const int n = static_cast<int>(triangles_.size());
  face_normals_.resize(n);
  for (int t = 0; t < n; ++t) {
    const Vector3d& a = vertices_[triangles_[t][0]];
    const Vector3d normal = (vertices_[triangles_[t][1]] - a).cross(vertices_[triangles_[t][2]] - a);
    const double area = 0.5 * normal.norm();
    face_normals_[t] = normal / (2 * area);
    area_m2_ += area;
  }

  vertex_normals_.assign(vertices_.size(), Vector3d::Zero());
  edge_normals_.resize(3 * triangles_.size());
  for (int t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) {
      const Vector3d& corner = vertices_[triangles_[t][k]];
      const Vector3d along = vertices_[triangles_[t][(k + 1) % 3]] - corner;
      const Vector3d across = vertices_[triangles_[t][(k + 2) % 3]] - corner;
      const double angle = std::atan2(along.cross(across).norm(), along.dot(across));
      vertex_normals_[triangles_[t][k]] += angle * face_normals_[t];
      edge_normals_[3 * t + k] = (face_normals_[t] + face_normals_[neighbours[3 * t + k]]).normalized();
    }
  }
  for (Vector3d& normal : vertex_normals_) {
    if (normal.squaredNorm() > 0) normal.normalize();
  }
  build_tree();
}

void TriangleSurface::build_tree() {
  const int n = static_cast<int>(triangles_.size());
  std::vector<Vector3d> centroids(n);
  for (int t = 0; t < n; ++t) {
    centroids[t] = (vertices_[triangles_[t][0]] + vertices_[triangles_[t][1]] + vertices_[triangles_[t][2]]) / 3;
  }
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0);
  nodes_.clear();
  nodes_.reserve(n);  // leaves hold at least two triangles, so there are fewer than n nodes

  struct Task {
    int node, begin, end;
  };
  const Node empty{Vector3d::Zero(), Vector3d::Zero(), 0, 0};
  std::vector<Task> tasks{{0, 0, n}};
  nodes_.push_back(empty);
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    Vector3d lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
    Vector3d upper = -lower;
    Vector3d centroid_lower = lower;
    Vector3d centroid_upper = upper;
    for (int i = task.begin; i < task.end; ++i) {
      for (int k = 0; k < 3; ++k) {
        lower = lower.cwiseMin(vertices_[triangles_[order_[i]][k]]);
        upper = upper.cwiseMax(vertices_[triangles_[order_[i]][k]]);
      }
      centroid_lower = centroid_lower.cwiseMin(centroids[order_[i]]);
      centroid_upper = centroid_upper.cwiseMax(centroids[order_[i]]);
    }
    nodes_[task.node].lower = lower;
    nodes_[task.node].upper = upper;
    if (task.end - task.begin <= leaf_size) {
      nodes_[task.node].first = task.begin;
      nodes_[task.node].count = task.end - task.begin;
      continue;
    }
    Eigen::Index axis = 0;
    (centroid_upper - centroid_lower).maxCoeff(&axis);
    const int middle = task.begin + (task.end - task.begin) / 2;
    std::nth_element(order_.begin() + task.begin, order_.begin() + middle, order_.begin() + task.end,
                     [&](int p, int q) { return centroids[p][axis] < centroids[q][axis]; });
    const int child = static_cast<int>(nodes_.size());
    nodes_[task.node].first = child;
    nodes_[task.node].count = 0;
    nodes_.push_back(empty);
    nodes_.push_back(empty);
    tasks.push_back({child, task.begin, middle});
    tasks.push_back({child + 1, middle, task.end});
  }

  // Corners in leaf order: a leaf's triangles are contiguous in memory. Each vertex is owned by
  // its first corner in that order, so that vertices_within() meets it once.
  corners_.resize(3 * static_cast<std::size_t>(n));
  owns_vertex_.assign(3 * static_cast<std::size_t>(n), 0);
  std::vector<char> owned(vertices_.size(), 0);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const int v = triangles_[order_[i]][k];
      corners_[3 * i + k] = vertices_[v];
      owns_vertex_[3 * i + k] = owned[v] == 0;
      owned[v] = 1;
    }
  }
}

std::vector<int> TriangleSurface::vertices_within(const Vector3d& centre_m, double radius_m) const {
  std::vector<int> found;
  if (!centre_m.allFinite() || !(radius_m >= 0) || nodes_.empty()) return found;
  const double reach = radius_m * radius_m;
  // Depth first, one deferred child per level, as project() does.
  std::array<int, max_stack> stack;
  int size = 0;
  stack[size++] = 0;
  while (size > 0) {
    const Node& node = nodes_[stack[--size]];
    if (box_distance_squared(node.lower, node.upper, centre_m) > reach) continue;
    if (node.count > 0) {
      for (int corner = 3 * node.first; corner < 3 * (node.first + node.count); ++corner) {
        if (owns_vertex_[corner] && (corners_[corner] - centre_m).squaredNorm() <= reach)
          found.push_back(triangles_[order_[corner / 3]][corner % 3]);
      }
      continue;
    }
    stack[size++] = node.first + 1;
    stack[size++] = node.first;
  }
  std::sort(found.begin(), found.end());
  return found;
}

SurfaceProjection TriangleSurface::project(const Vector3d& x) const {
  SurfaceProjection result;
  // A non-finite query has no closest point: triangle -1 and a NaN distance (no throw on a
  // real-time path).
  if (!x.allFinite()) {
    result.distance_m = std::numeric_limits<double>::quiet_NaN();
    return result;
  }
  double best = std::numeric_limits<double>::infinity();
  int best_slot = -1;
  int best_feature = face_feature;
  Vector3d best_point = Vector3d::Zero();

  std::array<std::pair<int, double>, max_stack> stack;
  int size = 0;
  stack[size++] = {0, box_distance_squared(nodes_[0].lower, nodes_[0].upper, x)};
  while (size > 0) {
    const auto [index, box_distance] = stack[--size];
    if (box_distance >= best) continue;
    const Node& node = nodes_[index];
    if (node.count > 0) {
      for (int slot = node.first; slot < node.first + node.count; ++slot) {
        // The distance to the triangle's plane is a lower bound that costs one dot product.
        const double height = (x - corners_[3 * slot]).dot(face_normals_[order_[slot]]);
        if (height * height >= best) continue;
        int feature = face_feature;
        const Vector3d point =
            closest_on_triangle(x, corners_[3 * slot], corners_[3 * slot + 1], corners_[3 * slot + 2], feature);
        const double distance = (point - x).squaredNorm();
        if (distance < best) {
          best = distance;
          best_slot = slot;
          best_feature = feature;
          best_point = point;
        }
      }
      continue;
    }
    int near = node.first;
    int far = node.first + 1;
    double near_distance = box_distance_squared(nodes_[near].lower, nodes_[near].upper, x);
    double far_distance = box_distance_squared(nodes_[far].lower, nodes_[far].upper, x);
    if (far_distance < near_distance) {
      std::swap(near, far);
      std::swap(near_distance, far_distance);
    }
    // The nearer child goes on top, so it is searched first and tightens `best` for the other.
    if (far_distance < best) stack[size++] = {far, far_distance};
    if (near_distance < best) stack[size++] = {near, near_distance};
  }

  // Coordinates so large that every squared distance overflows: "infinitely far outside".
  if (best_slot < 0) {
    result.distance_m = std::numeric_limits<double>::infinity();
    return result;
  }
  const int triangle = order_[best_slot];
  result.point = best_point;
  result.distance_m = std::sqrt(best);
  result.triangle = triangle;
  if (best_feature == face_feature) {
    result.normal = face_normals_[triangle];
  } else if (best_feature < first_vertex_feature) {
    result.normal = edge_normals_[3 * triangle + best_feature - first_edge_feature];
  } else {
    result.normal = vertex_normals_[triangles_[triangle][best_feature - first_vertex_feature]];
  }
  return result;
}

bool TriangleSurface::contains(const Vector3d& x) const {
  const SurfaceProjection closest = project(x);
  // Points on the surface (x == closest point) count as inside.
  return closest.triangle >= 0 && (x - closest.point).dot(closest.normal) <= 0;
}

double TriangleSurface::signed_distance(const Vector3d& x) const {
  const SurfaceProjection closest = project(x);
  if (closest.triangle < 0) return closest.distance_m;
  return (x - closest.point).dot(closest.normal) <= 0 ? -closest.distance_m : closest.distance_m;
}

double TriangleSurface::area_m2() const { return area_m2_; }

double TriangleSurface::volume_m3() const { return volume_m3_; }

}  // namespace touchstone::geometry
