// The benchmark bodies B1–B5 and the box as gmsh meshes them: names and parameter validation,
// each body's physical groups, measures and patch, refinement, the recorded geometry script and
// the size law. One file, as one source file makes them; every case meshes a body once.
#include "touchstone/meshes/benchmark_geometry.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

namespace touchstone::meshes {
namespace {

constexpr double pi = 3.14159265358979323846;

using Point = std::array<double, 3>;

Point minus(const Point& p, const Point& q) { return {p[0] - q[0], p[1] - q[1], p[2] - q[2]}; }
Point cross(const Point& p, const Point& q) {
  return {p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]};
}
double dot(const Point& p, const Point& q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; }
double norm(const Point& p) { return std::sqrt(dot(p, p)); }

/// The parts of an MSH 2.2 ASCII file the benchmarks use: physical names, nodes, and
/// triangles/tetrahedra with their physical tag (the first element tag).
struct MshFile {
  std::map<std::pair<int, int>, std::string> physical_names;  ///< (dim, tag) → name
  std::map<std::size_t, Point> nodes;
  struct Element {
    int type = 0;
    int physical = 0;
    std::vector<std::size_t> nodes;
  };
  std::vector<Element> elements;

  static MshFile read(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot open " + path);
    MshFile file;
    std::string section;
    while (in >> section) {
      if (section == "$MeshFormat") {
        double version = 0;
        int binary = 0;
        int data_size = 0;
        in >> version >> binary >> data_size;
        if (version != 2.2 || binary != 0) throw std::runtime_error("not MSH 2.2 ASCII");
      } else if (section == "$PhysicalNames") {
        int count = 0;
        in >> count;
        for (int i = 0; i < count; ++i) {
          int dim = 0;
          int tag = 0;
          std::string quoted;
          in >> dim >> tag >> quoted;
          file.physical_names[{dim, tag}] = quoted.substr(1, quoted.size() - 2);
        }
      } else if (section == "$Nodes") {
        std::size_t count = 0;
        in >> count;
        for (std::size_t i = 0; i < count; ++i) {
          std::size_t id = 0;
          Point x{};
          in >> id >> x[0] >> x[1] >> x[2];
          file.nodes[id] = x;
        }
      } else if (section == "$Elements") {
        std::size_t count = 0;
        in >> count;
        for (std::size_t i = 0; i < count; ++i) {
          std::size_t id = 0;
          int tag_count = 0;
          Element element;
          in >> id >> element.type >> tag_count;
          std::vector<int> tags(static_cast<std::size_t>(tag_count));
          for (int& tag : tags) in >> tag;
          element.physical = tags.empty() ? 0 : tags[0];
          const std::size_t node_count =
              element.type == 4 ? 4 : element.type == 2 ? 3 : element.type == 1 ? 2 : 1;
          element.nodes.resize(node_count);
          for (std::size_t& node : element.nodes) in >> node;
          file.elements.push_back(std::move(element));
        }
      }
    }
    return file;
  }

  std::vector<std::array<Point, 3>> triangles(int physical) const {
    std::vector<std::array<Point, 3>> result;
    for (const auto& element : elements) {
      if (element.type == 2 && element.physical == physical) {
        result.push_back({nodes.at(element.nodes[0]), nodes.at(element.nodes[1]),
                          nodes.at(element.nodes[2])});
      }
    }
    return result;
  }

  std::vector<Point> vertices(int physical) const {
    std::set<std::size_t> ids;
    for (const auto& element : elements) {
      if (element.type == 2 && element.physical == physical) {
        ids.insert(element.nodes.begin(), element.nodes.end());
      }
    }
    std::vector<Point> result;
    for (const std::size_t id : ids) result.push_back(nodes.at(id));
    return result;
  }

  double area(int physical) const {
    double sum = 0;
    for (const auto& t : triangles(physical)) {
      sum += 0.5 * norm(cross(minus(t[1], t[0]), minus(t[2], t[0])));
    }
    return sum;
  }

  std::size_t tetrahedron_count() const {
    return static_cast<std::size_t>(std::count_if(
        elements.begin(), elements.end(), [](const Element& e) { return e.type == 4; }));
  }

