#include "touchstone/realtime/graphics/vtk_time_series.hpp"

#include "vtk_error_collector.hpp"

#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkErrorCode.h>
#include <vtkExecutive.h>
#include <vtkFieldData.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkXMLPolyDataWriter.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <system_error>
#include <type_traits>
#include <unistd.h>

namespace touchstone::realtime::graphics {
namespace {

constexpr double pi = 3.14159265358979323846;

/// Shortest decimal that reads back as the same double.
std::string format_double(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

std::string xml_escape(const std::string& text) {
  std::string escaped;
  for (const char c : text) {
    switch (c) {
      case '&': escaped += "&amp;"; break;
      case '<': escaped += "&lt;"; break;
      case '>': escaped += "&gt;"; break;
      case '"': escaped += "&quot;"; break;
      case '\'': escaped += "&apos;"; break;
      default: escaped += c;
    }
  }
  return escaped;
}

std::string padded(int index) {
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "%06d", index);
  return buffer;
}

std::int64_t file_size_or_zero(const std::string& path) {
  std::error_code error;
  const auto size = std::filesystem::file_size(path, error);
  return error ? 0 : static_cast<std::int64_t>(size);
}

template <typename T>
void set_field(vtkFieldData* data, const char* name, T value) {
  auto* array = data->GetAbstractArray(name);
  if constexpr (std::is_same_v<T, int>) {
    static_cast<vtkIntArray*>(array)->SetValue(0, value);
  } else {
    static_cast<vtkDoubleArray*>(array)->SetValue(0, value);
  }
}

template <typename Array>
void add_field(vtkFieldData* data, const char* name) {
  vtkNew<Array> array;
  array->SetName(name);
  array->SetNumberOfTuples(1);
  array->SetValue(0, 0);
  data->AddArray(array);
}

vtkSmartPointer<vtkDoubleArray> point_array(const char* name, int components, vtkIdType points) {
  auto array = vtkSmartPointer<vtkDoubleArray>::New();
  array->SetName(name);
  array->SetNumberOfComponents(components);
  array->SetNumberOfTuples(points);
  array->Fill(0);
  return array;
}

vtkSmartPointer<vtkXMLPolyDataWriter> make_writer(vtkPolyData* data, int compression_level, ErrorCollector* errors) {
  auto writer = vtkSmartPointer<vtkXMLPolyDataWriter>::New();
  writer->SetInputData(data);
  writer->SetDataModeToAppended();
  writer->EncodeAppendedDataOff();
  writer->SetCompressorTypeToZLib();
  writer->SetCompressionLevel(compression_level);
  writer->SetHeaderTypeToUInt64();
  writer->SetIdTypeToInt32();
  writer->AddObserver(vtkCommand::ErrorEvent, errors);
  writer->GetExecutive()->AddObserver(vtkCommand::ErrorEvent, errors);
  return writer;
}

}  // namespace

struct VtkTimeSeriesWriter::Vtk {
  vtkNew<vtkPolyData> organ;
  vtkSmartPointer<vtkDoubleArray> displacement, magnitude;
  vtkNew<vtkPolyData> tool;
  vtkSmartPointer<vtkDoubleArray> force;
  vtkNew<ErrorCollector> errors;
  vtkSmartPointer<vtkXMLPolyDataWriter> organ_writer, tool_writer;
  /// The tool's points in its own frame (tip at the origin, axis e_z), placed per frame by
  /// part: the centre stays at the tip, sphere points are unit directions scaled by the tip
  /// radius, shaft points are (cos, sin, end) scaled by the shaft radius and length.
  struct ToolPoint {
    enum Part { centre, sphere, shaft } part;
    Eigen::Vector3d local;
  };
  std::vector<ToolPoint> tool_points;
};

void VtkTimeSeriesSettings::validate() const {
  const auto reject = [](const std::string& field, const std::string& value, const std::string& rule) {
    throw std::invalid_argument("VtkTimeSeriesSettings." + field + " = " + value + " " + rule);
  };
  if (output_directory.empty()) reject("output_directory", "\"\"", "must not be empty");
  if (base_name.empty()) reject("base_name", "\"\"", "must not be empty");
  if (base_name.find('/') != std::string::npos || base_name.find('\0') != std::string::npos)
    reject("base_name", "\"" + base_name + "\"", "must be a file name prefix without '/'");
  if (frame_stride < 1) reject("frame_stride", std::to_string(frame_stride), "must be >= 1");
  if (pvd_rewrite_every < 1) reject("pvd_rewrite_every", std::to_string(pvd_rewrite_every), "must be >= 1");
  if (compression_level < 1 || compression_level > 9)
    reject("compression_level", std::to_string(compression_level), "must be in [1, 9]");
  if (tool_sphere_resolution < 3 || tool_sphere_resolution > 256)
    reject("tool_sphere_resolution", std::to_string(tool_sphere_resolution), "must be in [3, 256]");
}

VtkTimeSeriesWriter::VtkTimeSeriesWriter(const VtkTimeSeriesSettings& settings) : settings_(settings) {
  settings_.validate();
}

VtkTimeSeriesWriter::~VtkTimeSeriesWriter() = default;

std::string VtkTimeSeriesWriter::path(const std::string& file_name) const {
  return (std::filesystem::path(settings_.output_directory) / file_name).string();
}

std::string VtkTimeSeriesWriter::organ_pvd_path() const { return path(settings_.base_name + "_organ.pvd"); }
std::string VtkTimeSeriesWriter::tool_pvd_path() const { return path(settings_.base_name + "_tool.pvd"); }

void VtkTimeSeriesWriter::begin(const geometry::TriangleSurface& organ) {
  const std::string& directory = settings_.output_directory;
  const std::string where = "VtkTimeSeriesWriter: output directory '" + directory + "'";
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error) throw std::runtime_error(where + " cannot be created: " + error.message());
  if (!std::filesystem::is_directory(directory, error))
    throw std::runtime_error(where + " is not a directory");
  // A probe file: a directory may exist and still refuse writes.
  const std::string probe = path("." + settings_.base_name + "_probe_" + std::to_string(::getpid()));
  {
    std::ofstream stream(probe, std::ios::binary);
    stream << "probe";
    if (!stream) throw std::runtime_error(where + " is not writable (cannot create '" + probe + "')");
  }
  std::filesystem::remove(probe, error);

