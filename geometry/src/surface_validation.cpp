// Validation of triangle surfaces: one check per SurfaceDefectKind, each naming its count and
// one example with the file's own numbers (one file: the checks share the edge and vertex maps
// they are read from, and a reader runs them all in order).
#include "surface_analysis.hpp"

#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <numeric>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

namespace touchstone::geometry {

namespace {

using Eigen::Vector3d;
using Eigen::Vector3i;

constexpr double degenerate_area_factor = 1e-14;
constexpr double coincident_vertex_factor = 1e-12;

std::string format_number(double value) {
  std::ostringstream text;
  text.precision(6);
  text << value;
  return text.str();
}

/// Names vertices, triangles and edges in messages, with the file's own numbers when known.
class Names {
 public:
  Names(const std::vector<Vector3d>& vertices, const SurfaceLabels& labels) : vertices_(vertices), labels_(labels) {}

  std::string vertex(int v) const {
    std::string text = "vertex " + std::to_string(v);
    if (has_vertex_tag(v)) text += " (" + labels_.vertex_kind + " " + std::to_string(labels_.vertex_tags[v]) + ")";
    return text;
  }
  /// "(x, y, z)" in metres.
  std::string point(int v) const {
    if (v < 0 || static_cast<std::size_t>(v) >= vertices_.size()) return "(?)";
    const Vector3d& x = vertices_[v];
    return "(" + format_number(x[0]) + ", " + format_number(x[1]) + ", " + format_number(x[2]) + ")";
  }
  std::string triangle(int t) const {
    std::string text = "triangle " + std::to_string(t);
    if (t >= 0 && static_cast<std::size_t>(t) < labels_.triangle_tags.size()) {
      text += " (" + labels_.triangle_kind + " " + std::to_string(labels_.triangle_tags[t]) + ")";
    }
    return text;
  }
  /// "edge (a, b)" with the file's numbers when known; `separator` " -> " for a directed edge.
  std::string edge(int a, int b, const char* separator = ", ") const {
    std::string text = "edge (" + std::to_string(a) + separator + std::to_string(b) + ")";
    if (has_vertex_tag(a) && has_vertex_tag(b)) {
      text += " (" + plural(labels_.vertex_kind) + " " + std::to_string(labels_.vertex_tags[a]) + separator +
              std::to_string(labels_.vertex_tags[b]) + ")";
    }
    return text;
  }

 private:
  bool has_vertex_tag(int v) const { return v >= 0 && static_cast<std::size_t>(v) < labels_.vertex_tags.size(); }
  static std::string plural(const std::string& noun) {
    const std::string vertex = "vertex";
    if (noun.size() >= vertex.size() && noun.compare(noun.size() - vertex.size(), vertex.size(), vertex) == 0) {
      return noun.substr(0, noun.size() - vertex.size()) + "vertices";
    }
    return noun + "s";
  }

  const std::vector<Vector3d>& vertices_;
  const SurfaceLabels& labels_;
};

/// "1 vertex", "3 vertices".
std::string counted(std::size_t count, const char* singular, const char* plural) {
  return std::to_string(count) + " " + (count == 1 ? singular : plural);
}

/// Union–find, to group triangle corners into fans and boundary edges into holes.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t size) {
    parent_.reserve(size);
    for (std::size_t i = 0; i < size; ++i) parent_.push_back(i);
  }
  std::size_t find(std::size_t i) {
    while (parent_[i] != i) {
      parent_[i] = parent_[parent_[i]];
      i = parent_[i];
    }
    return i;
  }
  void join(std::size_t i, std::size_t j) { parent_[find(i)] = find(j); }

 private:
  std::vector<std::size_t> parent_;
};

/// The input and what the checks so far found usable.
struct Surface {
  Surface(const std::vector<Vector3d>& vertices_in, const std::vector<Vector3i>& triangles_in,
          const std::string& source_in, const SurfaceLabels& labels, std::vector<SurfaceDefect>& found)
      : vertices(vertices_in), triangles(triangles_in), source(source_in), names(vertices_in, labels),
        defects(&found) {}

