// The study's files beside results.json (CSV tables, the ParaView collections) and its console
// summary.
#include "comparison_parts.hpp"

#include "touchstone/studies/output_files.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <string>

namespace touchstone::studies::comparison {
using nlohmann::json;

void write_csv_tables(const json& document, const std::vector<ProblemRun>& problems, const std::string& out) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> columns{
      {"id", {"id"}},
      {"model", {"model"}},
      {"part", {"part"}},
      {"series", {"series"}},
      {"formulation", {"params", "formulation"}},
      {"nodes_requested", {"params", "node_count_requested"}},
      {"nodes", {"params", "node_count"}},
      {"dofs", {"mesh", "dofs"}},
      {"axial_force_N", {"qoi", "axial_force_N"}},
      {"force_rel", {"error", "force_rel"}},
      {"force_signed_rel", {"error", "force_signed_rel"}},
      {"reference_uncertainty_rel", {"error", "reference_uncertainty_rel"}},
      {"disp_rel_l2", {"error", "disp_rel_l2"}},
      {"disp_max_m", {"error", "disp_max_m"}},
      {"force_rel_full_domain", {"error_full_domain", "force_rel"}},
      {"force_signed_rel_half_space", {"error_half_space", "force_signed_rel"}},
      {"model_s", {"time_s", "model"}},
      {"solution_s", {"time_s", "solution"}},
      {"total_s", {"time_s", "total"}},
      {"reference", {"reference"}},
      {"status", {"status"}},
      {"problem", {"params", "problem"}},
      {"force_method_spread", {"accuracy", "force_method_spread"}},
      {"accuracy_flags", {"accuracy", "flags"}}};
  std::ostringstream text;
  for (std::size_t i = 0; i < columns.size(); ++i) text << (i ? "," : "") << columns[i].first;
  text << "\n";
  for (const auto& c : document.at("cases")) {
    for (std::size_t i = 0; i < columns.size(); ++i) text << (i ? "," : "") << csv_value(json_at_path(c, columns[i].second));
    text << "\n";
  }
  write_file_atomically(out + "/cases.csv", text.str());

  std::ostringstream ramp;
  ramp << "id,model,depth_m,axial_force_N\n";
  for (const auto& c : document.at("cases")) {
    const json& depths = json_at_path(c, {"depths_m"});
    const json& forces = json_at_path(c, {"force_depth_N"});
    for (std::size_t i = 0; depths.is_array() && i < depths.size() && i < forces.size(); ++i)
      ramp << csv_value(c.at("id")) << "," << csv_value(c.at("model")) << "," << csv_value(depths[i]) << ","
           << csv_value(forces[i]) << "\n";
  }
  write_file_atomically(out + "/force_depth.csv", ramp.str());

  std::ostringstream probes;
  probes << "id,probe,x_m,y_m,z_m,ux_m,uy_m,uz_m\n";
  for (const auto& c : document.at("cases")) {
    const json& list = json_at_path(c, {"qoi", "probes"});
    const bool reference_case = std::any_of(problems.begin(), problems.end(), [&](const ProblemRun& r) {
      return c.at("id") == r.reference.id ||
             std::any_of(r.punch_references.begin(), r.punch_references.end(),
                         [&](const auto& punch) { return c.at("id") == punch.second.id; });
    });
    if (!list.is_array() || (c.at("model") != "mfs" && !reference_case)) continue;
    for (const auto& p : list) {
      const json& x = p.at("position_m");
      const json& u = p.value("displacement_m", json(nullptr));
      probes << csv_value(c.at("id")) << "," << csv_value(p.at("name"));
      for (int i = 0; i < 3; ++i) probes << "," << csv_value(x.at(i));
      for (int i = 0; i < 3; ++i) probes << "," << (u.is_array() ? csv_value(u.at(i)) : std::string());
      probes << "\n";
    }
  }
  write_file_atomically(out + "/probes.csv", probes.str());

  std::ostringstream targets;
  targets << "id,what,target,unit,measured,met,shortfall,basis\n";
  for (const auto& t : document.at("targets"))
    targets << csv_value(t.at("id")) << "," << csv_value(t.at("what")) << "," << csv_value(t.at("target")) << ","
            << csv_value(t.at("unit")) << "," << csv_value(t.at("measured")) << "," << csv_value(t.at("met")) << ","
            << csv_value(t.at("shortfall")) << "," << csv_value(t.at("basis")) << "\n";
  write_file_atomically(out + "/targets.csv", targets.str());
}

