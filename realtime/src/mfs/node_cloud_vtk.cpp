#include "touchstone/realtime/mfs/node_cloud_vtk.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <locale>
#include <stdexcept>
#include <system_error>

namespace touchstone::realtime::mfs {
namespace {

const std::string where = "write_node_cloud_vtu: ";

/// One point-data array: `value(i, c)` is component c of point i. Integer arrays go through
/// double too; every code written here is exact in a double.
struct PointArray {
  std::string name;
  bool integer = false;
  int components = 1;
  std::function<double(std::size_t, int)> value;
};

// The codes are part of the file format (documented in the header), so they are spelled out
// rather than taken from the enums' underlying values, which may be reordered.
int kind_code(NodeKind kind) {
  switch (kind) {
    case NodeKind::interior: return 0;
    case NodeKind::free_surface: return 1;
    case NodeKind::tool_patch: return 2;
    case NodeKind::cut: return 3;
  }
  return -1;
}

int row_code(CollocationRow::Type type) {
  switch (type) {
    case CollocationRow::Type::navier: return 0;
    case CollocationRow::Type::traction: return 1;
    case CollocationRow::Type::dirichlet: return 2;
  }
  return -1;
}

void check_size(const std::string& name, std::size_t size, std::size_t expected, bool may_be_empty,
                const std::string& per_node) {
  if (size == expected || (may_be_empty && size == 0)) return;
  throw std::invalid_argument(where + name + " has " + std::to_string(size) + " values, expected " +
                              (may_be_empty ? "0 or " : "") + std::to_string(expected) + " (" + per_node + ")");
}

// VTK 9.1's ASCII parser reads "-inf" as +inf, and drops the whole array when "inf" touches
// the closing tag: a non-finite value would be shown wrong or not at all, so refuse it here.
void check_finite(const std::string& name, std::size_t index, double value) {
  if (std::isfinite(value)) return;
  throw std::invalid_argument(where + name + "[" + std::to_string(index) + "] is " + std::to_string(value) +
                              "; VTK's ASCII reader does not read NaN or inf back reliably");
}

void check_finite(const std::string& name, std::size_t index, const Eigen::Vector3d& value) {
  for (int c = 0; c < 3; ++c) check_finite(name, index, value(c));
}

void validate(const NodeCloud& cloud, const NodeCloudFields& fields) {
  const std::size_t n = cloud.size();
  check_size("cloud.radii", cloud.radii.size(), n, false, "one per node");
  check_size("cloud.kinds", cloud.kinds.size(), n, false, "one per node");
  check_size("cloud.normals", cloud.normals.size(), n, false, "one per node");
  check_size("cloud.rows", cloud.rows.size(), n, false, "one per node");
  check_size("cloud.spacing", cloud.spacing.size(), n, false, "one per node");
  check_size("cloud.body_force", cloud.body_force.size(), n, true, "one per node");
  check_size("fields.displacement_m", static_cast<std::size_t>(fields.displacement_m.size()), 3 * n, true,
             "3 per node");
  check_size("fields.parameters_m", static_cast<std::size_t>(fields.parameters_m.size()), 3 * n, true, "3 per node");
  check_size("fields.rcond", fields.rcond.size(), n, true, "one per node");

  for (std::size_t i = 0; i < n; ++i) {
    check_finite("cloud.positions", i, cloud.positions[i]);
    check_finite("cloud.radii", i, cloud.radii[i]);
    check_finite("cloud.normals", i, cloud.normals[i]);
    check_finite("cloud.spacing", i, cloud.spacing[i]);
    if (!cloud.body_force.empty()) check_finite("cloud.body_force", i, cloud.body_force[i]);
    if (!fields.rcond.empty()) check_finite("fields.rcond", i, fields.rcond[i]);
  }
  for (Eigen::Index k = 0; k < fields.displacement_m.size(); ++k)
    check_finite("fields.displacement_m", static_cast<std::size_t>(k), fields.displacement_m(k));
  for (Eigen::Index k = 0; k < fields.parameters_m.size(); ++k)
    check_finite("fields.parameters_m", static_cast<std::size_t>(k), fields.parameters_m(k));
  for (std::size_t m = 0; m < cloud.extra_points.size(); ++m) {
    const CollocationPoint& point = cloud.extra_points[m];
    check_finite("cloud.extra_points.position", m, point.position);
    check_finite("cloud.extra_points.normal", m, point.normal);
    check_finite("cloud.extra_points.spacing", m, point.spacing);
  }
}

/// An UnstructuredGrid of n VTK_VERTEX cells, one per point, so that ParaView shows every point
/// (a grid with points and no cells renders nothing).
void write_vtu(std::ostream& out, std::size_t n, const std::function<Eigen::Vector3d(std::size_t)>& position,
               const std::vector<PointArray>& arrays) {
  constexpr int vtk_vertex = 1;
  out << "<?xml version=\"1.0\"?>\n"
         "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
         "<UnstructuredGrid>\n"
      << "<Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << n << "\">\n"
      << "<PointData>\n";
  for (const PointArray& array : arrays) {
    out << "<DataArray type=\"" << (array.integer ? "Int32" : "Float64") << "\" Name=\"" << array.name
        << "\" NumberOfComponents=\"" << array.components << "\" format=\"ascii\">\n";
    for (std::size_t i = 0; i < n; ++i) {
      for (int c = 0; c < array.components; ++c) {
        if (c > 0) out << ' ';
        if (array.integer)
          out << static_cast<long long>(array.value(i, c));
        else
          out << array.value(i, c);
      }
      out << '\n';
    }
    out << "</DataArray>\n";
  }
  out << "</PointData>\n"
         "<Points>\n"
         "<DataArray type=\"Float64\" Name=\"position_m\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = position(i);
    out << x.x() << ' ' << x.y() << ' ' << x.z() << '\n';
  }
  out << "</DataArray>\n"
         "</Points>\n"
         "<Cells>\n"
         "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < n; ++i) out << i << '\n';
  out << "</DataArray>\n"
         "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < n; ++i) out << i + 1 << '\n';
  out << "</DataArray>\n"
         "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < n; ++i) out << vtk_vertex << '\n';
  out << "</DataArray>\n"
         "</Cells>\n"
         "</Piece>\n"
         "</UnstructuredGrid>\n"
         "</VTKFile>\n";
}

/// Writes `<path>.tmp` and renames it over `path`: a reader (ParaView reloading, a script)
/// sees the old file or the new one, never a truncated one.
void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& body) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) {
      const int error = errno;
      throw std::runtime_error(where + "cannot write '" + path + "': cannot open '" + tmp +
                               "': " + std::strerror(error));
    }
    // A global locale with a decimal comma would make the numbers unreadable for VTK.
    out.imbue(std::locale::classic());
    out.precision(std::numeric_limits<double>::max_digits10);
    body(out);
    out.flush();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error(where + "cannot write '" + path + "': writing '" + tmp + "' failed (disk full?)");
    }
  }
  std::error_code error;
  std::filesystem::rename(tmp, path, error);
  if (error) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error(where + "cannot write '" + path + "': renaming '" + tmp + "' failed: " + error.message());
  }
}

}  // namespace