  /// Sum of |det|/6 and the smallest mean-ratio quality 12 (3V)^(2/3) / Σ l² (1 = regular).
  std::pair<double, double> volume_and_worst_quality() const {
    double volume = 0;
    double worst = 1;
    for (const auto& element : elements) {
      if (element.type != 4) continue;
      std::array<Point, 4> x;
      for (int i = 0; i < 4; ++i) x[i] = nodes.at(element.nodes[i]);
      const double v =
          std::abs(dot(minus(x[1], x[0]), cross(minus(x[2], x[0]), minus(x[3], x[0])))) / 6;
      double squared_lengths = 0;
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j) squared_lengths += dot(minus(x[i], x[j]), minus(x[i], x[j]));
      }
      volume += v;
      worst = std::min(worst, 12 * std::pow(3 * v, 2.0 / 3.0) / squared_lengths);
    }
    return {volume, worst};
  }
};

/// One scratch directory per process, so concurrent test runs never share files; removed at exit.
const std::filesystem::path& scratch_directory() {
  static const std::filesystem::path directory = [] {
    auto path = std::filesystem::path(::testing::TempDir()) /
                ("touchstone_meshes_" + std::to_string(::getpid()));
    std::filesystem::create_directories(path);
    return path;
  }();
  return directory;
}

class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ignored;
    std::filesystem::remove_all(scratch_directory(), ignored);
  }
};
[[maybe_unused]] const auto* const scratch_cleanup =
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

std::string output_path(const std::string& file_name) {
  return (scratch_directory() / file_name).string();
}

/// Small meshes (a few thousand tetrahedra) that still resolve the patch edge with a/4.
MeshParameters small_parameters(Benchmark benchmark) {
  MeshParameters p;
  p.benchmark = benchmark;
  p.body_radius_m = 0.05;
  p.tool_radius_m = 0.005;
  p.local_radius_m = 0.02;
  p.contact_polar_angle_rad = 0.6;
  p.edge_size_m = p.tool_radius_m / 4;
  p.size_growth = 0.5;
  p.max_size_m = p.body_radius_m / 6;
  p.refinement = 0;
  return p;
}

double spherical_cap_area(double r, double a) {
  return 2 * pi * r * r * (1 - std::cos(std::asin(a / r)));
}

/// Meshes p, reads the file back and checks what every benchmark shares.
MshFile mesh_and_read(const MeshParameters& p, const std::string& name,
                      const std::set<std::string>& expected_groups) {
  const std::string path = output_path(name + ".msh");
  const MeshSummary summary = generate_mesh(p, path);
  EXPECT_EQ(summary.path, path);
  EXPECT_TRUE(std::filesystem::exists(path));
  const MshFile file = MshFile::read(path);

  std::set<std::string> names;
  for (const auto& entry : file.physical_names) names.insert(entry.second);
  EXPECT_EQ(names, expected_groups);
  EXPECT_EQ(file.physical_names.at({3, boundary_tags::tissue}), "tissue");

  EXPECT_GT(summary.tetrahedron_count, 0u);
  EXPECT_EQ(summary.tetrahedron_count, file.tetrahedron_count());
  EXPECT_EQ(summary.node_count, file.nodes.size());
  EXPECT_EQ(summary.patch_triangle_count,
            p.benchmark == Benchmark::Box ? 0u : file.triangles(boundary_tags::tool_patch).size());
  EXPECT_GT(summary.seconds, 0.0);
  // Every written element belongs to a named group (Mesh.SaveAll = 0).
  for (const auto& element : file.elements) {
    const int dim = element.type == 4 ? 3 : 2;
    EXPECT_EQ(file.physical_names.count({dim, element.physical}), 1u);
  }
  return file;
}

void expect_on_sphere(const std::vector<Point>& points, const Point& centre, double radius,
                      double tolerance, const std::string& what) {
  ASSERT_FALSE(points.empty()) << what;
  double worst = 0;
  for (const Point& x : points) worst = std::max(worst, std::abs(norm(minus(x, centre)) - radius));
  EXPECT_LE(worst, tolerance) << what;
}

void expect_on_plane_z(const std::vector<Point>& points, double z, double tolerance,
                       const std::string& what) {
  ASSERT_FALSE(points.empty()) << what;
  for (const Point& x : points) ASSERT_NEAR(x[2], z, tolerance) << what;
}

