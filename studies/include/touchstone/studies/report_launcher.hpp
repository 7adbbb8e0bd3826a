#pragma once
/// @file
/// The one way the C++ programs write a report: they write data (results.json, summary.json)
/// and run the Python reports package on the output folder,
///
///     <python> -m touchstone_reports <kind> <output folder> [arguments...]
///
/// with PYTHONPATH set to the folder holding `touchstone_reports/`.

#include <string>
#include <vector>

namespace touchstone::studies {

/// The folder holding the `touchstone_reports` package, and every folder tried to find it.
struct ReportsPackageLocation {
  std::string directory;              ///< "" when not found
  std::vector<std::string> searched;  ///< in the order tried
};

/// Finds the package, in this order:
/// 1. $TOUCHSTONE_REPORTS_DIR when set (then only there: a wrong value is an error, not a fallback);
/// 2. the installed copy, <prefix>/share/touchstone/reports, where <prefix> is the parent of the
///    folder of the running executable (/proc/self/exe; `cmake --install` puts it in <prefix>/bin);
/// 3. the source tree this program was built from, <source>/reports.
/// A folder counts when it holds touchstone_reports/__main__.py.
ReportsPackageLocation find_reports_package();

struct ReportLaunchOptions {
  /// The interpreter: Debian's, where python3-matplotlib is installed (not a pyenv shim).
  std::string python = "/usr/bin/python3";
  /// Passed after the output folder, e.g. {"--no-plots"}.
  std::vector<std::string> arguments;
};

struct ReportStatus {
  /// The Python process's exit status (0 written; 2 a missing input or matplotlib, see the
  /// package); -1 when it did not run (package not found, interpreter not startable, killed).
  int exit_status = -1;
  /// "" on success; otherwise what went wrong, naming the folders searched or the command.
  std::string message;
  bool ok() const { return exit_status == 0; }
};

/// Runs the report `kind` ("study", "collision", "fem", "mfs", "sim") on `output_directory`;
/// the package's own output (the report's path, its error message) goes to this process's
/// stdout / stderr. Never throws for a failed report: the caller decides.
ReportStatus run_report(const std::string& kind, const std::string& output_directory,
                        const ReportLaunchOptions& options = {});

}  // namespace touchstone::studies
