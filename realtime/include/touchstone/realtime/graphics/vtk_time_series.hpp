#pragma once
/// @file
/// The graphics loop's output for ParaView: a time series of VTK XML PolyData
/// files (binary, appended, zlib-compressed) with two PVD collections that index them by time.
///
/// Per written frame, in `output_directory`:
/// - `<base>_organ_<index>.vtp`: the deformed organ surface. Points = deformed vertices [m]
///   (double), polys = the rest surface's triangles; point data `displacement_m` (3 components)
///   and `displacement_magnitude_m`; field data `time_s`, `frame_index`.
/// - `<base>_tool_<index>.vtp`: the tool. Point 0 is the tip centre, a vertex cell of its own;
///   then the tip sphere (latitude–longitude polygons) and the shaft (a closed cylinder of
///   polygons from the tip along the tool axis). Point data `force_on_hand_N` (3 components)
///   holds the force on point 0 and zero elsewhere, so that ParaView's Glyph filter (scale by
///   the vector) draws one arrow at the tip. Field data `time_s`, `frame_index`, `in_contact`
///   (0/1) and `force_on_hand_magnitude_N`.
/// and `<base>_organ.pvd`, `<base>_tool.pvd` listing the written files with timestep = time_s.
/// `<index>` is the frame's GraphicsFrame::index, zero-padded to six digits.
///
/// The PVDs are rewritten atomically (a temporary file renamed over the old one) after the
/// first written frame, every `pvd_rewrite_every` written frames and at end(): a run that is
/// interrupted still leaves collections that open in ParaView, listing only complete files.
///
/// Size: a VTP of an organ with V vertices and T triangles holds about 56 V + 16 T bytes
/// before compression (double points and displacements, 32-bit connectivity and offsets);
/// `frame_stride` thins the 30 Hz graphics stream (the default, 3, writes 10 frames/s). An
/// icosphere of 20,480 triangles (10,242 vertices) takes ~240 KiB per written frame when only
/// a local region moves (~610 KiB when every vertex does): ~140 MiB per minute at stride 3.

#include "touchstone/realtime/graphics/graphics_sink.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace touchstone::realtime::graphics {

struct VtkTimeSeriesSettings {
  std::string output_directory = ".";  ///< created (with parents) by begin() if missing
  std::string base_name = "touchstone";  ///< file name prefix; no '/' and no NUL
  /// Write every n-th frame handed to frame() (the 1st, the (n+1)-th, …); 1 writes all.
  int frame_stride = 3;
  /// Rewrite the PVD collections after every this many written frames (and at the first
  /// written frame and at end()).
  int pvd_rewrite_every = 10;
  /// zlib level, 1 (fastest) … 9 (smallest). Deformed coordinates hardly compress, so 1 is
  /// about as small as 5 and much faster to write.
  int compression_level = 1;
  int tool_sphere_resolution = 16;  ///< segments around the tip sphere and the shaft (>= 3)

  /// Throws std::invalid_argument naming the offending field and its value.
  void validate() const;
};

/// Writes the VTP/PVD time series described in the file comment. Not thread-safe: begin(),
/// frame() and end() are called from one thread (the graphics thread).
class VtkTimeSeriesWriter final : public GraphicsSink {
 public:
  /// Validates the settings (std::invalid_argument naming the field).
  explicit VtkTimeSeriesWriter(const VtkTimeSeriesSettings& settings);
  ~VtkTimeSeriesWriter() override;
  VtkTimeSeriesWriter(const VtkTimeSeriesWriter&) = delete;
  VtkTimeSeriesWriter& operator=(const VtkTimeSeriesWriter&) = delete;

  std::string name() const override { return "vtk_time_series"; }
  /// Creates the output directory, checks that a file can be written there and sets up the
  /// organ's connectivity. Throws std::runtime_error naming the directory when it cannot be
  /// created or written to.
  void begin(const geometry::TriangleSurface& organ) override;
  /// Writes the frame when it is the stride's turn. Throws std::invalid_argument when the
  /// frame does not match the organ (naming the array and sizes) and std::runtime_error
  /// naming the file when a write fails.
  void frame(const GraphicsFrame& frame) override;
  /// Writes the final PVD collections. Errors are recorded in last_error(), not thrown.
  void end() noexcept override;

  const VtkTimeSeriesSettings& settings() const { return settings_; }
  std::int64_t frames_received() const { return frames_received_; }
  std::int64_t frames_written() const { return frames_written_; }
  /// Bytes of every VTP and the latest PVDs written so far.
  std::int64_t bytes_written() const { return bytes_written_; }
  std::int64_t pvd_rewrites() const { return pvd_rewrites_; }
  /// Paths of the collections (valid after begin()).
  std::string organ_pvd_path() const;
  std::string tool_pvd_path() const;
  /// The last error end() met (empty when none).
  const std::string& last_error() const { return last_error_; }

 private:
  struct Vtk;  // the VTK objects, kept out of this header
  struct Entry {
    double time_s;
    std::string organ_file, tool_file;  ///< names relative to the output directory
  };
  std::string path(const std::string& file_name) const;
  void write_organ(const GraphicsFrame& frame, const std::string& file_name);
  void write_tool(const GraphicsFrame& frame, const std::string& file_name);
  void write_collections();

  VtkTimeSeriesSettings settings_;
  std::unique_ptr<Vtk> vtk_;
  std::size_t vertex_count_ = 0;
  std::vector<Entry> entries_;
  std::int64_t pvd_bytes_ = 0;  ///< size of the PVDs counted in bytes_written_
  std::int64_t frames_received_ = 0;
  std::int64_t frames_written_ = 0;
  std::int64_t bytes_written_ = 0;
  std::int64_t pvd_rewrites_ = 0;
  int last_index_ = -1;
  bool begun_ = false;
  std::string last_error_;
};

}  // namespace touchstone::realtime::graphics
