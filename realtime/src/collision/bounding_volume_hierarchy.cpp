// The bounding-volume hierarchy (OBB or AABB) over a triangle surface: settings, the top-down
// build, the collapse into 4-wide nodes and refit. The entry grid and its cover nodes are in
// bounding_volume_hierarchy_entry_grid.cpp, the queries that walk the nodes in
// bounding_volume_hierarchy_queries.cpp.
#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"

#include "touchstone/geometry/closest_point_on_triangle.hpp"  // the feature numbering

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace touchstone::realtime::collision {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Eigen::Vector3i;

constexpr double infinity = std::numeric_limits<double>::infinity();

// A median split halves the triangles, so a median binary tree has at most ⌈log2 n⌉ + 1 ≤ 33
// levels; mean splits are allowed only in the top max_mean_split_depth levels, so no binary
// tree exceeds 24 + 33 levels (the queries' fixed stacks rely on this bound).
constexpr int max_binary_depth = 57;
constexpr int max_mean_split_depth = 24;
// Boxes are widened by this fraction of the surface's bounding-box diagonal. Rounding in a box
// test is ~1e-16 of the coordinates, so a true hit is never pruned, and 1e-9 is far too small
// to cost a measurable number of extra tests.
constexpr double relative_margin = 1e-9;

using geometry::face_feature;
using geometry::first_edge_feature;
using geometry::first_vertex_feature;

}  // namespace

// ---------------------------------------------------------------------------------------------
// Settings and construction.

void BvhSettings::validate() const {
  if (bounding_volume != BoundingVolume::obb && bounding_volume != BoundingVolume::aabb) {
    throw std::invalid_argument("BvhSettings.bounding_volume = " +
                                std::to_string(static_cast<int>(bounding_volume)) + " must be obb or aabb");
  }
  if (split != SplitRule::median && split != SplitRule::mean) {
    throw std::invalid_argument("BvhSettings.split = " + std::to_string(static_cast<int>(split)) +
                                " must be median or mean");
  }
  if (max_leaf_triangles < 1 || max_leaf_triangles > 64) {
    throw std::invalid_argument("BvhSettings.max_leaf_triangles = " + std::to_string(max_leaf_triangles) +
                                " must be in [1, 64]");
  }
  if (children_per_node != 2 && children_per_node != 4) {
    throw std::invalid_argument("BvhSettings.children_per_node = " + std::to_string(children_per_node) +
                                " must be 2 or 4");
  }
  if (!(entry_grid_cell == 0 || (entry_grid_cell >= 0.5 && entry_grid_cell <= 1000))) {
    throw std::invalid_argument("BvhSettings.entry_grid_cell = " + std::to_string(entry_grid_cell) +
                                " must be 0 (no grid) or in [0.5, 1000]");
  }
}


BoundingVolumeHierarchy::BoundingVolumeHierarchy(const geometry::TriangleSurface& surface,
                                                 const BvhSettings& settings)
    : settings_(settings), vertices_(surface.vertices()), triangles_(surface.triangles()) {
  settings_.validate();
  build();
}

BoundingVolumeHierarchy::BoundingVolumeHierarchy(std::vector<Vector3d> vertices, std::vector<Vector3i> triangles,
                                                 const BvhSettings& settings, const std::string& source)
    : BoundingVolumeHierarchy((settings.validate(),
                               geometry::TriangleSurface(std::move(vertices), std::move(triangles), source)),
                              settings) {}