// ---------------------------------------------------------------------------------------------

TEST(BenchmarkNames, RoundTripIgnoringCase) {
  for (const Benchmark b :
       {Benchmark::B1, Benchmark::B2, Benchmark::B3, Benchmark::B5, Benchmark::Box}) {
    EXPECT_EQ(benchmark_from_string(to_string(b)), b);
  }
  EXPECT_EQ(benchmark_from_string("b1"), Benchmark::B1);
  EXPECT_EQ(benchmark_from_string("b5"), Benchmark::B5);
  EXPECT_EQ(benchmark_from_string("BOX"), Benchmark::Box);
  EXPECT_EQ(to_string(Benchmark::Box), "box");
}

TEST(BenchmarkNames, RejectsUnknownNameAndListsValidOnes) {
  try {
    benchmark_from_string("B9");
    FAIL() << "B9 was accepted";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("B9"), std::string::npos) << message;
    EXPECT_NE(message.find("B1"), std::string::npos) << message;
    EXPECT_NE(message.find("box"), std::string::npos) << message;
  }
  EXPECT_THROW(benchmark_from_string(""), std::invalid_argument);
  EXPECT_THROW(benchmark_from_string("B4"), std::invalid_argument);
}

TEST(Validate, AcceptsDefaultsOfEveryBenchmark) {
  for (const Benchmark b :
       {Benchmark::B1, Benchmark::B2, Benchmark::B3, Benchmark::B5, Benchmark::Box}) {
    MeshParameters p;
    p.benchmark = b;
    EXPECT_NO_THROW(p.validate()) << to_string(b);
    EXPECT_NO_THROW(small_parameters(b).validate()) << to_string(b);
  }
}

TEST(Validate, RejectsBadValuesNamingTheField) {
  struct Case {
    std::string field;
    std::function<void(MeshParameters&)> spoil;
  };
  const double nan = std::nan("");
  const std::vector<Case> cases{
      {"tool_radius_m", [](MeshParameters& p) { p.tool_radius_m = -1; }},
      {"tool_radius_m", [](MeshParameters& p) { p.tool_radius_m = p.body_radius_m / 2; }},
      {"body_radius_m", [nan](MeshParameters& p) { p.body_radius_m = nan; }},
      {"body_radius_m", [](MeshParameters& p) { p.body_radius_m = 0; }},
      {"edge_size_m", [](MeshParameters& p) { p.edge_size_m = p.tool_radius_m * 1.5; }},
      {"edge_size_m", [](MeshParameters& p) { p.edge_size_m = INFINITY; }},
      {"max_size_m", [](MeshParameters& p) { p.max_size_m = -0.01; }},
      {"max_size_m", [](MeshParameters& p) { p.max_size_m = p.edge_size_m / 2; }},
      {"size_growth", [](MeshParameters& p) { p.size_growth = 0; }},
      {"size_exponent", [](MeshParameters& p) { p.size_exponent = 1.5; }},
      {"size_exponent", [nan](MeshParameters& p) { p.size_exponent = nan; }},
      {"power_grading_extent", [](MeshParameters& p) { p.power_grading_extent = 0.5; }},
      {"refinement", [](MeshParameters& p) { p.refinement = 7; }},
      {"refinement", [](MeshParameters& p) { p.refinement = -1; }},
      {"local_radius_m",
       [](MeshParameters& p) {
         p.benchmark = Benchmark::B3;
         p.local_radius_m = p.tool_radius_m;
       }},
      {"local_radius_m",
       [](MeshParameters& p) {
         p.benchmark = Benchmark::B3;
         p.local_radius_m = p.body_radius_m * 1.01;
       }},
      {"contact_polar_angle_rad",
       [](MeshParameters& p) {
         p.benchmark = Benchmark::B5;
         p.contact_polar_angle_rad = pi / 2;
       }},
      {"contact_polar_angle_rad",
       [](MeshParameters& p) {
         p.benchmark = Benchmark::B5;
         p.contact_polar_angle_rad = -0.1;
       }},
      {"contact_polar_angle_rad",
       [](MeshParameters& p) {
         // Patch edge would dip through the base plane.
         p.benchmark = Benchmark::B5;
         p.contact_polar_angle_rad = pi / 2 - 0.5 * std::asin(p.tool_radius_m / p.body_radius_m);
       }},
      {"box_size_m[1]",
       [](MeshParameters& p) {
         p.benchmark = Benchmark::Box;
         p.box_size_m[1] = 0;
       }},
  };
  for (const Case& c : cases) {
    MeshParameters p;
    c.spoil(p);
    try {
      p.validate();
      ADD_FAILURE() << "accepted a bad " << c.field;
    } catch (const std::invalid_argument& error) {
      const std::string message = error.what();
      EXPECT_NE(message.find("MeshParameters." + c.field + " = "), std::string::npos) << message;
    }
    EXPECT_THROW(generate_mesh(p, output_path("rejected.msh")), std::invalid_argument) << c.field;
  }
  MeshParameters p;
  p.tool_radius_m = -1;
  try {
    p.validate();
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()), "MeshParameters.tool_radius_m = -1 must be > 0");
  }
}

