#pragma once
/// @file
/// What the graphics loop (30 Hz) hands to its outputs: the deformed organ, the
/// tool and the force. Outputs — a VTK/PVD time series for ParaView, an interactive VTK window,
/// the OpenIGTLink POLYDATA stream to 3D Slicer — implement GraphicsSink; the loop calls them
/// from the graphics thread only, never from the haptic thread.

#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace touchstone::realtime::graphics {

/// One frame. The organ's connectivity never changes during a run: it is given once to begin().
struct GraphicsFrame {
  double time_s = 0;
  int index = 0;  ///< 0, 1, 2, … in the order frames are sent
  /// Deformed organ vertex positions [m], in the order of the rest surface's vertices (only the
  /// vertices inside the local domain differ from the rest positions).
  const std::vector<Eigen::Vector3d>* organ_vertices_m = nullptr;
  /// Displacement of every vertex [m] (zero outside the local domain).
  const std::vector<Eigen::Vector3d>* organ_displacement_m = nullptr;
  Eigen::Vector3d tool_tip_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d tool_axis = Eigen::Vector3d::UnitZ();  ///< unit, from the tip along the shaft
  double tool_tip_radius_m = 0.0025;
  double tool_shaft_length_m = 0.1;
  double tool_shaft_radius_m = 0.0015;
  /// Force on the user's hand [N] (what the device renders after the safety filter).
  Eigen::Vector3d force_on_hand_N = Eigen::Vector3d::Zero();
  bool in_contact = false;
};

class GraphicsSink {
 public:
  virtual ~GraphicsSink() = default;
  virtual std::string name() const = 0;
  /// Called once before the first frame with the rest organ. May throw (files, windows).
  virtual void begin(const geometry::TriangleSurface& organ) = 0;
  /// One frame; exceptions are caught and counted by the graphics loop, which then disables the sink.
  virtual void frame(const GraphicsFrame& frame) = 0;
  /// Called once after the last frame (finishes files, closes windows). noexcept.
  virtual void end() noexcept = 0;
};

}  // namespace touchstone::realtime::graphics
