// The gmsh MSH reader: MSH 4.1 and 2.2 surfaces with their groups and gmsh numbers, every kind
// of broken file named with its line, and the $PhysicalNames the finite element reference uses.
#include "touchstone/meshes/msh_reader.hpp"

#include "support/expect_invalid_argument.hpp"
#include "support/temporary_directory.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"

#include <Eigen/Core>
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <sys/stat.h>

namespace touchstone::meshes {
namespace {

using touchstone::testing::TemporaryDirectory;
using touchstone::testing::expect_invalid_argument;

using Eigen::Vector3d;

/// The B2 benchmark (hemisphere) written by gmsh, generated once per test program.
const std::string& hemisphere_mesh() {
  static const TemporaryDirectory directory("msh_reader_b2");
  static const std::string path = [] {
    MeshParameters parameters;
    parameters.benchmark = Benchmark::B2;
    const std::string file = directory.path("B2.msh");
    generate_mesh(parameters, file);
    return file;
  }();
  return path;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

bool mentions(const geometry::SurfaceDefect& defect, const std::string& fragment) {
  return defect.message.find(fragment) != std::string::npos;
}


// ---------------------------------------------------------------------------------------------
// gmsh files.

// The unit octahedron as MSH 4.1: two surface entities ("top", "bottom"), nodes in two blocks,
// one with parametric coordinates.
const char* const octahedron_v41 = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
3
2 1 "top"
2 2 "bottom"
3 3 "inside"
$EndPhysicalNames
$Entities
0 0 2 1
1 -1 -1 0 1 1 1 1 1 0
2 -1 -1 -1 1 1 0 1 2 0
1 -1 -1 -1 1 1 1 1 3 2 1 2
$EndEntities
$Nodes
2 6 1 6
2 1 1 5
1
2
3
4
5
1 0 0 0.1 0.2
-1 0 0 0.3 0.4
0 1 0 0.5 0.5
0 -1 0 0 0
0 0 1 0 0
2 2 0 1
6
0 0 -1
$EndNodes
$Elements
2 8 1 8
2 1 2 4
1 1 3 5
2 3 2 5
3 2 4 5
4 4 1 5
2 2 2 4
5 3 1 6
6 2 3 6
7 4 2 6
8 1 4 6
$EndElements
)";

// The same as MSH 2.2, with sparse node tags, a line and a tetrahedron to skip, an unknown
// section, and element 13 repeated because it also belongs to the group "marked".
const char* const octahedron_v22 = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
4
1 9 "rim"
2 1 "top"
2 2 "bottom"
2 7 "marked"
$EndPhysicalNames
$Nodes
6
10 1 0 0
20 -1 0 0
30 0 1 0
40 0 -1 0
50 0 0 1
60 0 0 -1
$EndNodes
$Comments
anything $Nodes
$EndComments
$Elements
11
1 1 2 9 1 10 30
2 4 2 0 1 10 20 30 50
11 2 2 1 1 10 30 50
12 2 2 1 1 30 20 50
13 2 2 1 1 20 40 50
14 2 2 1 1 40 10 50
15 2 2 2 2 30 10 60
16 2 2 2 2 20 30 60
17 2 2 2 2 40 20 60
18 2 2 2 2 10 40 60
19 2 2 7 1 20 40 50
$EndElements
)";

TEST(MshReader, ReadsMsh41AndMsh22) {
  const TemporaryDirectory directory("msh_reader");
  for (const char* content : {octahedron_v41, octahedron_v22}) {
    const std::string path = directory.file("octahedron.msh", content);
    const geometry::TriangleSurface all = load_msh_surface(path);
    EXPECT_EQ(all.triangles().size(), 8u);
    EXPECT_EQ(all.vertices().size(), 6u);
    EXPECT_NEAR(all.volume_m3(), 4.0 / 3, 1e-15);
    EXPECT_NEAR(all.area_m2(), 4 * std::sqrt(3.0), 1e-14);
    const geometry::TriangleSurface named = load_msh_surface(path, {"bottom", "top"});
    EXPECT_EQ(named.triangles().size(), 8u);
    EXPECT_TRUE(named.contains({0.1, 0.1, 0.1}));
    EXPECT_FALSE(named.contains({0.5, 0.5, 0.5}));
    // One half is open: the error names the file and the gmsh element.
    expect_invalid_argument([&] { load_msh_surface(path, {"top"}); }, {path, "hole", "gmsh element", "gmsh nodes"});
  }
  // In 2.2 an element's repeats for other groups are one triangle.
  const std::string path = directory.file("octahedron.msh", octahedron_v22);
  EXPECT_EQ(load_msh_surface(path, {"top", "marked", "bottom"}).triangles().size(), 8u);
  // Renumbering keeps increasing tag order: node 10 → vertex 0, node 60 → vertex 5.
  const geometry::TriangleSurface surface = load_msh_surface(path);
  EXPECT_EQ(surface.vertices()[0], Vector3d(1, 0, 0));
  EXPECT_EQ(surface.vertices()[5], Vector3d(0, 0, -1));
}

TEST(MshReader, GmshHemisphereGroupsSelectTriangles) {
  const std::string& path = hemisphere_mesh();
  expect_invalid_argument([&] { load_msh_surface(path, {"free"}); }, {path, "not closed"});
  expect_invalid_argument([&] { load_msh_surface(path, {"free", "liver"}); },
               {path, "'liver'", "available: base, tool_patch, free"});
  // "tissue" is a volume group, not a surface group.
  expect_invalid_argument([&] { load_msh_surface(path, {"tissue"}); }, {path, "'tissue' is a 3-D group"});
}

TEST(MshReader, RejectsBrokenFilesNamingThem) {
  const TemporaryDirectory directory("msh_reader");
  const std::string missing = directory.path("missing.msh");
  expect_invalid_argument([&] { load_msh_surface(missing); }, {missing, "cannot open"});
  // A named pipe would block the read until a writer came.
  const std::string pipe = directory.path("pipe.msh");
  ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0);
  expect_invalid_argument([&] { load_msh_surface(pipe); }, {pipe, "cannot open", "not a regular file"});