TEST(GenerateMesh, B1CylinderWithFlatPatch) {
  const MeshParameters p = small_parameters(Benchmark::B1);
  const double w = p.body_radius_m;
  const double a = p.tool_radius_m;
  const MshFile file = mesh_and_read(p, "b1", {"base", "tool_patch", "free", "tissue"});

  EXPECT_NEAR(file.area(boundary_tags::tool_patch), pi * a * a, 0.02 * pi * a * a);
  expect_on_plane_z(file.vertices(boundary_tags::tool_patch), 0.0, 1e-12 * w, "patch z = 0");
  for (const Point& x : file.vertices(boundary_tags::tool_patch)) {
    EXPECT_LE(std::hypot(x[0], x[1]), a * (1 + 1e-9));
  }
  expect_on_plane_z(file.vertices(boundary_tags::base), -w, 1e-12 * w, "base z = -W");
  const double exact_volume = pi * w * w * w;
  EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 0.01 * exact_volume);
}

TEST(GenerateMesh, B2HemisphereWithPolarPatch) {
  const MeshParameters p = small_parameters(Benchmark::B2);
  const double r = p.body_radius_m;
  const MshFile file = mesh_and_read(p, "b2", {"base", "tool_patch", "free", "tissue"});

  const double cap = spherical_cap_area(r, p.tool_radius_m);
  EXPECT_NEAR(file.area(boundary_tags::tool_patch), cap, 0.02 * cap);
  const Point origin{0, 0, 0};
  expect_on_sphere(file.vertices(boundary_tags::free), origin, r, 1e-9 * r, "free on sphere R");
  expect_on_sphere(file.vertices(boundary_tags::tool_patch), origin, r, 1e-9 * r,
                   "patch on sphere R");
  const double z0 = std::sqrt(r * r - p.tool_radius_m * p.tool_radius_m);
  for (const Point& x : file.vertices(boundary_tags::tool_patch)) EXPECT_GE(x[2], z0 - 1e-9 * r);
  expect_on_plane_z(file.vertices(boundary_tags::base), 0.0, 1e-12 * r, "base z = 0");

  const auto [volume, worst_quality] = file.volume_and_worst_quality();
  const double exact_volume = 2 * pi * r * r * r / 3;
  EXPECT_NEAR(volume, exact_volume, 0.01 * exact_volume);
  // The patch edge is imprinted on the sphere, not cut out by an internal disk, so no thin
  // lens of flat tetrahedra sits under the patch.
  EXPECT_GT(worst_quality, 0.1);
}

TEST(GenerateMesh, B3LocalDomainHasCutAndNoBase) {
  MeshParameters p = small_parameters(Benchmark::B3);
  // The size law grows to ~L/2 on the cut sphere; cap it so facets follow that sphere to 1 %.
  p.max_size_m = p.local_radius_m / 8;
  const double r = p.body_radius_m;
  const double l = p.local_radius_m;
  const MshFile file = mesh_and_read(p, "b3", {"tool_patch", "free", "cut", "tissue"});

  const double cap = spherical_cap_area(r, p.tool_radius_m);
  EXPECT_NEAR(file.area(boundary_tags::tool_patch), cap, 0.02 * cap);
  const Point pole{0, 0, r};
  expect_on_sphere(file.vertices(boundary_tags::cut), pole, l, 1e-9 * r, "cut on sphere L");
  expect_on_sphere(file.vertices(boundary_tags::free), {0, 0, 0}, r, 1e-9 * r, "free on sphere R");
  for (const Point& x : file.vertices(boundary_tags::free)) EXPECT_LE(norm(minus(x, pole)), l * (1 + 1e-9));

  // Lens of two spheres with centre distance R: V = π L² (8 R L − 3 L²) / (12 R).
  const double exact_volume = pi * l * l * (8 * r * l - 3 * l * l) / (12 * r);
  EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 0.01 * exact_volume);
}

