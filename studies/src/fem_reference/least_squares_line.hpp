#pragma once
/// @file
/// The least-squares line y = intercept + slope·x through points, shared by the B1 half-space
/// extrapolation (force ratio against a/W) and the convergence rate of an MFS series (log error
/// against log N).

#include <optional>
#include <utility>
#include <vector>

namespace touchstone::studies {

struct Line {
  double slope = 0, intercept = 0;
};

/// Empty with fewer than two points or when every x is the same (no slope to fit).
inline std::optional<Line> least_squares_line(const std::vector<std::pair<double, double>>& points) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const auto& [x, y] : points) {
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  const double n = static_cast<double>(points.size());
  const double denominator = n * sxx - sx * sx;
  if (points.size() < 2 || !(denominator > 0)) return std::nullopt;
  Line line;
  line.slope = (n * sxy - sx * sy) / denominator;
  line.intercept = (sy - line.slope * sx) / n;
  return line;
}

}  // namespace touchstone::studies
