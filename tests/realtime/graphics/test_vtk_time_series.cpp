#include "support/expect_invalid_argument.hpp"
#include "support/temporary_directory.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/graphics/vtk_time_series.hpp"

#include <vtkCellArray.h>
#include <vtkDataArray.h>
#include <vtkFieldData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLDataParser.h>
#include <vtkXMLPolyDataReader.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::realtime::graphics {
namespace {

using touchstone::testing::TemporaryDirectory;
using touchstone::testing::expect_invalid_argument;
using Eigen::Vector3d;

constexpr double radius = 0.03;

geometry::TriangleSurface sphere(int level) {
  auto mesh = geometry::icosphere(level, radius);
  return geometry::TriangleSurface(mesh.vertices, mesh.triangles, "icosphere");
}

/// A deforming organ and a tool that presses it: frame k of a scripted run.
struct Scene {
  explicit Scene(const geometry::TriangleSurface& organ) : rest(organ.vertices()) {}

  GraphicsFrame make(int k) {
    displacement.assign(rest.size(), Vector3d::Zero());
    vertices = rest;
    // A dent under the tool growing with k, plus a vertex-dependent wobble so that every
    // value differs.
    for (std::size_t i = 0; i < rest.size(); ++i) {
      const double weight = std::exp(-(rest[i] - Vector3d(0, 0, radius)).squaredNorm() / (0.01 * 0.01));
      displacement[i] = wobble ? Vector3d(1e-5 * std::sin(double(i)), 1e-5 * std::cos(3.0 * i), -2e-4 * k * weight)
                               : Vector3d(0, 0, weight > 1e-3 ? -2e-4 * k * weight : 0.0);
      vertices[i] = rest[i] + displacement[i];
    }
    GraphicsFrame frame;
    frame.index = k;
    frame.time_s = k / 30.0;
    frame.organ_vertices_m = &vertices;
    frame.organ_displacement_m = &displacement;
    frame.tool_tip_m = Vector3d(0.001, 0.0, radius + 0.002 - 2e-4 * k);
    frame.tool_axis = Vector3d(0.4, 0.1, 1.0).normalized();
    frame.force_on_hand_N = Vector3d(0.05 * k, -0.01 * k, 0.3 * k);
    frame.in_contact = k > 2;
    return frame;
  }

  std::vector<Vector3d> rest, vertices, displacement;
  bool wobble = true;  ///< every vertex displaced (the worst case for compression)
};

vtkSmartPointer<vtkPolyData> read_vtp(const std::string& path) {
  EXPECT_TRUE(std::filesystem::exists(path)) << path;
  vtkNew<vtkXMLPolyDataReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  auto data = vtkSmartPointer<vtkPolyData>::New();
  data->ShallowCopy(reader->GetOutput());
  return data;
}

/// The <DataSet> elements of a PVD, after checking that it is well-formed XML and a collection.
struct PvdEntry {
  double timestep;
  std::string file;
};
std::vector<PvdEntry> read_pvd(const std::string& path) {
  vtkNew<vtkXMLDataParser> parser;
  parser->SetFileName(path.c_str());
  EXPECT_EQ(parser->Parse(), 1) << path << " is not well-formed XML";
  vtkXMLDataElement* root = parser->GetRootElement();
  std::vector<PvdEntry> entries;
  if (root == nullptr) {
    ADD_FAILURE() << path << ": no root element";
    return entries;
  }
  EXPECT_STREQ(root->GetName(), "VTKFile");
  EXPECT_STREQ(root->GetAttribute("type"), "Collection");
  vtkXMLDataElement* collection = root->FindNestedElementWithName("Collection");
  if (collection == nullptr) {
    ADD_FAILURE() << path << ": no <Collection>";
    return entries;
  }
  for (int i = 0; i < collection->GetNumberOfNestedElements(); ++i) {
    vtkXMLDataElement* dataset = collection->GetNestedElement(i);
    EXPECT_STREQ(dataset->GetName(), "DataSet");
    entries.push_back({std::stod(dataset->GetAttribute("timestep")), dataset->GetAttribute("file")});
  }
  return entries;
}

std::string padded(int index) {
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "%06d", index);
  return buffer;
}

std::int64_t directory_bytes(const std::string& directory) {
  std::int64_t bytes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(directory)) {
    if (entry.is_regular_file()) bytes += static_cast<std::int64_t>(entry.file_size());
  }
  return bytes;
}