  vtk_ = std::make_unique<Vtk>();
  Vtk& v = *vtk_;

  // The organ: points and triangles once, arrays filled per frame.
  const auto& vertices = organ.vertices();
  vertex_count_ = vertices.size();
  const auto n = static_cast<vtkIdType>(vertex_count_);
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(n);
  for (vtkIdType i = 0; i < n; ++i) points->SetPoint(i, vertices[i].data());
  vtkNew<vtkCellArray> triangles;
  triangles->AllocateExact(static_cast<vtkIdType>(organ.triangles().size()),
                           3 * static_cast<vtkIdType>(organ.triangles().size()));
  for (const Eigen::Vector3i& t : organ.triangles()) {
    const vtkIdType ids[3] = {t[0], t[1], t[2]};
    triangles->InsertNextCell(3, ids);
  }
  v.organ->SetPoints(points);
  v.organ->SetPolys(triangles);
  v.displacement = point_array("displacement_m", 3, n);
  v.magnitude = point_array("displacement_magnitude_m", 1, n);
  v.organ->GetPointData()->AddArray(v.displacement);
  v.organ->GetPointData()->AddArray(v.magnitude);
  v.organ->GetPointData()->SetActiveVectors("displacement_m");
  v.organ->GetPointData()->SetActiveScalars("displacement_magnitude_m");
  add_field<vtkDoubleArray>(v.organ->GetFieldData(), "time_s");
  add_field<vtkIntArray>(v.organ->GetFieldData(), "frame_index");