void BoundingVolumeHierarchy::build() {
  const int n = static_cast<int>(triangles_.size());
  std::vector<Vector3d> centroids(n);
  for (int t = 0; t < n; ++t) {
    centroids[t] = (vertices_[triangles_[t][0]] + vertices_[triangles_[t][1]] + vertices_[triangles_[t][2]]) / 3;
  }
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  const bool oriented = settings_.bounding_volume == BoundingVolume::obb;

  // A binary tree, top-down, each node split along the longest axis of its box: the OBB's
  // (Gottschalk) or the AABB's. Only the axes are kept; the extents come from refit_boxes(),
  // the same code that follows a deformation.
  struct BuildNode {
    Matrix3d axes;
    int begin, end;
    int left = -1, right = -1;
  };
  struct Task {
    int begin, end, depth, parent;
    bool right;
  };
  std::vector<BuildNode> binary;
  binary.reserve(2 * static_cast<std::size_t>(n));
  std::vector<Task> tasks{{0, n, 1, -1, false}};
  std::vector<Vector3d> corners;
  std::vector<double> keys(n);
  binary_depth_ = 0;
  leaf_count_ = 0;
  max_leaf_size_ = 0;
  leaf_slots_.clear();
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    const int index = static_cast<int>(binary.size());
    binary.push_back({Matrix3d::Identity(), task.begin, task.end});
    if (task.parent >= 0) (task.right ? binary[task.parent].right : binary[task.parent].left) = index;
    binary_depth_ = std::max(binary_depth_, task.depth);
    if (task.depth > max_binary_depth) throw std::logic_error("BoundingVolumeHierarchy: tree deeper than its stacks");

    corners.clear();
    for (int i = task.begin; i < task.end; ++i) {
      for (int k = 0; k < 3; ++k) corners.push_back(vertices_[triangles_[order[i]][k]]);
    }
    const OrientedBox box = oriented ? fit_oriented_box(corners)
                                     : enclose_with_axes(Matrix3d::Identity(), corners.data(), corners.size());
    binary[index].axes = box.axes;

    const int size = task.end - task.begin;
    if (size <= settings_.max_leaf_triangles) {
      ++leaf_count_;
      max_leaf_size_ = std::max(max_leaf_size_, size);
      leaf_slots_.emplace_back(task.begin, size);
      continue;
    }
    Eigen::Index axis = 0;
    box.half_extents.maxCoeff(&axis);
    const Vector3d direction = box.axes.row(axis).transpose();
    for (int i = task.begin; i < task.end; ++i) keys[order[i]] = direction.dot(centroids[order[i]]);
    int middle = task.begin + size / 2;
    bool median = true;
    if (settings_.split == SplitRule::mean && task.depth <= max_mean_split_depth) {
      double mean = 0;
      for (int i = task.begin; i < task.end; ++i) mean += keys[order[i]];
      mean /= size;
      const auto split = std::partition(order.begin() + task.begin, order.begin() + task.end,
                                        [&](int t) { return keys[t] < mean; });
      const int candidate = static_cast<int>(split - order.begin());
      if (candidate > task.begin && candidate < task.end) {
        middle = candidate;
        median = false;
      }
    }
    if (median) {
      // Ties broken by index, so the tree does not depend on the standard library's nth_element.
      std::nth_element(order.begin() + task.begin, order.begin() + middle, order.begin() + task.end,
                       [&](int p, int q) { return std::tie(keys[p], p) < std::tie(keys[q], q); });
    }
    tasks.push_back({middle, task.end, task.depth + 1, index, true});
    tasks.push_back({task.begin, middle, task.depth + 1, index, false});
  }
  root_box_ = OrientedBox{};
  root_box_.axes = binary[0].axes;

  // Collapse into nodes of W lanes: a binary inner node's children (W = 2) or grandchildren
  // (W = 4; a child that is a leaf stays a lane of its own, next to an empty lane).
  const auto collapse = [&](auto& out) {
    using Node = typename std::decay_t<decltype(out)>::value_type;
    constexpr int width = Node::width;
    out.clear();
    lane_ranges_.clear();
    depth_ = 1;
    node_count_ = 1;
    if (binary[0].left < 0) return;
    struct Work {
      int binary, parent, lane, level;
    };
    std::vector<Work> work{{0, -1, 0, 1}};
    while (!work.empty()) {
      const Work item = work.back();
      work.pop_back();
      const int index = static_cast<int>(out.size());
      out.emplace_back();
      lane_ranges_.emplace_back();
      if (item.parent >= 0) out[item.parent].child[item.lane] = index;
      Node& node = out[index];
      const BuildNode& x = binary[item.binary];
      std::array<int, 4> lanes{-1, -1, -1, -1};
      if constexpr (width == 2) {
        lanes = {x.left, x.right, -1, -1};
      } else {
        for (int g = 0; g < 2; ++g) {
          const BuildNode& group = binary[g == 0 ? x.left : x.right];
          if (group.left < 0) {
            lanes[2 * g] = g == 0 ? x.left : x.right;
          } else {
            lanes[2 * g] = group.left;
            lanes[2 * g + 1] = group.right;
          }
        }
      }
      for (int k = 0; k < width; ++k) {
        for (int i = 0; i < 3; ++i) {
          node.center[i][k] = 0;
          node.half_extents[i][k] = 0;
        }
        if constexpr (Node::oriented) {
          for (int a = 0; a < 9; ++a) node.axes[a][k] = 0;
        }
      }
      node.lanes = 0;
      for (int k = width - 1; k >= 0; --k) {
        node.child[k] = 0;
        node.count[k] = 0;
        if (lanes[k] < 0) continue;
        const BuildNode& child = binary[lanes[k]];
        node.lanes |= 1 << k;
        lane_ranges_[index].begin[k] = child.begin;
        lane_ranges_[index].end[k] = child.end;
        if constexpr (Node::oriented) {
          for (int a = 0; a < 9; ++a) node.axes[a][k] = child.axes(a / 3, a % 3);
        }
        ++node_count_;
        if (child.left < 0) {
          node.child[k] = child.begin;
          node.count[k] = static_cast<std::int16_t>(child.end - child.begin);
          depth_ = std::max(depth_, item.level + 1);
        } else {
          work.push_back({lanes[k], index, k, item.level + 1});
        }
      }
    }
  };
  obb2_.clear();
  obb4_.clear();
  aabb2_.clear();
  aabb4_.clear();
  const bool binary_width = settings_.children_per_node == 2;
  if (oriented) {
    binary_width ? collapse(obb2_) : collapse(obb4_);
  } else {
    binary_width ? collapse(aabb2_) : collapse(aabb4_);
  }

  slot_triangle_ = order;
  // The slot across each edge, for the edge pseudo-normals (the surface is closed and
  // consistently oriented, so edge a → b of one triangle is b → a of exactly one other).
  struct DirectedEdge {
    int low, high, slot, edge;
  };
  std::vector<DirectedEdge> edges;
  edges.reserve(3 * static_cast<std::size_t>(n));
  for (int slot = 0; slot < n; ++slot) {
    const Vector3i& t = triangles_[order[slot]];
    for (int k = 0; k < 3; ++k) {
      edges.push_back({std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]), slot, k});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const DirectedEdge& p, const DirectedEdge& q) {
    return std::tie(p.low, p.high) < std::tie(q.low, q.high);
  });
  edge_neighbour_slot_.assign(3 * static_cast<std::size_t>(n), 0);
  for (std::size_t i = 0; i + 1 < edges.size(); i += 2) {
    edge_neighbour_slot_[3 * edges[i].slot + edges[i].edge] = edges[i + 1].slot;
    edge_neighbour_slot_[3 * edges[i + 1].slot + edges[i + 1].edge] = edges[i].slot;
  }

  // Each vertex's corners, for its angle-weighted pseudo-normal (contains() near a vertex).
  vertex_corner_offsets_.assign(vertices_.size() + 1, 0);
  for (int slot = 0; slot < n; ++slot) {
    for (int k = 0; k < 3; ++k) ++vertex_corner_offsets_[triangles_[order[slot]][k] + 1];
  }
  std::partial_sum(vertex_corner_offsets_.begin(), vertex_corner_offsets_.end(), vertex_corner_offsets_.begin());
  vertex_corners_.resize(3 * static_cast<std::size_t>(n));
  std::vector<int> filled(vertex_corner_offsets_.begin(), vertex_corner_offsets_.end() - 1);
  for (int slot = 0; slot < n; ++slot) {
    for (int k = 0; k < 3; ++k) vertex_corners_[filled[triangles_[order[slot]][k]]++] = 3 * slot + k;
  }

  corners_.resize(3 * static_cast<std::size_t>(n));
  face_normals_.resize(n);
  update_geometry();
  refit_boxes();

  tree_node_slots_ = obb2_.size() + obb4_.size() + aabb2_.size() + aabb4_.size();
  // The grid's cell is fixed now (from the mean edge length); refit() keeps it.
  grid_ = EntryGrid{};
  const bool has_nodes = !(obb2_.empty() && obb4_.empty() && aabb2_.empty() && aabb4_.empty());
  if (settings_.entry_grid_cell > 0 && has_nodes) {
    double edges_total = 0;
    for (int slot = 0; slot < n; ++slot) {
      for (int k = 0; k < 3; ++k) edges_total += (corners_[3 * slot + (k + 1) % 3] - corners_[3 * slot + k]).norm();
    }
    grid_.cell_m = settings_.entry_grid_cell * edges_total / (3.0 * n);
    grid_.reach_m = grid_.cell_m / 2;
    update_entry_grid();
  }
}