TEST(VtkTimeSeriesSettings, ValidateNamesTheField) {
  const auto with = [](auto change) {
    VtkTimeSeriesSettings settings;
    change(settings);
    return [settings] { settings.validate(); };
  };
  EXPECT_NO_THROW(VtkTimeSeriesSettings().validate());
  expect_invalid_argument(with([](auto& s) { s.output_directory = ""; }), {"output_directory"});
  expect_invalid_argument(with([](auto& s) { s.base_name = ""; }), {"base_name"});
  expect_invalid_argument(with([](auto& s) { s.base_name = "a/b"; }), {"base_name", "a/b"});
  expect_invalid_argument(with([](auto& s) { s.frame_stride = 0; }), {"frame_stride", "0"});
  expect_invalid_argument(with([](auto& s) { s.pvd_rewrite_every = 0; }), {"pvd_rewrite_every"});
  expect_invalid_argument(with([](auto& s) { s.compression_level = 10; }), {"compression_level", "10"});
  expect_invalid_argument(with([](auto& s) { s.tool_sphere_resolution = 2; }), {"tool_sphere_resolution"});
  VtkTimeSeriesSettings bad;
  bad.frame_stride = -1;
  expect_invalid_argument([&] { VtkTimeSeriesWriter writer(bad); }, {"frame_stride", "-1"});
}

TEST(VtkTimeSeriesWriter, WritesFramesThatReadBackExactly) {
  TemporaryDirectory directory("vtk_time_series");
  const auto organ = sphere(2);
  VtkTimeSeriesSettings settings;
  settings.output_directory = directory.path("out");  // created by begin()
  settings.base_name = "run";
  settings.frame_stride = 1;
  settings.pvd_rewrite_every = 4;
  VtkTimeSeriesWriter writer(settings);
  writer.begin(organ);
  Scene scene(organ);
  constexpr int frames = 10;
  std::vector<GraphicsFrame> sent;
  for (int k = 0; k < frames; ++k) {
    const GraphicsFrame frame = scene.make(k);
    writer.frame(frame);

    // Every file as soon as it is written: points, cells and arrays exactly as sent.
    const std::string stem = settings.output_directory + "/run_";
    const auto organ_data = read_vtp(stem + "organ_" + padded(k) + ".vtp");
    ASSERT_EQ(organ_data->GetNumberOfPoints(), static_cast<vtkIdType>(organ.vertices().size()));
    ASSERT_EQ(organ_data->GetNumberOfPolys(), static_cast<vtkIdType>(organ.triangles().size()));
    vtkDataArray* displacement = organ_data->GetPointData()->GetArray("displacement_m");
    vtkDataArray* magnitude = organ_data->GetPointData()->GetArray("displacement_magnitude_m");
    ASSERT_NE(displacement, nullptr);
    ASSERT_NE(magnitude, nullptr);
    ASSERT_EQ(displacement->GetNumberOfComponents(), 3);
    for (vtkIdType i = 0; i < organ_data->GetNumberOfPoints(); ++i) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(organ_data->GetPoint(i)[c], scene.vertices[i][c], 1e-12);
        EXPECT_NEAR(displacement->GetComponent(i, c), scene.displacement[i][c], 1e-12);
      }
      EXPECT_NEAR(magnitude->GetTuple1(i), scene.displacement[i].norm(), 1e-12);
    }
    // Connectivity: the rest surface's triangles in order.
    vtkCellArray* polys = organ_data->GetPolys();
    for (vtkIdType t = 0; t < polys->GetNumberOfCells(); t += 37) {
      vtkNew<vtkIdList> ids;
      polys->GetCellAtId(t, ids);
      ASSERT_EQ(ids->GetNumberOfIds(), 3);
      for (int c = 0; c < 3; ++c) EXPECT_EQ(ids->GetId(c), organ.triangles()[t][c]);
    }
    EXPECT_DOUBLE_EQ(organ_data->GetFieldData()->GetArray("time_s")->GetTuple1(0), frame.time_s);

    const auto tool = read_vtp(stem + "tool_" + padded(k) + ".vtp");
    ASSERT_GT(tool->GetNumberOfPoints(), 10);
    EXPECT_EQ(tool->GetNumberOfVerts(), 1);
    EXPECT_GT(tool->GetNumberOfPolys(), 10);
    vtkDataArray* force = tool->GetPointData()->GetArray("force_on_hand_N");
    ASSERT_NE(force, nullptr);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(tool->GetPoint(0)[c], frame.tool_tip_m[c], 1e-12);
      EXPECT_NEAR(force->GetComponent(0, c), frame.force_on_hand_N[c], 1e-12);
    }
    double largest_elsewhere = 0, reach = 0, widest = 0;
    for (vtkIdType i = 1; i < tool->GetNumberOfPoints(); ++i) {
      for (int c = 0; c < 3; ++c) largest_elsewhere = std::max(largest_elsewhere, std::abs(force->GetComponent(i, c)));
      const Vector3d offset = Vector3d(tool->GetPoint(i)) - frame.tool_tip_m;
      const double along = offset.dot(frame.tool_axis);
      reach = std::max(reach, along);
      widest = std::max(widest, (offset - along * frame.tool_axis).norm());
    }
    EXPECT_EQ(largest_elsewhere, 0.0);  // one arrow when ParaView glyphs by the vector
    EXPECT_NEAR(reach, frame.tool_shaft_length_m, 1e-12);  // the shaft ends a shaft length up the axis
    EXPECT_NEAR(widest, std::max(frame.tool_tip_radius_m, frame.tool_shaft_radius_m), 1e-4);
    EXPECT_EQ(tool->GetFieldData()->GetArray("in_contact")->GetTuple1(0), frame.in_contact ? 1 : 0);
    EXPECT_DOUBLE_EQ(tool->GetFieldData()->GetArray("time_s")->GetTuple1(0), frame.time_s);
    EXPECT_NEAR(tool->GetFieldData()->GetArray("force_on_hand_magnitude_N")->GetTuple1(0),
                frame.force_on_hand_N.norm(), 1e-12);
    sent.push_back(frame);
  }
  // Collections rewritten after frames 1, 4 and 8 so far; end() writes the final ones.
  EXPECT_EQ(writer.pvd_rewrites(), 3);
  writer.end();
  EXPECT_TRUE(writer.last_error().empty()) << writer.last_error();
  EXPECT_EQ(writer.frames_received(), frames);
  EXPECT_EQ(writer.frames_written(), frames);
  EXPECT_EQ(writer.bytes_written(), directory_bytes(settings.output_directory));

  for (const std::string part : {"organ", "tool"}) {
    const auto entries = read_pvd(settings.output_directory + "/run_" + part + ".pvd");
    ASSERT_EQ(entries.size(), static_cast<std::size_t>(frames)) << part;
    for (int k = 0; k < frames; ++k) {
      EXPECT_EQ(entries[k].timestep, sent[k].time_s);  // written in round-trip precision
      EXPECT_EQ(entries[k].file, "run_" + part + "_" + padded(k) + ".vtp");
      EXPECT_TRUE(std::filesystem::exists(settings.output_directory + "/" + entries[k].file));
    }
  }
  for (const auto& entry : std::filesystem::directory_iterator(settings.output_directory))
    EXPECT_NE(entry.path().extension(), ".tmp") << "left behind: " << entry.path();

  // The ParaView route: python3-vtk9's readers open every dataset of both collections.
  const std::string command = "/usr/bin/python3 " + std::string(TOUCHSTONE_SOURCE_DIR) +
                              "/tests/realtime/graphics/check_vtp_series.py '" + settings.output_directory +
                              "' run " + std::to_string(frames);
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
}

