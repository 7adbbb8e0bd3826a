// VTU output of the node cloud: a hand-made cloud with every node kind and two extra
// collocation points is written and read back (counts, every array bit for bit), empty fields
// are left out, and bad input (wrong sizes, NaN, an unwritable path) throws naming what is wrong.
// That VTK itself reads the files is checked by check_node_cloud_vtu.py (ctest
// realtime.node_cloud_vtk_opens_in_vtk), on the file this test writes when
// TOUCHSTONE_NODE_CLOUD_VTU names a path.
#include "touchstone/realtime/mfs/node_cloud_vtk.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <locale>
#include <sstream>

namespace touchstone::realtime::mfs {
namespace {

constexpr std::size_t node_count = 8;

std::array<CollocationRow, 3> rows(CollocationRow::Type a, CollocationRow::Type b, CollocationRow::Type c) {
  std::array<CollocationRow, 3> r;
  r[0].type = a;
  r[1].type = b;
  r[2].type = c;
  for (int k = 0; k < 3; ++k) r[k].direction = Eigen::Vector3d::Unit(k);
  return r;
}

/// Two nodes of each kind; radii, positions and spacings are not short decimals, so only
/// max_digits10 output reads them back exactly. Node 0 has radius 2.5 mm and spacing 1 mm, the
/// values the VTK check looks for.
NodeCloud sample_cloud() {
  using Type = CollocationRow::Type;
  const NodeKind kinds[node_count] = {NodeKind::interior,   NodeKind::interior,   NodeKind::free_surface,
                                      NodeKind::free_surface, NodeKind::tool_patch, NodeKind::tool_patch,
                                      NodeKind::cut,        NodeKind::cut};
  NodeCloud cloud;
  for (std::size_t i = 0; i < node_count; ++i) {
    const double t = static_cast<double>(i);
    cloud.positions.emplace_back(0.01 * t / 3, -0.002 * t, 0.05 - 1e-3 * t / 7);
    cloud.radii.push_back(0.0025 * (1 + t / 3));
    cloud.kinds.push_back(kinds[i]);
    cloud.normals.push_back(kinds[i] == NodeKind::interior ? Eigen::Vector3d::Zero()
                                                           : Eigen::Vector3d(1, t, -2).normalized());
    cloud.spacing.push_back(0.001 * (1 + t / 7));
    cloud.body_force.emplace_back(0, 0, -9.81 * 1060);
  }
  cloud.rows = {rows(Type::navier, Type::navier, Type::navier),
                rows(Type::navier, Type::navier, Type::navier),
                rows(Type::traction, Type::traction, Type::traction),
                rows(Type::traction, Type::traction, Type::traction),
                rows(Type::dirichlet, Type::dirichlet, Type::dirichlet),
                rows(Type::dirichlet, Type::traction, Type::traction),  // frictionless: mixed
                rows(Type::dirichlet, Type::dirichlet, Type::dirichlet),
                rows(Type::dirichlet, Type::dirichlet, Type::dirichlet)};
  for (int m = 0; m < 2; ++m) {
    CollocationPoint point;
    point.position = {0.004 / 3, 0.001 * m, 0.049};
    point.kind = m == 0 ? NodeKind::free_surface : NodeKind::interior;
    point.normal = m == 0 ? Eigen::Vector3d(0, 0, 1) : Eigen::Vector3d::Zero();
    point.spacing = 0.0015 / 7;
    point.rows = m == 0 ? rows(Type::traction, Type::traction, Type::traction)
                        : rows(Type::navier, Type::navier, Type::navier);
    cloud.extra_points.push_back(point);
  }
  return cloud;
}

NodeCloudFields sample_fields() {
  NodeCloudFields fields;
  fields.displacement_m.resize(3 * node_count);
  fields.parameters_m.resize(3 * node_count);
  for (std::size_t k = 0; k < 3 * node_count; ++k) {
    fields.displacement_m(k) = 1e-4 * std::sin(static_cast<double>(k) + 0.5);
    fields.parameters_m(k) = 1.1e-4 * std::cos(static_cast<double>(k));
  }
  for (std::size_t i = 0; i < node_count; ++i) fields.rcond.push_back(1e-3 * static_cast<double>(i + 1) / 3);
  return fields;
}

/// A unique file in the temp folder (pid: parallel ctest runs of the same test do not collide),
/// removed with its collocation-point companion and any leftover .tmp.
class TempVtu {
 public:
  explicit TempVtu(const std::string& tag)
      : path_((std::filesystem::temp_directory_path() /
               ("touchstone_node_cloud_vtk_" + std::to_string(getpid()) + "_" + tag + ".vtu"))
                  .string()) {
    remove_all();
  }
  ~TempVtu() { remove_all(); }
  const std::string& path() const { return path_; }