// ---------------------------------------------------------------------------------------------
// Geometry that follows the vertices: corners, normals, margin, boxes.

void BoundingVolumeHierarchy::update_geometry() {
  const int n = static_cast<int>(slot_triangle_.size());
  for (int slot = 0; slot < n; ++slot) {
    const Vector3i& t = triangles_[slot_triangle_[slot]];
    for (int k = 0; k < 3; ++k) corners_[3 * slot + k] = vertices_[t[k]];
    const Vector3d normal = (corners_[3 * slot + 1] - corners_[3 * slot]).cross(corners_[3 * slot + 2] - corners_[3 * slot]);
    const double length = normal.norm();
    // A triangle squashed flat by a deformation has no normal; zero keeps every use finite.
    face_normals_[slot] = length > 0 ? Vector3d(normal / length) : Vector3d::Zero();
  }
  Vector3d lower = Vector3d::Constant(infinity);
  Vector3d upper = -lower;
  for (const Vector3d& v : vertices_) {
    lower = lower.cwiseMin(v);
    upper = upper.cwiseMax(v);
  }
  margin_ = relative_margin * (upper - lower).norm();

  leaf_corners_origin_ = 0.5 * (lower + upper);
  leaf_corners_extent_ = 0.5 * (upper - lower).maxCoeff();
  leaf_corners_.assign(9 * static_cast<std::size_t>(n) + 3, 0.0f);
  for (const auto& [first, count] : leaf_slots_) {
    float* leaf = leaf_corners_.data() + 9 * static_cast<std::size_t>(first);
    for (int i = 0; i < count; ++i) {
      for (int k = 0; k < 3; ++k) {
        const Vector3d relative = corners_[3 * static_cast<std::size_t>(first + i) + k] - leaf_corners_origin_;
        for (int axis = 0; axis < 3; ++axis) leaf[(3 * k + axis) * count + i] = static_cast<float>(relative[axis]);
      }
    }
  }
}