TEST(VtkTimeSeriesWriter, WritesEveryStrideThFrame) {
  TemporaryDirectory directory("vtk_time_series");
  const auto organ = sphere(1);
  VtkTimeSeriesSettings settings;
  settings.output_directory = directory.path("");
  settings.base_name = "strided";
  settings.frame_stride = 3;
  VtkTimeSeriesWriter writer(settings);
  writer.begin(organ);
  Scene scene(organ);
  for (int k = 0; k < 10; ++k) writer.frame(scene.make(k));
  writer.end();
  EXPECT_EQ(writer.frames_received(), 10);
  EXPECT_EQ(writer.frames_written(), 4);  // frames 0, 3, 6, 9
  for (int k = 0; k < 10; ++k) {
    const bool written = k % 3 == 0;
    EXPECT_EQ(std::filesystem::exists(directory.path("strided_organ_" + padded(k) + ".vtp")), written) << k;
    EXPECT_EQ(std::filesystem::exists(directory.path("strided_tool_" + padded(k) + ".vtp")), written) << k;
  }
  const auto entries = read_pvd(writer.tool_pvd_path());
  ASSERT_EQ(entries.size(), 4u);
  for (int j = 0; j < 4; ++j) EXPECT_EQ(entries[j].timestep, (3 * j) / 30.0);
}

