#include "touchstone/meshes/point_field_vtu.hpp"

#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLPUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <filesystem>
#include <stdexcept>

namespace touchstone::meshes {

namespace {

vtkSmartPointer<vtkUnstructuredGrid> read_grid(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error(path + ": no such file");
  vtkSmartPointer<vtkUnstructuredGrid> grid;
  if (std::filesystem::path(path).extension() == ".pvtu") {
    vtkNew<vtkXMLPUnstructuredGridReader> reader;
    reader->SetFileName(path.c_str());
    reader->Update();
    grid = reader->GetOutput();
  } else {
    vtkNew<vtkXMLUnstructuredGridReader> reader;
    reader->SetFileName(path.c_str());
    reader->Update();
    grid = reader->GetOutput();
  }
  if (grid == nullptr || grid->GetNumberOfPoints() == 0) throw std::runtime_error(path + ": no points (not a VTK unstructured grid?)");
  return grid;
}

}  // namespace

PointField read_point_field(const std::string& path, const std::string& array_name) {
  const auto grid = read_grid(path);
  vtkDataArray* array = grid->GetPointData()->GetArray(array_name.c_str());
  if (array == nullptr) throw std::runtime_error(path + ": no point array '" + array_name + "'");
  if (array->GetNumberOfComponents() != 3)
    throw std::runtime_error(path + ": point array '" + array_name + "' has " +
                             std::to_string(array->GetNumberOfComponents()) + " components, not 3");
  PointField field;
  const vtkIdType count = grid->GetNumberOfPoints();
  field.points_m.resize(static_cast<std::size_t>(count));
  field.values.resize(static_cast<std::size_t>(count));
  for (vtkIdType i = 0; i < count; ++i) {
    grid->GetPoint(i, field.points_m[static_cast<std::size_t>(i)].data());
    array->GetTuple(i, field.values[static_cast<std::size_t>(i)].data());
  }
  return field;
}

void write_with_point_arrays(const std::string& reference_path, const std::string& output_vtu,
                             const std::vector<std::pair<std::string, std::vector<Eigen::Vector3d>>>& vectors,
                             const std::vector<std::pair<std::string, std::vector<double>>>& scalars) {
  const auto grid = read_grid(reference_path);
  const auto count = static_cast<std::size_t>(grid->GetNumberOfPoints());
  for (const auto& [name, values] : vectors) {
    if (values.size() != count)
      throw std::invalid_argument("write_with_point_arrays: '" + name + "' has " + std::to_string(values.size()) +
                                  " values for " + std::to_string(count) + " points of " + reference_path);
    vtkNew<vtkDoubleArray> array;
    array->SetName(name.c_str());
    array->SetNumberOfComponents(3);
    array->SetNumberOfTuples(static_cast<vtkIdType>(count));
    for (std::size_t i = 0; i < count; ++i) array->SetTuple(static_cast<vtkIdType>(i), values[i].data());
    grid->GetPointData()->AddArray(array);
  }
  for (const auto& [name, values] : scalars) {
    if (values.size() != count)
      throw std::invalid_argument("write_with_point_arrays: '" + name + "' has " + std::to_string(values.size()) +
                                  " values for " + std::to_string(count) + " points of " + reference_path);
    vtkNew<vtkDoubleArray> array;
    array->SetName(name.c_str());
    array->SetNumberOfTuples(static_cast<vtkIdType>(count));
    for (std::size_t i = 0; i < count; ++i) array->SetValue(static_cast<vtkIdType>(i), values[i]);
    grid->GetPointData()->AddArray(array);
  }
  // Written beside the target and renamed into place. The temporary's name does not end in .vtu:
  // a run killed mid-write leaves nothing that ParaView or a glob for *.vtu would take for a
  // result, and the next write of the same file replaces it.
  const std::string temporary = output_vtu + ".partial";
  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  writer->SetFileName(temporary.c_str());
  writer->SetInputData(grid);
  writer->SetDataModeToAppended();
  writer->SetCompressorTypeToZLib();
  std::error_code error;
  if (writer->Write() != 1) {
    std::filesystem::remove(temporary, error);
    throw std::runtime_error(output_vtu + ": cannot write");
  }
  std::filesystem::rename(temporary, output_vtu, error);
  if (error) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw std::runtime_error(output_vtu + ": cannot write (renaming '" + temporary + "' failed: " + error.message() + ")");
  }
}

}  // namespace touchstone::meshes
