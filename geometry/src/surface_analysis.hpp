#pragma once
// The checks behind validate_surface, shared with the TriangleSurface constructor, which reuses
// the edge neighbours and the volume they compute.

#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace touchstone::geometry::detail {

/// What validation finds, plus what the constructor reuses.
struct SurfaceAnalysis {
  std::vector<SurfaceDefect> defects;
  std::vector<int> neighbours;  ///< across edge k (corner k → k + 1) of each triangle; complete when valid
  double volume_m3 = 0;         ///< enclosed volume; computed only when the surface is closed
};

/// Every check in SurfaceDefectKind order. Each check skips what an earlier one found broken,
/// so that one defect is reported once, not as a cascade of others.
SurfaceAnalysis analyse_surface(const std::vector<Eigen::Vector3d>& vertices,
                                const std::vector<Eigen::Vector3i>& triangles, const std::string& source,
                                const SurfaceLabels& labels);

}  // namespace touchstone::geometry::detail
