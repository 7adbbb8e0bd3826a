// The graphics outputs' cost per frame on an organ of 20,480 triangles (a level-5 icosphere, the
// size of the palpation scene's organ): the ParaView time series (one compressed VTP per written
// frame) and, when a display is there (DISPLAY set, e.g. under xvfb-run), the interactive
// window. Counters: bytes per written frame.
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/graphics/interactive_window.hpp"
#include "touchstone/realtime/graphics/vtk_time_series.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

using namespace touchstone;
using Eigen::Vector3d;

constexpr double radius_m = 0.03;

geometry::TriangleSurface organ() {
  auto mesh = geometry::icosphere(5, radius_m);
  return geometry::TriangleSurface(mesh.vertices, mesh.triangles, "icosphere");
}

/// Frame k of a tool pressing the organ: a dent under the tool growing with k (zero displacement
/// away from it, as in a run).
struct Frames {
  explicit Frames(const geometry::TriangleSurface& surface) : rest(surface.vertices()) {}
  realtime::graphics::GraphicsFrame make(int k) {
    displacement.assign(rest.size(), Vector3d::Zero());
    vertices = rest;
    for (std::size_t i = 0; i < rest.size(); ++i) {
      const double weight = std::exp(-(rest[i] - Vector3d(0, 0, radius_m)).squaredNorm() / (0.01 * 0.01));
      if (weight > 1e-3) displacement[i] = Vector3d(0, 0, -2e-4 * (k % 10) * weight);
      vertices[i] = rest[i] + displacement[i];
    }
    realtime::graphics::GraphicsFrame frame;
    frame.index = k;
    frame.time_s = k / 30.0;
    frame.organ_vertices_m = &vertices;
    frame.organ_displacement_m = &displacement;
    frame.tool_tip_m = Vector3d(0.001, 0.0, radius_m + 0.002 - 2e-4 * (k % 10));
    frame.force_on_hand_N = Vector3d(0, 0, 0.3 * (k % 10));
    frame.in_contact = k % 10 > 2;
    return frame;
  }
  std::vector<Vector3d> rest, vertices, displacement;
};

void BM_VtkTimeSeriesFrame(benchmark::State& state) {
  const auto surface = organ();
  Frames frames(surface);
  const std::filesystem::path directory =
      std::filesystem::temp_directory_path() / ("touchstone_graphics_benchmark_" + std::to_string(::getpid()));
  realtime::graphics::VtkTimeSeriesSettings settings;
  settings.output_directory = directory.string();
  settings.frame_stride = 1;
  realtime::graphics::VtkTimeSeriesWriter writer(settings);
  writer.begin(surface);
  int k = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const auto frame = frames.make(k++);
    state.ResumeTiming();
    writer.frame(frame);
  }
  writer.end();
  state.counters["bytes_per_frame"] = double(writer.bytes_written()) / double(std::max<std::int64_t>(1, writer.frames_written()));
  state.counters["triangles"] = double(surface.triangles().size());
  std::filesystem::remove_all(directory);
}
BENCHMARK(BM_VtkTimeSeriesFrame)->Unit(benchmark::kMillisecond);

void BM_InteractiveWindowFrame(benchmark::State& state) {
  const auto surface = organ();
  Frames frames(surface);
  realtime::graphics::InteractiveWindowSettings settings;
  settings.width = 640;
  settings.height = 480;
  realtime::graphics::InteractiveWindow window(settings);
  window.begin(surface);
  window.frame(frames.make(0));  // the first render compiles the shaders
  int k = 1;
  for (auto _ : state) {
    state.PauseTiming();
    const auto frame = frames.make(k++);
    state.ResumeTiming();
    window.frame(frame);
  }
  window.end();
  state.counters["triangles"] = double(surface.triangles().size());
}

}  // namespace

int main(int argc, char** argv) {
  // The window needs an X server; without one the case is not registered (not an error).
  if (std::getenv("DISPLAY") != nullptr)
    benchmark::RegisterBenchmark("BM_InteractiveWindowFrame", BM_InteractiveWindowFrame)->Unit(benchmark::kMillisecond);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
