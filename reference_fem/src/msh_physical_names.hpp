#pragma once
// deal.II's GridIn::read_msh keeps only the numeric physical tags; the names live in the
// $PhysicalNames section, which this reads so that boundaries are addressed by name.

#include <map>
#include <string>

namespace touchstone::fem {

struct MshPhysicalNames {
  std::map<std::string, int> surfaces;  ///< name → tag of 2-D groups
  std::map<std::string, int> volumes;   ///< name → tag of 3-D groups
  std::string surface_list() const;     ///< "base, free, tool_patch" for messages
};

/// Throws std::runtime_error naming the file when it cannot be read or has no $PhysicalNames.
MshPhysicalNames read_msh_physical_names(const std::string& msh_path);

}  // namespace touchstone::fem