TEST(GenerateMesh, B3WithLocalRadiusEqualToBodyRadius) {
  MeshParameters p = small_parameters(Benchmark::B3);
  p.local_radius_m = p.body_radius_m;
  p.max_size_m = p.body_radius_m / 8;
  const double r = p.body_radius_m;
  const MshFile file = mesh_and_read(p, "b3_full", {"tool_patch", "free", "cut", "tissue"});
  expect_on_sphere(file.vertices(boundary_tags::cut), {0, 0, r}, r, 1e-9 * r, "cut on sphere L");
  const double exact_volume = 5 * pi * r * r * r / 12;
  EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 0.01 * exact_volume);
}

TEST(GenerateMesh, B5OffPolePatch) {
  const MeshParameters p = small_parameters(Benchmark::B5);
  const double r = p.body_radius_m;
  const double theta = p.contact_polar_angle_rad;
  const MshFile file = mesh_and_read(p, "b5", {"base", "tool_patch", "free", "tissue"});

  const double cap = spherical_cap_area(r, p.tool_radius_m);
  EXPECT_NEAR(file.area(boundary_tags::tool_patch), cap, 0.02 * cap);
  const Point centre{std::sin(theta), 0, std::cos(theta)};
  const double half_angle = std::asin(p.tool_radius_m / r);
  for (const Point& x : file.vertices(boundary_tags::tool_patch)) {
    EXPECT_LE(std::acos(std::min(1.0, dot(x, centre) / norm(x))), half_angle * (1 + 1e-9));
  }
  expect_on_sphere(file.vertices(boundary_tags::free), {0, 0, 0}, r, 1e-9 * r, "free on sphere R");
  expect_on_plane_z(file.vertices(boundary_tags::base), 0.0, 1e-12 * r, "base z = 0");
  const double exact_volume = 2 * pi * r * r * r / 3;
  EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 0.01 * exact_volume);
}

// The exterior of the MFS local domain: the body minus ball(c, L). Its cut sphere is the part of
// the ball's sphere inside the body: on the hemisphere a cap of height L − L²/(2R) below the
// contact (the spheres |x| = R and |x − c| = L with |c| = R meet in the plane n·x = R − L²/(2R)),
// area 2π L (L − L²/(2R)); on the cylinder's flat top a half sphere, 2π L². Facets lose O(h²) of
// the area; with h ≤ L/8 on the cut that is well below the 2 % asserted.
TEST(GenerateMesh, ExteriorOfLocalBallOnTheHemisphereHasCutBaseAndFree) {
  for (const double theta : {0.0, 0.6}) {
    MeshParameters p = small_parameters(theta == 0 ? Benchmark::B2 : Benchmark::B5);
    p.contact_polar_angle_rad = theta;
    p.exterior_of_local_ball = true;
    p.edge_size_m = p.local_radius_m / 10;
    const double r = p.body_radius_m;
    const double l = p.local_radius_m;
    const MshFile file = mesh_and_read(p, "exterior_" + std::to_string(theta), {"base", "free", "cut", "tissue"});

    const double cap = 2 * pi * l * (l - l * l / (2 * r));
    EXPECT_NEAR(file.area(boundary_tags::cut), cap, 0.02 * cap) << "theta " << theta;
    const Point contact{r * std::sin(theta), 0, r * std::cos(theta)};
    expect_on_sphere(file.vertices(boundary_tags::cut), contact, l, 1e-9 * r, "cut on sphere L");
    expect_on_sphere(file.vertices(boundary_tags::free), {0, 0, 0}, r, 1e-9 * r, "free on sphere R");
    for (const Point& x : file.vertices(boundary_tags::free)) EXPECT_GE(norm(minus(x, contact)), l * (1 - 1e-9));
    expect_on_plane_z(file.vertices(boundary_tags::base), 0.0, 1e-12 * r, "base z = 0");
    // The hemisphere minus the lens B3 (same lens at any θ while the ball clears the base).
    const double exact_volume = 2 * pi * r * r * r / 3 - pi * l * l * (8 * r * l - 3 * l * l) / (12 * r);
    EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 0.01 * exact_volume);
  }
}