 private:
  void remove_all() const {
    for (const std::string& p : {path_, path_ + ".tmp", collocation_points_vtu_path(path_)}) std::remove(p.c_str());
  }
  std::string path_;
};

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << "cannot read " << path;
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The value of the first `name="..."` attribute.
std::string attribute(const std::string& text, const std::string& name) {
  const std::string key = name + "=\"";
  const std::size_t start = text.find(key);
  if (start == std::string::npos) return "";
  const std::size_t begin = start + key.size();
  return text.substr(begin, text.find('"', begin) - begin);
}

/// The numbers of the DataArray called `name`, in file order (empty if there is none).
std::vector<double> data_array(const std::string& text, const std::string& name) {
  const std::size_t start = text.find("Name=\"" + name + "\"");
  if (start == std::string::npos) return {};
  const std::size_t begin = text.find('>', start) + 1;
  std::istringstream in(text.substr(begin, text.find("</DataArray>", begin) - begin));
  in.imbue(std::locale::classic());
  std::vector<double> values;
  for (double v; in >> v;) values.push_back(v);
  return values;
}

void expect_same(const std::vector<double>& read, const std::vector<double>& written, const std::string& what) {
  ASSERT_EQ(read.size(), written.size()) << what;
  for (std::size_t k = 0; k < written.size(); ++k) EXPECT_EQ(read[k], written[k]) << what << "[" << k << "]";
}

TEST(NodeCloudVtk, WritesAndReadsBack) {
  const NodeCloud cloud = sample_cloud();
  const NodeCloudFields fields = sample_fields();
  // Under the VTK ctest the file goes where the Python check finds it, and stays for ParaView.
  const char* kept = std::getenv("TOUCHSTONE_NODE_CLOUD_VTU");
  const TempVtu temp("roundtrip");
  const std::string path = kept != nullptr ? kept : temp.path();
  write_node_cloud_vtu(cloud, fields, path);

  const std::string text = read_text(path);
  EXPECT_EQ(attribute(text, "type"), "UnstructuredGrid");
  EXPECT_EQ(attribute(text, "NumberOfPoints"), std::to_string(node_count));
  EXPECT_EQ(attribute(text, "NumberOfCells"), std::to_string(node_count));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));

  std::vector<double> positions, normals, body_force, kinds, row_types;
  for (std::size_t i = 0; i < node_count; ++i) {
    for (int c = 0; c < 3; ++c) {
      positions.push_back(cloud.positions[i](c));
      normals.push_back(cloud.normals[i](c));
      body_force.push_back(cloud.body_force[i](c));
    }
  }
  expect_same(data_array(text, "position_m"), positions, "position_m");
  expect_same(data_array(text, "sphere_radius_m"), cloud.radii, "sphere_radius_m");
  expect_same(data_array(text, "spacing_m"), cloud.spacing, "spacing_m");
  expect_same(data_array(text, "normal"), normals, "normal");
  expect_same(data_array(text, "body_force_N_per_m3"), body_force, "body_force_N_per_m3");
  expect_same(data_array(text, "kind"), {0, 0, 1, 1, 2, 2, 3, 3}, "kind");
  expect_same(data_array(text, "row_type"),
              {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 1, 1, 2, 2, 2, 2, 2, 2}, "row_type");
  const Eigen::VectorXd& u = fields.displacement_m;
  const Eigen::VectorXd& p = fields.parameters_m;
  expect_same(data_array(text, "displacement_m"), std::vector<double>(u.data(), u.data() + u.size()), "displacement_m");
  expect_same(data_array(text, "parameters_m"), std::vector<double>(p.data(), p.data() + p.size()), "parameters_m");
  expect_same(data_array(text, "rcond"), fields.rcond, "rcond");
  expect_same(data_array(text, "connectivity"), {0, 1, 2, 3, 4, 5, 6, 7}, "connectivity");
  expect_same(data_array(text, "types"), std::vector<double>(node_count, 1.0), "types (VTK_VERTEX)");

  const std::string extra = read_text(collocation_points_vtu_path(path));
  EXPECT_EQ(attribute(extra, "NumberOfPoints"), "2");
  EXPECT_EQ(attribute(extra, "NumberOfCells"), "2");
  expect_same(data_array(extra, "position_m"), {0.004 / 3, 0, 0.049, 0.004 / 3, 0.001, 0.049}, "extra position_m");
  expect_same(data_array(extra, "kind"), {1, 0}, "extra kind");
  expect_same(data_array(extra, "normal"), {0, 0, 1, 0, 0, 0}, "extra normal");
  expect_same(data_array(extra, "row_type"), {1, 1, 1, 0, 0, 0}, "extra row_type");
  expect_same(data_array(extra, "spacing_m"), {0.0015 / 7, 0.0015 / 7}, "extra spacing_m");
}

