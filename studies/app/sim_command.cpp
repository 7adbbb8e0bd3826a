// `touchstone sim <scene>`: the real-time runtime on real threads or, with --virtual, lock-step
// on a virtual clock (study mode). Ctrl-C ends the run cleanly (zero force).
#include "commands.hpp"

#include "touchstone/studies/sim_scene.hpp"

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <csignal>
#include <cstdio>
#include <memory>
#include <string>

namespace touchstone::app {

namespace {
struct SimCommandOptions {
  std::string scene, output, record, replay, screenshot, force_mode;
  std::optional<double> duration_s;  ///< unset: the scene's
  bool virtual_clock = false, window = false, no_window = false;
};

std::atomic<bool> interrupted{false};

/// A run length: a finite number of seconds >= 0 (NaN, infinity and negative values named).
const CLI::Validator finite_non_negative(
    [](std::string& text) -> std::string {
      char* end = nullptr;
      const double value = std::strtod(text.c_str(), &end);
      if (end == text.c_str() || *end != '\0' || !std::isfinite(value) || value < 0)
        return "'" + text + "' must be a finite number of seconds >= 0";
      return "";
    },
    "SECONDS");

int run_sim(const SimCommandOptions& o) {
  std::signal(SIGINT, [](int) { interrupted.store(true); });
  std::signal(SIGTERM, [](int) { interrupted.store(true); });
  const studies::SimScene scene = studies::read_sim_scene(o.scene);
  print_defaults_filled(o.scene, scene.defaults_filled, false);
  studies::SimOptions options;
  if (o.duration_s) options.duration_s = *o.duration_s;
  if (!o.output.empty()) options.output_directory = o.output;
  options.record_path = o.record;
  options.replay_path = o.replay;
  if (!o.force_mode.empty())
    options.force_mode = o.force_mode == "extrapolation" ? realtime::runtime::ForceMode::extrapolation
                                                         : realtime::runtime::ForceMode::stiffness;
  options.virtual_clock = o.virtual_clock;
  if (o.window) options.window = true;
  if (o.no_window) options.window = false;
  options.screenshot_path = o.screenshot;
  options.stop = &interrupted;
  const nlohmann::json summary = studies::run_sim(scene, options);
  write_short_report("sim", o.output.empty() ? scene.output_directory : o.output, false);
  // A run in which every model build failed felt no tissue at all: an error, not a result.
  const auto& work = summary.at("work");
  if (work.at("model_builds").get<long long>() > 0 &&
      work.at("model_build_failures").get<long long>() == work.at("model_builds").get<long long>()) {
    std::fprintf(stderr, "touchstone: error: every model build of %s failed, the device felt no force; the first: %s\n",
                 scene.name.c_str(), summary.at("model_builds").at("first_build_error").get<std::string>().c_str());
    return 1;
  }
  return 0;
}
}  // namespace

void add_sim_command(CLI::App& program, std::vector<Command>& commands) {
  auto o = std::make_shared<SimCommandOptions>();
  CLI::App* sim_cmd = program.add_subcommand(
      "sim", "Run a scene: haptic (1 kHz), model (~200 Hz) and graphics (30 Hz) loops with a device, until the "
             "trajectory ends, the device disconnects or Ctrl-C; prints and writes summary.json");
  sim_cmd->add_option("scene", o->scene, "Scene file (TOML), e.g. studies/configs/scenes/palpation.toml")
      ->required()->check(readable_file);
  sim_cmd->add_option("--duration", o->duration_s, "Run length [s] (overrides the scene; 0: until the device ends)")
      ->check(finite_non_negative);
  sim_cmd->add_option("--out", o->output, "Output folder (default: the scene's [output] directory)")->check(output_folder);
  sim_cmd->add_option("--record", o->record, "Record every tick's pose and force as CSV (replay with device.kind = \"replay\")")
      ->check(output_file);
  sim_cmd->add_option("--replay", o->replay, "Play a recording (from --record) instead of the scene's device")
      ->check(readable_file);
  sim_cmd->add_option("--force-mode", o->force_mode, "Override the scene's force mode")
      ->check(CLI::IsMember({"stiffness", "extrapolation"}));
  sim_cmd->add_flag("--virtual", o->virtual_clock, "Study mode: lock-step on a virtual clock, bit-reproducible");
  sim_cmd->add_flag("--window", o->window, "Open the interactive VTK window (needs a display)");
  sim_cmd->add_flag("--no-window", o->no_window, "Do not open the window even if the scene asks for it");
  sim_cmd->add_option("--screenshot", o->screenshot, "PNG of the window at the end (relative to the output folder)");
  commands.push_back({sim_cmd, [o] { return run_sim(*o); }});
}

}  // namespace touchstone::app
