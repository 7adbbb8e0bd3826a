#pragma once
/// @file
/// Bounding-volume hierarchy over the triangles of a closed surface (paper §3):
/// an OBB tree as in H-COLLIDE / OBBTree (the paper's) or an AABB tree with float boxes (the
/// default: exact answers all the same, fewer overlap tests and less time per query), answering
/// the SurfaceQueries in double precision and counting the overlap tests (the paper's Table 1).
/// collision_benchmark measures it against Embree; the tests compare it with brute force.

#include "touchstone/realtime/collision/oriented_box.hpp"
#include "touchstone/realtime/collision/surface_queries.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace touchstone::realtime::collision {

/// The bounding volume of every node.
enum class BoundingVolume : std::uint8_t {
  obb,   ///< oriented box fitted to the node's triangles (Gottschalk's covariance fit; the paper's)
  aabb,  ///< axis-aligned box, stored and first tested in float: looser, but a far cheaper test (default)
};

/// Where a node's triangles are split (along the longest axis of its box, by their centroids).
enum class SplitRule : std::uint8_t {
  median,  ///< equal halves: a balanced tree of depth ⌈log2(n / leaf size)⌉ + 1 (default)
  mean,    ///< at the mean centroid (OBBTree's rule); median where that leaves a side empty or the tree gets deep
};

struct BvhSettings {
  /// AABB by default: on short first-contact moves it makes fewer box tests than the OBB tree,
  /// each cheaper (collision_benchmark compares them; the README gives the figures).
  BoundingVolume bounding_volume = BoundingVolume::aabb;
  SplitRule split = SplitRule::median;
  /// A node with at most this many triangles is a leaf. 1 descends to single triangles as the
  /// paper's Table 1 counts do (the collision study's "paper tree"); 4 is the default: fewer box
  /// tests per short move than 2, for a few more triangle tests (collision_benchmark compares
  /// 1, 2, 4 and 8).
  int max_leaf_triangles = 4;
  /// 2: a binary tree (OBBTree, H-COLLIDE; the paper's overlap counts). 4: the binary tree with
  /// every other level collapsed, so a node tests its up to 4 grandchildren's boxes at once —
  /// half the levels on a query's path, the same boxes (default: faster).
  int children_per_node = 4;
  /// H-COLLIDE's uniform grid over the hierarchy (Gregory et al. 1999), cells of this many mean
  /// triangle edge lengths; 0 disables it. A segment or ray that moves at most half a cell
  /// along each axis (a tool-tip move in one cycle) starts its traversal not at the root but at
  /// its start cell's cover node: the boxes of the deepest (at most W) parts of the tree that
  /// together hold every triangle within that reach of the cell. A cell with no triangle within
  /// reach answers "no hit" without any test.
  double entry_grid_cell = 2;
  /// Segment and ray queries (and contains()'s parity rays) first test a leaf's triangles four
  /// at a time in float, with a bound on the rounding that makes the test conservative: it sets
  /// aside only triangles the double test would reject, and the double test decides the rest,
  /// so the answers are the same to the bit either way. false tests every triangle in double
  /// only (for comparison: collision_benchmark times both).
  bool float_leaf_test = true;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Shape of the tree.
struct BvhStats {
  int triangle_count = 0;
  int node_count = 0;       ///< inner nodes + leaves (2 · leaves − 1 for a binary tree)
  int leaf_count = 0;
  int depth = 0;            ///< levels of the tree as built (with its width): a lone root leaf has depth 1
  int binary_depth = 0;     ///< levels of the binary tree it was collapsed from
  int max_leaf_size = 0;    ///< most triangles in one leaf
  int entry_grid_cells = 0;      ///< cells of the entry grid with a triangle within reach (0: no grid)
  double entry_grid_cell_m = 0;  ///< cell edge [m]; segments reaching ≤ half of it per axis use the grid
  std::size_t memory_bytes = 0;  ///< nodes and per-triangle data (not the input vertices)
};

/// BVH over a closed, consistently oriented triangle surface: a binary tree built top-down
/// (median split along the longest box axis), stored as is or with every other level collapsed
/// into 4-wide nodes, plus H-COLLIDE's uniform entry grid for short segments. Queries are exact
/// in double precision (the same answer as testing every triangle), noexcept, allocation-free
/// (fixed stacks; the binary tree is at most 57 levels deep) and safe for concurrent readers;
/// refit() is the only writer and must not run while another thread queries.
///
/// What the counters count (QueryCounters):
/// - box_tests: one per bounding volume tested: the root's box, which segment, ray and contains
///   queries test first, then every child's box of every inner node the traversal enters (a
///   node stores its children's boxes side by side and tests them together). In a binary tree a
///   query that enters k inner nodes makes 1 + 2k box tests, so a single root-to-leaf path
///   through a tree of depth D (D − 1 inner levels) makes 2D − 1. A segment or ray that uses
///   the entry grid makes no root test: the grid lookup (an index computation, no overlap test)
///   is not counted, the cover node's boxes are (one per part), and a move in an empty cell
///   costs no test at all. closest_point() starts with the root's children.
/// - triangle_tests: one per triangle of a leaf whose box passed (segment–triangle or
///   point–triangle, including triangles the point–plane bound then skips).
class BoundingVolumeHierarchy final : public SurfaceQueries {
 public:
  /// Builds the tree (top-down, O(n log n)). Throws std::invalid_argument on invalid settings.
  explicit BoundingVolumeHierarchy(const geometry::TriangleSurface& surface, const BvhSettings& settings = {});
  /// Validates the surface as TriangleSurface does (closed, manifold, consistently oriented,
  /// no degenerate triangle), then builds; throws std::invalid_argument naming `source`.
  BoundingVolumeHierarchy(std::vector<Eigen::Vector3d> vertices, std::vector<Eigen::Vector3i> triangles,
                          const BvhSettings& settings = {}, const std::string& source = "surface");

