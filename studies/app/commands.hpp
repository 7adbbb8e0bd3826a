#pragma once
// The subcommands of `touchstone`: each file of this folder adds one (its options, its help and
// what it runs) to the program; main() runs the one the command line names. One dispatch style:
// every command is an action returning the exit status, and main() turns an exception into a
// message on stderr: status 2 for bad input, 1 for a run that failed.
//
// Exit status: 0 done; 1 a run that failed (named on stderr); 2 bad input (a command line or a
// config refused before anything is written), or `surface check` found defects; 3 `study` found
// a regression against its CI baseline.

#include <CLI/CLI.hpp>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace touchstone::app {

/// The process's arguments, for the commands that start MPI (fem, study, atlas).
struct ProgramArguments {
  int* argc = nullptr;
  char*** argv = nullptr;
};

struct Command {
  const CLI::App* subcommand = nullptr;  ///< parsed() when the command line names it
  std::function<int()> run;              ///< returns the exit status; throws on error
};

/// The short report of a subcommand's output folder (report.md from the reports package). A
/// report that cannot be written is a note on stderr, not an error: the data are written.
void write_short_report(const std::string& kind, const std::string& output_directory, bool quiet);

/// Prints, unless quiet, the settings a config file leaves at their defaults
/// (ConfigTable::defaults_filled), so that no default is filled in without a word.
void print_defaults_filled(const std::string& config_path, const std::vector<std::string>& filled, bool quiet);

/// An input file on the command line: it exists and is a regular file (a pipe or a device
/// would block the read or never end it; a folder cannot be read), checked before any work.
extern const CLI::Validator readable_file;
/// Why `folder` could not be made (a file where one of the folders above it would be), or "".
std::string folder_cannot_be_made_reason(const std::filesystem::path& folder);
/// An output folder on the command line: absent (it is made, so nothing above it is a file) or a
/// folder, not a file; checked before any work, since a run writes most of its files at its end.
extern const CLI::Validator output_folder;
/// An output file on the command line that is written when the work ends (a recording, a
/// geometry script): absent or a regular file, in a folder that exists, so that a run is not
/// lost to a path that could never be written.
extern const CLI::Validator output_file;

void add_mesh_command(CLI::App& program, std::vector<Command>& commands);
void add_fem_command(CLI::App& program, std::vector<Command>& commands, ProgramArguments arguments);
void add_mfs_command(CLI::App& program, std::vector<Command>& commands);
void add_surface_commands(CLI::App& program, std::vector<Command>& commands);
void add_collision_command(CLI::App& program, std::vector<Command>& commands);
void add_study_command(CLI::App& program, std::vector<Command>& commands, ProgramArguments arguments);
void add_atlas_command(CLI::App& program, std::vector<Command>& commands, ProgramArguments arguments);
void add_sim_command(CLI::App& program, std::vector<Command>& commands);

}  // namespace touchstone::app
