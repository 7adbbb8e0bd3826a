// The report launcher: finds the touchstone_reports package and runs it with posix_spawn (no
// shell: paths need no quoting), PYTHONPATH pointing at the package's folder.
#include "touchstone/studies/report_launcher.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <system_error>

extern char** environ;

// The package's folder under the install prefix (studies/CMakeLists.txt sets it from GNUInstallDirs).
#ifndef TOUCHSTONE_REPORTS_INSTALL_SUBDIR
#define TOUCHSTONE_REPORTS_INSTALL_SUBDIR "share/touchstone/reports"
#endif

namespace touchstone::studies {
namespace fs = std::filesystem;

namespace {

bool holds_package(const fs::path& directory) {
  std::error_code error;
  return fs::is_regular_file(directory / "touchstone_reports" / "__main__.py", error);
}

std::string joined(const std::vector<std::string>& items) {
  std::string text;
  for (const auto& item : items) text += (text.empty() ? "" : ", ") + item;
  return text;
}

}  // namespace

ReportsPackageLocation find_reports_package() {
  ReportsPackageLocation location;
  const auto consider = [&](const fs::path& directory) {
    location.searched.push_back(directory.string());
    if (holds_package(directory)) location.directory = directory.string();
    return !location.directory.empty();
  };
  if (const char* env = std::getenv("TOUCHSTONE_REPORTS_DIR"); env != nullptr && *env != '\0') {
    consider(env);
    return location;
  }
  std::error_code error;
  const fs::path executable = fs::read_symlink("/proc/self/exe", error);
  if (!error && consider(executable.parent_path().parent_path() / TOUCHSTONE_REPORTS_INSTALL_SUBDIR)) return location;
#ifdef TOUCHSTONE_SOURCE_DIR
  consider(fs::path(TOUCHSTONE_SOURCE_DIR) / "reports");
#endif
  return location;
}

ReportStatus run_report(const std::string& kind, const std::string& output_directory,
                        const ReportLaunchOptions& options) {
  ReportStatus status;
  const ReportsPackageLocation location = find_reports_package();
  if (location.directory.empty()) {
    status.message = "the reports package (touchstone_reports/__main__.py) was not found in: " +
                     joined(location.searched) + " (set TOUCHSTONE_REPORTS_DIR to the folder holding it)";
    return status;
  }

  std::vector<std::string> arguments{options.python, "-m", "touchstone_reports", kind, output_directory};
  arguments.insert(arguments.end(), options.arguments.begin(), options.arguments.end());
  std::string command;
  for (const auto& a : arguments) command += (command.empty() ? "" : " ") + a;

  // The environment with PYTHONPATH replaced: the package's folder first, then any previous value.
  std::vector<std::string> environment;
  std::string python_path = "PYTHONPATH=" + location.directory;
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::strncmp(*e, "PYTHONPATH=", 11) == 0) {
      if ((*e)[11] != '\0') python_path += std::string(":") + (*e + 11);
    } else {
      environment.emplace_back(*e);
    }
  }
  environment.push_back(python_path);

  std::vector<char*> argv, envp;
  for (auto& a : arguments) argv.push_back(a.data());
  argv.push_back(nullptr);
  for (auto& e : environment) envp.push_back(e.data());
  envp.push_back(nullptr);

  std::fflush(stdout);
  std::fflush(stderr);
  pid_t pid = 0;
  const int spawn_error = posix_spawn(&pid, options.python.c_str(), nullptr, nullptr, argv.data(), envp.data());
  if (spawn_error != 0) {
    status.message = "cannot start " + options.python + " (" + std::strerror(spawn_error) + "): " + command;
    return status;
  }
  int wait_status = 0;
  while (waitpid(pid, &wait_status, 0) < 0)
    if (errno != EINTR) {
      status.message = "lost the report process of `" + command + "`: " + std::strerror(errno);
      return status;
    }
  if (WIFEXITED(wait_status)) {
    status.exit_status = WEXITSTATUS(wait_status);
    if (status.exit_status != 0)
      status.message = "`" + command + "` (PYTHONPATH " + location.directory + ") failed with status " +
                       std::to_string(status.exit_status);
  } else {
    status.message = "`" + command + "` ended by signal " +
                     std::to_string(WIFSIGNALED(wait_status) ? WTERMSIG(wait_status) : 0);
  }
  return status;
}

}  // namespace touchstone::studies
