// Point fields in VTK unstructured grids (meshes/point_field_vtu): what the study runner uses to
// put the MFS field on the FEM reference's mesh. Round trips through VTK's own XML readers.
#include "touchstone/meshes/point_field_vtu.hpp"

#include "support/temporary_directory.hpp"

#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <gtest/gtest.h>

#include <filesystem>

namespace touchstone::meshes {
namespace {

/// Two tetrahedra sharing a face, with u = (x, 2y, 3z) as `displacement_m` and a scalar.
std::string write_grid(const touchstone::testing::TemporaryDirectory& directory, int components = 3) {
  vtkNew<vtkPoints> points;
  const double xyz[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  for (const auto& p : xyz) points->InsertNextPoint(p);
  vtkNew<vtkUnstructuredGrid> grid;
  grid->SetPoints(points);
  const vtkIdType a[4] = {0, 1, 2, 3}, b[4] = {1, 2, 3, 4};
  grid->InsertNextCell(VTK_TETRA, 4, a);
  grid->InsertNextCell(VTK_TETRA, 4, b);
  vtkNew<vtkDoubleArray> u;
  u->SetName("displacement_m");
  u->SetNumberOfComponents(components);
  u->SetNumberOfTuples(5);
  for (vtkIdType i = 0; i < 5; ++i)
    for (int k = 0; k < components; ++k) u->SetComponent(i, k, (k + 1) * xyz[i][k % 3]);
  grid->GetPointData()->AddArray(u);
  const std::string path = directory.path("grid.vtu");
  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  writer->SetFileName(path.c_str());
  writer->SetInputData(grid);
  writer->Write();
  return path;
}

TEST(PointFieldVtu, ReadsPointsAndAVectorArray) {
  touchstone::testing::TemporaryDirectory directory("point_field");
  const PointField field = read_point_field(write_grid(directory), "displacement_m");
  ASSERT_EQ(field.points_m.size(), 5U);
  EXPECT_EQ(field.points_m[4], Eigen::Vector3d(1, 1, 1));
  EXPECT_EQ(field.values[4], Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(field.values[2], Eigen::Vector3d(0, 2, 0));
}

TEST(PointFieldVtu, WritesTheGridWithExtraArraysThatReadBackExactly) {
  touchstone::testing::TemporaryDirectory directory("point_field");
  const std::string grid = write_grid(directory);
  std::vector<Eigen::Vector3d> extra(5);
  std::vector<double> mask(5);
  for (int i = 0; i < 5; ++i) {
    extra[i] = Eigen::Vector3d(0.1 * i, -1e-7 * i, 1.0 / 3.0);
    mask[i] = i % 2;
  }
  const std::string out = directory.path("out.vtu");
  write_with_point_arrays(grid, out, {{"mfs_displacement_m", extra}}, {{"in_local_domain", mask}});
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  reader->SetFileName(out.c_str());
  reader->Update();
  vtkUnstructuredGrid* read = reader->GetOutput();
  ASSERT_EQ(read->GetNumberOfPoints(), 5);
  EXPECT_EQ(read->GetNumberOfCells(), 2) << "the cells come along";
  ASSERT_NE(read->GetPointData()->GetArray("displacement_m"), nullptr) << "and the reference's arrays";
  const PointField back = read_point_field(out, "mfs_displacement_m");
  for (int i = 0; i < 5; ++i) EXPECT_EQ(back.values[i], extra[i]);
  vtkDataArray* scalars = read->GetPointData()->GetArray("in_local_domain");
  ASSERT_NE(scalars, nullptr);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(scalars->GetTuple1(i), i % 2);
}

// The grid is written beside the target and renamed into place; a write that cannot finish (here
// the target is a folder) names the file and leaves nothing behind, and the temporary never ends
// in .vtu (a run killed mid-write must not leave a file ParaView takes for a result).
TEST(PointFieldVtu, AFailedWriteLeavesNothingBehind) {
  touchstone::testing::TemporaryDirectory directory("point_field");
  const std::string grid = write_grid(directory);
  const std::string out = directory.path("taken.vtu");
  std::filesystem::create_directory(out);
  const std::vector<double> mask(5, 1.0);
  try {
    write_with_point_arrays(grid, out, {}, {{"in_local_domain", mask}});
    ADD_FAILURE() << "writing over a folder did not fail";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("taken.vtu"), std::string::npos) << e.what();
  }
  for (const auto& entry : std::filesystem::directory_iterator(directory.path("")))
    EXPECT_EQ(entry.path().string().find(".partial"), std::string::npos) << entry.path();
  EXPECT_TRUE(std::filesystem::is_directory(out));
}

TEST(PointFieldVtu, ErrorsNameTheFileAndTheArray) {
  touchstone::testing::TemporaryDirectory directory("point_field");
  const auto expect_error = [](const std::function<void()>& action, const std::string& fragment) {
    try {
      action();
      ADD_FAILURE() << "no error; expected one mentioning " << fragment;
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  const std::string grid = write_grid(directory);
  expect_error([&] { read_point_field(directory.path("missing.vtu"), "displacement_m"); }, "missing.vtu");
  expect_error([&] { read_point_field(grid, "velocity"); }, "'velocity'");
  const std::string scalar_grid = [&] {
    touchstone::testing::TemporaryDirectory other("point_field_scalar");
    const std::string path = write_grid(other, 1);
    const std::string copy = directory.path("scalar.vtu");
    std::filesystem::copy_file(path, copy);
    return copy;
  }();
  expect_error([&] { read_point_field(scalar_grid, "displacement_m"); }, "1 components");
  expect_error([&] { write_with_point_arrays(grid, directory.path("x.vtu"), {{"short", {Eigen::Vector3d::Zero()}}}, {}); },
               "'short' has 1 values for 5 points");
  expect_error([&] { read_point_field(directory.file("text.vtu", "not xml"), "displacement_m"); }, "text.vtu");
}

}  // namespace
}  // namespace touchstone::meshes