TEST(GenerateMesh, ExteriorOfLocalBallOnTheCylinderTop) {
  MeshParameters p = small_parameters(Benchmark::B1);
  p.exterior_of_local_ball = true;
  p.edge_size_m = p.local_radius_m / 10;
  const double w = p.body_radius_m;
  const double l = p.local_radius_m;
  const MshFile file = mesh_and_read(p, "exterior_b1", {"base", "free", "cut", "tissue"});
  const double half_sphere = 2 * pi * l * l;
  EXPECT_NEAR(file.area(boundary_tags::cut), half_sphere, 0.02 * half_sphere);
  expect_on_sphere(file.vertices(boundary_tags::cut), {0, 0, 0}, l, 1e-9 * w, "cut on sphere L");
  for (const Point& x : file.vertices(boundary_tags::cut)) EXPECT_LE(x[2], 1e-9 * w);
  expect_on_plane_z(file.vertices(boundary_tags::base), -w, 1e-12 * w, "base z = -W");
  const double exact_volume = pi * w * w * w - 2 * pi * l * l * l / 3;
  EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 0.01 * exact_volume);
}

TEST(Validate, ExteriorOfLocalBallNamesTheField) {
  const auto message_of = [](const MeshParameters& p) {
    try {
      p.validate();
    } catch (const std::invalid_argument& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  MeshParameters p = small_parameters(Benchmark::B3);
  p.exterior_of_local_ball = true;
  EXPECT_NE(message_of(p).find("exterior_of_local_ball"), std::string::npos) << message_of(p);
  p = small_parameters(Benchmark::B2);
  p.exterior_of_local_ball = true;
  p.local_radius_m = 0.9 * p.tool_radius_m;  // the patch would stick out of the ball
  EXPECT_NE(message_of(p).find("local_radius_m"), std::string::npos) << message_of(p);
  p.local_radius_m = p.body_radius_m;  // the ball would reach the clamped base
  EXPECT_NE(message_of(p).find("base"), std::string::npos) << message_of(p);
}

TEST(ContactSite, PoleOffPoleAndCylinderTop) {
  MeshParameters p = small_parameters(Benchmark::B5);
  const ContactSite site = contact_site(p);
  EXPECT_NEAR(site.point_m[0], p.body_radius_m * std::sin(0.6), 1e-15);
  EXPECT_NEAR(site.point_m[2], p.body_radius_m * std::cos(0.6), 1e-15);
  EXPECT_NEAR(site.outward_normal[0], std::sin(0.6), 1e-15);
  EXPECT_EQ(contact_site(small_parameters(Benchmark::B2)).point_m[2], p.body_radius_m);
  EXPECT_EQ(contact_site(small_parameters(Benchmark::B1)).point_m[2], 0.0);
}

TEST(GenerateMesh, BoxFacesAndExactVolume) {
  MeshParameters p;
  p.benchmark = Benchmark::Box;
  p.box_size_m = {0.01, 0.02, 0.03};
  p.edge_size_m = 0.004;
  const MshFile file = mesh_and_read(
      p, "box", {"x_min", "x_max", "y_min", "y_max", "z_min", "z_max", "tissue"});
  const std::array<std::array<int, 2>, 3> faces{{
      {boundary_tags::x_min, boundary_tags::x_max},
      {boundary_tags::y_min, boundary_tags::y_max},
      {boundary_tags::z_min, boundary_tags::z_max},
  }};
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      const double coordinate = side == 0 ? 0.0 : p.box_size_m[axis];
      const auto vertices = file.vertices(faces[axis][side]);
      ASSERT_FALSE(vertices.empty());
      for (const Point& x : vertices) ASSERT_NEAR(x[axis], coordinate, 1e-12);
      const double exact_area = p.box_size_m[(axis + 1) % 3] * p.box_size_m[(axis + 2) % 3];
      EXPECT_NEAR(file.area(faces[axis][side]), exact_area, 1e-9 * exact_area);
    }
  }
  const double exact_volume = p.box_size_m[0] * p.box_size_m[1] * p.box_size_m[2];
  EXPECT_NEAR(file.volume_and_worst_quality().first, exact_volume, 1e-9 * exact_volume);
}