  const std::string empty = directory.file("empty.msh", "");
  expect_invalid_argument([&] { load_msh_surface(empty); }, {empty, "not a gmsh MSH file", "empty"});

  const std::string garbage = directory.file("garbage.msh", "solid liver\n  facet normal 0 0 1\n");
  expect_invalid_argument([&] { load_msh_surface(garbage); }, {garbage, "not a gmsh MSH file"});

  std::string noise;
  std::mt19937 random(7);
  for (int i = 0; i < 4096; ++i) noise += static_cast<char>(random() & 0xff);
  const std::string bytes = directory.file("noise.msh", noise);
  expect_invalid_argument([&] { load_msh_surface(bytes); }, {bytes, "not a gmsh MSH file"});

  static constexpr char binary_header[] = "$MeshFormat\n4.1 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n";
  const std::string binary =
      directory.file("binary.msh", std::string(binary_header, sizeof binary_header - 1) + noise);
  expect_invalid_argument([&] { load_msh_surface(binary); }, {binary, "binary", "ASCII"});

  const std::string version = directory.file("v3.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n");
  expect_invalid_argument([&] { load_msh_surface(version); }, {version, "version 3"});

  const std::string v22(octahedron_v22);
  const std::string truncated = directory.file("truncated.msh", v22.substr(0, v22.find("14 2 2")));
  expect_invalid_argument([&] { load_msh_surface(truncated); }, {truncated, "unexpected end of file", "$Elements"});

  std::string bad_number = v22;
  bad_number.replace(bad_number.find("30 0 1 0"), 8, "30 0 x 0");
  const std::string malformed = directory.file("malformed.msh", bad_number);
  expect_invalid_argument([&] { load_msh_surface(malformed); }, {malformed, "line 15", "coordinate", "'x'"});

  std::string short_section = v22;
  short_section.replace(short_section.find("$Nodes\n6"), 8, "$Nodes\n7");
  const std::string miscounted = directory.file("miscounted.msh", short_section);
  expect_invalid_argument([&] { load_msh_surface(miscounted); }, {miscounted, "$Nodes"});

  std::string dangling = v22;
  dangling.replace(dangling.find("18 2 2 2 2 10 40 60"), 19, "18 2 2 2 2 10 40 99");
  const std::string missing_node = directory.file("dangling.msh", dangling);
  expect_invalid_argument([&] { load_msh_surface(missing_node); }, {missing_node, "node 99"});

  const std::string no_triangles = directory.file("tet.msh",
                                                  "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n"
                                                  "3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 2 1 1 1 2 3 4\n"
                                                  "$EndElements\n");
  expect_invalid_argument([&] { load_msh_surface(no_triangles); }, {no_triangles, "no triangles"});

  const std::string quadrangles = directory.file("quad.msh",
                                                 "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n"
                                                 "3 1 1 0\n4 0 1 0\n$EndNodes\n$Elements\n1\n5 3 2 1 1 1 2 3 4\n"
                                                 "$EndElements\n");
  expect_invalid_argument([&] { load_msh_surface(quadrangles); }, {quadrangles, "element 5", "quadrangle"});

