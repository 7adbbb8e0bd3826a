#pragma once
/// @file
/// An interactive VTK window for the graphics loop: the deformed organ, the
/// tool (tip sphere and shaft) and the force on the hand as an arrow from the tool tip, with a
/// trackball camera the user can turn while the simulation runs. Each frame() renders and then
/// processes the window's pending events without blocking; closing the window (the window
/// manager's close button, or 'q'/'e' in the window) ends the output but not the run.
///
/// Every VTK call happens in the thread that calls begin(), frame() and end() (the graphics
/// thread); calling frame() or end() from another thread is refused. Needs an X display with
/// GLX: check display_available() first (VTK aborts the process when it cannot open one).

#include "touchstone/realtime/graphics/graphics_sink.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

namespace touchstone::realtime::graphics {

struct InteractiveWindowSettings {
  int width = 960;   ///< window size [pixels]
  int height = 720;
  std::string title = "Touchstone";
  /// A PNG of the window written at end() (and periodically, see below); empty: none.
  std::string screenshot_path;
  /// > 0: also write the screenshot after every this many rendered frames (the same path,
  /// replaced atomically); 0: only at end().
  int screenshot_every_n_frames = 0;
  Eigen::Vector3d background = {0.10, 0.11, 0.14};       ///< RGB in [0, 1]
  Eigen::Vector3d organ_color = {0.85, 0.55, 0.50};      ///< tissue
  Eigen::Vector3d tool_color = {0.27, 0.51, 0.71};       ///< steel blue
  Eigen::Vector3d force_arrow_color = {0.60, 0.90, 0.15};  ///< yellow-green
  /// Arrow length per newton of force on the hand [m/N]: 0.01 draws 1 N as 1 cm.
  double force_arrow_scale_m_per_N = 0.01;
  /// The arrow is hidden below this force [N].
  double force_arrow_min_N = 1e-6;
  /// Direction from the organ's centre to the camera (need not be unit); the view up is +z
  /// (or +y when the direction is along z). Default: from the front (−y), 30° above.
  Eigen::Vector3d camera_direction = {0.0, -0.866, 0.5};

  /// Throws std::invalid_argument naming the offending field and its value.
  void validate() const;
};

class InteractiveWindow final : public GraphicsSink {
 public:
  /// Validates the settings (std::invalid_argument naming the field). Opens nothing yet.
  explicit InteractiveWindow(const InteractiveWindowSettings& settings);
  ~InteractiveWindow() override;
  InteractiveWindow(const InteractiveWindow&) = delete;
  InteractiveWindow& operator=(const InteractiveWindow&) = delete;

  std::string name() const override { return "interactive_window"; }
  /// Opens the window showing the rest organ, framed by the camera. Throws std::runtime_error
  /// when display_available() is false (instead of letting VTK abort).
  void begin(const geometry::TriangleSurface& organ) override;
  /// Updates the organ's points in place, moves the tool and the arrow, renders, processes
  /// pending window events. A no-op once the user has closed the window. Throws
  /// std::invalid_argument when the frame does not match the organ, std::logic_error from a
  /// thread other than begin()'s, std::runtime_error when a periodic screenshot fails.
  void frame(const GraphicsFrame& frame) override;
  /// Writes the screenshot (unless the window was closed) and closes the window. Errors are
  /// recorded in last_error().
  void end() noexcept override;

  /// True when a window can be opened: DISPLAY is set, the X server answers and has GLX.
  static bool display_available();

  const InteractiveWindowSettings& settings() const { return settings_; }
  bool closed_by_user() const { return closed_by_user_; }
  std::int64_t frames_rendered() const { return frames_rendered_; }
  std::int64_t screenshots_written() const { return screenshots_written_; }
  const std::string& last_error() const { return last_error_; }

 private:
  struct Vtk;  // the VTK objects, kept out of this header
  void write_screenshot();
  void close_window() noexcept;  ///< destroys the X window; the VTK objects stay
  void release() noexcept;       ///< closes the window, frees the VTK objects and the display
  static void on_exit(void* self);

  InteractiveWindowSettings settings_;
  std::unique_ptr<Vtk> vtk_;
  std::thread::id thread_;
  std::size_t vertex_count_ = 0;
  std::int64_t frames_rendered_ = 0;
  std::int64_t screenshots_written_ = 0;
  bool closed_by_user_ = false;
  std::string last_error_;
};

}  // namespace touchstone::realtime::graphics