TEST(GenerateMesh, RefinementHalvesEverySize) {
  MeshParameters p = small_parameters(Benchmark::B2);
  p.edge_size_m = p.tool_radius_m / 2;
  p.max_size_m = p.body_radius_m / 3;
  const MeshSummary coarse = generate_mesh(p, output_path("b2_r0.msh"));
  p.refinement = 1;
  const MeshSummary fine = generate_mesh(p, output_path("b2_r1.msh"));
  EXPECT_GT(fine.tetrahedron_count, 4 * coarse.tetrahedron_count);
  EXPECT_GT(fine.patch_triangle_count, 3 * coarse.patch_triangle_count);
}

TEST(GenerateMesh, ConcurrentCallsAreSerialised) {
  MeshParameters p;
  p.benchmark = Benchmark::Box;
  p.box_size_m = {0.01, 0.01, 0.01};
  p.edge_size_m = 0.005;
  std::array<MeshSummary, 2> summaries;
  std::thread first([&] { summaries[0] = generate_mesh(p, output_path("box_thread_0.msh")); });
  std::thread second([&] { summaries[1] = generate_mesh(p, output_path("box_thread_1.msh")); });
  first.join();
  second.join();
  EXPECT_GT(summaries[0].tetrahedron_count, 0u);
  EXPECT_EQ(summaries[0].tetrahedron_count, summaries[1].tetrahedron_count);
}

TEST(GenerateMesh, UnwritablePathThrowsNamingBenchmarkAndPath) {
  const std::string path = "/nonexistent-touchstone-directory/b2.msh";
  try {
    generate_mesh(small_parameters(Benchmark::B2), path);
    FAIL() << "wrote to " << path;
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find("B2"), std::string::npos) << message;
  }
  // gmsh is left in a usable state after the failure.
  EXPECT_GT(generate_mesh(small_parameters(Benchmark::B1), output_path("after_failure.msh"))
                .tetrahedron_count,
            0u);
}

TEST(WriteGeometryScript, WritesGeoUnrolledWithPhysicalGroups) {
  const std::string path = output_path("b5.geo_unrolled");
  write_geometry_script(small_parameters(Benchmark::B5), path);
  std::ifstream in(path);
  ASSERT_TRUE(in.good());
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("SetFactory(\"OpenCASCADE\")"), std::string::npos);
  EXPECT_NE(text.str().find("Physical Surface(\"tool_patch\", 2)"), std::string::npos);
  EXPECT_NE(text.str().find("Physical Volume(\"tissue\", 100)"), std::string::npos);
  EXPECT_NE(text.str().find("Background Field"), std::string::npos);
}

// Beyond one tool radius the power law h ∝ d^β (β < 1) grows slower than the linear law with
// the same growth, so the mesh has more elements; its tangent continuation beyond t₀ radii
// grows linearly again and fills the far field with fewer.
TEST(SizeField, PowerGradingGrowsSlowerAndItsExtentCoarsensTheFarField) {
  MeshParameters p;
  p.benchmark = Benchmark::B2;
  p.edge_size_m = p.tool_radius_m / 8;
  p.size_growth = 0.5;
  p.max_size_m = 0.01;
  const MeshSummary linear = generate_mesh(p, output_path("grading_linear.msh"));
  p.size_exponent = 0.75;
  const MeshSummary power = generate_mesh(p, output_path("grading_power.msh"));
  p.power_grading_extent = 2;
  const MeshSummary tangent = generate_mesh(p, output_path("grading_tangent.msh"));
  EXPECT_GT(power.tetrahedron_count, linear.tetrahedron_count);
  EXPECT_LT(tangent.tetrahedron_count, power.tetrahedron_count);
}

}  // namespace
}  // namespace touchstone::meshes