  const std::vector<Vector3d>& vertices;
  const std::vector<Vector3i>& triangles;
  const std::string& source;
  Names names;
  int n = 0;                   ///< triangles
  int vertex_count = 0;
  std::vector<char> finite;    ///< per vertex: finite coordinates
  std::vector<char> in_range;  ///< per triangle: its three indices address vertices
  std::vector<char> used;      ///< per vertex: a corner of a triangle in range
  std::vector<char> distinct;  ///< per triangle: in range and three different indices
  Vector3d lower = Vector3d::Zero();  ///< bounding box of the used, finite vertices
  Vector3d upper = Vector3d::Zero();
  double diagonal = 0;
  std::vector<SurfaceDefect>* defects = nullptr;

  void report(SurfaceDefectKind kind, std::size_t count, const std::string& what) const {
    defects->push_back({kind, count, source + ": " + what});
  }
  bool finite_triangle(int t) const {
    return in_range[t] && finite[triangles[t][0]] && finite[triangles[t][1]] && finite[triangles[t][2]];
  }
};

/// No triangles, or more than int indices address: nothing else can be checked.
bool check_size(const Surface& s) {
  if (s.triangles.empty()) {
    s.report(SurfaceDefectKind::no_triangles, 0, "the surface has no triangles");
    return false;
  }
  constexpr std::size_t limit = std::numeric_limits<int>::max() / 3;
  if (s.triangles.size() > limit || s.vertices.size() > limit) {
    s.report(SurfaceDefectKind::too_large, std::max(s.triangles.size(), s.vertices.size()),
             "too many triangles (" + std::to_string(s.triangles.size()) + ") or vertices (" +
                 std::to_string(s.vertices.size()) + "): at most " + std::to_string(limit));
    return false;
  }
  return true;
}

void check_finite_coordinates(Surface& s) {
  s.finite.assign(s.vertex_count, 0);
  std::size_t non_finite = 0, far = 0;
  int first_non_finite = -1, first_far = -1;
  for (int v = 0; v < s.vertex_count; ++v) {
    const Vector3d& x = s.vertices[v];
    const bool finite = x.allFinite();
    // Far beyond any organ the squared lengths and volumes of the later checks overflow, and
    // every triangle would be blamed for what is one vertex's (unit or parse) error.
    const bool near = finite && x.cwiseAbs().maxCoeff() <= max_surface_coordinate_m;
    s.finite[v] = near;
    if (!finite && non_finite++ == 0) first_non_finite = v;
    if (finite && !near && far++ == 0) first_far = v;
  }
  if (non_finite > 0) {
    s.report(SurfaceDefectKind::non_finite_coordinate, non_finite,
             "non-finite coordinate in " + counted(non_finite, "vertex", "vertices") + ", e.g. " +
                 s.names.vertex(first_non_finite) + " = " + s.names.point(first_non_finite));
  }
  if (far > 0) {
    s.report(SurfaceDefectKind::non_finite_coordinate, far,
             "coordinate beyond +-" + format_number(max_surface_coordinate_m) + " m in " + counted(far, "vertex", "vertices") +
                 ", e.g. " + s.names.vertex(first_far) + " = " + s.names.point(first_far) +
                 " (no organ is that large: a unit or a number misread?)");
  }
}

/// Triangles whose indices are in range; their vertices are "used".
void check_index_range(Surface& s) {
  s.in_range.assign(s.n, 1);
  s.used.assign(s.vertex_count, 0);
  std::size_t count = 0;
  int first = -1;
  int first_index = 0;
  for (int t = 0; t < s.n; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = s.triangles[t][k];
      if (v < 0 || v >= s.vertex_count) {
        if (s.in_range[t] && count++ == 0) {
          first = t;
          first_index = v;
        }
        s.in_range[t] = 0;
      }
    }
    if (s.in_range[t]) {
      for (int k = 0; k < 3; ++k) s.used[s.triangles[t][k]] = 1;
    }
  }
  if (count > 0) {
    s.report(SurfaceDefectKind::index_out_of_range, count,
             "vertex index out of range [0, " + std::to_string(s.vertex_count) + ") in " +
                 counted(count, "triangle", "triangles") + ", e.g. " + s.names.triangle(first) + " refers to vertex " +
                 std::to_string(first_index));
  }
}

