// Surface meshes in five formats: exact round trips, welding, unit scale, polygons, and every
// broken file a user or a fuzzer produced failing with the file's name and the count or element
// at fault (the regression tests of the fuzz findings are here, next to the reader they broke).
// Over 600 lines because each format's broken files need their own bytes; they share the
// writers and the temporary folder.
#include "support/temporary_directory.hpp"
#include "support/expect_invalid_argument.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"

#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <vtkNew.h>
#include <vtkPolyData.h>
#include <vtkPolyDataWriter.h>
#include <vtkSmartPointer.h>
#include <vtkBitArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkFloatArray.h>
#include <vtkIntArray.h>
#include <vtkPointData.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include <array>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

namespace touchstone::meshes {
namespace {

using touchstone::testing::TemporaryDirectory;
using touchstone::testing::expect_invalid_argument;

using Eigen::Vector3d;
using Eigen::Vector3i;
using geometry::TriangleMeshData;
using geometry::TriangleSurface;

constexpr double pi = 3.14159265358979323846;

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The sphere of the round trips: 320 triangles, coordinates that are not short decimals.
TriangleMeshData sphere() {
  TriangleMeshData mesh = geometry::icosphere(2, 0.04);
  for (Vector3d& x : mesh.vertices) x += Vector3d(0.1, -0.2, 0.3);
  return mesh;
}

/// The sphere as VTK poly data (written by the project's writer, read back by VTK): the input
/// of the tests that write the other VTK XML layouts with VTK's own writer.
vtkSmartPointer<vtkPolyData> sphere_poly_data(const TemporaryDirectory& directory) {
  const TriangleMeshData mesh = sphere();
  write_surface_mesh(directory.path("plain.vtp"), mesh.vertices, mesh.triangles);
  vtkNew<vtkXMLPolyDataReader> plain;
  plain->SetFileName(directory.path("plain.vtp").c_str());
  plain->Update();
  return plain->GetOutput();
}

/// STL stores floats: the sphere rounded to them, so that the round trip is exact.
TriangleMeshData float_sphere() {
  TriangleMeshData mesh = sphere();
  for (Vector3d& x : mesh.vertices) {
    for (int i = 0; i < 3; ++i) {
      // volatile: GCC 12 at -O2 vectorises the x, y pair of this round trip into a no-op.
      volatile float rounded = static_cast<float>(x[i]);
      x[i] = rounded;
    }
  }
  return mesh;
}

void expect_same_surface(const TriangleMeshData& expected, const SurfaceMesh& read) {
  ASSERT_EQ(read.vertices.size(), expected.vertices.size());
  ASSERT_EQ(read.triangles.size(), expected.triangles.size());
  // Corner by corner: the same points in the same order, whatever the vertex numbering.
  for (std::size_t t = 0; t < expected.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(read.vertices[read.triangles[t][k]], expected.vertices[expected.triangles[t][k]])
          << "triangle " << t << " corner " << k;
    }
  }
  const TriangleSurface original(expected.vertices, expected.triangles);
  const TriangleSurface loaded(read.vertices, read.triangles, read.path, read.labels);
  EXPECT_NEAR(loaded.area_m2(), original.area_m2(), 1e-12 * original.area_m2());
  EXPECT_NEAR(loaded.volume_m3(), original.volume_m3(), 1e-12 * original.volume_m3());
}

// ---------------------------------------------------------------------------------------------
// Round trips.

TEST(SurfaceMeshIo, ExactFormatsRoundTripVerticesAndTriangles) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = sphere();
  for (const char* name : {"sphere.vtp", "sphere.vtk", "sphere.obj", "sphere.msh", "SPHERE.VTP"}) {
    SCOPED_TRACE(name);
    const std::string path = directory.path(name);
    write_surface_mesh(path, mesh.vertices, mesh.triangles);
    const SurfaceMesh read = read_surface_mesh(path);
    EXPECT_EQ(read.path, path);
    // Nothing welded: the numbering is the file's.
    EXPECT_EQ(read.vertices, mesh.vertices);
    EXPECT_EQ(read.triangles, mesh.triangles);
    EXPECT_EQ(read.vertices_welded, 0u);
    EXPECT_EQ(read.polygons_triangulated, 0u);
    EXPECT_EQ(read.unused_vertices, 0u);
    expect_same_surface(mesh, read);
    EXPECT_TRUE(validate_surface_mesh(read).empty());
  }
}

TEST(SurfaceMeshIo, StlRoundTripsBinaryAndAsciiAfterWelding) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = float_sphere();
  for (const bool ascii : {false, true}) {
    SCOPED_TRACE(ascii ? "ASCII" : "binary");
    SurfaceWriteOptions options;
    options.ascii_stl = ascii;
    const std::string path = directory.path(ascii ? "ascii.stl" : "binary.stl");
    write_surface_mesh(path, mesh.vertices, mesh.triangles, options);
    EXPECT_EQ(read_file(path).rfind("solid", 0) == 0, ascii);
    const SurfaceMesh read = read_surface_mesh(path);
    EXPECT_EQ(read.format, SurfaceFormat::stl);
    // Each facet stores its three corners: welding leaves one vertex per point.
    EXPECT_EQ(read.vertices_welded, 3 * mesh.triangles.size() - mesh.vertices.size());
    expect_same_surface(mesh, read);
    EXPECT_EQ(read.labels.triangle_kind, "STL facet");
    EXPECT_TRUE(read.labels.vertex_tags.empty());
    EXPECT_EQ(read.labels.triangle_tags[7], 7);
  }
}

TEST(SurfaceMeshIo, UnitScaleConvertsMillimetreFiles) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = sphere();
  SurfaceWriteOptions millimetres;
  millimetres.unit_scale = 1e-3;
  const std::string path = directory.path("sphere_mm.vtp");
  write_surface_mesh(path, mesh.vertices, mesh.triangles, millimetres);

  const SurfaceMesh raw = read_surface_mesh(path);
  EXPECT_NEAR((raw.vertices[5] - 1e3 * mesh.vertices[5]).norm(), 0, 1e-12);
  SurfaceReadOptions options;
  options.unit_scale = 1e-3;
  const TriangleSurface surface = load_surface(path, options);
  const TriangleSurface original(mesh.vertices, mesh.triangles);
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    EXPECT_NEAR((surface.vertices()[v] - mesh.vertices[v]).norm(), 0, 1e-16);
  }
  EXPECT_NEAR(surface.volume_m3(), original.volume_m3(), 1e-12 * original.volume_m3());

  options.unit_scale = 0;
  expect_invalid_argument([&] { read_surface_mesh(path, options); }, {"SurfaceReadOptions.unit_scale = 0"});
  options.unit_scale = 1;
  options.weld_relative_tolerance = -1;
  expect_invalid_argument([&] { read_surface_mesh(path, options); }, {"weld_relative_tolerance"});
  SurfaceWriteOptions bad;
  bad.unit_scale = std::nan("");
  expect_invalid_argument([&] { write_surface_mesh(path, mesh.vertices, mesh.triangles, bad); }, {"unit_scale"});
}