  /// First hit of the segment from + t (to − from), 0 ≤ t ≤ 1, with either side of a face;
  /// distance_m = t |to − from|. Watertight (Woop, Benthin & Wald 2013): a segment through an
  /// edge or a vertex hits one of the triangles there. A zero-length or non-finite segment
  /// has no hit.
  SurfaceHit first_hit_segment(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                               QueryCounters* counters = nullptr) const noexcept override;
  /// First hit of origin + s d̂, 0 ≤ s ≤ max_distance_m, d̂ = direction / |direction| (so a
  /// slightly non-unit direction still measures metres); max_distance_m may be +∞. No hit for a
  /// zero or non-finite direction, a non-finite origin, or max_distance_m < 0 or NaN.
  SurfaceHit first_hit_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                           double max_distance_m, QueryCounters* counters = nullptr) const noexcept override;
  /// Closest point (exact: Ericson's point–triangle test in the leaves, boxes pruned by their
  /// distance, nearer child first). A non-finite x gives triangle −1 and distance +∞.
  ClosestSurfacePoint closest_point(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept override;
  /// True when x is strictly inside (points on the surface are outside). Ray parity: a ray
  /// from x to the bounding box's exit crosses the closed surface an odd number of times iff x
  /// is inside; the watertight test counts every crossing once unless the ray meets an edge or
  /// vertex exactly, which is detected and retried with another direction. Points within
  /// 10⁻⁹ of the bounding-box diagonal of the surface fall back to the sign of (x − p)·n at the
  /// closest point p with the angle-weighted pseudo-normal n there (Bærentzen & Aanæs 2005).
  bool contains(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept override;

  /// Moves the vertices (same count, same triangles) and recomputes every box: an AABB exactly
  /// from its children (O(n)), an OBB with its axes kept and its extents fitted to its own
  /// triangles' corners (O(n log n): enclosing the children's boxes instead would loosen the
  /// boxes level by level). Normals and the entry grid are recomputed (same cell size; larger
  /// cells if the deformed surface needs more cells than were allocated); the grid's cover
  /// nodes are rebuilt, which allocates (the boxes and nodes do not). The tree's quality
  /// degrades with large deformations (rebuild then). Throws
  /// std::invalid_argument on a size mismatch or a non-finite coordinate (the tree is
  /// unchanged then).
  void refit(const std::vector<Eigen::Vector3d>& deformed_vertices);

  const BvhSettings& settings() const { return settings_; }
  BvhStats stats() const;
  const std::vector<Eigen::Vector3d>& vertices() const { return vertices_; }
  const std::vector<Eigen::Vector3i>& triangles() const { return triangles_; }

 private:
  /// A node as the boxes of its W children (lane k = child k) in structure-of-arrays form, so
  /// that all of them are tested at once from one block of memory (the compiler vectorizes the
  /// per-lane loops). Nodes are in depth-first order: a child node comes after its parent.
  /// Half extents include the rounding margin. Lanes 2g and 2g + 1 (W = 4) are the children of
  /// one binary node; an empty lane (next to a leaf) holds its sibling's centre, so that the
  /// lane centres order the children along a query direction.
  template <int W>
  struct alignas(64) ObbNode {
    using Scalar = double;
    static constexpr int width = W;
    static constexpr bool oriented = true;
    alignas(16) double center[3][W];        ///< c [m]
    alignas(16) double axes[9][W];          ///< axes[3 i + j]: component j of unit axis a_i
    alignas(16) double half_extents[3][W];  ///< e [m]
    std::int32_t child[W] = {};  ///< inner child: its node; leaf child: its first slot
    std::int16_t count[W] = {};  ///< leaf child: its number of triangles; inner child: 0
    std::int32_t lanes = 0;      ///< bit k set: lane k holds a child
  };
  /// An AABB node stores its boxes in float: half the memory a query streams through (128 bytes
  /// for W = 4). Each stored box contains its double box (the half extent grows by the centre's
  /// rounding and is rounded up), and the tests run in double on the stored values, so the
  /// queries stay exact.
  template <int W>
  struct alignas(64) AabbNode {
    using Scalar = float;
    static constexpr int width = W;
    static constexpr bool oriented = false;
    alignas(16) float center[3][W];        ///< c [m]
    alignas(16) float half_extents[3][W];  ///< e [m]
    std::int32_t child[W] = {};
    std::int16_t count[W] = {};
    std::int32_t lanes = 0;
  };
  /// Per node and lane: the child's triangle slots [begin, end) (for refit).
  struct LaneRanges {
    int begin[4] = {0, 0, 0, 0};
    int end[4] = {0, 0, 0, 0};
  };
  /// The entry grid over the vertices' bounds widened by the reach (half a cell).
  struct EntryGrid {
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();  ///< lower corner [m]
    double cell_m = 0;   ///< edge [m]; 0: no grid
    double reach_m = 0;  ///< cell_m / 2 [m]
    Eigen::Vector3i dims = Eigen::Vector3i::Zero();
    /// Per cell: −1, nothing within reach; −2 − i, start at cover node i; otherwise the tree node
    /// to start at (a cell whose triangles no W subtrees below their common ancestor cover).
    std::vector<std::int32_t> entry;
    std::vector<std::int32_t> lowest, highest;  ///< per cell: the slots within reach (build scratch)
    int occupied = 0;
    /// Cover nodes, of the tree's node type (the other three stay empty): the boxes of up to W
    /// parts of the binary tree (a node, or half of a 4-wide node's lanes, whose node then
    /// follows the tree's nodes as a copy with the other lanes masked) that together hold
    /// every triangle within a cell's reach, as deep as W parts allow. Cells with the same
    /// cover share one.
    std::vector<ObbNode<2>> obb2;
    std::vector<ObbNode<4>> obb4;
    std::vector<AabbNode<2>> aabb2;
    std::vector<AabbNode<4>> aabb4;
  };
  struct Traversal;  // the query algorithms, templated on the node type and on counting
  friend struct Traversal;

  void build();
  void update_geometry();  ///< corners, face normals, margin from vertices_
  /// Outward pseudo-normal at a closest-point feature of a slot (0 face, 1 + k edge k, 4 + k
  /// corner k); not normalised.
  Eigen::Vector3d pseudo_normal(int slot, int feature) const noexcept;
  void refit_boxes();
  /// The tree's node vector of type Node (the other three are empty).
  template <class Node>
  std::vector<Node>& nodes() {
    if constexpr (std::is_same_v<Node, ObbNode<2>>) {
      return obb2_;
    } else if constexpr (std::is_same_v<Node, ObbNode<4>>) {
      return obb4_;
    } else if constexpr (std::is_same_v<Node, AabbNode<2>>) {
      return aabb2_;
    } else {
      return aabb4_;
    }
  }
  template <class Node>
  void refit_nodes();
  void update_entry_grid();
  /// The grid's cover nodes of type Node (Grid: EntryGrid, const or not).
  template <class Node, class Grid>
  static auto& cover_nodes(Grid& grid) {
    if constexpr (std::is_same_v<Node, ObbNode<2>>) {
      return grid.obb2;
    } else if constexpr (std::is_same_v<Node, ObbNode<4>>) {
      return grid.obb4;
    } else if constexpr (std::is_same_v<Node, AabbNode<2>>) {
      return grid.aabb2;
    } else {
      return grid.aabb4;
    }
  }
  template <class Node>
  int entry_node(int lowest, int highest);
  struct CoverScratch;  // the lookups the cover nodes are built with
  /// The grid entry of a cell (EntryGrid::entry) from its slots within reach and its box
  /// widened by the reach, [lower, upper] [m].
  template <class Node>
  int entry_cover(int lowest, int highest, const Eigen::Vector3d& lower, const Eigen::Vector3d& upper,
                  CoverScratch& scratch);
  template <class Node>
  void truncate_to_tree();  ///< drops the masked node copies the entry grid appended

  BvhSettings settings_;
  std::vector<Eigen::Vector3d> vertices_;
  std::vector<Eigen::Vector3i> triangles_;
  OrientedBox root_box_;  ///< the whole surface's box (axes = I for an AABB tree), with margin
  std::vector<ObbNode<2>> obb2_;   ///< the tree of the chosen bounding volume and width;
  std::vector<ObbNode<4>> obb4_;   ///< the other three stay empty
  std::vector<AabbNode<2>> aabb2_;
  std::vector<AabbNode<4>> aabb4_;
  std::vector<LaneRanges> lane_ranges_;
  std::vector<int> slot_triangle_;        ///< triangle index of each slot
  std::vector<Eigen::Vector3d> corners_;  ///< 3 per slot (leaf order: a leaf's triangles are contiguous)
  /// The leaves' slot ranges [first, first + count), in slot order.
  std::vector<std::pair<int, int>> leaf_slots_;
  /// The corners again, in float and relative to leaf_corners_origin_, for the ray queries'
  /// conservative pre-test of a leaf's triangles four at a time (exact answers still come from
  /// the double test). A leaf of count slots starting at slot s occupies the 9 · count floats
  /// from 9 s, row 3 k + i (corner k, axis i) holding its count slots' values; three padding
  /// floats follow the last leaf, so that any leaf's rows can be loaded four floats at a time.
  std::vector<float> leaf_corners_;
  Eigen::Vector3d leaf_corners_origin_ = Eigen::Vector3d::Zero();  ///< centre of the vertices' box [m]
  double leaf_corners_extent_ = 0;  ///< max |corner − leaf_corners_origin_|∞ [m]
  std::vector<Eigen::Vector3d> face_normals_;  ///< per slot, outward unit
  std::vector<int> edge_neighbour_slot_;       ///< 3 per slot: the slot across edge k (corner k → k + 1)
  std::vector<int> vertex_corner_offsets_;     ///< per vertex v: its corners at [offsets[v], offsets[v + 1])
  std::vector<int> vertex_corners_;            ///< 3 · slot + k for each corner k of each slot
  EntryGrid grid_;
  double margin_ = 0;  ///< boxes are widened by this [m] so that rounding never prunes a hit
  std::size_t tree_node_slots_ = 0;  ///< the tree's nodes; the entry grid's masked copies follow
  int depth_ = 0;
  int binary_depth_ = 0;
  int node_count_ = 0;
  int leaf_count_ = 0;
  int max_leaf_size_ = 0;
};

}  // namespace touchstone::realtime::collision