/// Sizes are relative to the bounding box of the used, finite vertices.
void measure(Surface& s) {
  s.lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
  s.upper = -s.lower;
  for (int v = 0; v < s.vertex_count; ++v) {
    if (s.used[v] && s.finite[v]) {
      s.lower = s.lower.cwiseMin(s.vertices[v]);
      s.upper = s.upper.cwiseMax(s.vertices[v]);
    }
  }
  s.diagonal = s.lower[0] <= s.upper[0] ? (s.upper - s.lower).norm() : 0.0;
}

/// Degenerate: a repeated index (no edge structure), or an area that is zero relative to the
/// size of the surface (no normal).
void check_degenerate_triangles(Surface& s) {
  s.distinct.assign(s.n, 0);
  const double minimum_area = degenerate_area_factor * s.diagonal * s.diagonal;
  std::size_t count = 0;
  std::string example;
  for (int t = 0; t < s.n; ++t) {
    if (!s.in_range[t]) continue;
    const Vector3i& c = s.triangles[t];
    s.distinct[t] = c[0] != c[1] && c[1] != c[2] && c[2] != c[0];
    std::string why;
    if (!s.distinct[t]) {
      why = " repeats vertex " + std::to_string(c[0] == c[1] || c[0] == c[2] ? c[0] : c[1]);
    } else if (s.finite_triangle(t)) {
      const double area =
          0.5 * (s.vertices[c[1]] - s.vertices[c[0]]).cross(s.vertices[c[2]] - s.vertices[c[0]]).norm();
      if (!(area > minimum_area)) {
        why = " has area " + format_number(area) + " m^2 <= 1e-14 * (bounding-box diagonal)^2 = " +
              format_number(minimum_area) + " m^2";
      }
    }
    if (!why.empty() && count++ == 0) example = s.names.triangle(t) + why;
  }
  if (count > 0) {
    s.report(SurfaceDefectKind::degenerate_triangle, count,
             counted(count, "degenerate triangle", "degenerate triangles") + ", e.g. " + example);
  }
}

void check_duplicate_triangles(const Surface& s) {
  std::vector<std::pair<std::array<int, 3>, int>> sorted;
  sorted.reserve(s.n);
  for (int t = 0; t < s.n; ++t) {
    if (!s.distinct[t]) continue;
    std::array<int, 3> key{s.triangles[t][0], s.triangles[t][1], s.triangles[t][2]};
    std::sort(key.begin(), key.end());
    sorted.emplace_back(key, t);
  }
  std::sort(sorted.begin(), sorted.end());
  std::size_t count = 0;
  std::pair<int, int> example{s.n, s.n};
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i].first != sorted[i - 1].first) continue;
    ++count;
    // The group's first triangle is the earlier one; report the pair with the lowest numbers.
    std::size_t first = i - 1;
    while (first > 0 && sorted[first - 1].first == sorted[i].first) --first;
    example = std::min(example, {sorted[first].second, sorted[i].second});
  }
  if (count > 0) {
    s.report(SurfaceDefectKind::duplicate_triangle, count,
             counted(count, "duplicate triangle", "duplicate triangles") +
                 " (the same three vertices as an earlier triangle), e.g. " + s.names.triangle(example.first) +
                 " and " + s.names.triangle(example.second) + " are duplicates");
  }
}

void check_duplicate_vertices(const Surface& s) {
  std::vector<char> used_finite(s.vertex_count);
  for (int v = 0; v < s.vertex_count; ++v) used_finite[v] = s.used[v] && s.finite[v];
  const double tolerance = coincident_vertex_factor * s.diagonal;
  const std::vector<int> representative = coincident_vertices(s.vertices, tolerance, used_finite);
  std::size_t count = 0;
  int first = -1;
  for (int v = 0; v < s.vertex_count; ++v) {
    if (representative[v] != v && count++ == 0) first = v;
  }
  if (count > 0) {
    s.report(SurfaceDefectKind::duplicate_vertex, count,
             counted(count, "duplicated vertex", "duplicated vertices") +
                 " (at the same point as an earlier vertex, within 1e-12 * bounding-box diagonal = " +
                 format_number(tolerance) + " m; weld them), e.g. " + s.names.vertex(representative[first]) +
                 " and " + s.names.vertex(first) + " at " + s.names.point(first));
  }
}