// The unit cube [0, 1]³ with quadrilateral faces, counter-clockwise seen from outside.
const char* const cube_obj = R"(# a cube of quadrilaterals
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
)";

TEST(SurfaceMeshIo, PolygonsAreTriangulatedKeepingTheirNumbers) {
  const TemporaryDirectory directory("surface_io");
  const std::string path = directory.file("cube.obj", cube_obj);
  const SurfaceMesh read = read_surface_mesh(path);
  EXPECT_EQ(read.triangles.size(), 12u);
  EXPECT_EQ(read.polygons_triangulated, 6u);
  EXPECT_EQ(read.labels.triangle_kind, "OBJ face");
  EXPECT_EQ(read.labels.vertex_kind, "OBJ vertex");
  EXPECT_EQ(read.labels.vertex_tags.front(), 1);
  for (std::size_t t = 0; t < 12; ++t) EXPECT_EQ(read.labels.triangle_tags[t], static_cast<long long>(t / 2 + 1));
  const TriangleSurface cube = load_surface(path);
  EXPECT_NEAR(cube.volume_m3(), 1, 1e-15);
  EXPECT_NEAR(cube.area_m2(), 6, 1e-15);

  // A prism over a notched (concave) pentagon: the pentagons are polygons, the sides triangle
  // strips, one side is left open. The file also holds a vertex cell and a line, which take
  // the first cell ids.
  const std::string legacy = directory.file("prism.vtk", R"(# vtk DataFile Version 4.2
prism of polygons and strips
ASCII
DATASET POLYDATA
POINTS 10 double
0 0 0  2 0 0  2 2 0  1 0.5 0  0 2 0
0 0 1  2 0 1  2 2 1  1 0.5 1  0 2 1
VERTICES 1 2
1 0
LINES 1 3
2 0 1
POLYGONS 2 12
5 0 4 3 2 1
5 5 6 7 8 9
TRIANGLE_STRIPS 4 20
4 0 1 5 6
4 1 2 6 7
4 2 3 7 8
4 3 4 8 9
)");
  const SurfaceMesh prism = read_surface_mesh(legacy);
  EXPECT_EQ(prism.labels.triangle_kind, "VTK cell");
  EXPECT_EQ(prism.polygons_triangulated, 2u + 4u);
  EXPECT_EQ(prism.triangles.size(), 2u * 3u + 4u * 2u);
  EXPECT_EQ(prism.labels.triangle_tags.front(), 2);  // after the vertex cell 0 and the line 1
  EXPECT_EQ(prism.labels.triangle_tags.back(), 7);
  // Only the open side is wrong: the ear cutting and the strips keep the orientation.
  const auto defects = validate_surface_mesh(prism);
  ASSERT_EQ(defects.size(), 1u) << defects.front().message;
  EXPECT_EQ(defects[0].kind, geometry::SurfaceDefectKind::boundary_edge);
  EXPECT_EQ(defects[0].count, 4u);
  EXPECT_NE(defects[0].message.find("1 hole"), std::string::npos) << defects[0].message;
  EXPECT_NE(defects[0].message.find("(VTK points "), std::string::npos) << defects[0].message;
  EXPECT_NE(defects[0].message.find("(VTK cell "), std::string::npos) << defects[0].message;
}

