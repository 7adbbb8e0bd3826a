#include "msh_physical_names.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace touchstone::fem {

std::string MshPhysicalNames::surface_list() const {
  std::string list;
  for (const auto& [name, tag] : surfaces) list += (list.empty() ? "" : ", ") + name;
  return list.empty() ? "none" : list;
}

MshPhysicalNames read_msh_physical_names(const std::string& msh_path) {
  std::ifstream in(msh_path);
  if (!in) throw std::runtime_error(msh_path + ": cannot open mesh file");
  std::string line;
  while (std::getline(in, line) && line.rfind("$PhysicalNames", 0) != 0) {
  }
  if (!in) throw std::runtime_error(msh_path + ": no $PhysicalNames section (name the boundaries with gmsh physical groups)");
  int count = 0;
  if (!(in >> count) || count < 0) throw std::runtime_error(msh_path + ": malformed $PhysicalNames section");
  MshPhysicalNames names;
  for (int i = 0; i < count; ++i) {
    int dimension = 0, tag = 0;
    std::string quoted;
    if (!(in >> dimension >> tag) || !std::getline(in >> std::ws, quoted) || quoted.size() < 2 ||
        quoted.front() != '"')
      throw std::runtime_error(msh_path + ": malformed entry " + std::to_string(i + 1) +
                               " of $PhysicalNames");
    const std::string name = quoted.substr(1, quoted.find('"', 1) - 1);
    if (dimension == 2) names.surfaces[name] = tag;
    if (dimension == 3) names.volumes[name] = tag;
  }
  return names;
}

}  // namespace touchstone::fem