/// A triangle edge as traversed by its triangle.
struct DirectedEdge {
  int low, high, triangle, edge;
  bool forward;  // traversed low → high
};

/// The edges of the triangles with distinct corners, grouped by their two vertices. Each edge
/// should join exactly two triangles that traverse it in opposite directions.
struct Edges {
  std::vector<DirectedEdge> sorted;  ///< by (low, high, triangle, edge): a group per undirected edge
  std::vector<int> neighbours;       ///< across edge k of triangle t at 3t + k; -1 unless a two-triangle edge
  std::vector<char> same_direction;  ///< at 3t + k: both triangles traverse the edge in the same direction
  std::vector<char> on_bad_edge;     ///< per vertex: an endpoint of a boundary or non-manifold edge
  std::size_t boundary_count = 0;
  std::size_t non_manifold_count = 0;
  std::size_t conflict_count = 0;    ///< two-triangle edges traversed in the same direction
  // Examples: the group whose first triangle has the lowest number, so that messages do not
  // depend on the sort. [begin, end) in `sorted`.
  std::pair<std::size_t, std::size_t> boundary_example;
  std::pair<std::size_t, std::size_t> non_manifold_example;

  /// Calls visit(begin, end) for each group of one undirected edge.
  template <typename Visit>
  void for_each_group(Visit&& visit) const {
    for (std::size_t begin = 0; begin < sorted.size();) {
      std::size_t end = begin + 1;
      while (end < sorted.size() && sorted[end].low == sorted[begin].low && sorted[end].high == sorted[begin].high) {
        ++end;
      }
      visit(begin, end);
      begin = end;
    }
  }
};

Edges edges_of(const Surface& s) {
  Edges e;
  e.sorted.reserve(3 * static_cast<std::size_t>(s.n));
  for (int t = 0; t < s.n; ++t) {
    if (!s.distinct[t]) continue;
    for (int k = 0; k < 3; ++k) {
      const int a = s.triangles[t][k];
      const int b = s.triangles[t][(k + 1) % 3];
      e.sorted.push_back({std::min(a, b), std::max(a, b), t, k, a < b});
    }
  }
  std::sort(e.sorted.begin(), e.sorted.end(), [](const DirectedEdge& p, const DirectedEdge& q) {
    return std::tie(p.low, p.high, p.triangle, p.edge) < std::tie(q.low, q.high, q.triangle, q.edge);
  });

  e.neighbours.assign(3 * static_cast<std::size_t>(s.n), -1);
  e.same_direction.assign(3 * static_cast<std::size_t>(s.n), 0);
  e.on_bad_edge.assign(s.vertex_count, 0);
  e.boundary_example = {e.sorted.size(), e.sorted.size()};
  e.non_manifold_example = {e.sorted.size(), e.sorted.size()};
  const auto lower_triangle = [&](std::size_t candidate, std::size_t current) {
    return current == e.sorted.size() || e.sorted[candidate].triangle < e.sorted[current].triangle;
  };
  e.for_each_group([&](std::size_t begin, std::size_t end) {
    const DirectedEdge& p = e.sorted[begin];
    if (end - begin == 2) {
      const DirectedEdge& q = e.sorted[begin + 1];
      e.neighbours[3 * p.triangle + p.edge] = q.triangle;
      e.neighbours[3 * q.triangle + q.edge] = p.triangle;
      if (p.forward == q.forward) {
        e.same_direction[3 * p.triangle + p.edge] = 1;
        e.same_direction[3 * q.triangle + q.edge] = 1;
        ++e.conflict_count;
      }
    } else {
      e.on_bad_edge[p.low] = 1;
      e.on_bad_edge[p.high] = 1;
      if (end - begin == 1) {
        ++e.boundary_count;
        if (lower_triangle(begin, e.boundary_example.first)) e.boundary_example = {begin, end};
      } else {
        ++e.non_manifold_count;
        if (lower_triangle(begin, e.non_manifold_example.first)) e.non_manifold_example = {begin, end};
      }
    }
  });
  return e;
}

