// The bounding-volume hierarchy's entry grid (H-COLLIDE's uniform grid over the tree): for each
// cell, the node a short move starting there enters first — a cover node holding the boxes of
// the deepest parts of the tree that together hold every triangle within reach of the cell.
#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <vector>

namespace touchstone::realtime::collision {

namespace {

using Eigen::Vector3d;
using Eigen::Vector3i;

constexpr double infinity = std::numeric_limits<double>::infinity();
// The entry grid never has more cells than this (its cells grow instead): 16 MB of entries.
constexpr std::int64_t max_grid_cells = std::int64_t{1} << 22;

}  // namespace

template <class Node>
int BoundingVolumeHierarchy::entry_node(int lowest, int highest) {
  // Subtrees hold contiguous slot ranges, so the deepest node holding slots lowest..highest
  // is the lowest common ancestor of their leaves: descend while one inner lane holds them all.
  const std::vector<Node>& all = nodes<Node>();
  int index = 0;
  for (;;) {
    const Node& node = all[index];
    int next = -1;
    for (int k = 0; k < Node::width; ++k) {
      if ((node.lanes >> k & 1) == 0 || node.count[k] != 0) continue;
      if (lane_ranges_[index].begin[k] <= lowest && highest < lane_ranges_[index].end[k]) next = node.child[k];
    }
    if (next < 0) return index;
    index = next;
  }
}

struct BoundingVolumeHierarchy::CoverScratch {
  /// A cover's parts as node · 16 + lane mask, sorted, −1 after the last.
  using Key = std::array<std::int64_t, 4>;
  struct KeyHash {
    std::size_t operator()(const Key& key) const noexcept {
      std::size_t hash = 0;
      for (std::int64_t part : key) hash = hash * 1000003u ^ std::hash<std::int64_t>{}(part);
      return hash;
    }
  };
  std::unordered_map<Key, int, KeyHash> covers;  ///< a cover's parts → its cover node
  std::unordered_map<std::int64_t, int> masked;  ///< node · 16 + lane mask → its masked copy
  std::vector<int> parent, parent_lane;          ///< per tree node: where its box is stored
};


template <class Node>
int BoundingVolumeHierarchy::entry_cover(int lowest, int highest, const Vector3d& lower, const Vector3d& upper,
                                         CoverScratch& scratch) {
  // From its cell, a short segment meets only triangles within reach; entered at their common
  // ancestor, the traversal would test every box on the way to them. The cover starts at the
  // root and splits its largest part along the binary tree (a 4-wide node into its two halves,
  // a half into its lanes, an inner lane into its node) while at most W parts remain; a part
  // keeps only the lanes that may hold a triangle within reach (slots in [lowest, highest] and
  // an axis-aligned hull meeting the widened cell).
  std::vector<Node>& all = nodes<Node>();
  const auto hull = [&](const Node& node, int k, Vector3d& low, Vector3d& high) {
    for (int i = 0; i < 3; ++i) {
      double radius = node.half_extents[i][k];
      if constexpr (Node::oriented) {
        radius = 0;
        for (int j = 0; j < 3; ++j) radius += std::abs(node.axes[3 * j + i][k]) * node.half_extents[j][k];
      }
      low[i] = static_cast<double>(node.center[i][k]) - radius;
      high[i] = static_cast<double>(node.center[i][k]) + radius;
    }
  };
  const auto lanes_within_reach = [&](int index, int mask) {
    const Node& node = all[index];
    int kept = 0;
    for (int k = 0; k < Node::width; ++k) {
      if ((mask >> k & 1) == 0) continue;
      if (lane_ranges_[index].end[k] <= lowest || highest < lane_ranges_[index].begin[k]) continue;
      Vector3d low, high;
      hull(node, k, low, high);
      if ((high.array() < lower.array()).any() || (low.array() > upper.array()).any()) continue;
      kept |= 1 << k;
    }
    return kept;
  };
  struct Part {
    int node, mask;
  };
  const auto slots = [&](const Part& part) {
    int total = 0;
    for (int k = 0; k < Node::width; ++k) {
      if (part.mask >> k & 1) total += lane_ranges_[part.node].end[k] - lane_ranges_[part.node].begin[k];
    }
    return total;
  };
  // A single inner lane is its node (the same triangles), so parts never stop at one.
  const auto normalised = [&](Part part) {
    while (part.mask != 0 && (part.mask & (part.mask - 1)) == 0) {
      const int k = __builtin_ctz(static_cast<unsigned>(part.mask));
      if (all[part.node].count[k] != 0) break;
      const int child = all[part.node].child[k];
      part = {child, lanes_within_reach(child, all[child].lanes)};
    }
    return part;
  };
  const auto splittable = [&](const Part& part) { return (part.mask & (part.mask - 1)) != 0; };
  // Fixed-size lists (a cover has at most W parts, a split makes at most W pieces): this runs
  // for every occupied cell at every build and refit.
  struct Parts {
    std::array<Part, 4> part{};
    std::array<bool, 4> final{};
    int size = 0;
  };
  const auto split = [&](const Part& part, Parts& pieces) {
    pieces.size = 0;
    const auto add = [&](Part piece) {
      piece = normalised(piece);
      if (piece.mask != 0) pieces.part[pieces.size++] = piece;
    };
    if (Node::width == 4 && (part.mask & 0b0011) != 0 && (part.mask & 0b1100) != 0) {
      add({part.node, part.mask & 0b0011});
      add({part.node, part.mask & 0b1100});
    } else {
      for (int k = 0; k < Node::width; ++k) {
        if (part.mask >> k & 1) add({part.node, 1 << k});
      }
    }
  };

  Parts parts;
  if (const Part root = normalised({0, lanes_within_reach(0, all[0].lanes)}); root.mask != 0) {
    parts.part[parts.size++] = root;
  }
  Parts pieces;
  for (;;) {
    int largest = -1;
    int most = 0;
    for (int i = 0; i < parts.size; ++i) {
      if (parts.final[i] || !splittable(parts.part[i])) continue;
      if (const int size = slots(parts.part[i]); size > most) {
        most = size;
        largest = i;
      }
    }
    if (largest < 0) break;
    split(parts.part[largest], pieces);
    if (parts.size - 1 + pieces.size > Node::width) {
      parts.final[largest] = true;
      continue;
    }
    // The largest part's place takes the last part; the pieces follow.
    --parts.size;
    parts.part[largest] = parts.part[parts.size];
    parts.final[largest] = parts.final[parts.size];
    for (int i = 0; i < pieces.size; ++i) {
      parts.part[parts.size] = pieces.part[i];
      parts.final[parts.size++] = false;
    }
  }
  if (parts.size == 0) return -1;

  CoverScratch::Key key;
  key.fill(-1);
  for (int i = 0; i < parts.size; ++i) key[i] = std::int64_t{parts.part[i].node} * 16 + parts.part[i].mask;
  for (int i = 1; i < parts.size; ++i) {  // insertion sort of at most 4
    for (int j = i; j > 0 && key[j - 1] > key[j]; --j) std::swap(key[j - 1], key[j]);
  }
  std::vector<Node>& cover = cover_nodes<Node>(grid_);
  if (const auto found = scratch.covers.find(key); found != scratch.covers.end()) return -2 - found->second;

  Node node;
  for (int lane = 0; lane < Node::width; ++lane) {
    // An empty lane repeats the last part's box (its centre orders the lanes; the lane bit
    // masks it).
    const Part& part = parts.part[std::min(lane, parts.size - 1)];
    const Node& source = all[part.node];
    int from_node = part.node;  // the node and lane whose stored box is the part's box
    int from_lane = -1;
    if (!splittable(part)) {
      from_lane = __builtin_ctz(static_cast<unsigned>(part.mask));
      node.child[lane] = source.child[from_lane];
      node.count[lane] = source.count[from_lane];
    } else {
      if (part.mask == source.lanes && scratch.parent[part.node] >= 0) {
        from_node = scratch.parent[part.node];
        from_lane = scratch.parent_lane[part.node];
        node.child[lane] = part.node;
      } else {
        const auto [copy, inserted] =
            scratch.masked.try_emplace(std::int64_t{part.node} * 16 + part.mask, static_cast<int>(all.size()));
        if (inserted) {
          Node masked = source;
          masked.lanes = part.mask;
          all.push_back(masked);
        }
        node.child[lane] = copy->second;
      }
      node.count[lane] = 0;
    }
    if (from_lane >= 0) {
      const Node& box = all[from_node];
      for (int i = 0; i < 3; ++i) {
        node.center[i][lane] = box.center[i][from_lane];
        node.half_extents[i][lane] = box.half_extents[i][from_lane];
      }
      if constexpr (Node::oriented) {
        for (int i = 0; i < 9; ++i) node.axes[i][lane] = box.axes[i][from_lane];
      }
    } else {
      // Half a node: the axis-aligned hull of its lanes' boxes (held in Scalar by rounding the
      // centre and widening the half extent outward, as the tree's own boxes are).
      Vector3d low = Vector3d::Constant(infinity), high = -low;
      for (int k = 0; k < Node::width; ++k) {
        if ((part.mask >> k & 1) == 0) continue;
        Vector3d l, h;
        hull(all[part.node], k, l, h);
        low = low.cwiseMin(l);
        high = high.cwiseMax(h);
      }
      using Scalar = typename Node::Scalar;
      for (int i = 0; i < 3; ++i) {
        const double centre = 0.5 * (low[i] + high[i]);
        const Scalar c = static_cast<Scalar>(centre);
        const double needed =
            std::max(high[i] - static_cast<double>(c), static_cast<double>(c) - low[i]) * (1 + 4 * std::numeric_limits<double>::epsilon());
        Scalar e = static_cast<Scalar>(needed);
        if (static_cast<double>(e) < needed) e = std::nextafter(e, std::numeric_limits<Scalar>::infinity());
        node.center[i][lane] = c;
        node.half_extents[i][lane] = e;
      }
      if constexpr (Node::oriented) {
        for (int i = 0; i < 9; ++i) node.axes[i][lane] = (i % 4 == 0) ? 1.0 : 0.0;
      }
    }
    if (lane < parts.size) node.lanes |= 1 << lane;
  }
  scratch.covers.emplace(key, static_cast<int>(cover.size()));
  cover.push_back(node);
  return -1 - static_cast<int>(cover.size());
}

void BoundingVolumeHierarchy::update_entry_grid() {
  // Cells over the vertices' bounds widened by the reach (a segment starting outside them and
  // moving at most the reach cannot touch a triangle), as many as the cap allows.
  Vector3d lower = Vector3d::Constant(infinity);
  Vector3d upper = -lower;
  for (const Vector3d& v : vertices_) {
    lower = lower.cwiseMin(v);
    upper = upper.cwiseMax(v);
  }
  const auto capacity = static_cast<std::int64_t>(grid_.entry.capacity());
  const std::int64_t limit = capacity > 0 ? capacity : max_grid_cells;
  std::int64_t cells = 0;
  for (;;) {
    grid_.reach_m = grid_.cell_m / 2;
    grid_.origin = lower - Vector3d::Constant(grid_.reach_m + margin_);
    const Vector3d extent = upper - lower + Vector3d::Constant(2 * (grid_.reach_m + margin_));
    cells = 1;
    for (int i = 0; i < 3; ++i) {
      grid_.dims[i] = std::max(1, static_cast<int>(std::ceil(extent[i] / grid_.cell_m)));
      cells *= grid_.dims[i];
    }
    if (cells <= limit) break;
    grid_.cell_m *= 1.25;
  }
  grid_.entry.resize(cells);
  grid_.lowest.assign(cells, std::numeric_limits<std::int32_t>::max());
  grid_.highest.assign(cells, -1);

  // Every cell within reach of a triangle's box learns the triangle's slot.
  const double widen = grid_.reach_m + margin_;
  const int n = static_cast<int>(slot_triangle_.size());
  for (int slot = 0; slot < n; ++slot) {
    const Vector3d& a = corners_[3 * slot];
    const Vector3d& b = corners_[3 * slot + 1];
    const Vector3d& c = corners_[3 * slot + 2];
    const Vector3d low = (a.cwiseMin(b).cwiseMin(c) - Vector3d::Constant(widen) - grid_.origin) / grid_.cell_m;
    const Vector3d high = (a.cwiseMax(b).cwiseMax(c) + Vector3d::Constant(widen) - grid_.origin) / grid_.cell_m;
    Vector3i first, last;
    for (int i = 0; i < 3; ++i) {
      first[i] = std::clamp(static_cast<int>(std::floor(low[i])), 0, grid_.dims[i] - 1);
      last[i] = std::clamp(static_cast<int>(std::floor(high[i])), 0, grid_.dims[i] - 1);
    }
    for (int z = first.z(); z <= last.z(); ++z) {
      for (int y = first.y(); y <= last.y(); ++y) {
        for (int x = first.x(); x <= last.x(); ++x) {
          const std::int64_t cell =
              x + static_cast<std::int64_t>(grid_.dims.x()) * (y + static_cast<std::int64_t>(grid_.dims.y()) * z);
          grid_.lowest[cell] = std::min(grid_.lowest[cell], slot);
          grid_.highest[cell] = std::max(grid_.highest[cell], slot);
        }
      }
    }
  }
  const bool binary_width = settings_.children_per_node == 2;
  const bool oriented = settings_.bounding_volume == BoundingVolume::obb;
  grid_.obb2.clear();
  grid_.obb4.clear();
  grid_.aabb2.clear();
  grid_.aabb4.clear();
  CoverScratch scratch;
  const auto find_parents = [&](const auto& all) {
    scratch.parent.assign(all.size(), -1);
    scratch.parent_lane.assign(all.size(), -1);
    for (std::size_t p = 0; p < all.size(); ++p) {
      for (int k = 0; k < std::decay_t<decltype(all[0])>::width; ++k) {
        if ((all[p].lanes >> k & 1) == 0 || all[p].count[k] != 0) continue;
        scratch.parent[all[p].child[k]] = static_cast<int>(p);
        scratch.parent_lane[all[p].child[k]] = k;
      }
    }
  };
  if (oriented) {
    binary_width ? find_parents(obb2_) : find_parents(obb4_);
  } else {
    binary_width ? find_parents(aabb2_) : find_parents(aabb4_);
  }
  grid_.occupied = 0;
  std::int64_t cell = 0;
  for (int z = 0; z < grid_.dims.z(); ++z) {
    for (int y = 0; y < grid_.dims.y(); ++y) {
      for (int x = 0; x < grid_.dims.x(); ++x, ++cell) {
        if (grid_.highest[cell] < 0) {
          grid_.entry[cell] = -1;
          continue;
        }
        ++grid_.occupied;
        const int lowest = grid_.lowest[cell];
        const int highest = grid_.highest[cell];
        const Vector3d lower = grid_.origin + grid_.cell_m * Vector3d(x, y, z) - Vector3d::Constant(widen);
        const Vector3d upper = lower + Vector3d::Constant(grid_.cell_m + 2 * widen);
        if (oriented) {
          grid_.entry[cell] = binary_width ? entry_cover<ObbNode<2>>(lowest, highest, lower, upper, scratch)
                                           : entry_cover<ObbNode<4>>(lowest, highest, lower, upper, scratch);
        } else {
          grid_.entry[cell] = binary_width ? entry_cover<AabbNode<2>>(lowest, highest, lower, upper, scratch)
                                           : entry_cover<AabbNode<4>>(lowest, highest, lower, upper, scratch);
        }
      }
    }
  }
}

}  // namespace touchstone::realtime::collision