  // A node count the rest of the file cannot hold (every node takes at least one line of 8
  // bytes) is refused before anything is reserved for it: a fuzzer's 134-byte MSH 2.2 file
  // claiming 1,496,650,413 nodes made the reader ask for 12.8 GB (also for MSH 4.1's header).
  const std::string huge_v22 = directory.file("huge_count.msh",
                                              "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1496650413\n"
                                              "1 0 0 0\n$EndNodes\n");
  expect_invalid_argument([&] { load_msh_surface(huge_v22); },
                          {huge_v22, "line 5", "$Nodes", "1496650413 nodes", "bytes left"});
  const std::string huge_v41 = directory.file("huge_count_v41.msh",
                                              "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 1496650413 1 "
                                              "1496650413\n2 1 0 1\n1\n0 0 0\n$EndNodes\n");
  expect_invalid_argument([&] { load_msh_surface(huge_v41); },
                          {huge_v41, "line 5", "$Nodes", "1496650413 nodes", "bytes left"});

  const std::string no_nodes = directory.file("no_nodes.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
  expect_invalid_argument([&] { load_msh_surface(no_nodes); }, {no_nodes, "no $Nodes"});

  // Prefixes of a real file: each fails with std::invalid_argument naming the file.
  const std::string hemisphere = read_file(hemisphere_mesh());
  for (std::size_t length = 0; length < hemisphere.size(); length += hemisphere.size() / 37 + 1) {
    const std::string prefix = directory.file("prefix.msh", hemisphere.substr(0, length));
    expect_invalid_argument([&] { load_msh_surface(prefix); }, {prefix});
  }
}

TEST(MshReader, ReadMshSurfaceKeepsGmshLabelsWithoutValidating) {
  const TemporaryDirectory directory("msh_reader");
  const std::string path = directory.file("octahedron.msh", octahedron_v22);
  const geometry::SurfaceData top = read_msh_surface(path, {"top"});
  EXPECT_EQ(top.triangles.size(), 4u);
  EXPECT_EQ(top.labels.vertex_kind, "gmsh node");
  EXPECT_EQ(top.labels.triangle_kind, "gmsh element");
  EXPECT_EQ(top.labels.triangle_tags, (std::vector<long long>{11, 12, 13, 14}));
  EXPECT_EQ(top.labels.vertex_tags, (std::vector<long long>{10, 20, 30, 40, 50}));
  const auto defects = geometry::validate_surface(top.vertices, top.triangles, path, top.labels);
  ASSERT_EQ(defects.size(), 1u);
  EXPECT_TRUE(mentions(defects[0], "1 hole (4 boundary edges")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], "(gmsh nodes ")) << defects[0].message;
  EXPECT_TRUE(mentions(defects[0], "(gmsh element 1")) << defects[0].message;
}

TEST(MshReader, PhysicalNamesInFileOrderWithoutReadingTheMesh) {
  const TemporaryDirectory directory("msh_reader");
  const std::string v22 = directory.file("octahedron.msh", octahedron_v22);
  const std::vector<MshPhysicalName> names = read_msh_physical_names(v22);
  ASSERT_EQ(names.size(), 4u);
  EXPECT_EQ(names[0].dimension, 1);
  EXPECT_EQ(names[0].tag, 9);
  EXPECT_EQ(names[0].name, "rim");
  EXPECT_EQ(names[3].dimension, 2);
  EXPECT_EQ(names[3].tag, 7);
  EXPECT_EQ(names[3].name, "marked");
  const std::vector<MshPhysicalName> v41 = read_msh_physical_names(directory.file("v41.msh", octahedron_v41));
  ASSERT_EQ(v41.size(), 3u);
  EXPECT_EQ(v41[2].dimension, 3);
  EXPECT_EQ(v41[2].name, "inside");

  // The gmsh benchmark mesh names its boundaries and its volume.
  bool tissue = false;
  for (const MshPhysicalName& name : read_msh_physical_names(hemisphere_mesh())) {
    tissue = tissue || (name.dimension == 3 && name.tag == boundary_tags::tissue && name.name == "tissue");
  }
  EXPECT_TRUE(tissue);

  // Nodes and elements are not parsed: a file of names only is fine, and has no surface.
  const std::string names_only = directory.file(
      "names.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 4 \"base\"\n$EndPhysicalNames\n");
  ASSERT_EQ(read_msh_physical_names(names_only).size(), 1u);
  expect_invalid_argument([&] { read_msh_surface(names_only); }, {names_only, "no $Nodes"});
  const std::string unnamed = directory.file("unnamed.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
  EXPECT_TRUE(read_msh_physical_names(unnamed).empty());

  const std::string missing = directory.path("missing.msh");
  expect_invalid_argument([&] { read_msh_physical_names(missing); }, {missing, "cannot open"});
  const std::string unquoted = directory.file(
      "unquoted.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 4 base\n$EndPhysicalNames\n");
  expect_invalid_argument([&] { read_msh_physical_names(unquoted); }, {unquoted, "line 6", "quoted name"});
  const std::string binary = directory.file("binary.msh", "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n");
  expect_invalid_argument([&] { read_msh_physical_names(binary); }, {binary, "binary"});
}

}  // namespace
}  // namespace touchstone::meshes