void write_comparison_pvds(const json& cases, const std::string& out) {
  std::map<std::string, std::vector<std::pair<double, std::string>>> by_series;
  for (const auto& c : cases)
    if (c.value("part", "") == "mfs" && c.value("comparison_vtu", json(nullptr)).is_string())
      by_series[c.at("id").get<std::string>().substr(0, c.at("id").get<std::string>().rfind('/') + 1) +
                c.at("series").get<std::string>()].push_back(
          {c.at("params").value("node_count", 0.0), c.at("comparison_vtu").get<std::string>()});
  for (auto& [series, files] : by_series) {
    std::sort(files.begin(), files.end());
    std::ostringstream pvd;
    pvd << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n";
    for (const auto& [n, file] : files) pvd << "    <DataSet timestep=\"" << n << "\" group=\"\" part=\"0\" file=\"" << file << "\"/>\n";
    pvd << "  </Collection>\n</VTKFile>\n";
    // A variant's series: "<name>/<series>" → mfs_on_reference_<name>_<series>.pvd.
    std::string file_name = series;
    std::replace(file_name.begin(), file_name.end(), '/', '_');
    write_file_atomically(out + "/mfs_on_reference_" + file_name + ".pvd", pvd.str());
  }
}

void print_summary(const json& document, const std::vector<ProblemRun>& problems) {
  for (const ProblemRun& r : problems) {
    if (!r.runs_reference) continue;
    std::printf("\nreference %s: F = %.6f mN, estimated discretisation error %s", r.reference.id.c_str(),
                1e3 * r.reference.force_N,
                std::isfinite(r.reference.uncertainty_rel) ? (format_number(100 * r.reference.uncertainty_rel) + " %").c_str()
                                                           : "not estimated (fewer than three levels)");
    if (std::isfinite(r.reference.half_space_force_N))
      std::printf("\n  half-space closed form (%s): F = %.6f mN; reference / half-space = %.5f",
                  r.reference.half_space_formula.c_str(), 1e3 * r.reference.half_space_force_N,
                  r.reference.force_N / r.reference.half_space_force_N);
  }
  std::printf("\n");
  // A signed error against the half-space closed form where the problem has one (B1, B2).
  const bool half_space = std::any_of(problems.begin(), problems.end(), [](const ProblemRun& r) {
    return std::isfinite(r.reference.half_space_force_N);
  });
  std::printf("%-28s %6s %12s %10s %10s %11s%s\n", "case", "N", "F [mN]", "F err [%]", "u err [%]", "time [ms]",
              half_space ? "  vs half-space [%]" : "");
  for (const auto& c : document.at("cases")) {
    if (c.at("model") != "mfs") continue;
    std::string flags;
    for (const auto& f : c.at("accuracy").at("flags")) flags += " " + f.get<std::string>();
    const std::string versus =
        half_space ? " " + table_cell(100 * value_or_nan(json_at_path(c, {"error_half_space"}), "force_signed_rel"), 18, 2) : "";
    std::printf("%-28s %6s %s %s %s %s%s  %s%s\n", c.at("id").get<std::string>().c_str(),
                c.at("params").at("node_count").dump().c_str(),
                table_cell(1e3 * value_or_nan(c.at("qoi"), "axial_force_N"), 12, 5).c_str(),
                table_cell(100 * value_or_nan(c.at("error"), "force_rel"), 10, 2).c_str(),
                table_cell(100 * value_or_nan(c.at("error"), "disp_rel_l2"), 10, 2).c_str(),
                table_cell(1e3 * value_or_nan(c.at("time_s"), "total"), 11, 2).c_str(), versus.c_str(),
                c.at("status").get<std::string>().c_str(), flags.c_str());
  }
  std::printf("\nTargets:\n");
  for (const auto& t : document.at("targets")) {
    const std::string met = t.at("met").is_null() ? "n/a " : (t.at("met").get<bool>() ? "MET " : "MISS");
    std::printf("  %s %s: %s %s\n", met.c_str(), t.at("what").get<std::string>().c_str(),
                t.at("measured").is_null() ? "-" : format_number(t.at("measured").get<double>()).c_str(),
                t.at("shortfall").get<std::string>().c_str());
  }
  std::fflush(stdout);
}

}  // namespace touchstone::studies::comparison