void check_non_manifold_edges(const Surface& s, const Edges& e) {
  if (e.non_manifold_count == 0) return;
  const auto [begin, end] = e.non_manifold_example;
  std::string list;
  for (std::size_t i = begin; i < end; ++i) list += (i == begin ? "" : ", ") + s.names.triangle(e.sorted[i].triangle);
  s.report(SurfaceDefectKind::non_manifold_edge, e.non_manifold_count,
           "the surface is non-manifold: " + counted(e.non_manifold_count, "edge", "edges") +
               " shared by more than two triangles, e.g. " + s.names.edge(e.sorted[begin].low, e.sorted[begin].high) +
               " is shared by " + std::to_string(end - begin) + " triangles (" + list + ")");
}

void check_boundary_edges(const Surface& s, const Edges& e) {
  if (e.boundary_count == 0) return;
  // A hole is a connected set of boundary edges.
  DisjointSets holes(s.vertex_count);
  e.for_each_group([&](std::size_t begin, std::size_t end) {
    if (end - begin == 1) holes.join(e.sorted[begin].low, e.sorted[begin].high);
  });
  std::set<std::size_t> hole_roots;
  e.for_each_group([&](std::size_t begin, std::size_t end) {
    if (end - begin == 1) hole_roots.insert(holes.find(e.sorted[begin].low));
  });
  const DirectedEdge& example = e.sorted[e.boundary_example.first];
  const int from = s.triangles[example.triangle][example.edge];
  const int to = s.triangles[example.triangle][(example.edge + 1) % 3];
  s.report(SurfaceDefectKind::boundary_edge, e.boundary_count,
           "the surface is not closed: " + counted(hole_roots.size(), "hole", "holes") + " (" +
               counted(e.boundary_count, "boundary edge", "boundary edges") +
               ", each in one triangle only), e.g. " + s.names.edge(from, to) + " from " + s.names.point(from) +
               " to " + s.names.point(to) + " belongs only to " + s.names.triangle(example.triangle));
}

void check_orientation_consistency(const Surface& s, const Edges& e) {
  if (e.conflict_count == 0) return;
  const int n = s.n;
  // Two-colour the triangles across two-triangle edges: a same-direction edge joins opposite
  // colours. In each connected piece the smaller colour class is the flipped set.
  std::vector<signed char> colour(n, -1);
  std::vector<int> piece(n, -1);
  std::vector<std::array<std::size_t, 2>> piece_sizes;
  bool non_orientable = false;
  std::vector<int> queue;
  for (int seed = 0; seed < n; ++seed) {
    if (!s.distinct[seed] || colour[seed] >= 0) continue;
    const int id = static_cast<int>(piece_sizes.size());
    piece_sizes.push_back({0, 0});
    colour[seed] = 0;
    piece[seed] = id;
    queue.assign(1, seed);
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const int t = queue[head];
      ++piece_sizes[id][colour[t]];
      for (int k = 0; k < 3; ++k) {
        const int u = e.neighbours[3 * t + k];
        if (u < 0) continue;
        const signed char wanted = static_cast<signed char>(colour[t] ^ e.same_direction[3 * t + k]);
        if (colour[u] < 0) {
          colour[u] = wanted;
          piece[u] = id;
          queue.push_back(u);
        } else if (colour[u] != wanted) {
          non_orientable = true;
        }
      }
    }
  }
  const auto flipped = [&](int t) {
    const auto& sizes = piece_sizes[piece[t]];
    const int minority = sizes[1] <= sizes[0] ? 1 : 0;
    return colour[t] == minority;
  };
  std::size_t flipped_count = 0;
  for (int t = 0; t < n; ++t) {
    if (colour[t] >= 0 && flipped(t)) ++flipped_count;
  }
  // The example: the lowest flipped triangle on a same-direction edge (any such triangle
  // when the surface is non-orientable).
  int example = -1;
  int example_edge = 0;
  for (int t = 0; t < n && example < 0; ++t) {
    if (colour[t] < 0 || (!non_orientable && !flipped(t))) continue;
    for (int k = 0; k < 3; ++k) {
      if (e.same_direction[3 * t + k]) {
        example = t;
        example_edge = k;
        break;
      }
    }
  }
  const int from = s.triangles[example][example_edge];
  const int to = s.triangles[example][(example_edge + 1) % 3];
  const int other = e.neighbours[3 * example + example_edge];
  std::string what = "inconsistent orientation: ";
  if (non_orientable) {
    what += "the surface is non-orientable (no set of flips makes it consistent; " +
            counted(e.conflict_count, "edge is", "edges are") + " traversed in the same direction by both triangles)";
  } else {
    what += counted(flipped_count, "triangle", "triangles") + " flipped against " +
            (flipped_count == 1 ? "its" : "their") + " neighbours (" + counted(e.conflict_count, "edge", "edges") +
            " traversed in the same direction by both triangles)";
  }
  what += ", e.g. " + s.names.triangle(example) + " and " + s.names.triangle(other) + " both traverse " +
          s.names.edge(from, to, " -> ");
  s.report(SurfaceDefectKind::inconsistent_orientation, non_orientable ? e.conflict_count : flipped_count, what);
}