  // The tool: the tip centre (a vertex of its own, carrying the force), a latitude–longitude
  // sphere with poles on the axis, and a capped cylinder from the tip along the axis.
  const int around = settings_.tool_sphere_resolution;
  const int rings = std::max(2, around / 2);  // latitude bands
  auto& tp = v.tool_points;
  tp.push_back({Vtk::ToolPoint::centre, Eigen::Vector3d::Zero()});
  tp.push_back({Vtk::ToolPoint::sphere, Eigen::Vector3d::UnitZ()});
  for (int ring = 1; ring < rings; ++ring) {
    const double polar = pi * ring / rings;
    for (int k = 0; k < around; ++k) {
      const double azimuth = 2 * pi * k / around;
      tp.push_back({Vtk::ToolPoint::sphere, {std::sin(polar) * std::cos(azimuth),
                                             std::sin(polar) * std::sin(azimuth), std::cos(polar)}});
    }
  }
  tp.push_back({Vtk::ToolPoint::sphere, -Eigen::Vector3d::UnitZ()});
  const vtkIdType north = 1, south = static_cast<vtkIdType>(tp.size()) - 1;
  const auto ring_point = [&](int ring, int k) -> vtkIdType { return 2 + (ring - 1) * around + (k % around); };
  const vtkIdType shaft_start = static_cast<vtkIdType>(tp.size());
  for (int end = 0; end < 2; ++end) {
    for (int k = 0; k < around; ++k) {
      const double azimuth = 2 * pi * k / around;
      tp.push_back({Vtk::ToolPoint::shaft, {std::cos(azimuth), std::sin(azimuth), double(end)}});
    }
  }
  const auto shaft_point = [&](int end, int k) -> vtkIdType { return shaft_start + end * around + (k % around); };

  vtkNew<vtkCellArray> tool_vertices, tool_polys;
  const vtkIdType centre = 0;
  tool_vertices->InsertNextCell(1, &centre);
  for (int k = 0; k < around; ++k) {
    // Counter-clockwise seen from outside.
    const vtkIdType cap_north[3] = {north, ring_point(1, k), ring_point(1, k + 1)};
    tool_polys->InsertNextCell(3, cap_north);
    for (int ring = 1; ring + 1 < rings; ++ring) {
      const vtkIdType quad[4] = {ring_point(ring, k), ring_point(ring + 1, k), ring_point(ring + 1, k + 1),
                                 ring_point(ring, k + 1)};
      tool_polys->InsertNextCell(4, quad);
    }
    const vtkIdType cap_south[3] = {south, ring_point(rings - 1, k + 1), ring_point(rings - 1, k)};
    tool_polys->InsertNextCell(3, cap_south);
    const vtkIdType side[4] = {shaft_point(0, k), shaft_point(0, k + 1), shaft_point(1, k + 1), shaft_point(1, k)};
    tool_polys->InsertNextCell(4, side);
  }
  std::vector<vtkIdType> cap(around);
  for (int k = 0; k < around; ++k) cap[k] = shaft_point(1, k);
  tool_polys->InsertNextCell(around, cap.data());
  for (int k = 0; k < around; ++k) cap[k] = shaft_point(0, around - k);
  tool_polys->InsertNextCell(around, cap.data());

  vtkNew<vtkPoints> tool_points;
  tool_points->SetDataTypeToDouble();
  tool_points->SetNumberOfPoints(static_cast<vtkIdType>(tp.size()));
  v.tool->SetPoints(tool_points);
  v.tool->SetVerts(tool_vertices);
  v.tool->SetPolys(tool_polys);
  v.force = point_array("force_on_hand_N", 3, static_cast<vtkIdType>(tp.size()));
  v.tool->GetPointData()->AddArray(v.force);
  v.tool->GetPointData()->SetActiveVectors("force_on_hand_N");
  add_field<vtkDoubleArray>(v.tool->GetFieldData(), "time_s");
  add_field<vtkIntArray>(v.tool->GetFieldData(), "frame_index");
  add_field<vtkIntArray>(v.tool->GetFieldData(), "in_contact");
  add_field<vtkDoubleArray>(v.tool->GetFieldData(), "force_on_hand_magnitude_N");

