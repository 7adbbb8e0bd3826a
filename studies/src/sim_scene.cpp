#include "touchstone/studies/sim_scene.hpp"

#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/realtime/haptics/device_recorder.hpp"
#include "touchstone/realtime/haptics/replay_device.hpp"
#include "touchstone/realtime/haptics/palpation_device.hpp"
#include "touchstone/studies/collision_study.hpp"
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#ifdef TOUCHSTONE_HAVE_VTK
#include "touchstone/realtime/graphics/interactive_window.hpp"
#include "touchstone/realtime/graphics/vtk_time_series.hpp"
#endif
#ifdef TOUCHSTONE_HAVE_OPENIGTLINK
#include "touchstone/realtime/haptics/openigtlink_device.hpp"
#endif
#ifdef TOUCHSTONE_HAVE_OPENHAPTICS
#include "touchstone/realtime/haptics/openhaptics_device.hpp"
#endif

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace rt = realtime::runtime;
namespace haptics = realtime::haptics;
using nlohmann::json;

json summary_json(const rt::RunSummary& r) {
  const auto loop = [](const rt::LoopStatistics& l) {
    return json{{"period_s", l.period_s},          {"ticks", l.ticks},
                {"lateness_p50_s", l.lateness_p50_s}, {"lateness_p99_s", l.lateness_p99_s},
                {"lateness_max_s", l.lateness_max_s}, {"late_ticks", l.late_ticks},
                {"late_threshold_s", l.late_threshold_s}, {"late_fraction", l.ticks ? double(l.late_ticks) / l.ticks : 0.0},
                {"skipped_deadlines", l.skipped_deadlines}, {"work_p50_s", l.work_p50_s},
                {"work_p99_s", l.work_p99_s},         {"work_max_s", l.work_max_s}};
  };
  const auto& p = r.prediction;
  const auto& w = r.work;
  const auto& f = r.forces;
  return json{
      {"device", r.device},
      {"clock", r.virtual_clock ? "virtual" : "real"},
      {"duration_s", r.duration_s},
      {"end_reason", r.end_reason},
      {"force_mode", rt::to_string(r.force_mode)},
      {"loops", {{"haptic", loop(r.haptic)}, {"model", loop(r.model)}, {"graphics", loop(r.graphics)}}},
      {"haptic_thread", {{"fifo", r.haptic_thread.fifo}, {"timer_slack_set", r.haptic_thread.timer_slack_set}, {"note", r.haptic_thread.note}}},
      {"safety",
       {{"ticks", r.safety.ticks}, {"interventions", r.safety.interventions()}, {"non_finite", r.safety.non_finite},
        {"stale", r.safety.stale}, {"clamped", r.safety.clamped}, {"rate_limited", r.safety.rate_limited},
        {"disconnect_zero", r.safety.disconnect_zero}}},
      {"prediction",
       {{"cycles", p.cycles}, {"cheap_checks", p.cheap_checks}, {"corridor_advances", p.corridor_advances},
        {"predictions", p.predictions}, {"repredictions", p.repredictions()}, {"handovers", p.handovers},
        {"full_detections", p.full_detections}, {"closest_point_queries", p.closest_point_queries},
        {"ray_casts", p.ray_casts}, {"contacts", p.contacts}, {"box_tests", p.queries.box_tests},
        {"triangle_tests", p.queries.triangle_tests}}},
      {"work",
       {{"haptic_ticks", w.haptic_ticks}, {"free_ticks", w.free_ticks}, {"contact_ticks", w.contact_ticks},
        {"hierarchy_queries", w.hierarchy_queries}, {"model_steps", w.model_steps},
        {"model_idle_steps", w.model_idle_steps}, {"model_builds", w.model_builds},
        {"model_prebuilds", w.model_prebuilds}, {"model_resprinkles", w.model_resprinkles},
        {"model_build_failures", w.model_build_failures}, {"model_forces", w.model_forces}, {"contacts", w.contacts},
        {"contacts_with_model_ready", w.contacts_with_model_ready}, {"graphics_frames", w.graphics_frames},
        {"surface_updates", w.surface_updates}, {"vertices_written", w.vertices_written},
        {"organ_vertices", w.organ_vertices}, {"sink_errors", w.sink_errors}}},
      {"forces",
       {{"max_force_N", f.max_force_N}, {"extrapolation_error_rms_N", f.extrapolation_error_rms_N},
        {"extrapolation_error_max_N", f.extrapolation_error_max_N}, {"compared_ticks", f.compared_ticks},
        {"model_switches", f.model_switches}, {"switch_jump_max_N", f.switch_jump_max_N},
        {"switch_jump_mean_N", f.switch_jump_mean_N}, {"crossfade_step_max_N", f.crossfade_step_max_N},
        {"late_model_fade_ins", f.late_model_fade_ins},
        {"extrapolation_updates", f.extrapolation_updates},
        {"extrapolation_update_step_max_N", f.extrapolation_update_step_max_N},
        {"extrapolation_update_step_mean_N", f.extrapolation_update_step_mean_N},
        {"output_step_max_N", f.output_step_max_N}, {"model_latency_p50_s", f.model_latency_p50_s},
        {"model_latency_max_s", f.model_latency_max_s}, {"model_latency_samples", f.model_latency_samples},
        {"build_p50_s", f.build_p50_s}, {"build_max_s", f.build_max_s}}},
      {"model_builds",
       {{"exterior_used", r.exterior_used},
        {"first_build_error", r.first_build_error.empty() ? json(nullptr) : json(r.first_build_error)},
        {"first_exterior_note", r.first_exterior_note.empty() ? json(nullptr) : json(r.first_exterior_note)},
        {"implausible_stiffness_models", r.implausible_stiffness_models},
        {"first_implausible_stiffness_ratio", json_number(r.first_implausible_stiffness_ratio)}}},
      {"models", model_records_json(r.models)},
      {"models_not_recorded", r.models_not_recorded},
      {"notes", r.notes},
  };
}