Vector3d BoundingVolumeHierarchy::pseudo_normal(int slot, int feature) const noexcept {
  // Computed when needed (only contains() next to the surface asks), so that refit() does not
  // pay for three arctangents per triangle.
  if (feature == face_feature) return face_normals_[slot];
  if (feature < first_vertex_feature) {
    const int edge = feature - first_edge_feature;
    return face_normals_[slot] + face_normals_[edge_neighbour_slot_[3 * slot + edge]];
  }
  // Angle-weighted (Thürmer & Wüthrich): the pseudo-normal whose sign test is exact at a vertex.
  const int vertex = triangles_[slot_triangle_[slot]][feature - first_vertex_feature];
  Vector3d normal = Vector3d::Zero();
  for (int i = vertex_corner_offsets_[vertex]; i < vertex_corner_offsets_[vertex + 1]; ++i) {
    const int corner_slot = vertex_corners_[i] / 3;
    const int k = vertex_corners_[i] % 3;
    const Vector3d& corner = corners_[3 * corner_slot + k];
    const Vector3d u = corners_[3 * corner_slot + (k + 1) % 3] - corner;
    const Vector3d w = corners_[3 * corner_slot + (k + 2) % 3] - corner;
    normal += std::atan2(u.cross(w).norm(), u.dot(w)) * face_normals_[corner_slot];
  }
  return normal;
}