/// Around each vertex the triangles must form one fan: corners meeting across an edge join.
void check_non_manifold_vertices(const Surface& s, const Edges& e) {
  const int n = s.n;
  DisjointSets fans(3 * static_cast<std::size_t>(n));
  for (int t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int u = e.neighbours[3 * t + k];
      if (u < 0) continue;
      const int a = s.triangles[t][k];
      const int b = s.triangles[t][(k + 1) % 3];
      for (int m = 0; m < 3; ++m) {
        if (s.triangles[u][m] == a) fans.join(3 * t + k, 3 * u + m);
        if (s.triangles[u][m] == b) fans.join(3 * t + (k + 1) % 3, 3 * u + m);
      }
    }
  }
  std::vector<std::size_t> fan_of_vertex(s.vertex_count, std::numeric_limits<std::size_t>::max());
  std::vector<int> triangle_of_vertex(s.vertex_count, -1);
  std::vector<char> reported(s.vertex_count, 0);
  std::size_t count = 0;
  int worst_vertex = -1;
  int first_triangle = -1;
  int other_triangle = -1;
  for (int t = 0; t < n; ++t) {
    if (!s.distinct[t]) continue;
    for (int k = 0; k < 3; ++k) {
      const int v = s.triangles[t][k];
      if (e.on_bad_edge[v]) continue;
      const std::size_t fan = fans.find(3 * static_cast<std::size_t>(t) + k);
      if (triangle_of_vertex[v] < 0) {
        fan_of_vertex[v] = fan;
        triangle_of_vertex[v] = t;
      } else if (fan_of_vertex[v] != fan && !reported[v]) {
        reported[v] = 1;
        ++count;
        if (worst_vertex < 0 || v < worst_vertex) {
          worst_vertex = v;
          first_triangle = triangle_of_vertex[v];
          other_triangle = t;
        }
      }
    }
  }
  if (count > 0) {
    s.report(SurfaceDefectKind::non_manifold_vertex, count,
             counted(count, "non-manifold vertex", "non-manifold vertices") +
                 " (its triangles form separate fans that touch only there), e.g. " + s.names.vertex(worst_vertex) +
                 " at " + s.names.point(worst_vertex) + ": " + s.names.triangle(first_triangle) + " and " +
                 s.names.triangle(other_triangle) + " are in different fans");
  }
}

/// Whether segment pq crosses triangle abc (Möller–Trumbore with the segment's parameter in
/// [0, 1]); a segment in the triangle's plane is not counted.
bool segment_crosses_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d d = q - p, e1 = b - a, e2 = c - a;
  const Vector3d h = d.cross(e2);
  const double det = e1.dot(h);
  const double scale = d.norm() * e1.norm() * e2.norm();
  if (!(std::abs(det) > 1e-12 * scale)) return false;
  const Vector3d r = p - a;
  const double u = r.dot(h) / det;
  if (u < 0 || u > 1) return false;
  const Vector3d k = r.cross(e1);
  const double v = d.dot(k) / det;
  if (v < 0 || u + v > 1) return false;
  const double t = e2.dot(k) / det;
  return t >= 0 && t <= 1;
}