TEST(SurfaceMeshIo, WeldingMergesSoupsOnRequest) {
  const TemporaryDirectory directory("surface_io");
  // The cube as a soup: every face has its own four vertices.
  std::ostringstream soup;
  soup.precision(17);
  const std::vector<Vector3d> corners{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                      {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const std::vector<std::array<int, 4>> faces{{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                              {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  for (const auto& face : faces) {
    for (const int c : face) {
      // Written points differ by rounding only (1e-13 m on a 1 m cube).
      const Vector3d x = corners[c] + Vector3d::Constant(1e-13 * ((&face - faces.data()) % 2));
      soup << "v " << x[0] << ' ' << x[1] << ' ' << x[2] << '\n';
    }
  }
  for (int f = 0; f < 6; ++f) soup << "f " << 4 * f + 1 << ' ' << 4 * f + 2 << ' ' << 4 * f + 3 << ' ' << 4 * f + 4 << '\n';
  const std::string path = directory.file("soup.obj", soup.str());
  expect_invalid_argument([&] { load_surface(path); }, {path, "duplicated vertices", "weld"});
  SurfaceReadOptions weld;
  weld.weld_vertices = true;
  const SurfaceMesh welded = read_surface_mesh(path, weld);
  EXPECT_EQ(welded.vertices.size(), 8u);
  EXPECT_EQ(welded.vertices_welded, 16u);
  // The welded vertices keep the OBJ number of their first occurrence.
  EXPECT_EQ(welded.labels.vertex_tags, (std::vector<long long>{1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_NEAR(load_surface(path, weld).volume_m3(), 1, 1e-12);
  // A tolerance below the rounding keeps them apart.
  weld.weld_relative_tolerance = 1e-15;
  EXPECT_EQ(read_surface_mesh(path, weld).vertices_welded, 8u);
}

// ---------------------------------------------------------------------------------------------
// Defects: one per file, named with the file's own numbers.

/// The octahedron with vertices (±1, 0, 0), (0, ±1, 0), (0, 0, ±1), faces outward.
const char* const octahedron_vertices = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n";
const std::vector<std::string> octahedron_faces{"1 3 5", "3 2 5", "2 4 5", "4 1 5",
                                                "3 1 6", "2 3 6", "4 2 6", "1 4 6"};

std::string obj(const std::string& vertices, const std::vector<std::string>& faces) {
  std::string text = vertices;
  for (const std::string& face : faces) text += "f " + face + "\n";
  return text;
}

TEST(SurfaceMeshIo, EachDefectIsNamedWithTheFileAndElement) {
  const TemporaryDirectory directory("surface_io");
  const auto load = [&](const std::string& name, const std::string& content) {
    return directory.file(name, content);
  };
  const std::string good = load("good.obj", obj(octahedron_vertices, octahedron_faces));
  EXPECT_NEAR(load_surface(good).volume_m3(), 4.0 / 3, 1e-15);

  // Hole: face 3 missing.
  std::vector<std::string> faces = octahedron_faces;
  faces.erase(faces.begin() + 2);
  const std::string hole = load("hole.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { load_surface(hole); },
               {hole, "not closed", "1 hole", "3 boundary edges", "(OBJ vertices ", "OBJ face "});

  // Flipped: face 4 reversed.
  faces = octahedron_faces;
  faces[3] = "4 5 1";
  const std::string flipped = load("flipped.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { load_surface(flipped); },
               {flipped, "inconsistent orientation", "1 triangle flipped", "triangle 3 (OBJ face 4)", " -> "});

  // Duplicate triangle: face 9 repeats face 1 in another order.
  faces = octahedron_faces;
  faces.push_back("5 1 3");
  const std::string duplicate = load("duplicate.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { load_surface(duplicate); },
               {duplicate, "1 duplicate triangle", "triangle 0 (OBJ face 1) and triangle 8 (OBJ face 9)"});

  // Degenerate: face 1 split at a point of its edge 1–3; the piece (1, 3, 7) has no area.
  faces = octahedron_faces;
  faces[0] = "1 3 7";
  faces.push_back("3 5 7");
  faces.push_back("5 1 7");
  const std::string degenerate = load("degenerate.obj", obj(std::string(octahedron_vertices) + "v 0.5 0.5 0\n", faces));
  expect_invalid_argument([&] { load_surface(degenerate); }, {degenerate, "1 degenerate triangle", "triangle 0 (OBJ face 1)", "area"});
  faces = octahedron_faces;
  faces[0] = "1 1 5";
  const std::string repeated = load("repeated.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { load_surface(repeated); }, {repeated, "degenerate", "OBJ face 1", "repeats vertex 0"});

  // Duplicated vertex: a second octahedron, shifted by 2 along x, touches the first at
  // (1, 0, 0) with a vertex of its own.
  std::string two = std::string(octahedron_vertices) + "v 3 0 0\nv 1 0 0\nv 2 1 0\nv 2 -1 0\nv 2 0 1\nv 2 0 -1\n";
  faces = octahedron_faces;
  for (const std::string& face : octahedron_faces) {
    std::istringstream in(face);
    int a = 0, b = 0, c = 0;
    in >> a >> b >> c;
    faces.push_back(std::to_string(a + 6) + " " + std::to_string(b + 6) + " " + std::to_string(c + 6));
  }
  const std::string touching = load("touching.obj", obj(two, faces));
  expect_invalid_argument([&] { load_surface(touching); },
               {touching, "1 duplicated vertex", "vertex 0 (OBJ vertex 1) and vertex 7 (OBJ vertex 8) at (1, 0, 0)"});

  // Non-manifold edge: two tetrahedra sharing the edge 1–2.
  const std::string tetrahedra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 -1 0\nv 0 0 -1\n";
  const std::string fin = load("fin.obj", obj(tetrahedra, {"1 3 2", "1 2 4", "1 4 3", "2 3 4",
                                                             "1 5 2", "1 2 6", "1 6 5", "2 5 6"}));
  expect_invalid_argument([&] { load_surface(fin); },
               {fin, "non-manifold", "1 edge shared by more than two triangles", "edge (0, 1) (OBJ vertices 1, 2)",
                "4 triangles", "triangle 5 (OBJ face 6)"});

  // Non-manifold vertex: two tetrahedra sharing vertex 1 only.
  const std::string pinch = load("pinch.obj", obj(tetrahedra + "v -1 0 0\n", {"1 3 2", "1 2 4", "1 4 3", "2 3 4",
                                                                                "1 7 5", "1 6 7", "1 5 6", "7 6 5"}));
  expect_invalid_argument([&] { load_surface(pinch); },
               {pinch, "1 non-manifold vertex", "vertex 0 (OBJ vertex 1) at (0, 0, 0)", "separate fans"});

  // Inward: every face reversed.
  faces.clear();
  for (const std::string& face : octahedron_faces) faces.push_back(std::string(face.rbegin(), face.rend()));
  const std::string inward = load("inward.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { load_surface(inward); }, {inward, "non-positive volume (-1.33333 m^3)", "inward"});

  // Index out of range: caught by the reader, in the file's numbering.
  faces = octahedron_faces;
  faces[5] = "2 3 9";
  const std::string range = load("range.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { read_surface_mesh(range); },
               {range, "OBJ face 6 (line 12) refers to vertex 9, but the file has 6 vertices (numbered from 1)"});

  // Non-finite: VTK's OBJ reader would misread "nan"; the check names the line and vertex.
  const std::string nan = load("nan.obj", obj("v 1 0 0\nv -1 nan 0\n" + std::string(octahedron_vertices).substr(17),
                                              octahedron_faces));
  expect_invalid_argument([&] { read_surface_mesh(nan); }, {nan, "line 2: OBJ vertex 2 has a non-finite coordinate 'nan'"});
  // In STL (read with strtod) NaN arrives and validation names it.
  const std::string stl_nan = load("nan.stl",
                                   "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 nan 0\n"
                                   "endloop\nendfacet\nendsolid s\n");
  expect_invalid_argument([&] { load_surface(stl_nan); }, {stl_nan, "non-finite coordinate in 1 vertex", "vertex 2 = (0, nan, 0)"});

  // A polygon with two vertices.
  faces = octahedron_faces;
  faces.push_back("1 2");
  const std::string line = load("line_face.obj", obj(octahedron_vertices, faces));
  expect_invalid_argument([&] { read_surface_mesh(line); }, {line, "OBJ face 9 (line 15) has 2 vertices"});
}

TEST(SurfaceMeshIo, ValidateSurfaceMeshListsEveryDefect) {
  const TemporaryDirectory directory("surface_io");
  // Face 3 missing (a hole) and face 5 reversed (flipped): both reported, in order.
  std::vector<std::string> faces = octahedron_faces;
  faces[4] = "6 1 3";
  faces.erase(faces.begin() + 2);
  const std::string path = directory.file("two_defects.obj", obj(octahedron_vertices, faces));
  const SurfaceMesh mesh = read_surface_mesh(path);
  const auto defects = validate_surface_mesh(mesh);
  ASSERT_EQ(defects.size(), 2u);
  EXPECT_EQ(defects[0].kind, geometry::SurfaceDefectKind::boundary_edge);
  EXPECT_EQ(defects[1].kind, geometry::SurfaceDefectKind::inconsistent_orientation);
  EXPECT_EQ(defects[1].message.rfind(path + ": inconsistent orientation", 0), 0u) << defects[1].message;
  expect_invalid_argument([&] { load_surface(path); }, {path, "not closed", "(further defects: inconsistent orientation)"});
}

// ---------------------------------------------------------------------------------------------
// Broken files: std::invalid_argument naming the file, never a crash or a silent success.

std::string noise(std::size_t size, unsigned seed) {
  std::mt19937 random(seed);
  std::string bytes;
  for (std::size_t i = 0; i < size; ++i) bytes += static_cast<char>(random() & 0xff);
  return bytes;
}

TEST(SurfaceMeshIo, BrokenFilesOfEveryFormatFailClearly) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = float_sphere();
  SurfaceWriteOptions ascii;
  ascii.ascii_stl = true;
  for (const std::string name : {"s.obj", "s.stl", "ascii.stl", "s.vtk", "s.vtp", "s.msh"}) {
    SCOPED_TRACE(name);
    const std::string extension = name.substr(name.find('.'));
    const std::string missing = directory.path("missing" + extension);
    expect_invalid_argument([&] { read_surface_mesh(missing); }, {missing});

    const std::string empty = directory.file("empty" + extension, "");
    expect_invalid_argument([&] { read_surface_mesh(empty); }, {empty});
    const std::string blank = directory.file("blank" + extension, "\n\n  \n");
    expect_invalid_argument([&] { read_surface_mesh(blank); }, {blank});
    const std::string text = directory.file("text" + extension, "this is not a mesh\n1 2 3\n");
    expect_invalid_argument([&] { read_surface_mesh(text); }, {text});
    for (const unsigned seed : {1u, 2u}) {
      const std::string bytes = directory.file("noise" + extension, noise(seed == 1 ? 300 : 5000, seed));
      expect_invalid_argument([&] { read_surface_mesh(bytes); }, {bytes});
    }

    // Prefixes of a good file: an error from the reader, or (a prefix that ends between
    // complete faces) a surface that validation rejects.
    const std::string good = directory.path("good_" + name);
    write_surface_mesh(good, mesh.vertices, mesh.triangles, name == "ascii.stl" ? ascii : SurfaceWriteOptions{});
    ASSERT_NO_THROW(load_surface(good));
    const std::string content = read_file(good);
    for (std::size_t length = 1; length + 8 < content.size(); length += content.size() / 23 + 1) {
      const std::string prefix = directory.file("prefix" + extension, content.substr(0, length));
      expect_invalid_argument([&] { load_surface(prefix); }, {prefix});
    }
  }
  expect_invalid_argument([&] { read_surface_mesh(directory.path("mesh.ply")); }, {"mesh.ply", "unsupported", ".stl"});
  expect_invalid_argument([&] { read_surface_mesh(directory.path("no_extension")); }, {"no_extension", "unsupported"});
  std::filesystem::create_directory(directory.path("folder.obj"));
  expect_invalid_argument([&] { read_surface_mesh(directory.path("folder.obj")); }, {"folder.obj", "cannot open the file (it is a folder)"});

  // A binary STL whose facet count does not match its size: VTK would read it silently.
  const std::string binary = directory.path("count.stl");
  write_surface_mesh(binary, mesh.vertices, mesh.triangles);
  std::string bytes = read_file(binary);
  const std::string cut = directory.file("cut.stl", bytes.substr(0, bytes.size() - 50));
  expect_invalid_argument([&] { read_surface_mesh(cut); }, {cut, "header announces 320 facets, the file holds 319"});
  const std::string partial = directory.file("partial.stl", bytes.substr(0, bytes.size() - 20));
  expect_invalid_argument([&] { read_surface_mesh(partial); }, {partial, "not a whole number of 50-byte facets"});

  // Corrupt headers are caught before VTK allocates or misreads: a mangled legacy version (VTK
  // would read version 5 cells in the old layout, out of bounds) and a count no file of that
  // size can hold (VTK would allocate it first).
  write_surface_mesh(directory.path("header.vtk"), mesh.vertices, mesh.triangles);
  std::string legacy = read_file(directory.path("header.vtk"));
  legacy[legacy.find("5.1")] = 'x';
  const std::string version = directory.file("version.vtk", legacy);
  expect_invalid_argument([&] { read_surface_mesh(version); }, {version, "# vtk DataFile Version <major>.<minor>"});
  write_surface_mesh(directory.path("header.vtp"), mesh.vertices, mesh.triangles);
  std::string xml = read_file(directory.path("header.vtp"));
  xml.replace(xml.find("NumberOfPoints=\"162\""), 20, "NumberOfPoints=\"999999999162\"");
  const std::string count = directory.file("count.vtp", xml);
  expect_invalid_argument([&] { read_surface_mesh(count); }, {count, "declares 999999999162 points"});
  // The XML reader allocates an offset per declared cell and NumberOfComponents values per point
  // before reading them, so a corrupt count in a small file must be refused first.
  const std::size_t polys = xml.find("NumberOfPolys=\"");
  const std::string polys_value = xml.substr(polys, xml.find('"', polys + 15) + 1 - polys);
  std::string many_cells = read_file(directory.path("header.vtp"));
  many_cells.replace(many_cells.find(polys_value), polys_value.size(), "NumberOfPolys=\"1073741847\"");
  const std::string cells = directory.file("cells.vtp", many_cells);
  expect_invalid_argument([&] { read_surface_mesh(cells); }, {cells, "piece 1 declares 162 points and 1073741847 cells"});
  std::string many_components = read_file(directory.path("header.vtp"));
  many_components.replace(many_components.find("NumberOfComponents=\"3\""), 22, "NumberOfComponents='300000000'");
  const std::string components = directory.file("components.vtp", many_components);
  expect_invalid_argument([&] { read_surface_mesh(components); },
                          {components, "a DataArray of piece 1 declares 300000000 components of 320 tuples"});
  // VTK sizes the connectivity by the last offset before reading it.
  const std::string ascii_offsets = directory.file(
      "offsets.vtp",
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
      "<PolyData><Piece NumberOfPoints=\"3\" NumberOfPolys=\"1\"><Points>\n"
      "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0</DataArray>\n"
      "</Points><Polys>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2</DataArray>\n"
      "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">402653184</DataArray>\n"
      "</Polys></Piece></PolyData></VTKFile>\n");
  expect_invalid_argument([&] { read_surface_mesh(ascii_offsets); },
                          {ascii_offsets, "an offsets array of piece 1 ends at 402653184"});
  std::string good_offsets = read_file(ascii_offsets);
  good_offsets.replace(good_offsets.find("402653184"), 9, "3");
  EXPECT_EQ(read_surface_mesh(directory.file("offsets_ok.vtp", good_offsets)).triangles.size(), 1U);

  // A legacy file of another dataset type.
  const std::string grid = directory.file("grid.vtk",
                                          "# vtk DataFile Version 4.2\ngrid\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                                          "POINTS 3 double\n0 0 0 1 0 0 0 1 0\nCELLS 1 4\n3 0 1 2\nCELL_TYPES 1\n5\n");
  expect_invalid_argument([&] { read_surface_mesh(grid); }, {grid, "not a legacy VTK POLYDATA file"});
  // Only points and lines.
  const std::string lines = directory.file("lines.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n");
  expect_invalid_argument([&] { read_surface_mesh(lines); }, {lines, "no polygons"});
  // Groups are for .msh files.
  SurfaceReadOptions groups;
  groups.msh_groups = {"free"};
  expect_invalid_argument([&] { read_surface_mesh(directory.path("good_s.obj"), groups); }, {"msh_groups", ".msh files only"});
}

// Found by fuzzing (tests/fuzz): VTK 9.1's legacy reader crashes (a null stream) when the cell
// list of an ASCII file ends early or holds a word; the reader checks the lists first.
TEST(SurfaceMeshIo, LegacyCellListsCutShortFailClearly) {
  const TemporaryDirectory directory("surface_io");
  const std::string header =
      "# vtk DataFile Version 4.2\noctahedron\nASCII\nDATASET POLYDATA\nPOINTS 6 double\n"
      "1 0 0 -1 0 0 0 1 0 0 -1 0 0 0 1 0 0 -1\nPOLYGONS 8 32\n"
      "3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n";
  ASSERT_NO_THROW(load_surface(directory.file("whole.vtk", header + "3 0 3 5\n")));
  const std::string word = directory.file("word.vtk", header + "N10__cxxabiv120__si_class_type_in3 0 3 5\n");
  expect_invalid_argument([&] { read_surface_mesh(word); }, {word, "POLYGONS", "'N10__cxxabiv120__si_class_type_in3'"});
  const std::string cut = directory.file("cut.vtk", header);
  expect_invalid_argument([&] { read_surface_mesh(cut); }, {cut, "POLYGONS declares 32 values", "ends after 28"});
  // Found by CI's fuzz smoke run: a point id beyond the 32-bit ints VTK reads these lists into
  // fails its stream the same way.
  const std::string wide = directory.file("wide.vtk", header + "3 1666666666666666 3 5\n");
  expect_invalid_argument([&] { read_surface_mesh(wide); },
                          {wide, "POLYGONS value 30 is 1666666666666666", "outside the 32-bit integers"});
  // The version 5 layout: offsets, then connectivity.
  const std::string v5 =
      "# vtk DataFile Version 5.1\ntriangle\nASCII\nDATASET POLYDATA\nPOINTS 3 double\n0 0 0 1 0 0 0 1 0\n"
      "POLYGONS 2 3\nOFFSETS vtktypeint64\n0 3\nCONNECTIVITY vtktypeint64\n0 1\n";
  const std::string short_v5 = directory.file("short_v5.vtk", v5);
  expect_invalid_argument([&] { read_surface_mesh(short_v5); }, {short_v5, "CONNECTIVITY of POLYGONS declares 3 values", "ends after 2"});
}

// Found by CI's fuzz smoke run: ASCII coordinates cut short (the next keyword where a coordinate
// should be) made VTK 9.1 read on from a failed stream and dereference null.
TEST(SurfaceMeshIo, LegacyPointsCutShortOrHoldingAWordFailClearly) {
  const TemporaryDirectory directory("surface_io");
  const std::string cut = directory.file("points_cut.vtk",
                                         "# vtk DataFile Version 4.2\noctahedron\nASCII\nDATASET POLYDATA\nPOINTS 6 double\n"
                                         "1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0\nPOLYGONS 8 32\n3 0 2 4\n");
  expect_invalid_argument([&] { read_surface_mesh(cut); }, {cut, "POINTS declares 6 points", "coordinate 15 is 'POLYGONS'"});
  const std::string ended = directory.file("points_end.vtk",
                                           "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0\n");
  expect_invalid_argument([&] { read_surface_mesh(ended); }, {ended, "coordinate 6 is missing"});
  const std::string word = directory.file("points_word.vtk",
                                          "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 1 float\n0 x1 0\n");
  expect_invalid_argument([&] { read_surface_mesh(word); }, {word, "coordinate 2 is 'x1'"});
  // The fuzzer's file: the same, with a second header pasted in whose "BINARY" line once made the
  // check read this ASCII file as binary.
  const std::string pasted = directory.file("points_pasted.vtk",
                                            "# vtk DataFile Version 4.2\noctahedron\nASCII\nDATASET POLYDATA\nPOINTS 6 double\n"
                                            "1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0\nPOLYGONS 8 32\n3 0 2 4\n3 2 1 4"
                                            "# vtk DataFile Version 3.0\noctahedron\nBINARY\nDATASET POLYDATA\n");
  expect_invalid_argument([&] { read_surface_mesh(pasted); }, {pasted, "coordinate 15 is 'POLYGONS'"});
  // VTK takes a word that starts with a keyword for the keyword (lower-cased, prefix only).
  const std::string glued = directory.file("glued.vtk",
                                           "# vtk DataFile Version 4.2\noctahedron\nASCII\nDATASET POLYDATA\nPOINTS 6 double\n"
                                           "1 0 0 -1 0 0 0 1 0 0 -1 0 0 0 1 0 0 -1\nPOLYGONSSt12length_error 8 32\n"
                                           "3 0 2 4\n3 0 5\n3 1 2 5\n3 6 1 5\n3 0 3 5\n");
  expect_invalid_argument([&] { read_surface_mesh(glued); }, {glued, "POLYGONS"});
}

// Found by fuzzing: a cell that claims more points than its list holds made VTK 9.1 read past
// the list's buffer (a binary file here: the first triangle's point count became 2^20).
TEST(SurfaceMeshIo, LegacyCellsClaimingMorePointsThanTheirListFailClearly) {
  const TemporaryDirectory directory("surface_io");
  const auto big_endian = [](std::initializer_list<std::int32_t> values) {
    std::string bytes;
    for (const std::int32_t value : values)
      for (int shift = 24; shift >= 0; shift -= 8) bytes += static_cast<char>((static_cast<std::uint32_t>(value) >> shift) & 0xff);
    return bytes;
  };
  std::string points;
  for (const float x : {1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f}) {
    std::int32_t word;
    std::memcpy(&word, &x, sizeof word);
    points += big_endian({word});
  }
  const std::string header = "# vtk DataFile Version 3.0\ntetrahedron\nBINARY\nDATASET POLYDATA\nPOINTS 4 float\n" + points +
                             "\nPOLYGONS 4 16\n";
  const std::string faces = big_endian({3, 0, 1, 2, 3, 0, 3, 1, 3, 0, 2, 3, 3, 1, 3, 2});
  ASSERT_NO_THROW(load_surface(directory.file("whole.vtk", header + faces + "\n")));
  std::string corrupt = faces;
  corrupt.replace(0, 4, big_endian({1 << 20}));
  const std::string binary = directory.file("binary.vtk", header + corrupt + "\n");
  expect_invalid_argument([&] { read_surface_mesh(binary); }, {binary, "POLYGONS cell 1 claims 1048576 points", "15 values left"});
  // A mangled point type: VTK read on into the cells misaligned, past their buffer.
  std::string mangled = header + corrupt + "\n";
  mangled.replace(mangled.find("4 float"), 7, "4 fl\x83oat");
  const std::string type = directory.file("type.vtk", mangled);
  expect_invalid_argument([&] { read_surface_mesh(type); }, {type, "POINTS of an unknown data type"});
  const std::string ascii = directory.file("ascii.vtk",
                                           "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 double\n"
                                           "0 0 0 1 0 0 0 1 0\nPOLYGONS 1 4\n9 0 1 2\n");
  expect_invalid_argument([&] { read_surface_mesh(ascii); }, {ascii, "POLYGONS cell 1 claims 9 points"});
}

// A surface reads only the geometry of a legacy file. FIELD blocks and the point and cell data
// are left out of what VTK is given: VTK 9.1 dereferences null on a FIELD block it cannot read
// (a mutation the fuzzer found: "fieldONS 8 32" among the polygons) and sizes point data by a
// count the file declares. Files VTK writes with field, point and cell data, ASCII and binary,
// read as the bare surface; a FIELD block whose extent is not certain is refused by name.
TEST(SurfaceMeshIo, LegacyFieldAndAttributeDataAreSkippedAndAMalformedFieldFailsClearly) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = sphere();
  const vtkSmartPointer<vtkPolyData> data = sphere_poly_data(directory);
  vtkNew<vtkDoubleArray> time;
  time->SetName("TIME");
  time->InsertNextValue(0.5);
  vtkNew<vtkIntArray> cycle;
  cycle->SetName("CYCLE");
  cycle->SetNumberOfComponents(2);
  cycle->InsertNextTuple2(3, 4);
  vtkNew<vtkBitArray> flags;
  flags->SetName("flags");
  for (int k = 0; k < 11; ++k) flags->InsertNextValue(k % 2);
  vtkNew<vtkFieldData> field;
  field->AddArray(time);
  field->AddArray(cycle);
  field->AddArray(flags);
  data->SetFieldData(field);
  vtkNew<vtkFloatArray> temperature;
  temperature->SetName("temperature");
  for (vtkIdType v = 0; v < data->GetNumberOfPoints(); ++v) temperature->InsertNextValue(static_cast<float>(v));
  data->GetPointData()->AddArray(temperature);
  vtkNew<vtkIntArray> region;
  region->SetName("region");
  for (vtkIdType c = 0; c < data->GetNumberOfCells(); ++c) region->InsertNextValue(static_cast<int>(c % 3));
  data->GetCellData()->AddArray(region);
  // Each read is compared with the same writer's file of the bare surface (ASCII rounds).
  vtkNew<vtkPolyData> bare;
  bare->SetPoints(data->GetPoints());
  bare->SetPolys(data->GetPolys());
  for (const bool binary : {false, true}) {
    SCOPED_TRACE(binary ? "binary" : "ascii");
    const auto write = [&](vtkPolyData* surface, const char* name) {
      const std::string path = directory.path(name);
      vtkNew<vtkPolyDataWriter> writer;
      writer->SetInputData(surface);
      writer->SetFileName(path.c_str());
      writer->SetFileVersion(42);  // the version most exporters still write
      if (binary) writer->SetFileTypeToBinary();
      EXPECT_EQ(writer->Write(), 1);
      return path;
    };
    const std::string path = write(data, binary ? "with_data_binary.vtk" : "with_data_ascii.vtk");
    const std::string bytes = read_file(path);
    ASSERT_NE(bytes.find("FIELD FieldData 3"), std::string::npos);
    ASSERT_NE(bytes.find("POINT_DATA"), std::string::npos);
    ASSERT_NE(bytes.find("CELL_DATA"), std::string::npos);
    const SurfaceMesh read = read_surface_mesh(path);
    const SurfaceMesh expected = read_surface_mesh(write(bare, binary ? "bare_binary.vtk" : "bare_ascii.vtk"));
    EXPECT_EQ(read.vertices, expected.vertices);
    EXPECT_EQ(read.triangles, mesh.triangles);
    if (binary) {
      EXPECT_EQ(read.vertices, mesh.vertices);
    }
  }
  // Point data that declares 10^12 points: never read, so never allocated.
  const std::string octahedron =
      "# vtk DataFile Version 4.2\noctahedron\nASCII\nDATASET POLYDATA\nPOINTS 6 double\n"
      "1 0 0 -1 0 0 0 1 0 0 -1 0 0 0 1 0 0 -1\nPOLYGONS 8 32\n"
      "3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n";
  const std::string huge_point_data = directory.file(
      "huge_point_data.vtk", octahedron + "POINT_DATA 1000000000000\nSCALARS s double 1\nLOOKUP_TABLE default\n1 2 3\n");
  EXPECT_EQ(read_surface_mesh(huge_point_data).triangles.size(), 8U);
  // A FIELD block before the points, as VisIt writes one, with a METADATA block after an array.
  const std::string visit = directory.file(
      "visit.vtk", "# vtk DataFile Version 4.2\noctahedron\nASCII\nDATASET POLYDATA\nFIELD FieldData 2\n"
                   "TIME 1 1 double\n0.5\nMETADATA\nINFORMATION 0\n\nCYCLE 1 1 int\n3\n" +
                       octahedron.substr(octahedron.find("POINTS")));
  EXPECT_EQ(read_surface_mesh(visit).triangles.size(), 8U);
  // Malformed FIELD blocks: a type that is not numeric, values cut short, no array count.
  const std::string found = std::string(TOUCHSTONE_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_surface_vtk/corrupt_field_among_polygons.vtk";
  expect_invalid_argument([&] { read_surface_mesh(found); },
                          {"corrupt_field_among_polygons.vtk", "FIELD '8' array '3'", "type '4tk'"});
  const std::string cut = directory.file(
      "field_cut.vtk", octahedron + "FIELD FieldData 1\nTIME 1 3 double\n0.5 0.7\n");
  expect_invalid_argument([&] { read_surface_mesh(cut); }, {cut, "FIELD 'FieldData' array 'TIME' declares 3 values", "value 3 is missing"});
  const std::string no_count = directory.file("field_no_count.vtk", octahedron + "FIELD FieldData\n");
  expect_invalid_argument([&] { read_surface_mesh(no_count); }, {no_count, "FIELD must be followed by a name and its number of arrays"});
  const std::string strings = directory.file(
      "field_strings.vtk", octahedron + "FIELD FieldData 1\nnames 1 1 string\nliver\n");
  expect_invalid_argument([&] { read_surface_mesh(strings); }, {strings, "FIELD 'FieldData' array 'names'", "type 'string'"});
}

// Found by fuzzing: text that VTK takes for a binary STL (NUL bytes among the first 256) with a
// header "count" of half a billion facets made VTK ask for ~20 GB before reading. Under a 2 GB
// address-space limit (a child process: the limit stays there) the count must be refused
// before VTK allocates, with the file's own numbers.
TEST(SurfaceMeshIo, BinaryStlCountIsCheckedBeforeVtkAllocates) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "sanitizers reserve terabytes of address space: no address-space limit possible";
#else
  const TemporaryDirectory directory("surface_io");
  std::string bytes = "solid octahedron\n";
  bytes.resize(80, '\0');
  bytes += "tex ";  // 544,761,204 facets, little-endian
  bytes.resize(84 + 2 * 50, '\0');
  const std::string path = directory.file("text_with_nul.stl", bytes);
  const auto read_with_2_gb = [&] {
    const rlimit limit{rlim_t{2} << 30, rlim_t{2} << 30};
    if (setrlimit(RLIMIT_AS, &limit) != 0) std::_Exit(2);
    try {
      read_surface_mesh(path);
    } catch (const std::invalid_argument& error) {
      const bool named = std::string(error.what()).find("header announces 544761204 facets, the file holds 2") !=
                         std::string::npos;
      std::fprintf(stderr, "%s\n", error.what());
      std::_Exit(named ? 0 : 1);
    }
    std::_Exit(3);
  };
  EXPECT_EXIT(read_with_2_gb(), ::testing::ExitedWithCode(0), "text_with_nul.stl");
#endif
}

// An appended compressed DataArray whose tag ends right after "offset=" (a mutation the fuzzer
// found: reading the value past the tag's end threw std::out_of_range) is a named error.
TEST(SurfaceMeshIo, AnAppendedArrayWithAnEmptyOffsetFailsClearly) {
  const TemporaryDirectory directory("surface_io");
  const std::string path = directory.path("appended.vtp");
  vtkNew<vtkXMLPolyDataWriter> writer;
  writer->SetInputData(sphere_poly_data(directory));
  writer->SetFileName(path.c_str());
  writer->SetCompressorTypeToZLib();
  writer->SetDataMode(vtkXMLWriter::Appended);
  ASSERT_EQ(writer->Write(), 1);
  std::string bytes = read_file(path);
  const std::size_t offset = bytes.find(" offset=\"");
  ASSERT_NE(offset, std::string::npos);
  const std::size_t tag_end = bytes.find('>', offset);
  bytes.replace(offset, tag_end - offset, " offset=");
  const std::string corrupt = directory.file("empty_offset.vtp", bytes);
  expect_invalid_argument([&] { read_surface_mesh(corrupt); },
                          {corrupt, "has offset '', not a byte offset into the appended data"});
}

// Compressed VTK XML files (zlib, as ParaView writes them) inline, appended raw and appended
// base64 read like uncompressed ones; a corrupt block count in any of them is refused before VTK
// allocates a size per claimed block.
TEST(SurfaceMeshIo, CompressedVtpReadsAndACorruptBlockCountFailsClearly) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = sphere();
  const vtkSmartPointer<vtkPolyData> plain = sphere_poly_data(directory);
  struct Layout {
    const char* name;
    int mode;
    bool base64;
    bool header64;  // UInt64 header words, else UInt32 (VTK's default)
  };
  for (const Layout layout : {Layout{"inline.vtp", vtkXMLWriter::Binary, true, true},
                              Layout{"inline32.vtp", vtkXMLWriter::Binary, true, false},
                              Layout{"appended_raw.vtp", vtkXMLWriter::Appended, false, true},
                              Layout{"appended_base64.vtp", vtkXMLWriter::Appended, true, false}}) {
    SCOPED_TRACE(layout.name);
    const std::string path = directory.path(layout.name);
    vtkNew<vtkXMLPolyDataWriter> writer;
    writer->SetInputData(plain);
    writer->SetFileName(path.c_str());
    writer->SetCompressorTypeToZLib();
    writer->SetDataMode(layout.mode);
    writer->SetEncodeAppendedData(layout.base64);
    if (layout.header64) writer->SetHeaderTypeToUInt64();
    ASSERT_EQ(writer->Write(), 1);
    std::string bytes = read_file(path);
    ASSERT_NE(bytes.find("compressor=\"vtkZLibDataCompressor\""), std::string::npos);
    const SurfaceMesh read = read_surface_mesh(path);
    EXPECT_EQ(read.vertices, mesh.vertices);
    EXPECT_EQ(read.triangles, mesh.triangles);

    // The first array's block count: one header word, as base64 (12 characters hold a UInt64
    // and one more byte, 8 characters a UInt32 and two more) or as raw bytes.
    const std::size_t appended = bytes.find("<AppendedData");
    std::size_t first = appended == std::string::npos ? bytes.find('>', bytes.find("format=\"binary\"")) + 1
                                                      : bytes.find('_', appended) + 1;
    while (layout.base64 && std::isspace(static_cast<unsigned char>(bytes[first]))) ++first;
    ASSERT_NE(bytes.find(layout.header64 ? "header_type=\"UInt64\"" : "header_type=\"UInt32\""), std::string::npos);
    if (layout.base64) {
      // 2^31 - 1 blocks; the bytes after the word are zero.
      if (layout.header64) bytes.replace(first, 12, "////fwAAAAAA");
      else bytes.replace(first, 8, "////fwAA");
    } else {
      const unsigned char count[8] = {0xff, 0xff, 0xff, 0x7f, 0, 0, 0, 0};
      bytes.replace(first, 8, reinterpret_cast<const char*>(count), 8);
    }
    const std::string corrupt = directory.file(std::string("corrupt_") + layout.name, bytes);
    expect_invalid_argument([&] { read_surface_mesh(corrupt); },
                            {corrupt, "compressed DataArray of piece 1 declares 2147483647 compressed blocks"});

    // Raw UInt64 header words [count, block size, last block size]: no blocks but a last block
    // (VTK's size underflows and it reads a block that is not there: a null dereference), and
    // blocks of 0 bytes (VTK divides by the block size).
    if (!layout.base64) {
      const std::string original = read_file(path);
      const auto with_words = [&](unsigned long long count, unsigned long long block_size, const char* name) {
        std::string changed = original;
        for (int b = 0; b < 8; ++b) {
          changed[first + b] = static_cast<char>(count >> (8 * b) & 0xff);
          changed[first + 8 + b] = static_cast<char>(block_size >> (8 * b) & 0xff);
        }
        return directory.file(name, changed);
      };
      const std::string no_blocks = with_words(0, 32768, "no_blocks.vtp");
      expect_invalid_argument([&] { read_surface_mesh(no_blocks); },
                              {no_blocks, "declares no compressed blocks but a last block of"});
      const std::string empty_blocks = with_words(1, 0, "empty_blocks.vtp");
      expect_invalid_argument([&] { read_surface_mesh(empty_blocks); },
                              {empty_blocks, "declares compressed blocks of 0 bytes"});
      // VTK allocates a block's uncompressed and compressed sizes before reading it: 6 GB
      // claimed by a 2 kB file (a mutation the fuzzer found) is refused, either way.
      if (layout.header64) {
        const std::string huge_block = with_words(1, 6383763632ULL, "huge_block.vtp");
        expect_invalid_argument([&] { read_surface_mesh(huge_block); },
                                {huge_block, "declares compressed blocks of 6383763632 bytes uncompressed"});
        std::string changed = original;
        for (int b = 0; b < 8; ++b) changed[first + 24 + b] = static_cast<char>(6383763632ULL >> (8 * b) & 0xff);
        const std::string huge_compressed = directory.file("huge_compressed.vtp", changed);
        expect_invalid_argument([&] { read_surface_mesh(huge_compressed); },
                                {huge_compressed, "declares a compressed block 0 of 6383763632 bytes"});
      }
    }
  }
  // The input CI's fuzz run found, kept in the harness's corpus: a mutation of a compressed
  // sphere left two UInt32 headers with no blocks and a last block (the strips' offsets, 301,568
  // bytes, reported first; the polygons' connectivity, 2,304 bytes, which VTK crashed on).
  const std::string found = std::string(TOUCHSTONE_SOURCE_DIR) +
                            "/tests/fuzz/corpus/fuzz_surface_vtp/corrupt_zero_blocks_with_last_block.vtp";
  expect_invalid_argument([&] { read_surface_mesh(found); },
                          {"corrupt_zero_blocks_with_last_block.vtp", "no compressed blocks but a last block of 301568 bytes"});
  // Another: an appended array whose offset is "P", not a number. VTK reads the data at offset 0,
  // whose header claims a block of 4,294,967,280 bytes, and allocates it.
  const std::string no_offset = std::string(TOUCHSTONE_SOURCE_DIR) +
                                "/tests/fuzz/corpus/fuzz_surface_vtp/corrupt_offset_not_a_number.vtp";
  expect_invalid_argument([&] { read_surface_mesh(no_offset); },
                          {"corrupt_offset_not_a_number.vtp", "appended compressed DataArray of piece 1", "offset 'P'"});
  // Another: a byte 0xA0 in front of the '_' that marks the appended data. VTK then starts the
  // data at that byte, three bytes early, and reads "\xa0  _" as the first array's block count:
  // 1,595,941,024 blocks, and allocates gigabytes for their sizes.
  const std::string stray_byte = std::string(TOUCHSTONE_SOURCE_DIR) +
                                 "/tests/fuzz/corpus/fuzz_surface_vtp/corrupt_stray_byte_before_appended_data.vtp";
  expect_invalid_argument([&] { read_surface_mesh(stray_byte); },
                          {"corrupt_stray_byte_before_appended_data.vtp",
                           "appended compressed DataArray of piece 1 declares 1595941024 compressed blocks"});
}

TEST(SurfaceMeshIo, WriteRejectsBadInputAndUnwritablePaths) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = sphere();
  std::vector<Vector3i> bad = mesh.triangles;
  bad[3][1] = 999;
  expect_invalid_argument([&] { write_surface_mesh(directory.path("bad.vtp"), mesh.vertices, bad); },
               {"bad.vtp", "triangle 3", "vertex 999"});
  expect_invalid_argument([&] { write_surface_mesh(directory.path("bad.ply"), mesh.vertices, mesh.triangles); }, {"unsupported"});
  for (const char* name : {"x.vtp", "x.vtk", "x.stl", "x.obj", "x.msh"}) {
    const std::string path = directory.path(std::string("no/such/dir/") + name);
    EXPECT_THROW(write_surface_mesh(path, mesh.vertices, mesh.triangles), std::runtime_error) << name;
  }
}

// Point vectors (e.g. the displacements the palpation replay writes for ParaView) go to the VTK
// formats only, one per vertex, and come back from the file unchanged.
TEST(SurfaceMeshIo, PointVectorsAreWrittenToVtpAndRefusedElsewhere) {
  const TemporaryDirectory directory("surface_io");
  const TriangleMeshData mesh = sphere();
  std::vector<Vector3d> field(mesh.vertices.size());
  for (std::size_t i = 0; i < field.size(); ++i) field[i] = Vector3d(1e-3 * double(i), -2.0 * double(i), 0.5);
  SurfaceWriteOptions options;
  options.point_vectors = {{"displacement_m", field}};
  const std::string vtp = directory.path("field.vtp");
  write_surface_mesh(vtp, mesh.vertices, mesh.triangles, options);
  vtkNew<vtkXMLPolyDataReader> reader;
  reader->SetFileName(vtp.c_str());
  reader->Update();
  vtkDataArray* array = reader->GetOutput()->GetPointData()->GetArray("displacement_m");
  ASSERT_NE(array, nullptr);
  ASSERT_EQ(array->GetNumberOfTuples(), static_cast<vtkIdType>(field.size()));
  for (std::size_t i = 0; i < field.size(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(array->GetComponent(static_cast<vtkIdType>(i), k), field[i][k]);
  expect_invalid_argument([&] { write_surface_mesh(directory.path("field.stl"), mesh.vertices, mesh.triangles, options); },
                          {"field.stl", "point vectors"});
  options.point_vectors[0].second.pop_back();
  expect_invalid_argument([&] { write_surface_mesh(directory.path("short.vtp"), mesh.vertices, mesh.triangles, options); },
                          {"short.vtp", "displacement_m", "values for"});
}

}  // namespace
}  // namespace touchstone::meshes