template <class Node>
void BoundingVolumeHierarchy::refit_nodes() {
  std::vector<Node>& all = nodes<Node>();
  const Vector3d margin = Vector3d::Constant(margin_);
  const int n = static_cast<int>(slot_triangle_.size());
  const auto enclose = [&](const Matrix3d& axes, int begin, int end) {
    OrientedBox box = enclose_with_axes(axes, corners_.data() + 3 * begin, 3 * static_cast<std::size_t>(end - begin));
    box.half_extents += margin;
    return box;
  };
  const auto store = [](Node& node, int k, const Vector3d& center, const Vector3d& half_extents) {
    using Scalar = typename Node::Scalar;
    for (int i = 0; i < 3; ++i) {
      // A float centre moves the box by its rounding: the half extent grows by that much and is
      // rounded up, so the stored box contains the given one (nothing changes in double).
      const Scalar c = static_cast<Scalar>(center[i]);
      const double needed = half_extents[i] + std::abs(center[i] - static_cast<double>(c));
      Scalar e = static_cast<Scalar>(needed);
      if (static_cast<double>(e) < needed) e = std::nextafter(e, std::numeric_limits<Scalar>::infinity());
      node.center[i][k] = c;
      node.half_extents[i][k] = e;
      // An empty neighbour lane takes the centre too (the visiting order compares centres).
      if ((node.lanes >> (k ^ 1) & 1) == 0) node.center[i][k ^ 1] = c;
    }
  };
  if constexpr (Node::oriented) {
    // Every box from its own triangles' corners, exact for its kept axes (enclosing each
    // child's box instead would loosen the boxes level by level).
    root_box_ = enclose(root_box_.axes, 0, n);
    for (std::size_t p = 0; p < all.size(); ++p) {
      Node& node = all[p];
      for (int k = 0; k < Node::width; ++k) {
        if ((node.lanes >> k & 1) == 0) continue;
        Matrix3d axes;
        for (int a = 0; a < 9; ++a) axes(a / 3, a % 3) = node.axes[a][k];
        const OrientedBox box = enclose(axes, lane_ranges_[p].begin[k], lane_ranges_[p].end[k]);
        store(node, k, box.center, box.half_extents);
      }
    }
  } else {
    // Bottom-up: a child node follows its parent, so a reverse sweep has every lane of a child
    // node before it merges them.
    const auto merge = [](const Node& node, Vector3d& lower, Vector3d& upper) {
      lower = Vector3d::Constant(infinity);
      upper = -lower;
      for (int k = 0; k < Node::width; ++k) {
        if ((node.lanes >> k & 1) == 0) continue;
        for (int i = 0; i < 3; ++i) {
          lower[i] = std::min(lower[i], static_cast<double>(node.center[i][k]) - node.half_extents[i][k]);
          upper[i] = std::max(upper[i], static_cast<double>(node.center[i][k]) + node.half_extents[i][k]);
        }
      }
    };
    for (int p = static_cast<int>(all.size()) - 1; p >= 0; --p) {
      Node& node = all[p];
      for (int k = 0; k < Node::width; ++k) {
        if ((node.lanes >> k & 1) == 0) continue;
        Vector3d lower, upper;
        if (node.count[k] > 0) {
          lower = Vector3d::Constant(infinity);
          upper = -lower;
          for (int i = 3 * lane_ranges_[p].begin[k]; i < 3 * lane_ranges_[p].end[k]; ++i) {
            lower = lower.cwiseMin(corners_[i]);
            upper = upper.cwiseMax(corners_[i]);
          }
          lower -= margin;
          upper += margin;
        } else {
          merge(all[node.child[k]], lower, upper);
        }
        // Rounding the centre can move a face by an ulp; the margin (≫ an ulp) covers it.
        store(node, k, 0.5 * (lower + upper), 0.5 * (upper - lower));
      }
    }
    if (all.empty()) {
      root_box_ = enclose(Matrix3d::Identity(), 0, n);
    } else {
      Vector3d lower, upper;
      merge(all[0], lower, upper);
      root_box_.axes.setIdentity();
      root_box_.center = 0.5 * (lower + upper);
      root_box_.half_extents = 0.5 * (upper - lower);
    }
  }
}