/// Triangles that pass through each other (an organ folded into itself, two shells that overlap):
/// on such a surface "inside" has no meaning and no volume can be meshed. Only pairs sharing no
/// vertex are tested, and only where an edge of one crosses the other; coplanar overlaps are not
/// detected. Checked on closed, manifold, consistently oriented surfaces only (the defects before
/// this one explain the others), through a uniform grid of cells about two edges wide.
void check_self_intersections(const Surface& s) {
  using Kind = SurfaceDefectKind;
  const bool closed = std::none_of(s.defects->begin(), s.defects->end(), [](const SurfaceDefect& d) {
    return d.kind != Kind::inward_orientation;
  });
  if (!closed || s.n == 0) return;
  double edge_sum = 0;
  for (int t = 0; t < s.n; ++t)
    for (int k = 0; k < 3; ++k) edge_sum += (s.vertices[s.triangles[t][k]] - s.vertices[s.triangles[t][(k + 1) % 3]]).norm();
  // Cells about two mean edges wide, coarsened until the triangles' cell ranges stay within a
  // few dozen per triangle (a few huge triangles among small ones must not fill memory).
  double cell = std::max(2 * edge_sum / (3.0 * s.n), 1e-3 * s.diagonal);
  for (;;) {
    double entries = 0;
    for (int t = 0; t < s.n; ++t) {
      const Vector3d& a = s.vertices[s.triangles[t][0]];
      const Vector3d& b = s.vertices[s.triangles[t][1]];
      const Vector3d& c = s.vertices[s.triangles[t][2]];
      const Vector3d extent = a.cwiseMax(b).cwiseMax(c) - a.cwiseMin(b).cwiseMin(c);
      entries += (extent.x() / cell + 2) * (extent.y() / cell + 2) * (extent.z() / cell + 2);
    }
    if (entries <= 64.0 * s.n + 1e6) break;
    cell *= 2;
  }
  std::array<long long, 3> counts{};
  for (int d = 0; d < 3; ++d) counts[d] = std::max(1LL, static_cast<long long>(std::ceil((s.upper[d] - s.lower[d]) / cell)) + 1);
  const auto cell_of = [&](const Vector3d& x, int d) {
    return std::clamp(static_cast<long long>(std::floor((x[d] - s.lower[d]) / cell)), 0LL, counts[d] - 1);
  };
  std::unordered_map<long long, std::vector<int>> cells;
  std::vector<std::array<long long, 6>> boxes(s.n);
  for (int t = 0; t < s.n; ++t) {
    const Vector3d& a = s.vertices[s.triangles[t][0]];
    const Vector3d& b = s.vertices[s.triangles[t][1]];
    const Vector3d& c = s.vertices[s.triangles[t][2]];
    const Vector3d lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    for (int d = 0; d < 3; ++d) boxes[t][d] = cell_of(lo, d), boxes[t][3 + d] = cell_of(hi, d);
    for (long long x = boxes[t][0]; x <= boxes[t][3]; ++x)
      for (long long y = boxes[t][1]; y <= boxes[t][4]; ++y)
        for (long long z = boxes[t][2]; z <= boxes[t][5]; ++z) cells[(x * counts[1] + y) * counts[2] + z].push_back(t);
  }
  std::size_t count = 0;
  std::pair<int, int> example{-1, -1};
  for (const auto& [key, members] : cells) {
    const long long z = key % counts[2], y = (key / counts[2]) % counts[1], x = key / (counts[1] * counts[2]);
    for (std::size_t i = 0; i < members.size(); ++i)
      for (std::size_t j = i + 1; j < members.size(); ++j) {
        const int t = members[i], u = members[j];
        // Each pair once: in the cell at the low corner of the overlap of their cell ranges.
        if (x != std::max(boxes[t][0], boxes[u][0]) || y != std::max(boxes[t][1], boxes[u][1]) ||
            z != std::max(boxes[t][2], boxes[u][2]))
          continue;
        const Vector3i& p = s.triangles[t];
        const Vector3i& q = s.triangles[u];
        bool shared = false;
        for (int k = 0; k < 3; ++k)
          for (int l = 0; l < 3; ++l) shared = shared || p[k] == q[l];
        if (shared) continue;
        bool crossing = false;
        for (int k = 0; k < 3 && !crossing; ++k) {
          crossing = segment_crosses_triangle(s.vertices[p[k]], s.vertices[p[(k + 1) % 3]], s.vertices[q[0]], s.vertices[q[1]], s.vertices[q[2]]) ||
                     segment_crosses_triangle(s.vertices[q[k]], s.vertices[q[(k + 1) % 3]], s.vertices[p[0]], s.vertices[p[1]], s.vertices[p[2]]);
        }
        if (!crossing) continue;
        if (count++ == 0) example = {std::min(t, u), std::max(t, u)};
      }
  }
  if (count > 0)
    s.report(Kind::self_intersection, count,
             counted(count, "pair of intersecting triangles", "pairs of intersecting triangles") +
                 " (the surface passes through itself), e.g. " + s.names.triangle(example.first) + " and " +
                 s.names.triangle(example.second));
}