std::string collocation_points_vtu_path(const std::string& path) {
  const std::string suffix = ".vtu";
  const bool has_suffix =
      path.size() >= suffix.size() && path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0;
  return (has_suffix ? path.substr(0, path.size() - suffix.size()) : path) + "_collocation_points.vtu";
}

void write_node_cloud_vtu(const NodeCloud& cloud, const NodeCloudFields& fields, const std::string& path) {
  // Everything is checked before the first byte is written, so bad input leaves no files behind.
  validate(cloud, fields);

  std::vector<PointArray> nodes = {
      {"sphere_radius_m", false, 1, [&](std::size_t i, int) { return cloud.radii[i]; }},
      {"spacing_m", false, 1, [&](std::size_t i, int) { return cloud.spacing[i]; }},
      {"kind", true, 1, [&](std::size_t i, int) { return double(kind_code(cloud.kinds[i])); }},
      {"normal", false, 3, [&](std::size_t i, int c) { return cloud.normals[i](c); }},
      {"row_type", true, 3, [&](std::size_t i, int c) { return double(row_code(cloud.rows[i][c].type)); }},
  };
  if (!cloud.body_force.empty())
    nodes.push_back({"body_force_N_per_m3", false, 3, [&](std::size_t i, int c) { return cloud.body_force[i](c); }});
  if (fields.displacement_m.size() > 0)
    nodes.push_back(
        {"displacement_m", false, 3, [&](std::size_t i, int c) { return fields.displacement_m(3 * i + c); }});
  if (fields.parameters_m.size() > 0)
    nodes.push_back({"parameters_m", false, 3, [&](std::size_t i, int c) { return fields.parameters_m(3 * i + c); }});
  if (!fields.rcond.empty())
    nodes.push_back({"rcond", false, 1, [&](std::size_t i, int) { return fields.rcond[i]; }});
  write_atomically(path, [&](std::ostream& out) {
    write_vtu(out, cloud.size(), [&](std::size_t i) { return cloud.positions[i]; }, nodes);
  });

  if (cloud.extra_points.empty()) return;
  const std::vector<CollocationPoint>& extra = cloud.extra_points;
  const std::vector<PointArray> points = {
      {"spacing_m", false, 1, [&](std::size_t m, int) { return extra[m].spacing; }},
      {"kind", true, 1, [&](std::size_t m, int) { return double(kind_code(extra[m].kind)); }},
      {"normal", false, 3, [&](std::size_t m, int c) { return extra[m].normal(c); }},
      {"row_type", true, 3, [&](std::size_t m, int c) { return double(row_code(extra[m].rows[c].type)); }},
  };
  write_atomically(collocation_points_vtu_path(path), [&](std::ostream& out) {
    write_vtu(out, extra.size(), [&](std::size_t m) { return extra[m].position; }, points);
  });
}

}  // namespace touchstone::realtime::mfs
