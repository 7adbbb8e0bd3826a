#include "touchstone/geometry/triangle_surface.hpp"

#include "touchstone/geometry/closest_point_on_triangle.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
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
constexpr double degenerate_area_factor = 1e-14;
constexpr double coincident_vertex_factor = 1e-12;

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

/// What validation finds, plus what the constructor reuses.
struct Analysis {
  std::vector<SurfaceDefect> defects;
  std::vector<int> neighbours;  ///< across edge k (corner k → k + 1) of each triangle; complete when valid
  double volume_m3 = 0;
};

/// The checks behind validate_surface and the constructor. Every check skips what an earlier
/// one found broken, so that one defect is reported once, not as a cascade of others.
Analysis analyse(const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles,
                 const std::string& source, const SurfaceLabels& labels) {
  using Kind = SurfaceDefectKind;
  Analysis result;
  const Names names(vertices, labels);
  const auto report = [&](Kind kind, std::size_t count, const std::string& what) {
    result.defects.push_back({kind, count, source + ": " + what});
  };
  if (triangles.empty()) {
    report(Kind::no_triangles, 0, "the surface has no triangles");
    return result;
  }
  constexpr std::size_t limit = std::numeric_limits<int>::max() / 3;
  if (triangles.size() > limit || vertices.size() > limit) {
    report(Kind::too_large, std::max(triangles.size(), vertices.size()),
           "too many triangles (" + std::to_string(triangles.size()) + ") or vertices (" +
               std::to_string(vertices.size()) + "): at most " + std::to_string(limit));
    return result;
  }
  const int n = static_cast<int>(triangles.size());
  const int vertex_count = static_cast<int>(vertices.size());

  std::vector<char> finite(vertex_count);
  {
    std::size_t count = 0;
    int first = -1;
    for (int v = 0; v < vertex_count; ++v) {
      finite[v] = vertices[v].allFinite();
      if (!finite[v] && count++ == 0) first = v;
    }
    if (count > 0) {
      report(Kind::non_finite_coordinate, count,
             "non-finite coordinate in " + counted(count, "vertex", "vertices") + ", e.g. " + names.vertex(first) +
                 " = " + names.point(first));
    }
  }

  // Triangles whose indices are in range; their vertices are "used".
  std::vector<char> in_range(n, 1);
  std::vector<char> used(vertex_count, 0);
  {
    std::size_t count = 0;
    int first = -1;
    int first_index = 0;
    for (int t = 0; t < n; ++t) {
      for (int k = 0; k < 3; ++k) {
        const int v = triangles[t][k];
        if (v < 0 || v >= vertex_count) {
          if (in_range[t] && count++ == 0) {
            first = t;
            first_index = v;
          }
          in_range[t] = 0;
        }
      }
      if (in_range[t]) {
        for (int k = 0; k < 3; ++k) used[triangles[t][k]] = 1;
      }
    }
    if (count > 0) {
      report(Kind::index_out_of_range, count,
             "vertex index out of range [0, " + std::to_string(vertex_count) + ") in " +
                 counted(count, "triangle", "triangles") + ", e.g. " + names.triangle(first) + " refers to vertex " +
                 std::to_string(first_index));
    }
  }

  // Sizes are relative to the bounding box of the used, finite vertices.
  Vector3d lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
  Vector3d upper = -lower;
  for (int v = 0; v < vertex_count; ++v) {
    if (used[v] && finite[v]) {
      lower = lower.cwiseMin(vertices[v]);
      upper = upper.cwiseMax(vertices[v]);
    }
  }
  const double diagonal = lower[0] <= upper[0] ? (upper - lower).norm() : 0.0;
  const auto finite_triangle = [&](int t) {
    return in_range[t] && finite[triangles[t][0]] && finite[triangles[t][1]] && finite[triangles[t][2]];
  };

  // Degenerate: a repeated index (no edge structure), or an area that is zero relative to the
  // size of the surface (no normal).
  std::vector<char> distinct(n, 0);
  {
    const double minimum_area = degenerate_area_factor * diagonal * diagonal;
    std::size_t count = 0;
    std::string example;
    for (int t = 0; t < n; ++t) {
      if (!in_range[t]) continue;
      const Vector3i& c = triangles[t];
      distinct[t] = c[0] != c[1] && c[1] != c[2] && c[2] != c[0];
      std::string why;
      if (!distinct[t]) {
        why = " repeats vertex " + std::to_string(c[0] == c[1] || c[0] == c[2] ? c[0] : c[1]);
      } else if (finite_triangle(t)) {
        const double area = 0.5 * (vertices[c[1]] - vertices[c[0]]).cross(vertices[c[2]] - vertices[c[0]]).norm();
        if (!(area > minimum_area)) {
          why = " has area " + format_number(area) + " m^2 <= 1e-14 * (bounding-box diagonal)^2 = " +
                format_number(minimum_area) + " m^2";
        }
      }
      if (!why.empty() && count++ == 0) example = names.triangle(t) + why;
    }
    if (count > 0) {
      report(Kind::degenerate_triangle, count,
             counted(count, "degenerate triangle", "degenerate triangles") + ", e.g. " + example);
    }
  }

  {
    std::vector<std::pair<std::array<int, 3>, int>> sorted;
    sorted.reserve(n);
    for (int t = 0; t < n; ++t) {
      if (!distinct[t]) continue;
      std::array<int, 3> key{triangles[t][0], triangles[t][1], triangles[t][2]};
      std::sort(key.begin(), key.end());
      sorted.emplace_back(key, t);
    }
    std::sort(sorted.begin(), sorted.end());
    std::size_t count = 0;
    std::pair<int, int> example{n, n};
    for (std::size_t i = 1; i < sorted.size(); ++i) {
      if (sorted[i].first != sorted[i - 1].first) continue;
      ++count;
      // The group's first triangle is the earlier one; report the pair with the lowest numbers.
      std::size_t first = i - 1;
      while (first > 0 && sorted[first - 1].first == sorted[i].first) --first;
      example = std::min(example, {sorted[first].second, sorted[i].second});
    }
    if (count > 0) {
      report(Kind::duplicate_triangle, count,
             counted(count, "duplicate triangle", "duplicate triangles") +
                 " (the same three vertices as an earlier triangle), e.g. " + names.triangle(example.first) + " and " +
                 names.triangle(example.second) + " are duplicates");
    }
  }

  {
    std::vector<char> used_finite(vertex_count);
    for (int v = 0; v < vertex_count; ++v) used_finite[v] = used[v] && finite[v];
    const double tolerance = coincident_vertex_factor * diagonal;
    const std::vector<int> representative = coincident_vertices(vertices, tolerance, used_finite);
    std::size_t count = 0;
    int first = -1;
    for (int v = 0; v < vertex_count; ++v) {
      if (representative[v] != v && count++ == 0) first = v;
    }
    if (count > 0) {
      report(Kind::duplicate_vertex, count,
             counted(count, "duplicated vertex", "duplicated vertices") +
                 " (at the same point as an earlier vertex, within 1e-12 * bounding-box diagonal = " +
                 format_number(tolerance) + " m; weld them), e.g. " + names.vertex(representative[first]) + " and " +
                 names.vertex(first) + " at " + names.point(first));
    }
  }

  // Edges: each should join exactly two triangles that traverse it in opposite directions.
  struct DirectedEdge {
    int low, high, triangle, edge;
    bool forward;  // traversed low → high
  };
  std::vector<DirectedEdge> edges;
  edges.reserve(3 * static_cast<std::size_t>(n));
  for (int t = 0; t < n; ++t) {
    if (!distinct[t]) continue;
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[t][k];
      const int b = triangles[t][(k + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), t, k, a < b});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const DirectedEdge& p, const DirectedEdge& q) {
    return std::tie(p.low, p.high, p.triangle, p.edge) < std::tie(q.low, q.high, q.triangle, q.edge);
  });

  result.neighbours.assign(3 * static_cast<std::size_t>(n), -1);
  std::vector<char> same_direction(3 * static_cast<std::size_t>(n), 0);
  std::vector<char> on_bad_edge(vertex_count, 0);  // an endpoint of a boundary or non-manifold edge
  DisjointSets holes(vertex_count);
  std::size_t boundary_count = 0;
  std::size_t non_manifold_count = 0;
  std::size_t conflict_count = 0;
  // Examples: the group whose first triangle has the lowest number, so that messages do not
  // depend on the sort.
  std::pair<std::size_t, std::size_t> boundary_example{edges.size(), edges.size()};
  std::pair<std::size_t, std::size_t> non_manifold_example{edges.size(), edges.size()};
  const auto lower_triangle = [&](std::size_t candidate, std::size_t current) {
    return current == edges.size() || edges[candidate].triangle < edges[current].triangle;
  };
  for (std::size_t begin = 0; begin < edges.size();) {
    std::size_t end = begin + 1;
    while (end < edges.size() && edges[end].low == edges[begin].low && edges[end].high == edges[begin].high) ++end;
    const DirectedEdge& p = edges[begin];
    if (end - begin == 2) {
      const DirectedEdge& q = edges[begin + 1];
      result.neighbours[3 * p.triangle + p.edge] = q.triangle;
      result.neighbours[3 * q.triangle + q.edge] = p.triangle;
      if (p.forward == q.forward) {
        same_direction[3 * p.triangle + p.edge] = 1;
        same_direction[3 * q.triangle + q.edge] = 1;
        ++conflict_count;
      }
    } else {
      on_bad_edge[p.low] = 1;
      on_bad_edge[p.high] = 1;
      if (end - begin == 1) {
        ++boundary_count;
        holes.join(p.low, p.high);
        if (lower_triangle(begin, boundary_example.first)) boundary_example = {begin, end};
      } else {
        ++non_manifold_count;
        if (lower_triangle(begin, non_manifold_example.first)) non_manifold_example = {begin, end};
      }
    }
    begin = end;
  }

  if (non_manifold_count > 0) {
    const auto [begin, end] = non_manifold_example;
    std::string list;
    for (std::size_t i = begin; i < end; ++i) list += (i == begin ? "" : ", ") + names.triangle(edges[i].triangle);
    report(Kind::non_manifold_edge, non_manifold_count,
           "the surface is non-manifold: " + counted(non_manifold_count, "edge", "edges") +
               " shared by more than two triangles, e.g. " + names.edge(edges[begin].low, edges[begin].high) +
               " is shared by " + std::to_string(end - begin) + " triangles (" + list + ")");
  }
  if (boundary_count > 0) {
    // A hole is a connected set of boundary edges.
    std::set<std::size_t> hole_roots;
    for (std::size_t begin = 0; begin < edges.size();) {
      std::size_t end = begin + 1;
      while (end < edges.size() && edges[end].low == edges[begin].low && edges[end].high == edges[begin].high) ++end;
      if (end - begin == 1) hole_roots.insert(holes.find(edges[begin].low));
      begin = end;
    }
    const DirectedEdge& e = edges[boundary_example.first];
    const int from = triangles[e.triangle][e.edge];
    const int to = triangles[e.triangle][(e.edge + 1) % 3];
    report(Kind::boundary_edge, boundary_count,
           "the surface is not closed: " + counted(hole_roots.size(), "hole", "holes") + " (" +
               counted(boundary_count, "boundary edge", "boundary edges") +
               ", each in one triangle only), e.g. " + names.edge(from, to) + " from " + names.point(from) + " to " +
               names.point(to) + " belongs only to " + names.triangle(e.triangle));
  }

  if (conflict_count > 0) {
    // Two-colour the triangles across two-triangle edges: a same-direction edge joins opposite
    // colours. In each connected piece the smaller colour class is the flipped set.
    std::vector<signed char> colour(n, -1);
    std::vector<int> piece(n, -1);
    std::vector<std::array<std::size_t, 2>> piece_sizes;
    bool non_orientable = false;
    std::vector<int> queue;
    for (int seed = 0; seed < n; ++seed) {
      if (!distinct[seed] || colour[seed] >= 0) continue;
      const int id = static_cast<int>(piece_sizes.size());
      piece_sizes.push_back({0, 0});
      colour[seed] = 0;
      piece[seed] = id;
      queue.assign(1, seed);
      for (std::size_t head = 0; head < queue.size(); ++head) {
        const int t = queue[head];
        ++piece_sizes[id][colour[t]];
        for (int k = 0; k < 3; ++k) {
          const int u = result.neighbours[3 * t + k];
          if (u < 0) continue;
          const signed char wanted = static_cast<signed char>(colour[t] ^ same_direction[3 * t + k]);
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
        if (same_direction[3 * t + k]) {
          example = t;
          example_edge = k;
          break;
        }
      }
    }
    const int from = triangles[example][example_edge];
    const int to = triangles[example][(example_edge + 1) % 3];
    const int other = result.neighbours[3 * example + example_edge];
    std::string what = "inconsistent orientation: ";
    if (non_orientable) {
      what += "the surface is non-orientable (no set of flips makes it consistent; " +
              counted(conflict_count, "edge is", "edges are") + " traversed in the same direction by both triangles)";
    } else {
      what += counted(flipped_count, "triangle", "triangles") + " flipped against " +
              (flipped_count == 1 ? "its" : "their") + " neighbours (" +
              counted(conflict_count, "edge", "edges") + " traversed in the same direction by both triangles)";
    }
    what += ", e.g. " + names.triangle(example) + " and " + names.triangle(other) + " both traverse " +
            names.edge(from, to, " -> ");
    report(Kind::inconsistent_orientation, non_orientable ? conflict_count : flipped_count, what);
  }

  // Around each vertex the triangles must form one fan: corners meeting across an edge join.
  {
    DisjointSets fans(3 * static_cast<std::size_t>(n));
    for (int t = 0; t < n; ++t) {
      for (int k = 0; k < 3; ++k) {
        const int u = result.neighbours[3 * t + k];
        if (u < 0) continue;
        const int a = triangles[t][k];
        const int b = triangles[t][(k + 1) % 3];
        for (int m = 0; m < 3; ++m) {
          if (triangles[u][m] == a) fans.join(3 * t + k, 3 * u + m);
          if (triangles[u][m] == b) fans.join(3 * t + (k + 1) % 3, 3 * u + m);
        }
      }
    }
    std::vector<std::size_t> fan_of_vertex(vertex_count, std::numeric_limits<std::size_t>::max());
    std::vector<int> triangle_of_vertex(vertex_count, -1);
    std::vector<char> reported(vertex_count, 0);
    std::size_t count = 0;
    int worst_vertex = -1;
    int first_triangle = -1;
    int other_triangle = -1;
    for (int t = 0; t < n; ++t) {
      if (!distinct[t]) continue;
      for (int k = 0; k < 3; ++k) {
        const int v = triangles[t][k];
        if (on_bad_edge[v]) continue;
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
      report(Kind::non_manifold_vertex, count,
             counted(count, "non-manifold vertex", "non-manifold vertices") +
                 " (its triangles form separate fans that touch only there), e.g. " + names.vertex(worst_vertex) +
                 " at " + names.point(worst_vertex) + ": " + names.triangle(first_triangle) + " and " +
                 names.triangle(other_triangle) + " are in different fans");
    }
  }

  // The volume's sign means something only on a closed, consistently oriented surface.
  const bool closed = std::none_of(result.defects.begin(), result.defects.end(), [](const SurfaceDefect& d) {
                        return d.kind == Kind::non_finite_coordinate || d.kind == Kind::index_out_of_range ||
                               d.kind == Kind::non_manifold_edge || d.kind == Kind::boundary_edge ||
                               d.kind == Kind::inconsistent_orientation;
                      });
  if (closed) {
    // Divergence theorem about the box centre, which keeps the triple products well scaled.
    const Vector3d origin = 0.5 * (lower + upper);
    for (const Vector3i& triangle : triangles) {
      const Vector3d a = vertices[triangle[0]] - origin;
      const Vector3d b = vertices[triangle[1]] - origin;
      const Vector3d c = vertices[triangle[2]] - origin;
      result.volume_m3 += a.dot(b.cross(c)) / 6;
    }
    if (!(result.volume_m3 > 0)) {
      report(Kind::inward_orientation, triangles.size(),
             "the surface encloses a non-positive volume (" + format_number(result.volume_m3) +
                 " m^3): its triangles are oriented inward (expected counter-clockwise seen from outside)");
    }
  }
  return result;
}

// ---------------------------------------------------------------------------------------------
// gmsh MSH 2.2 / 4.1 ASCII.

/// The file's lines, with the line number in every error.
class MshText {
 public:
  explicit MshText(const std::string& path) : path_(path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      throw std::invalid_argument(path + ": cannot open the mesh file (" + std::strerror(errno) + ")");
    }
    text_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) throw std::invalid_argument(path + ": cannot read the mesh file");
  }

  /// Next line without its line break; false at the end of the file.
  bool next(std::string_view& line) {
    if (position_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', position_);
    if (end == std::string::npos) end = text_.size();
    line = std::string_view(text_).substr(position_, end - position_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    position_ = end + 1;
    ++line_number_;
    return true;
  }
  /// Next line, which must exist (`where` names the section for the error).
  std::string_view require(const std::string& where) {
    std::string_view line;
    if (!next(line)) fail("unexpected end of file in " + where);
    return line;
  }
  void expect(std::string_view wanted) {
    const std::string_view line = require(std::string(wanted));
    if (trim(line) != wanted) {
      fail("expected " + std::string(wanted) + ", found '" + shorten(line) + "'");
    }
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument(path_ + ", line " + std::to_string(line_number_) + ": " + what);
  }
  const std::string& path() const { return path_; }

  static std::string_view trim(std::string_view text) {
    const std::size_t begin = text.find_first_not_of(" \t");
    if (begin == std::string_view::npos) return {};
    const std::size_t end = text.find_last_not_of(" \t");
    return text.substr(begin, end - begin + 1);
  }
  /// A printable excerpt of a (possibly binary) line.
  static std::string shorten(std::string_view line) {
    std::string text;
    for (char c : line.substr(0, 40)) text += (c >= 32 && c < 127) ? c : '?';
    if (line.size() > 40) text += "...";
    return text;
  }

 private:
  std::string path_;
  std::string text_;
  std::size_t position_ = 0;
  int line_number_ = 0;
};

/// Whitespace-separated numbers of one line.
class Fields {
 public:
  Fields(const MshText& text, std::string_view line, const char* section)
      : text_(text), rest_(line), section_(section) {}

  template <typename Number>
  Number next(const char* what) {
    const std::size_t begin = rest_.find_first_not_of(" \t");
    if (begin == std::string_view::npos) {
      text_.fail(std::string("missing ") + what + " in " + section_);
    }
    rest_.remove_prefix(begin);
    const std::size_t end = std::min(rest_.find_first_of(" \t"), rest_.size());
    const std::string_view token = rest_.substr(0, end);
    rest_.remove_prefix(end);
    Number value{};
    const auto [stop, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (error != std::errc() || stop != token.data() + token.size()) {
      text_.fail(std::string("expected ") + what + " in " + section_ + ", found '" +
                 MshText::shorten(token) + "'");
    }
    return value;
  }
  bool empty() const { return MshText::trim(rest_).empty(); }

 private:
  const MshText& text_;
  std::string_view rest_;
  const char* section_;
};

/// A 2-D element as read, before group selection.
struct RawElement {
  long long tag = 0;
  int type = 0;
  int entity = 0;
  int physical = 0;  // MSH 2 only: the first element tag
  std::array<long long, 3> nodes{};
};

/// gmsh element types of dimension 2 (triangles and quadrangles of any order).
bool is_two_dimensional(int type) {
  static constexpr std::array<int, 16> types{2, 3, 9, 10, 16, 20, 21, 22, 23, 24, 25, 36, 37, 38, 39, 40};
  return std::find(types.begin(), types.end(), type) != types.end();
}

struct MshContent {
  std::map<int, std::string> surface_names;              // physical tag → name (dimension 2)
  std::map<std::string, int> other_names;                // name → dimension, for groups of dimension ≠ 2
  std::map<int, std::vector<int>> surface_physicals;     // MSH 4: surface entity → physical tags
  std::unordered_map<long long, Vector3d> nodes;
  std::vector<RawElement> elements;                      // every 2-D element
  bool version4 = false;
  bool has_nodes = false;
  bool has_elements = false;
  bool has_entities = false;
};

void read_physical_names(MshText& text, MshContent& content) {
  const char* section = "$PhysicalNames";
  Fields header(text, text.require(section), section);
  const int count = header.next<int>("the number of names");
  for (int i = 0; i < count; ++i) {
    const std::string_view line = text.require(section);
    Fields fields(text, line, section);
    const int dimension = fields.next<int>("a dimension");
    const int tag = fields.next<int>("a physical tag");
    const std::size_t open = line.find('"');
    const std::size_t close = line.rfind('"');
    if (open == std::string_view::npos || close == open) text.fail("expected a quoted name in $PhysicalNames");
    std::string name(line.substr(open + 1, close - open - 1));
    if (dimension == 2) {
      content.surface_names[tag] = std::move(name);
    } else {
      content.other_names[std::move(name)] = dimension;
    }
  }
  text.expect("$EndPhysicalNames");
}

void read_entities(MshText& text, MshContent& content) {
  const char* section = "$Entities";
  Fields header(text, text.require(section), section);
  std::array<long long, 4> counts{};
  for (long long& count : counts) count = header.next<long long>("an entity count");
  for (int dimension = 0; dimension < 4; ++dimension) {
    for (long long i = 0; i < counts[dimension]; ++i) {
      Fields fields(text, text.require(section), section);
      const int tag = fields.next<int>("an entity tag");
      // Points carry X Y Z, the others a bounding box.
      for (int j = 0; j < (dimension == 0 ? 3 : 6); ++j) fields.next<double>("a coordinate");
      const int physical_count = fields.next<int>("the number of physical tags");
      std::vector<int> physicals;
      for (int j = 0; j < physical_count; ++j) physicals.push_back(fields.next<int>("a physical tag"));
      if (dimension == 2) content.surface_physicals[tag] = std::move(physicals);
    }
  }
  text.expect("$EndEntities");
  content.has_entities = true;
}

void read_nodes_v2(MshText& text, MshContent& content) {
  const char* section = "$Nodes";
  Fields header(text, text.require(section), section);
  const long long count = header.next<long long>("the number of nodes");
  if (count < 0) text.fail("negative node count in $Nodes");
  content.nodes.reserve(static_cast<std::size_t>(count));
  for (long long i = 0; i < count; ++i) {
    Fields fields(text, text.require(section), section);
    const long long tag = fields.next<long long>("a node tag");
    Vector3d x;
    for (int j = 0; j < 3; ++j) x[j] = fields.next<double>("a coordinate");
    content.nodes[tag] = x;
  }
  text.expect("$EndNodes");
  content.has_nodes = true;
}

void read_nodes_v4(MshText& text, MshContent& content) {
  const char* section = "$Nodes";
  Fields header(text, text.require(section), section);
  const long long blocks = header.next<long long>("the number of entity blocks");
  const long long count = header.next<long long>("the number of nodes");
  if (blocks < 0 || count < 0) text.fail("negative count in $Nodes");
  content.nodes.reserve(static_cast<std::size_t>(count));
  std::vector<long long> tags;
  for (long long b = 0; b < blocks; ++b) {
    Fields block(text, text.require(section), section);
    block.next<int>("an entity dimension");
    block.next<int>("an entity tag");
    block.next<int>("the parametric flag");
    const long long size = block.next<long long>("the number of nodes in the block");
    if (size < 0) text.fail("negative block size in $Nodes");
    tags.clear();
    for (long long i = 0; i < size; ++i) {
      tags.push_back(Fields(text, text.require(section), section).next<long long>("a node tag"));
    }
    // Parametric coordinates, when present, follow x y z on the same line and are not needed.
    for (long long i = 0; i < size; ++i) {
      Fields fields(text, text.require(section), section);
      Vector3d x;
      for (int j = 0; j < 3; ++j) x[j] = fields.next<double>("a coordinate");
      content.nodes[tags[i]] = x;
    }
  }
  text.expect("$EndNodes");
  content.has_nodes = true;
}

void read_elements_v2(MshText& text, MshContent& content) {
  const char* section = "$Elements";
  Fields header(text, text.require(section), section);
  const long long count = header.next<long long>("the number of elements");
  for (long long i = 0; i < count; ++i) {
    Fields fields(text, text.require(section), section);
    RawElement element;
    element.tag = fields.next<long long>("an element tag");
    element.type = fields.next<int>("an element type");
    const int tag_count = fields.next<int>("the number of element tags");
    for (int j = 0; j < tag_count; ++j) {
      const int tag = fields.next<int>("an element tag");
      if (j == 0) element.physical = tag;
      if (j == 1) element.entity = tag;
    }
    if (!is_two_dimensional(element.type)) continue;
    if (element.type == 2) {
      for (long long& node : element.nodes) node = fields.next<long long>("a node tag");
      if (!fields.empty()) text.fail("a triangle (type 2) with more than 3 nodes in $Elements");
    }
    content.elements.push_back(element);
  }
  text.expect("$EndElements");
  content.has_elements = true;
}

void read_elements_v4(MshText& text, MshContent& content) {
  const char* section = "$Elements";
  Fields header(text, text.require(section), section);
  const long long blocks = header.next<long long>("the number of entity blocks");
  for (long long b = 0; b < blocks; ++b) {
    Fields block(text, text.require(section), section);
    const int dimension = block.next<int>("an entity dimension");
    const int entity = block.next<int>("an entity tag");
    const int type = block.next<int>("an element type");
    const long long size = block.next<long long>("the number of elements in the block");
    for (long long i = 0; i < size; ++i) {
      const std::string_view line = text.require(section);
      if (dimension != 2) continue;
      Fields fields(text, line, section);
      RawElement element;
      element.tag = fields.next<long long>("an element tag");
      element.type = type;
      element.entity = entity;
      if (type == 2) {
        for (long long& node : element.nodes) node = fields.next<long long>("a node tag");
        if (!fields.empty()) text.fail("a triangle (type 2) with more than 3 nodes in $Elements");
      }
      content.elements.push_back(element);
    }
  }
  text.expect("$EndElements");
  content.has_elements = true;
}

MshContent read_msh(const std::string& path) {
  MshText text(path);
  MshContent content;
  std::string_view line;
  while (text.next(line) && MshText::trim(line).empty()) {
  }
  if (MshText::trim(line).empty()) throw std::invalid_argument(path + ": not a gmsh MSH file (it is empty)");
  if (MshText::trim(line) != "$MeshFormat") {
    throw std::invalid_argument(path + ": not a gmsh MSH file (it does not start with $MeshFormat)");
  }
  {
    Fields format(text, text.require("$MeshFormat"), "$MeshFormat");
    const double version = format.next<double>("the format version");
    const int file_type = format.next<int>("the file type");
    if (file_type != 0) {
      text.fail("binary MSH files are not supported: save the mesh as ASCII (Mesh.Binary = 0)");
    }
    if (version >= 2 && version < 3) {
      content.version4 = false;
    } else if (version == 4.1) {
      content.version4 = true;
    } else {
      text.fail("MSH version " + format_number(version) + " is not supported (2.2 or 4.1 ASCII)");
    }
    text.expect("$EndMeshFormat");
  }
  while (text.next(line)) {
    const std::string_view name = MshText::trim(line);
    if (name.empty()) continue;
    if (name.front() != '$') text.fail("expected a section ($Name), found '" + MshText::shorten(line) + "'");
    if (name == "$PhysicalNames") {
      read_physical_names(text, content);
    } else if (name == "$Entities" && content.version4) {
      read_entities(text, content);
    } else if (name == "$Nodes") {
      content.version4 ? read_nodes_v4(text, content) : read_nodes_v2(text, content);
    } else if (name == "$Elements") {
      content.version4 ? read_elements_v4(text, content) : read_elements_v2(text, content);
    } else {
      // Sections not needed here ($Periodic, $NodeData, ...): skip to their end.
      const std::string end = "$End" + std::string(name.substr(1));
      std::string_view inner;
      do {
        inner = text.require(std::string(name));
      } while (MshText::trim(inner) != end);
    }
  }
  if (!content.has_nodes) throw std::invalid_argument(path + ": no $Nodes section");
  if (!content.has_elements) throw std::invalid_argument(path + ": no $Elements section");
  return content;
}

std::string element_type_name(int type) {
  switch (type) {
    case 3: return "4-node quadrangle";
    case 9: return "6-node triangle";
    case 10: return "9-node quadrangle";
    case 16: return "8-node quadrangle";
    default: return "higher-order 2-D element";
  }
}

}  // namespace

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
  }
  return "unknown defect";
}