/// The volume's sign means something only on a closed, consistently oriented surface: returns
/// the enclosed volume [m³] there (0 otherwise) and reports a non-positive one.
double check_inward_orientation(const Surface& s) {
  using Kind = SurfaceDefectKind;
  const bool closed = std::none_of(s.defects->begin(), s.defects->end(), [](const SurfaceDefect& d) {
    return d.kind == Kind::non_finite_coordinate || d.kind == Kind::index_out_of_range ||
           d.kind == Kind::non_manifold_edge || d.kind == Kind::boundary_edge ||
           d.kind == Kind::inconsistent_orientation;
  });
  if (!closed) return 0;
  // Divergence theorem about the box centre, which keeps the triple products well scaled.
  const Vector3d origin = 0.5 * (s.lower + s.upper);
  double volume_m3 = 0;
  for (const Vector3i& triangle : s.triangles) {
    const Vector3d a = s.vertices[triangle[0]] - origin;
    const Vector3d b = s.vertices[triangle[1]] - origin;
    const Vector3d c = s.vertices[triangle[2]] - origin;
    volume_m3 += a.dot(b.cross(c)) / 6;
  }
  if (!(volume_m3 > 0)) {
    s.report(Kind::inward_orientation, s.triangles.size(),
             "the surface encloses a non-positive volume (" + format_number(volume_m3) +
                 " m^3): its triangles are oriented inward (expected counter-clockwise seen from outside)");
  }
  return volume_m3;
}

}  // namespace

namespace detail {

SurfaceAnalysis analyse_surface(const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles,
                                const std::string& source, const SurfaceLabels& labels) {
  SurfaceAnalysis result;
  Surface s(vertices, triangles, source, labels, result.defects);
  if (!check_size(s)) return result;
  s.n = static_cast<int>(triangles.size());
  s.vertex_count = static_cast<int>(vertices.size());
  check_finite_coordinates(s);
  check_index_range(s);
  measure(s);
  check_degenerate_triangles(s);
  check_duplicate_triangles(s);
  check_duplicate_vertices(s);
  Edges edges = edges_of(s);
  check_non_manifold_edges(s, edges);
  check_boundary_edges(s, edges);
  check_orientation_consistency(s, edges);
  check_non_manifold_vertices(s, edges);
  result.volume_m3 = check_inward_orientation(s);
  check_self_intersections(s);
  result.neighbours = std::move(edges.neighbours);
  return result;
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------

const char* to_string(SurfaceDefectKind kind) {
  switch (kind) {
    case SurfaceDefectKind::no_triangles: return "no triangles";
    case SurfaceDefectKind::too_large: return "too large";
    case SurfaceDefectKind::non_finite_coordinate: return "non-finite coordinate";
    case SurfaceDefectKind::index_out_of_range: return "index out of range";
    case SurfaceDefectKind::degenerate_triangle: return "degenerate triangle";
    case SurfaceDefectKind::duplicate_triangle: return "duplicate triangle";
    case SurfaceDefectKind::duplicate_vertex: return "duplicated vertex";
    case SurfaceDefectKind::non_manifold_edge: return "non-manifold edge";
    case SurfaceDefectKind::boundary_edge: return "hole (boundary edge)";
    case SurfaceDefectKind::inconsistent_orientation: return "inconsistent orientation";
    case SurfaceDefectKind::non_manifold_vertex: return "non-manifold vertex";
    case SurfaceDefectKind::inward_orientation: return "inward orientation";
    case SurfaceDefectKind::self_intersection: return "self-intersection";
  }
  return "unknown defect";
}

std::vector<SurfaceDefect> validate_surface(const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles,
                                            const std::string& source, const SurfaceLabels& labels) {
  return detail::analyse_surface(vertices, triangles, source, labels).defects;
}

}  // namespace touchstone::geometry