json model_records_json(const std::vector<rt::ModelRecord>& models) {
  json list = json::array();
  for (const auto& m : models)
    list.push_back({{"model_id", m.model_id},
                    {"adopted_s", m.adopted_s},
                    {"reason", m.reason},
                    {"contact_point_m", vector_json(m.contact_point_m)},
                    {"direction", vector_json(m.direction)},
                    {"tool_stiffness_N_per_m", matrix_json(m.tool_stiffness_N_per_m)},
                    {"load_force_N", vector_json(m.load_force_N)},
                    {"exterior_used", m.exterior_used},
                    {"node_count", m.node_count},
                    {"build_s", m.build_s},
                    {"stiffness_ratio_to_half_space", json_number(m.stiffness_ratio_to_half_space)}});
  return list;
}

std::string summary_text(const rt::RunSummary& r) {
  std::ostringstream out;
  char line[512];
  std::snprintf(line, sizeof line, "run: %s clock, device %s, %.2f s, ended: %s, force mode %s\n",
                r.virtual_clock ? "virtual" : "real", r.device.c_str(), r.duration_s, r.end_reason.c_str(),
                rt::to_string(r.force_mode));
  out << line;
  for (const rt::LoopStatistics* l : {&r.haptic, &r.model, &r.graphics}) {
    if (l->ticks == 0) {
      out << "  " << l->name << ": not run\n";
      continue;
    }
    std::snprintf(line, sizeof line,
                  "  %-8s %7lld ticks  lateness p50 %7.1f us  p99 %7.1f us  max %8.1f us  late(>%.1f ms) %lld (%.3f %%)  "
                  "skipped %lld  work p50 %.1f us p99 %.1f us\n",
                  l->name.c_str(), l->ticks, l->lateness_p50_s * 1e6, l->lateness_p99_s * 1e6, l->lateness_max_s * 1e6,
                  l->late_threshold_s * 1e3, l->late_ticks, 100.0 * l->late_ticks / l->ticks, l->skipped_deadlines,
                  l->work_p50_s * 1e6, l->work_p99_s * 1e6);
    out << line;
  }
  out << "  haptic thread: " << r.haptic_thread.note << "\n";
  const auto& s = r.safety;
  std::snprintf(line, sizeof line,
                "  safety: %lld interventions (non-finite %lld, stale %lld, clamped %lld, rate-limited %lld), "
                "disconnect zeros %lld\n",
                s.interventions(), s.non_finite, s.stale, s.clamped, s.rate_limited, s.disconnect_zero);
  out << line;
  const auto& w = r.work;
  std::snprintf(line, sizeof line,
                "  work: %lld contacts (%lld with the model ready), %lld contact ticks, %lld hierarchy queries in %lld "
                "free ticks; model: %lld steps, %lld idle, %lld builds (%lld before contact, %lld re-sprinkles, %lld failed)\n",
                w.contacts, w.contacts_with_model_ready, w.contact_ticks, w.hierarchy_queries, w.free_ticks,
                w.model_steps, w.model_idle_steps, w.model_builds, w.model_prebuilds, w.model_resprinkles,
                w.model_build_failures);
  out << line;
  std::snprintf(line, sizeof line, "  graphics: %lld frames, %lld surface updates, %lld vertex writes (organ: %lld vertices)\n",
                w.graphics_frames, w.surface_updates, w.vertices_written, w.organ_vertices);
  out << line;
  const auto& f = r.forces;
  std::snprintf(line, sizeof line,
                "  force: max %.4f N; extrapolation vs exact: rms %.3g N, max %.3g N over %lld ticks; model switches "
                "%lld (jump max %.3g N, cross-fade step max %.3g N), late models faded in %lld; output step max %.3g N\n",
                f.max_force_N, f.extrapolation_error_rms_N, f.extrapolation_error_max_N, f.compared_ticks, f.model_switches,
                f.switch_jump_max_N, f.crossfade_step_max_N, f.late_model_fade_ins, f.output_step_max_N);
  out << line;
  std::snprintf(line, sizeof line,
                "  model latency after contact: p50 %.1f ms, max %.1f ms (%lld contacts); build p50 %.1f ms, max %.1f ms\n",
                f.model_latency_p50_s * 1e3, f.model_latency_max_s * 1e3, f.model_latency_samples, f.build_p50_s * 1e3,
                f.build_max_s * 1e3);
  out << line;
  for (const auto& note : r.notes) out << "  note: " << note << "\n";
  return out.str();
}