TEST(NodeCloudVtk, EmptyFieldsAndNoExtraPointsAreNotWritten) {
  NodeCloud cloud = sample_cloud();
  cloud.body_force.clear();
  cloud.extra_points.clear();
  const TempVtu temp("bare");
  write_node_cloud_vtu(cloud, {}, temp.path());

  const std::string text = read_text(temp.path());
  EXPECT_EQ(attribute(text, "NumberOfPoints"), std::to_string(node_count));
  for (const char* absent : {"body_force_N_per_m3", "displacement_m", "parameters_m", "rcond"})
    EXPECT_EQ(text.find(absent), std::string::npos) << absent;
  expect_same(data_array(text, "sphere_radius_m"), cloud.radii, "sphere_radius_m");
  EXPECT_FALSE(std::filesystem::exists(collocation_points_vtu_path(temp.path())));
}

TEST(NodeCloudVtk, OverwritesAnOlderFile) {
  const TempVtu temp("overwrite");
  NodeCloud cloud = sample_cloud();
  write_node_cloud_vtu(cloud, sample_fields(), temp.path());
  cloud.positions.resize(3);
  cloud.radii.resize(3);
  cloud.kinds.resize(3);
  cloud.normals.resize(3);
  cloud.rows.resize(3);
  cloud.spacing.resize(3);
  cloud.body_force.resize(3);
  write_node_cloud_vtu(cloud, {}, temp.path());
  const std::string text = read_text(temp.path());
  EXPECT_EQ(attribute(text, "NumberOfPoints"), "3");
  EXPECT_EQ(data_array(text, "sphere_radius_m").size(), 3u);
}

/// Calls `write` and returns the message of the std::invalid_argument it must throw; checks that
/// no file was left behind.
template <class Write>
std::string invalid_argument_message(const std::string& path, Write write) {
  try {
    write();
  } catch (const std::invalid_argument& e) {
    EXPECT_FALSE(std::filesystem::exists(path));
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
    return e.what();
  }
  ADD_FAILURE() << "no std::invalid_argument";
  return "";
}

TEST(NodeCloudVtk, WrongSizeFieldThrowsNamingIt) {
  const NodeCloud cloud = sample_cloud();
  const TempVtu temp("wrong_size");
  const auto message = [&](const NodeCloudFields& fields) {
    return invalid_argument_message(temp.path(), [&] { write_node_cloud_vtu(cloud, fields, temp.path()); });
  };
  NodeCloudFields fields = sample_fields();
  fields.displacement_m.resize(3 * node_count - 1);
  EXPECT_NE(message(fields).find("displacement_m"), std::string::npos);
  fields = sample_fields();
  fields.parameters_m.resize(node_count);  // one per node instead of three
  EXPECT_NE(message(fields).find("parameters_m"), std::string::npos);
  fields = sample_fields();
  fields.rcond.push_back(1.0);
  EXPECT_NE(message(fields).find("rcond"), std::string::npos);

  NodeCloud short_radii = sample_cloud();
  short_radii.radii.pop_back();
  EXPECT_NE(invalid_argument_message(temp.path(), [&] { write_node_cloud_vtu(short_radii, {}, temp.path()); })
                .find("cloud.radii"),
            std::string::npos);
}

TEST(NodeCloudVtk, NonFiniteValueThrowsNamingIt) {
  const TempVtu temp("nan");
  NodeCloudFields fields = sample_fields();
  fields.rcond[3] = std::numeric_limits<double>::quiet_NaN();
  const std::string message =
      invalid_argument_message(temp.path(), [&] { write_node_cloud_vtu(sample_cloud(), fields, temp.path()); });
  EXPECT_NE(message.find("rcond[3]"), std::string::npos) << message;
}

TEST(NodeCloudVtk, UnwritablePathThrowsNamingIt) {
  const std::string path = "/nonexistent_dir/x.vtu";
  try {
    write_node_cloud_vtu(sample_cloud(), sample_fields(), path);
    FAIL() << "no std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(NodeCloudVtk, CollocationPointsGoNextToTheCloud) {
  EXPECT_EQ(collocation_points_vtu_path("out/cloud.vtu"), "out/cloud_collocation_points.vtu");
  EXPECT_EQ(collocation_points_vtu_path("out/cloud"), "out/cloud_collocation_points.vtu");
}

}  // namespace
}  // namespace touchstone::realtime::mfs