  v.organ_writer = make_writer(v.organ, settings_.compression_level, v.errors);
  v.tool_writer = make_writer(v.tool, settings_.compression_level, v.errors);

  entries_.clear();
  frames_received_ = frames_written_ = bytes_written_ = pvd_bytes_ = pvd_rewrites_ = 0;
  last_index_ = -1;
  last_error_.clear();
  begun_ = true;
}

void VtkTimeSeriesWriter::frame(const GraphicsFrame& frame) {
  if (!begun_) throw std::logic_error("VtkTimeSeriesWriter: frame() before begin()");
  const bool due = frames_received_ % settings_.frame_stride == 0;
  ++frames_received_;
  if (!due) return;

  const auto check = [&](const std::vector<Eigen::Vector3d>* array, const char* name) {
    if (array == nullptr)
      throw std::invalid_argument("VtkTimeSeriesWriter: frame " + std::to_string(frame.index) + ": " + name +
                                  " is null");
    if (array->size() != vertex_count_)
      throw std::invalid_argument("VtkTimeSeriesWriter: frame " + std::to_string(frame.index) + ": " + name +
                                  " has " + std::to_string(array->size()) + " vertices, the organ has " +
                                  std::to_string(vertex_count_));
  };
  check(frame.organ_vertices_m, "organ_vertices_m");
  check(frame.organ_displacement_m, "organ_displacement_m");
  if (frame.index <= last_index_)
    throw std::invalid_argument("VtkTimeSeriesWriter: frame index " + std::to_string(frame.index) +
                                " after " + std::to_string(last_index_) + " (indices name files: they must increase)");

  const std::string organ_file = settings_.base_name + "_organ_" + padded(frame.index) + ".vtp";
  const std::string tool_file = settings_.base_name + "_tool_" + padded(frame.index) + ".vtp";
  write_organ(frame, organ_file);
  write_tool(frame, tool_file);
  last_index_ = frame.index;
  entries_.push_back({frame.time_s, organ_file, tool_file});
  ++frames_written_;
  if (frames_written_ == 1 || frames_written_ % settings_.pvd_rewrite_every == 0) write_collections();
}

void VtkTimeSeriesWriter::write_organ(const GraphicsFrame& frame, const std::string& file_name) {
  Vtk& v = *vtk_;
  const auto& x = *frame.organ_vertices_m;
  const auto& u = *frame.organ_displacement_m;
  auto* points = static_cast<vtkDoubleArray*>(v.organ->GetPoints()->GetData());
  double* p = points->GetPointer(0);
  double* d = v.displacement->GetPointer(0);
  double* m = v.magnitude->GetPointer(0);
  for (std::size_t i = 0; i < vertex_count_; ++i) {
    for (int c = 0; c < 3; ++c) {
      p[3 * i + c] = x[i][c];
      d[3 * i + c] = u[i][c];
    }
    m[i] = u[i].norm();
  }
  points->Modified();
  v.organ->GetPoints()->Modified();
  v.displacement->Modified();
  v.magnitude->Modified();
  set_field(v.organ->GetFieldData(), "time_s", frame.time_s);
  set_field(v.organ->GetFieldData(), "frame_index", frame.index);
  v.organ->Modified();

  const std::string file = path(file_name);
  v.errors->message.clear();
  v.organ_writer->SetFileName(file.c_str());
  if (v.organ_writer->Write() != 1 || v.organ_writer->GetErrorCode() != vtkErrorCode::NoError)
    throw std::runtime_error("VtkTimeSeriesWriter: cannot write '" + file + "': " +
                             vtkErrorCode::GetStringFromErrorCode(v.organ_writer->GetErrorCode()) + " " +
                             v.errors->message);
  bytes_written_ += file_size_or_zero(file);
}