std::string generated_organ_cache_name(const meshes::OrganParameters& organ) {
  std::ostringstream key;
  key.precision(17);
  key << "organ-v1|" << meshes::to_string(organ.shape) << "|" << organ.target_triangles << "|"
      << organ.relative_tolerance << "|" << organ.stomach_scale << "|" << organ.stomach_flattening << "|"
      << organ.hemisphere_radius_m << "|" << organ.max_passes;
  return "organ_" + meshes::to_string(organ.shape) + "_" + std::to_string(organ.target_triangles) + "_" +
         sha256_hex(key.str()).substr(0, 12) + ".vtp";
}

namespace {

/// Organs span millimetres to decimetres; a file in millimetres read as metres spans metres. A
/// warning (the run goes on: a phantom may be large) when the bounding box is outside that range.
std::string organ_size_warning(const geometry::TriangleSurface& organ, const std::string& name) {
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), high = -low;
  for (const auto& v : organ.vertices()) {
    low = low.cwiseMin(v);
    high = high.cwiseMax(v);
  }
  const double diagonal_m = (high - low).norm();
  constexpr double smallest_m = 0.005, largest_m = 1.0;
  if (diagonal_m >= smallest_m && diagonal_m <= largest_m) return "";
  char text[320];
  std::snprintf(text, sizeof text,
                "the organ %s is %.3g m across (bounding-box diagonal), outside %g-%g m: if its file is not in "
                "metres, set [organ] unit_scale (0.001 for millimetres)",
                name.c_str(), diagonal_m, smallest_m, largest_m);
  return text;
}