std::vector<SurfaceDefect> validate_surface(const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles,
                                            const std::string& source, const SurfaceLabels& labels) {
  return analyse(vertices, triangles, source, labels).defects;
}

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

SurfaceData read_msh_surface(const std::string& path, const std::vector<std::string>& groups) {
  const MshContent content = read_msh(path);

  std::set<int> selected;
  for (const std::string& group : groups) {
    bool found = false;
    for (const auto& [tag, name] : content.surface_names) {
      if (name == group) {
        selected.insert(tag);
        found = true;
      }
    }
    if (!found) {
      std::string available;
      for (const auto& [tag, name] : content.surface_names) {
        available += (available.empty() ? "" : ", ") + name;
      }
      const auto other = content.other_names.find(group);
      const std::string hint = other == content.other_names.end()
                                   ? std::string()
                                   : " ('" + group + "' is a " + std::to_string(other->second) + "-D group)";
      throw std::invalid_argument(path + ": no physical surface group named '" + group + "'" + hint +
                                  " (available: " + (available.empty() ? "none" : available) + ")");
    }
  }
  if (!selected.empty() && content.version4 && !content.has_entities) {
    throw std::invalid_argument(path + ": an MSH 4.1 file without $Entities has no physical groups");
  }
  const auto is_selected = [&](const RawElement& element) {
    if (selected.empty()) return true;
    if (!content.version4) return selected.count(element.physical) > 0;
    const auto entity = content.surface_physicals.find(element.entity);
    if (entity == content.surface_physicals.end()) return false;
    return std::any_of(entity->second.begin(), entity->second.end(),
                       [&](int tag) { return selected.count(tag) > 0; });
  };

  // MSH 2 repeats an element once per physical group it belongs to: keep one copy.
  std::set<std::tuple<int, long long, long long, long long>> seen;
  std::vector<const RawElement*> kept;
  for (const RawElement& element : content.elements) {
    if (!is_selected(element)) continue;
    if (element.type != 2) {
      throw std::invalid_argument(path + ": element " + std::to_string(element.tag) + " is a " +
                                  element_type_name(element.type) + " (type " + std::to_string(element.type) +
                                  "): only 3-node triangles (type 2) are supported");
    }
    if (seen.insert({element.entity, element.nodes[0], element.nodes[1], element.nodes[2]}).second) {
      kept.push_back(&element);
    }
  }
  if (kept.empty()) {
    std::string names;
    for (const std::string& group : groups) names += (names.empty() ? "" : ", ") + group;
    throw std::invalid_argument(path + ": no triangles (type 2 elements)" +
                                (names.empty() ? std::string() : " in the groups " + names));
  }

  // Only the nodes the triangles use, numbered in increasing gmsh tag order.
  SurfaceData data;
  data.labels.vertex_kind = "gmsh node";
  data.labels.triangle_kind = "gmsh element";
  std::vector<long long>& vertex_tags = data.labels.vertex_tags;
  vertex_tags.reserve(3 * kept.size());
  for (const RawElement* element : kept) {
    vertex_tags.insert(vertex_tags.end(), element->nodes.begin(), element->nodes.end());
  }
  std::sort(vertex_tags.begin(), vertex_tags.end());
  vertex_tags.erase(std::unique(vertex_tags.begin(), vertex_tags.end()), vertex_tags.end());
  data.vertices.reserve(vertex_tags.size());
  std::unordered_map<long long, int> index_of;
  index_of.reserve(vertex_tags.size());
  for (long long tag : vertex_tags) {
    const auto node = content.nodes.find(tag);
    if (node == content.nodes.end()) {
      throw std::invalid_argument(path + ": node " + std::to_string(tag) +
                                  " is used by a triangle but missing from $Nodes");
    }
    index_of[tag] = static_cast<int>(data.vertices.size());
    data.vertices.push_back(node->second);
  }
  data.triangles.reserve(kept.size());
  data.labels.triangle_tags.reserve(kept.size());
  for (const RawElement* element : kept) {
    data.triangles.emplace_back(index_of[element->nodes[0]], index_of[element->nodes[1]], index_of[element->nodes[2]]);
    data.labels.triangle_tags.push_back(element->tag);
  }
  return data;
}

TriangleSurface::TriangleSurface(std::vector<Vector3d> vertices, std::vector<Vector3i> triangles,
                                 const std::string& source)
    : TriangleSurface(std::move(vertices), std::move(triangles), source, SurfaceLabels{}) {}

TriangleSurface::TriangleSurface(std::vector<Vector3d> vertices, std::vector<Vector3i> triangles,
                                 const std::string& source, const SurfaceLabels& labels)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
  const Analysis analysis = analyse(vertices_, triangles_, source, labels);
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

TriangleSurface TriangleSurface::from_msh(const std::string& path, const std::vector<std::string>& groups) {
  SurfaceData data = read_msh_surface(path, groups);
  return TriangleSurface(std::move(data.vertices), std::move(data.triangles), path, data.labels);
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

  // Corners in leaf order: a leaf's triangles are contiguous in memory.
  corners_.resize(3 * static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) corners_[3 * i + k] = vertices_[triangles_[order_[i]][k]];
  }
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