void VtkTimeSeriesWriter::write_tool(const GraphicsFrame& frame, const std::string& file_name) {
  Vtk& v = *vtk_;
  // An orthonormal frame (e1, e2, axis) of the tool.
  Eigen::Vector3d axis = frame.tool_axis;
  axis = axis.norm() > 0 ? Eigen::Vector3d(axis.normalized()) : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d helper = std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = axis.cross(helper).normalized();
  const Eigen::Vector3d e2 = axis.cross(e1);
  auto* points = static_cast<vtkDoubleArray*>(v.tool->GetPoints()->GetData());
  double* p = points->GetPointer(0);
  for (std::size_t i = 0; i < v.tool_points.size(); ++i) {
    const auto& point = v.tool_points[i];
    Eigen::Vector3d world = frame.tool_tip_m;
    if (point.part == Vtk::ToolPoint::sphere) {
      world += frame.tool_tip_radius_m * (point.local.x() * e1 + point.local.y() * e2 + point.local.z() * axis);
    } else if (point.part == Vtk::ToolPoint::shaft) {
      world += frame.tool_shaft_radius_m * (point.local.x() * e1 + point.local.y() * e2) +
               frame.tool_shaft_length_m * point.local.z() * axis;
    }
    for (int c = 0; c < 3; ++c) p[3 * i + c] = world[c];
  }
  points->Modified();
  v.tool->GetPoints()->Modified();
  for (int c = 0; c < 3; ++c) v.force->SetComponent(0, c, frame.force_on_hand_N[c]);
  v.force->Modified();
  set_field(v.tool->GetFieldData(), "time_s", frame.time_s);
  set_field(v.tool->GetFieldData(), "frame_index", frame.index);
  set_field(v.tool->GetFieldData(), "in_contact", frame.in_contact ? 1 : 0);
  set_field(v.tool->GetFieldData(), "force_on_hand_magnitude_N", frame.force_on_hand_N.norm());
  v.tool->Modified();

  const std::string file = path(file_name);
  v.errors->message.clear();
  v.tool_writer->SetFileName(file.c_str());
  if (v.tool_writer->Write() != 1 || v.tool_writer->GetErrorCode() != vtkErrorCode::NoError)
    throw std::runtime_error("VtkTimeSeriesWriter: cannot write '" + file + "': " +
                             vtkErrorCode::GetStringFromErrorCode(v.tool_writer->GetErrorCode()) + " " +
                             v.errors->message);
  bytes_written_ += file_size_or_zero(file);
}

void VtkTimeSeriesWriter::write_collections() {
  // Write to a temporary file in the same directory, then rename it over the collection:
  // rename is atomic, so a reader (or an interrupted run) never sees a half-written PVD.
  std::int64_t bytes = 0;
  for (const bool organ : {true, false}) {
    const std::string file = organ ? organ_pvd_path() : tool_pvd_path();
    const std::string temporary = file + ".tmp";
    {
      std::ofstream stream(temporary, std::ios::binary | std::ios::trunc);
      if (!stream) throw std::runtime_error("VtkTimeSeriesWriter: cannot write '" + temporary + "'");
      stream << "<?xml version=\"1.0\"?>\n"
                "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
                "  <Collection>\n";
      for (const Entry& entry : entries_) {
        stream << "    <DataSet timestep=\"" << format_double(entry.time_s) << "\" group=\"\" part=\"0\" file=\""
               << xml_escape(organ ? entry.organ_file : entry.tool_file) << "\"/>\n";
      }
      stream << "  </Collection>\n"
                "</VTKFile>\n";
      stream.close();
      if (!stream) throw std::runtime_error("VtkTimeSeriesWriter: cannot write '" + temporary + "'");
    }
    std::error_code error;
    std::filesystem::rename(temporary, file, error);
    if (error)
      throw std::runtime_error("VtkTimeSeriesWriter: cannot rename '" + temporary + "' to '" + file +
                               "': " + error.message());
    bytes += file_size_or_zero(file);
  }
  bytes_written_ += bytes - pvd_bytes_;
  pvd_bytes_ = bytes;
  ++pvd_rewrites_;
}

void VtkTimeSeriesWriter::end() noexcept {
  if (!begun_) return;
  begun_ = false;
  try {
    write_collections();
  } catch (const std::exception& error) {
    last_error_ = error.what();
  }
}

}  // namespace touchstone::realtime::graphics