std::string fmt_seconds(double seconds) {
  char text[64];
  std::snprintf(text, sizeof text, "%g s", seconds);
  return text;
}

geometry::TriangleSurface load_organ(const SimScene& scene, const std::string& output_directory, bool print) {
  if (!scene.surface_path.empty()) {
    meshes::SurfaceReadOptions read;
    read.unit_scale = scene.surface_unit_scale;
    return meshes::load_surface(scene.surface_path, read);
  }
  // Generated shapes are cached beside the outputs under a name that hashes every parameter;
  // a cached file that cannot be read (a run killed while writing it, before the atomic
  // rename existed) is generated again, not an error.
  const auto& g = scene.generated_organ;
  const fs::path cached = fs::path(output_directory) / generated_organ_cache_name(g);
  if (fs::is_regular_file(cached)) {
    try {
      return meshes::load_surface(cached.string());
    } catch (const std::exception& e) {
      if (print) std::printf("note: the cached organ %s cannot be read (%s); generating it again\n", cached.string().c_str(), e.what());
    }
  }
  const auto start = std::chrono::steady_clock::now();
  const meshes::OrganMesh mesh = meshes::generate_organ_mesh(g);
  fs::create_directories(cached.parent_path());
  const fs::path partial = cached.string() + ".partial.vtp";
  meshes::write_surface_mesh(partial.string(), mesh.vertices, mesh.triangles);
  fs::rename(partial, cached);
  if (print)
    std::printf("organ: %s, %zu triangles (generated in %.1f s, cached as %s)\n", meshes::to_string(g.shape).c_str(),
                mesh.triangles.size(), std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                cached.string().c_str());
  return geometry::TriangleSurface(mesh.vertices, mesh.triangles, cached.string());
}

}  // namespace

std::string scene_organ_file(const SimScene& scene, const std::string& output_directory) {
  if (!scene.surface_path.empty()) return scene.surface_path;
  return (fs::path(output_directory) / generated_organ_cache_name(scene.generated_organ)).string();
}

