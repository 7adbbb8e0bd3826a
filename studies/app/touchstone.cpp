// touchstone — one program, one subcommand per job (one file each in this folder), `--help` on
// each.
#include "commands.hpp"

#include "touchstone/geometry/regular_file.hpp"
#include "touchstone/realtime/runtime/loop_timing.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/report_launcher.hpp"

#include <cstdio>
#include <exception>
#include <filesystem>
#include <stdexcept>
#include <string>

const CLI::Validator touchstone::app::readable_file(
    [](std::string& path) -> std::string {
      if (const std::string reason = touchstone::geometry::non_regular_file_reason(path); !reason.empty())
        return "'" + path + "' cannot be read (" + reason + ")";
      std::error_code error;
      if (!std::filesystem::exists(path, error)) return "no such file '" + path + "'";
      return "";
    },
    "FILE");

std::string touchstone::app::folder_cannot_be_made_reason(const std::filesystem::path& folder) {
  std::error_code error;
  for (std::filesystem::path above = folder.parent_path(); !above.empty(); above = above.parent_path()) {
    if (std::filesystem::exists(above, error)) {
      if (!std::filesystem::is_directory(above, error)) return "'" + above.string() + "' is not a folder";
      return "";
    }
    if (above == above.parent_path()) break;
  }
  return "";
}

const CLI::Validator touchstone::app::output_folder(
    [](std::string& path) -> std::string {
      std::error_code error;
      if (std::filesystem::exists(path, error) && !std::filesystem::is_directory(path, error))
        return "'" + path + "' exists and is not a folder (the output folder holds several files)";
      if (const std::string reason = folder_cannot_be_made_reason(path); !reason.empty())
        return "'" + path + "' cannot be made (" + reason + ")";
      return "";
    },
    "FOLDER");

const CLI::Validator touchstone::app::output_file(
    [](std::string& path) -> std::string {
      if (const std::string reason = touchstone::geometry::non_regular_file_reason(path); !reason.empty())
        return "'" + path + "' cannot be written (" + reason + ")";
      const std::filesystem::path folder = std::filesystem::path(path).parent_path();
      std::error_code error;
      if (!folder.empty() && !std::filesystem::is_directory(folder, error))
        return "'" + path + "' cannot be written (no folder '" + folder.string() + "')";
      return "";
    },
    "FILE");

void touchstone::app::write_short_report(const std::string& kind, const std::string& output_directory, bool quiet) {
  studies::ReportLaunchOptions options;
  if (quiet) options.arguments.push_back("--quiet");
  std::fflush(stdout);
  const studies::ReportStatus status = studies::run_report(kind, output_directory, options);
  if (!status.ok()) std::fprintf(stderr, "touchstone: note: no report.md: %s\n", status.message.c_str());
}

void touchstone::app::print_defaults_filled(const std::string& config_path, const std::vector<std::string>& filled, bool quiet) {
  if (quiet || filled.empty()) return;
  std::string list;
  for (const std::string& setting : filled) list += (list.empty() ? "" : "; ") + setting;
  std::printf("note: %s does not set %zu setting(s); their defaults: %s\n", config_path.c_str(), filled.size(), list.c_str());
}

int main(int argc, char** argv) {
  using namespace touchstone::app;
  // Before any thread starts: the model loop's builds (sim) and the MFS cases' timed builds
  // reuse freed memory instead of faulting in fresh pages each time.
  touchstone::realtime::runtime::keep_freed_memory_for_reuse();
  // Mesh generation and the FEM's factorisation touch most of their memory once: on huge pages
  // they take a page fault per 2 MiB instead of per 4 KiB.
  touchstone::realtime::runtime::advise_huge_pages_for_heap();
  CLI::App program{"Touchstone: a real-time meshless tissue model checked against a converged FEM reference"};
  program.require_subcommand(1);
  // Exit status: 0 done, 1 a run that failed, 2 bad input (a command line or a config refused
  // before anything is written), 3 a regression against a CI baseline (study).
  constexpr int bad_input = 2;
  std::vector<Command> commands;
  const ProgramArguments arguments{&argc, &argv};
  add_mesh_command(program, commands);
  add_fem_command(program, commands, arguments);
  add_mfs_command(program, commands);
  add_study_command(program, commands, arguments);
  add_atlas_command(program, commands, arguments);
  add_collision_command(program, commands);
  add_surface_commands(program, commands);
  add_sim_command(program, commands);

  // An unknown first word is a misspelt subcommand: say which, not "a subcommand is required".
  if (argc > 1 && argv[1][0] != '-') {
    bool known = false;
    std::string names;
    for (const CLI::App* subcommand : program.get_subcommands({})) {
      known = known || subcommand->get_name() == argv[1];
      names += (names.empty() ? "" : ", ") + subcommand->get_name();
    }
    if (!known) {
      std::fprintf(stderr, "touchstone: error: unknown subcommand '%s' (one of: %s; touchstone --help)\n", argv[1],
                   names.c_str());
      return bad_input;
    }
  }
  try {
    program.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int status = program.exit(e);  // prints the help, or CLI11's message naming the option
    return status == 0 ? 0 : bad_input;
  }
  for (const Command& command : commands) {
    if (!command.subcommand->parsed()) continue;
    try {
      return command.run();
    } catch (const touchstone::studies::ConfigError& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      return bad_input;
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      return bad_input;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      return 1;
    }
  }
  return 1;  // unreachable: CLI11 requires one subcommand
}