TEST(VtkTimeSeriesWriter, InterruptedRunLeavesValidCollections) {
  TemporaryDirectory directory("vtk_time_series");
  const auto organ = sphere(1);
  VtkTimeSeriesSettings settings;
  settings.output_directory = directory.path("");
  settings.base_name = "cut";
  settings.frame_stride = 1;
  settings.pvd_rewrite_every = 4;
  Scene scene(organ);
  {
    VtkTimeSeriesWriter writer(settings);
    writer.begin(organ);
    for (int k = 0; k < 6; ++k) writer.frame(scene.make(k));
    // No end(): the run stops here (a crash, a kill).
  }
  for (const std::string part : {"organ", "tool"}) {
    const auto entries = read_pvd(directory.path("cut_" + part + ".pvd"));
    ASSERT_EQ(entries.size(), 4u) << "the collection as rewritten after the 4th frame";
    for (const auto& entry : entries) {
      const auto data = read_vtp(directory.path(entry.file));
      EXPECT_GT(data->GetNumberOfPoints(), 0);
    }
  }
  const std::string command = "/usr/bin/python3 " + std::string(TOUCHSTONE_SOURCE_DIR) +
                              "/tests/realtime/graphics/check_vtp_series.py '" + directory.path("") + "' cut 4";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
}

TEST(VtkTimeSeriesWriter, BadDirectoryIsNamed) {
  TemporaryDirectory directory("vtk_time_series");
  const std::string file = directory.file("not_a_directory", "x");
  VtkTimeSeriesSettings settings;
  settings.output_directory = file + "/out";
  VtkTimeSeriesWriter writer(settings);
  try {
    writer.begin(sphere(1));
    ADD_FAILURE() << "begin() accepted a directory under a regular file";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(settings.output_directory), std::string::npos) << error.what();
  }
  // The directory vanishing during the run: the error names the file.
  VtkTimeSeriesSettings vanishing;
  vanishing.output_directory = directory.path("gone");
  vanishing.frame_stride = 1;
  VtkTimeSeriesWriter second(vanishing);
  const auto organ = sphere(1);
  second.begin(organ);
  std::filesystem::remove_all(vanishing.output_directory);
  Scene scene(organ);
  try {
    second.frame(scene.make(0));
    ADD_FAILURE() << "frame() wrote into a removed directory";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(vanishing.output_directory + "/touchstone_organ_000000.vtp"),
              std::string::npos)
        << error.what();
  }
  second.end();
  EXPECT_NE(second.last_error().find("touchstone_organ.pvd"), std::string::npos) << second.last_error();
}

TEST(VtkTimeSeriesWriter, RejectsFramesThatDoNotMatchTheOrgan) {
  TemporaryDirectory directory("vtk_time_series");
  const auto organ = sphere(1);
  VtkTimeSeriesSettings settings;
  settings.output_directory = directory.path("");
  settings.frame_stride = 1;
  VtkTimeSeriesWriter writer(settings);
  writer.begin(organ);
  Scene scene(organ);
  GraphicsFrame frame = scene.make(0);
  std::vector<Vector3d> short_list(5, Vector3d::Zero());
  frame.organ_vertices_m = &short_list;
  expect_invalid_argument([&] { writer.frame(frame); }, {"organ_vertices_m", "5", "42"});
  frame = scene.make(1);
  frame.organ_displacement_m = nullptr;
  expect_invalid_argument([&] { writer.frame(frame); }, {"organ_displacement_m", "null"});
  writer.frame(scene.make(3));
  expect_invalid_argument([&] { writer.frame(scene.make(3)); }, {"frame index 3"});
  writer.end();
}

// A one-minute run at 30 Hz with the default stride stays far from gigabytes for an organ of
// ~20,000 triangles; prints the cost of one written frame (not asserted: unit tests never assert
// wall-clock times).
TEST(VtkTimeSeriesWriter, DefaultStrideKeepsAMinuteSmall) {
  TemporaryDirectory directory("vtk_time_series");
  const auto organ = sphere(5);  // 20,480 triangles
  VtkTimeSeriesSettings settings;
  settings.output_directory = directory.path("");
  VtkTimeSeriesWriter writer(settings);
  writer.begin(organ);
  Scene scene(organ);
  scene.wobble = false;  // as in a run: zero displacement outside the local domain
  constexpr int frames = 12;
  for (int k = 0; k < frames; ++k) writer.frame(scene.make(k));
  writer.end();
  const double bytes_per_written = double(writer.bytes_written()) / writer.frames_written();
  const double minute_bytes = bytes_per_written * 60 * 30 / settings.frame_stride;
  std::cout << "[ info ] " << organ.triangles().size() << " triangles: " << bytes_per_written / 1024
            << " KiB per written frame, " << minute_bytes / (1 << 20) << " MiB per minute at stride "
            << settings.frame_stride << " (the time per frame: graphics_benchmark)\n";
  EXPECT_EQ(writer.frames_written(), frames / settings.frame_stride);
  EXPECT_LT(minute_bytes, 0.5e9);
}

}  // namespace
}  // namespace touchstone::realtime::graphics