json run_sim(const SimScene& scene_in, const SimOptions& options) {
  SimScene scene = scene_in;
  rt::SceneSettings& s = scene.settings;
  if (options.duration_s) s.duration_s = *options.duration_s;
  if (options.force_mode) s.force_mode = *options.force_mode;
  if (options.output_directory) scene.output_directory = *options.output_directory;
  if (options.window) scene.window = *options.window;
  if (!options.screenshot_path.empty()) scene.screenshot_path = options.screenshot_path;
  if (!options.replay_path.empty()) {
    scene.device = DeviceKind::replay;
    scene.replay_path = options.replay_path;
  }
  if (options.virtual_clock) s.record_force_history = true;
  if (scene.write_force_history) s.record_force_history = true;
  // The scripted hand with the run's duration and rate: refused before anything is written.
  haptics::PalpationSettings palpation = scene.palpation;
  if (s.duration_s > 0) palpation.duration_s = s.duration_s;
  palpation.sample_rate_hz = s.rates.haptic_hz;
  if (scene.device == DeviceKind::scripted) palpation.validate();
  fs::create_directories(scene.output_directory);
  const std::string out = scene.output_directory;

  const geometry::TriangleSurface organ = load_organ(scene, out, options.print);
  std::vector<std::string> notes;
  if (const std::string warning = organ_size_warning(organ, scene.surface_path.empty() ? meshes::to_string(scene.generated_organ.shape) : scene.surface_path); !warning.empty()) {
    notes.push_back(warning);
    if (options.print) std::printf("warning: %s\n", warning.c_str());
  }

  // The device.
  std::unique_ptr<haptics::HapticDevice> device;
  int palpations = 0;
  switch (scene.device) {
    case DeviceKind::none: break;
    case DeviceKind::scripted: {
      // Poses computed as they are read: the memory of a run does not grow with its duration.
      haptics::PalpationScript script = haptics::make_palpation_script(organ, palpation);
      palpations = script.palpations;
      device = std::make_unique<haptics::PalpationDevice>(std::move(script), scene.device_max_force_N);
      break;
    }
    case DeviceKind::replay:
      device = std::make_unique<haptics::ReplayDevice>(haptics::ReplayDevice::from_csv(scene.replay_path, scene.device_max_force_N));
      break;
    case DeviceKind::openigtlink: {
#ifdef TOUCHSTONE_HAVE_OPENIGTLINK
      haptics::OpenIgtLinkSettings igtl;
      igtl.port = scene.igtl_port;
      igtl.length_unit_m = scene.igtl_length_unit_m;
      igtl.max_force_N = scene.device_max_force_N;
      device = std::make_unique<haptics::OpenIgtLinkDevice>(igtl);
      if (options.print) std::printf("openigtlink: waiting for a peer on port %d\n", igtl.port);
#else
      throw ConfigError(scene.config_path + ": device.kind = \"openigtlink\": built without libOpenIGTLink");
#endif
      break;
    }
    case DeviceKind::openhaptics: {
#ifdef TOUCHSTONE_HAVE_OPENHAPTICS
      haptics::OpenHapticsSettings settings;
      settings.device_name = scene.openhaptics_device_name;
      settings.max_force_N = scene.device_max_force_N;
      device = std::make_unique<haptics::OpenHapticsDevice>(settings);
#else
      throw ConfigError(scene.config_path +
                        ": device.kind = \"openhaptics\": the OpenHaptics SDK was not found when this program was "
                        "built (set OPENHAPTICS_ROOT and rebuild)");
#endif
      break;
    }
  }
  std::unique_ptr<haptics::RecordingDevice> recorder;
  haptics::HapticDevice* active = device.get();
  if (device && !options.record_path.empty()) {
    const double seconds = s.duration_s > 0 ? s.duration_s : 600.0;
    // Reserved before the run (no allocation in the haptic tick), bounded like the force history.
    const double ticks = std::min(seconds * s.rates.haptic_hz + 16, double(rt::max_force_history_samples));
    recorder = std::make_unique<haptics::RecordingDevice>(*device, static_cast<std::size_t>(ticks));
    active = recorder.get();
  }

  // The outputs.
  std::vector<realtime::graphics::GraphicsSink*> sinks;
#ifdef TOUCHSTONE_HAVE_VTK
  std::unique_ptr<realtime::graphics::VtkTimeSeriesWriter> series;
  std::unique_ptr<realtime::graphics::InteractiveWindow> window;
  if (scene.write_time_series) {
    realtime::graphics::VtkTimeSeriesSettings settings;
    settings.output_directory = out;
    settings.base_name = scene.name;
    settings.frame_stride = scene.time_series_frame_stride;
    series = std::make_unique<realtime::graphics::VtkTimeSeriesWriter>(settings);
    sinks.push_back(series.get());
  }
  if (scene.window) {
    if (realtime::graphics::InteractiveWindow::display_available()) {
      realtime::graphics::InteractiveWindowSettings settings;
      settings.title = "Touchstone: " + scene.name;
      if (!scene.screenshot_path.empty()) settings.screenshot_path = path_relative_to(out, scene.screenshot_path);
      window = std::make_unique<realtime::graphics::InteractiveWindow>(settings);
      sinks.push_back(window.get());
    } else {
      notes.push_back("no display: the interactive window was skipped (set DISPLAY, or run under xvfb-run)");
    }
  }
#else
  if (scene.write_time_series || scene.window) notes.push_back("built without VTK: no time series, no window");
#endif
#ifdef TOUCHSTONE_HAVE_OPENIGTLINK
  if (scene.device == DeviceKind::openigtlink && scene.igtl_polydata)
    sinks.push_back(static_cast<haptics::OpenIgtLinkDevice*>(device.get()));
#endif

  rt::Simulation simulation(organ, s, active, sinks);
  // forces.csv streams during the run (a line per haptic tick, about 200 bytes): an hour's
  // history never sits in memory. A failed run leaves no half file.
  std::unique_ptr<AtomicFileWriter> forces_csv;
  long long forces_written = 0;
  if (s.record_force_history) {
    forces_csv = std::make_unique<AtomicFileWriter>((fs::path(out) / "forces.csv").string());
    forces_csv->append("time_s,tip_x_m,tip_y_m,tip_z_m,force_x_N,force_y_N,force_z_N,exact_x_N,exact_y_N,exact_z_N,in_contact,model_id\n");
    simulation.stream_force_history([&](const std::vector<rt::ForceSample>& chunk) {
      std::string text;
      text.reserve(chunk.size() * 200);
      char line[400];
      for (const auto& f : chunk) {
        const int n = std::snprintf(line, sizeof line, "%.6f,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d,%llu\n", f.time_s,
                                    f.tip_m.x(), f.tip_m.y(), f.tip_m.z(), f.force_on_hand_N.x(), f.force_on_hand_N.y(),
                                    f.force_on_hand_N.z(), -f.exact_N.x(), -f.exact_N.y(), -f.exact_N.z(), f.in_contact ? 1 : 0,
                                    static_cast<unsigned long long>(f.model_id));
        text.append(line, static_cast<std::size_t>(std::clamp(n, 0, static_cast<int>(sizeof line) - 1)));
      }
      forces_csv->append(text);
      forces_written += static_cast<long long>(chunk.size());
      if (options.force_history_observer) options.force_history_observer(chunk);
    });
  }
  if (options.print)
    std::printf("sim %s: organ %zu triangles, device %s, %s clock, %s\n", scene.name.c_str(), organ.triangles().size(),
                to_string(scene.device).c_str(), options.virtual_clock ? "virtual" : "real",
                s.duration_s > 0 ? fmt_seconds(s.duration_s).c_str() : "until the device ends");
  std::fflush(stdout);  // the run may last minutes: say it started (pipes buffer fully)
  rt::RunSummary summary = options.virtual_clock ? simulation.run_virtual(options.stop) : simulation.run_threaded(options.stop);
  for (const auto& note : notes) summary.notes.push_back(note);

  json document = summary_json(summary);
  document["scene"] = scene.name;
  document["config"] = scene.config_path;
  document["organ_triangles"] = organ.triangles().size();
  document["provenance"] = provenance(scene.config_text);
  // The scene as run (command-line overrides applied), one key per setting.
  document["params"] = sim_scene_params(scene);
  document["config_resolved"] = "config.resolved.toml";
  if (scene.device == DeviceKind::scripted) document["palpations"] = palpations;
#ifdef TOUCHSTONE_HAVE_VTK
  if (series) {
    document["time_series"] = {{"organ_pvd", series->organ_pvd_path()}, {"tool_pvd", series->tool_pvd_path()},
                               {"frames_written", series->frames_written()}, {"bytes_written", series->bytes_written()}};
  }
  if (window) document["window"] = {{"frames_rendered", window->frames_rendered()},
                                    {"screenshots_written", window->screenshots_written()},
                                    {"screenshot", window->settings().screenshot_path}};
#endif
  if (recorder) {
    recorder->write_csv(options.record_path);
    document["recording"] = {{"file", options.record_path}, {"samples", recorder->samples().size()},
                             {"dropped", recorder->dropped()}};
  }
  if (forces_csv) {
    forces_csv->commit();
    document["force_history"] = forces_csv->path();
    document["force_history_ticks"] = forces_written;
  }
  write_file_atomically((fs::path(out) / "config.resolved.toml").string(), resolved_scene_toml(scene));
  write_file_atomically((fs::path(out) / "summary.json").string(), document.dump(2) + "\n");
  if (options.print) {
    std::printf("%s", summary_text(summary).c_str());
    std::printf("summary: %s\n", (fs::path(out) / "summary.json").string().c_str());
  }
  return document;
}

}  // namespace touchstone::studies