void BoundingVolumeHierarchy::refit_boxes() {
  const bool binary_width = settings_.children_per_node == 2;
  if (settings_.bounding_volume == BoundingVolume::obb) {
    binary_width ? refit_nodes<ObbNode<2>>() : refit_nodes<ObbNode<4>>();
  } else {
    binary_width ? refit_nodes<AabbNode<2>>() : refit_nodes<AabbNode<4>>();
  }
}

void BoundingVolumeHierarchy::refit(const std::vector<Vector3d>& deformed_vertices) {
  if (deformed_vertices.size() != vertices_.size()) {
    throw std::invalid_argument("BoundingVolumeHierarchy::refit: " + std::to_string(deformed_vertices.size()) +
                                " vertices given, the surface has " + std::to_string(vertices_.size()));
  }
  for (std::size_t v = 0; v < deformed_vertices.size(); ++v) {
    if (!deformed_vertices[v].allFinite()) {
      throw std::invalid_argument("BoundingVolumeHierarchy::refit: vertex " + std::to_string(v) +
                                  " has a non-finite coordinate");
    }
  }
  std::copy(deformed_vertices.begin(), deformed_vertices.end(), vertices_.begin());
  update_geometry();
  const bool binary_width = settings_.children_per_node == 2;
  if (settings_.bounding_volume == BoundingVolume::obb) {
    binary_width ? truncate_to_tree<ObbNode<2>>() : truncate_to_tree<ObbNode<4>>();
  } else {
    binary_width ? truncate_to_tree<AabbNode<2>>() : truncate_to_tree<AabbNode<4>>();
  }
  refit_boxes();
  if (grid_.cell_m > 0) update_entry_grid();
}

template <class Node>
void BoundingVolumeHierarchy::truncate_to_tree() {
  nodes<Node>().resize(tree_node_slots_);
}

BvhStats BoundingVolumeHierarchy::stats() const {
  BvhStats stats;
  stats.triangle_count = static_cast<int>(triangles_.size());
  stats.node_count = node_count_;
  stats.leaf_count = leaf_count_;
  stats.depth = depth_;
  stats.binary_depth = binary_depth_;
  stats.max_leaf_size = max_leaf_size_;
  stats.entry_grid_cells = grid_.occupied;
  stats.entry_grid_cell_m = grid_.cell_m;
  stats.memory_bytes = obb2_.size() * sizeof(ObbNode<2>) + obb4_.size() * sizeof(ObbNode<4>) +
                       aabb2_.size() * sizeof(AabbNode<2>) + aabb4_.size() * sizeof(AabbNode<4>) +
                       lane_ranges_.size() * sizeof(LaneRanges) + corners_.size() * sizeof(Vector3d) +
                       leaf_corners_.size() * sizeof(float) + leaf_slots_.size() * sizeof(std::pair<int, int>) +
                       face_normals_.size() * sizeof(Vector3d) +
                       (vertex_corner_offsets_.size() + vertex_corners_.size()) * sizeof(int) +
                       slot_triangle_.size() * sizeof(int) + edge_neighbour_slot_.size() * sizeof(int) +
                       (grid_.entry.capacity() + grid_.lowest.capacity() + grid_.highest.capacity()) * sizeof(std::int32_t) +
                       grid_.obb2.size() * sizeof(ObbNode<2>) + grid_.obb4.size() * sizeof(ObbNode<4>) +
                       grid_.aabb2.size() * sizeof(AabbNode<2>) + grid_.aabb4.size() * sizeof(AabbNode<4>);
  return stats;
}

}  // namespace touchstone::realtime::collision
