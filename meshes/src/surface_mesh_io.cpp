// Surface meshes in five formats behind one read and one write (one file: the formats share the
// welding, unit scaling, triangulation of polygons and the error naming by file and element).
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/geometry/regular_file.hpp"

#include "text_of.hpp"
#include "vtk_file_checks.hpp"
#include "touchstone/meshes/msh_reader.hpp"

#include <Eigen/Geometry>
#include <vtkAlgorithm.h>
#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkExecutive.h>
#include <vtkIdList.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkOBJWriter.h>
#include <vtkPoints.h>
#include <vtkDoubleArray.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkPolyDataReader.h>
#include <vtkPolyDataWriter.h>
#include <vtkPolygon.h>
#include <vtkSTLReader.h>
#include <vtkSTLWriter.h>
#include <vtkSmartPointer.h>
#include <vtkObjectFactory.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>
#include <vtksys/SystemTools.hxx>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <limits>
#include <mutex>
#include <new>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::meshes {

namespace {

using Eigen::Vector3d;
using Eigen::Vector3i;
using geometry::SurfaceLabels;

using internal::check_binary_stl_size;
using internal::check_legacy_declared_sizes;
using internal::check_xml_declared_sizes;
using internal::max_xml_bytes_per_file_byte;
using internal::text_of;

std::string lower_case(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::invalid_argument(path + ": " + what);
}

// ---------------------------------------------------------------------------------------------
// VTK reports problems through vtkErrorMacro, which prints to stderr and leaves the output
// empty or partial. An observer on the algorithm and its executive receives the text instead
// (which stops the printing) without replacing VTK's process-wide output window; the errors
// become exceptions, the warnings are dropped.

class VtkMessages : public vtkCommand {
 public:
  static VtkMessages* New() { return new VtkMessages; }
  void Execute(vtkObject*, unsigned long event, void* data) override {
    if (event == vtkCommand::ErrorEvent) errors_.push_back(clean(data ? static_cast<const char*>(data) : ""));
  }
  /// Observes `algorithm` and its executive.
  void watch(vtkAlgorithm* algorithm) {
    for (vtkObject* object : {static_cast<vtkObject*>(algorithm), static_cast<vtkObject*>(algorithm->GetExecutive())}) {
      object->AddObserver(vtkCommand::ErrorEvent, this);
      object->AddObserver(vtkCommand::WarningEvent, this);
    }
  }
  bool failed() const { return !errors_.empty(); }
  /// The first error (the cause; later ones are the pipeline reporting the failure).
  std::string first_error() const { return errors_.empty() ? std::string() : errors_.front(); }

 private:
  /// "ERROR: In file.cxx, line 12\nvtkOBJReader (0x...): text\n\n" → "text".
  static std::string clean(std::string text) {
    const std::size_t line_break = text.find('\n');
    if (text.rfind("ERROR: In ", 0) == 0 || text.rfind("Warning: In ", 0) == 0) {
      text = line_break == std::string::npos ? std::string() : text.substr(line_break + 1);
    }
    const std::size_t object = text.find("): ");
    if (object != std::string::npos && object < 80) text = text.substr(object + 3);
    const std::size_t end = text.find_last_not_of(" \n\r\t");
    text = end == std::string::npos ? std::string() : text.substr(0, end + 1);
    const std::size_t first_line = text.find('\n');
    return first_line == std::string::npos ? text : text.substr(0, first_line);
  }

  std::vector<std::string> errors_;
};

/// Generic warnings (vtkGenericWarningMacro, e.g. "Error reading binary data!" from the legacy
/// reader) have no object to observe and go straight to VTK's logger on stderr. While a reader
/// or writer runs, the logger's stderr output is off; they are serialised so that the saved
/// level is the one restored. (VTK has no getter for the stderr level: the current cutoff is restored,
/// which is the stderr level unless a log file with another level is open.)
class QuietVtkLogger {
 public:
  QuietVtkLogger() : lock_(mutex()), saved_(vtkLogger::GetCurrentVerbosityCutoff()) {
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
  }
  ~QuietVtkLogger() { vtkLogger::SetStderrVerbosity(saved_); }
  QuietVtkLogger(const QuietVtkLogger&) = delete;
  QuietVtkLogger& operator=(const QuietVtkLogger&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex instance;
    return instance;
  }
  std::lock_guard<std::mutex> lock_;
  vtkLogger::Verbosity saved_;
};

/// Runs a reader and returns its output; any VTK error becomes std::invalid_argument.
template <class Reader>
vtkSmartPointer<vtkPolyData> run_reader(Reader* reader, vtkNew<VtkMessages>& messages, const std::string& path,
                                        const char* what) {
  reader->SetFileName(path.c_str());
  {
    const QuietVtkLogger quiet;
    reader->Update();
  }
  if (messages->failed()) fail(path, std::string("cannot read the ") + what + " file: " + messages->first_error());
  vtkSmartPointer<vtkPolyData> output = reader->GetOutput();
  if (output == nullptr) fail(path, std::string("cannot read the ") + what + " file");
  return output;
}

/// The file's size; std::invalid_argument when it is missing or not a regular file.
std::uintmax_t require_file(const std::string& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (error || !std::filesystem::exists(status)) fail(path, "cannot open the file (it does not exist)");
  if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
    fail(path, "cannot open the file (" + reason + ")");
  const std::uintmax_t size = std::filesystem::file_size(path, error);
  if (error) fail(path, "cannot open the file (" + error.message() + ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, std::string("cannot open the file (") + std::strerror(errno) + ")");
  if (size == 0) fail(path, "the file is empty");
  return size;
}

// ---------------------------------------------------------------------------------------------
// Polygons → triangles, each piece keeping the polygon's number in the file.

/// Splits polygons into triangles with VTK's ear cutting (in the polygon's plane; the pieces
/// keep the polygon's orientation) and appends them to the mesh.
class Triangulator {
 public:
  Triangulator(SurfaceMesh& mesh, const std::string& path) : mesh_(mesh), path_(path) {}

  /// `ids`: the polygon's vertex indices, already checked against the vertex count;
  /// `name`: how errors call it ("OBJ face 12 (line 40)").
  void add(const std::vector<vtkIdType>& ids, long long number, const std::string& name) {
    const vtkIdType count = static_cast<vtkIdType>(ids.size());
    if (count < 3) fail(path_, name + " has " + std::to_string(count) + " vertices: a polygon needs at least 3");
    if (count == 3) {
      push(ids[0], ids[1], ids[2], number);
      return;
    }
    polygon_->GetPoints()->SetNumberOfPoints(count);
    polygon_->GetPointIds()->SetNumberOfIds(count);
    for (vtkIdType k = 0; k < count; ++k) {
      polygon_->GetPoints()->SetPoint(k, mesh_.vertices[static_cast<std::size_t>(ids[k])].data());
      polygon_->GetPointIds()->SetId(k, ids[k]);
    }
    pieces_->Reset();
    if (!polygon_->Triangulate(pieces_) || pieces_->GetNumberOfIds() != 3 * (count - 2)) {
      fail(path_, "cannot triangulate " + name + " (" + std::to_string(count) +
                      " vertices): the polygon is degenerate or self-intersecting");
    }
    for (vtkIdType k = 0; k < pieces_->GetNumberOfIds(); k += 3) {
      push(ids[pieces_->GetId(k)], ids[pieces_->GetId(k + 1)], ids[pieces_->GetId(k + 2)], number);
    }
    ++mesh_.polygons_triangulated;
  }

  /// A triangle strip: every other triangle runs backwards, so two corners swap to keep the
  /// strip's orientation.
  void add_strip(const std::vector<vtkIdType>& ids, long long number, const std::string& name) {
    if (ids.size() < 3) fail(path_, name + " is a triangle strip of " + std::to_string(ids.size()) + " points");
    for (std::size_t k = 0; k + 2 < ids.size(); ++k) {
      if (k % 2 == 0) {
        push(ids[k], ids[k + 1], ids[k + 2], number);
      } else {
        push(ids[k + 1], ids[k], ids[k + 2], number);
      }
    }
    ++mesh_.polygons_triangulated;
  }

 private:
  void push(vtkIdType a, vtkIdType b, vtkIdType c, long long number) {
    mesh_.triangles.emplace_back(static_cast<int>(a), static_cast<int>(b), static_cast<int>(c));
    mesh_.labels.triangle_tags.push_back(number);
  }

  SurfaceMesh& mesh_;
  const std::string& path_;
  vtkNew<vtkPolygon> polygon_;
  vtkNew<vtkIdList> pieces_;
};

/// The polygons and strips of VTK output (STL, .vtk, .vtp), numbered from first_poly and
/// first_strip; points become the vertices in order.
void append_polydata(vtkPolyData* data, const std::string& path, const char* kind, long long first_poly,
                     long long first_strip, SurfaceMesh& mesh) {
  mesh.labels.triangle_kind = kind;
  vtkPoints* points = data->GetPoints();
  const vtkIdType point_count = points == nullptr ? 0 : points->GetNumberOfPoints();
  mesh.vertices.resize(static_cast<std::size_t>(point_count));
  for (vtkIdType i = 0; i < point_count; ++i) points->GetPoint(i, mesh.vertices[static_cast<std::size_t>(i)].data());

  Triangulator triangulator(mesh, path);
  std::vector<vtkIdType> corners;
  const auto gather = [&](vtkIdType count, const vtkIdType* ids, const std::string& name) {
    corners.assign(ids, ids + count);
    for (const vtkIdType id : corners) {
      if (id < 0 || id >= point_count) {
        fail(path, name + " refers to point " + std::to_string(id) + ", but the file has " +
                       std::to_string(point_count) + " points");
      }
    }
  };
  // VTK does not check what it read: corrupt offsets would send the traversal out of bounds.
  for (vtkCellArray* cells : {data->GetPolys(), data->GetStrips()}) {
    if (!cells->IsValid()) fail(path, "corrupt cell arrays (offsets inconsistent with the connectivity)");
  }
  vtkIdType count = 0;
  const vtkIdType* ids = nullptr;
  long long number = first_poly;
  vtkCellArray* polys = data->GetPolys();
  for (polys->InitTraversal(); polys->GetNextCell(count, ids); ++number) {
    const std::string name = std::string(kind) + " " + std::to_string(number);
    gather(count, ids, name);
    triangulator.add(corners, number, name);
  }
  number = first_strip;
  vtkCellArray* strips = data->GetStrips();
  for (strips->InitTraversal(); strips->GetNextCell(count, ids); ++number) {
    const std::string name = std::string(kind) + " " + std::to_string(number);
    gather(count, ids, name);
    triangulator.add_strip(corners, number, name);
  }
}

// ---------------------------------------------------------------------------------------------
// Per-format readers.

void read_stl(const std::string& path, SurfaceMesh& mesh) {
  const std::uintmax_t size = require_file(path);
  // VTK sizes its arrays by a binary file's facet count before reading the facets: a corrupt
  // count claims gigabytes. It is checked against the file size first, for every file VTK will
  // read as binary (its own test: vtkSTLReader takes all but plain text for binary).
  if (vtksys::SystemTools::DetectFileType(path.c_str()) != vtksys::SystemTools::FileTypeText)
    check_binary_stl_size(path, size);
  vtkNew<VtkMessages> messages;
  vtkNew<vtkSTLReader> reader;
  messages->watch(reader);
  reader->MergingOff();  // keeps cell i = facet i; welding follows with a relative tolerance
  vtkSmartPointer<vtkPolyData> data = run_reader(reader.Get(), messages, path, "STL");
  if (reader->GetBinaryHeader() != nullptr) check_binary_stl_size(path, size);
  append_polydata(data, path, "STL facet", 0, 0, mesh);
}

/// OBJ is read here rather than by VTK: VTK 9.1's vtkOBJReader parses coordinates as 32-bit
/// floats and silently misreads "nan" and "inf" (shifting the coordinates). Read: `v` (x y z,
/// an optional w ignored) and `f` (v, v/vt, v//vn, v/vt/vn; negative indices count back from
/// the last vertex), with `\` continuation lines; everything else (vt, vn, g, o, s, l, p,
/// materials, comments) is skipped.
void read_obj(const std::string& path, SurfaceMesh& mesh) {
  require_file(path);
  std::ifstream in(path, std::ios::binary);
  struct Face {
    std::vector<long long> references;  // as written: from 1, or negative counting back
    std::size_t defined;                // vertices defined before the face (for negative references)
    std::size_t line;
  };
  std::vector<Face> faces;
  std::string line;
  std::string logical;
  std::size_t line_number = 0;
  std::size_t first_line = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find('\0') != std::string::npos) {
      fail(path, "line " + std::to_string(line_number) + ": binary data in an OBJ file (OBJ is text)");
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (logical.empty()) first_line = line_number;
    if (!line.empty() && line.back() == '\\') {
      logical += line.substr(0, line.size() - 1) + " ";
      continue;
    }
    logical += line;
    std::istringstream fields(logical);
    logical.clear();
    const std::string where = "line " + std::to_string(first_line) + ": ";
    std::string command;
    if (!(fields >> command)) continue;
    if (command == "v") {
      const std::string name = "OBJ vertex " + std::to_string(mesh.vertices.size() + 1);
      Vector3d x;
      for (int i = 0; i < 3; ++i) {
        std::string token;
        if (!(fields >> token)) {
          fail(path, where + name + " has " + std::to_string(i) + " coordinates, expected 3");
        }
        char* end = nullptr;
        x[i] = std::strtod(token.c_str(), &end);
        if (token.empty() || end != token.c_str() + token.size()) {
          fail(path, where + name + " has a coordinate that is not a number: '" + token.substr(0, 40) + "'");
        }
        if (!std::isfinite(x[i])) fail(path, where + name + " has a non-finite coordinate '" + token + "'");
      }
      mesh.vertices.push_back(x);
    } else if (command == "f") {
      Face face{{}, mesh.vertices.size(), first_line};
      const std::string name = "OBJ face " + std::to_string(faces.size() + 1);
      std::string token;
      while (fields >> token) {
        const std::string index = token.substr(0, token.find('/'));
        long long value = 0;
        const auto [stop, error] = std::from_chars(index.data(), index.data() + index.size(), value);
        if (error != std::errc() || stop != index.data() + index.size() || value == 0) {
          fail(path, where + name + " has a vertex reference that is not a non-zero integer: '" +
                         token.substr(0, 40) + "'");
        }
        face.references.push_back(value);
      }
      faces.push_back(std::move(face));
    }
  }
  if (in.bad()) fail(path, "cannot read the OBJ file");

  mesh.labels.vertex_kind = "OBJ vertex";
  mesh.labels.vertex_tags.resize(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) mesh.labels.vertex_tags[v] = static_cast<long long>(v) + 1;
  mesh.labels.triangle_kind = "OBJ face";
  Triangulator triangulator(mesh, path);
  std::vector<vtkIdType> corners;
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const std::string name = "OBJ face " + std::to_string(f + 1) + " (line " + std::to_string(faces[f].line) + ")";
    corners.clear();
    for (const long long reference : faces[f].references) {
      // Negative: relative to the vertices defined before the face (-1 is the last one).
      const long long corner = reference > 0 ? reference - 1 : static_cast<long long>(faces[f].defined) + reference;
      if (corner < 0 || corner >= static_cast<long long>(mesh.vertices.size())) {
        fail(path, name + " refers to vertex " + std::to_string(reference) + ", but the file has " +
                       std::to_string(mesh.vertices.size()) + " vertices (numbered from 1)");
      }
      corners.push_back(static_cast<vtkIdType>(corner));
    }
    triangulator.add(corners, static_cast<long long>(f) + 1, name);
  }
}

/// VTK cell ids run over verts, lines, polys and strips in that order; point ids from 0.
void label_vtk(vtkPolyData* data, const std::string& path, SurfaceMesh& mesh) {
  const long long first_poly = data->GetNumberOfVerts() + data->GetNumberOfLines();
  append_polydata(data, path, "VTK cell", first_poly, first_poly + data->GetNumberOfPolys(), mesh);
  mesh.labels.vertex_kind = "VTK point";
  mesh.labels.vertex_tags.resize(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) mesh.labels.vertex_tags[v] = static_cast<long long>(v);
}

void read_vtk(const std::string& path, SurfaceMesh& mesh) {
  const std::string geometry = check_legacy_declared_sizes(path, require_file(path));
  // VTK reads its input string's length as an int.
  if (geometry.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    fail(path, "a legacy VTK surface of 2 GB or more is not read (write it as .vtp)");
  vtkNew<VtkMessages> messages;
  vtkNew<vtkPolyDataReader> reader;
  messages->watch(reader);
  reader->SetFileName(path.c_str());
  reader->ReadFromInputStringOn();
  reader->SetBinaryInputString(geometry.data(), static_cast<int>(geometry.size()));
  bool polydata = false;
  {
    const QuietVtkLogger quiet;
    polydata = reader->IsFilePolyData() != 0;
  }
  if (!polydata) {
    fail(path, "not a legacy VTK POLYDATA file" +
                   (messages->failed() ? " (" + messages->first_error() + ")"
                                       : std::string(" (it holds another dataset type; only POLYDATA is read)")));
  }
  vtkSmartPointer<vtkPolyData> data = run_reader(reader.Get(), messages, path, "legacy VTK");
  label_vtk(data, path, mesh);
}

/// VTK's XML reader sizes a cell kind's connectivity by the last value of its offsets array
/// before it reads a connectivity entry, so one corrupt offset claims gigabytes. This reader
/// checks that value against what the file can hold as soon as the offsets are read (VTK has
/// decoded them, whatever their encoding or compression), and stops the read if it cannot be.
class BoundedXmlPolyDataReader : public vtkXMLPolyDataReader {
 public:
  static BoundedXmlPolyDataReader* New();
  vtkTypeMacro(BoundedXmlPolyDataReader, vtkXMLPolyDataReader);

  double max_connectivity_entries = 0;
  std::string refusal;  // why the read was stopped; empty if it was not

 protected:
  int ReadArrayValues(vtkXMLDataElement* element, vtkIdType array_index, vtkAbstractArray* array,
                      vtkIdType start_index, vtkIdType value_count, FieldType type) override {
    const int read = vtkXMLPolyDataReader::ReadArrayValues(element, array_index, array, start_index, value_count, type);
    const char* name = element->GetAttribute("Name");
    auto* values = vtkDataArray::SafeDownCast(array);
    if (read == 0 || name == nullptr || std::strcmp(name, "offsets") != 0 || values == nullptr ||
        values->GetNumberOfTuples() == 0 || values->GetNumberOfComponents() != 1) {
      return read;
    }
    const double last = values->GetComponent(values->GetNumberOfTuples() - 1, 0);
    if (last > max_connectivity_entries) {
      std::ostringstream why;
      why << "corrupt file: an offsets array of piece " << this->Piece + 1 << " ends at " << std::fixed << std::setprecision(0) << last
          << ", more connectivity entries than the file's bytes can hold";
      refusal = why.str();
      return 0;
    }
    return read;
  }
};
vtkStandardNewMacro(BoundedXmlPolyDataReader);

void read_vtp(const std::string& path, SurfaceMesh& mesh) {
  const std::uintmax_t size = require_file(path);
  check_xml_declared_sizes(path, size);
  vtkNew<VtkMessages> messages;
  vtkNew<BoundedXmlPolyDataReader> reader;
  reader->max_connectivity_entries = max_xml_bytes_per_file_byte * static_cast<double>(size) / 8;
  messages->watch(reader);
  reader->SetReaderErrorObserver(messages);
  reader->SetParserErrorObserver(messages);
  vtkSmartPointer<vtkPolyData> data;
  try {
    data = run_reader(reader.Get(), messages, path, "VTK XML PolyData");
  } catch (const std::invalid_argument&) {
    if (!reader->refusal.empty()) fail(path, reader->refusal);  // VTK's own message is vaguer
    throw;
  }
  label_vtk(data, path, mesh);
}

// ---------------------------------------------------------------------------------------------

/// Merges vertices within `relative_tolerance` × bounding-box diagonal into the earliest one and
/// drops the merged ones; triangles and vertex labels follow.
void weld(SurfaceMesh& mesh, double relative_tolerance) {
  Vector3d lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
  Vector3d upper = -lower;
  for (const Vector3d& x : mesh.vertices) {
    if (!x.allFinite()) continue;
    lower = lower.cwiseMin(x);
    upper = upper.cwiseMax(x);
  }
  if (!(lower[0] <= upper[0])) return;
  const std::vector<int> representative =
      geometry::coincident_vertices(mesh.vertices, relative_tolerance * (upper - lower).norm());
  std::vector<int> new_index(mesh.vertices.size(), -1);
  std::vector<Vector3d> vertices;
  std::vector<long long> tags;
  const bool tagged = mesh.labels.vertex_tags.size() == mesh.vertices.size();
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    if (representative[v] != static_cast<int>(v)) continue;
    new_index[v] = static_cast<int>(vertices.size());
    vertices.push_back(mesh.vertices[v]);
    if (tagged) tags.push_back(mesh.labels.vertex_tags[v]);
  }
  for (Vector3i& triangle : mesh.triangles) {
    for (int k = 0; k < 3; ++k) triangle[k] = new_index[representative[triangle[k]]];
  }
  mesh.vertices_welded += mesh.vertices.size() - vertices.size();
  mesh.vertices = std::move(vertices);
  if (tagged) mesh.labels.vertex_tags = std::move(tags);
}

vtkSmartPointer<vtkPolyData> to_polydata(const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles,
                                         double unit_scale) {
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(static_cast<vtkIdType>(vertices.size()));
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    const Vector3d x = vertices[v] / unit_scale;
    points->SetPoint(static_cast<vtkIdType>(v), x.data());
  }
  vtkNew<vtkCellArray> cells;
  cells->AllocateExact(static_cast<vtkIdType>(triangles.size()), 3 * static_cast<vtkIdType>(triangles.size()));
  for (const Vector3i& t : triangles) {
    const vtkIdType ids[3] = {t[0], t[1], t[2]};
    cells->InsertNextCell(3, ids);
  }
  auto data = vtkSmartPointer<vtkPolyData>::New();
  data->SetPoints(points);
  data->SetPolys(cells);
  return data;
}

template <class Writer>
void run_writer(Writer* writer, vtkPolyData* data, const std::string& path) {
  vtkNew<VtkMessages> messages;
  messages->watch(writer);
  writer->SetFileName(path.c_str());
  writer->SetInputData(data);
  int status = 0;
  {
    const QuietVtkLogger quiet;
    status = writer->Write();
  }
  if (status != 1 || messages->failed()) {
    throw std::runtime_error(path + ": writing the surface failed" +
                             (messages->failed() ? ": " + messages->first_error() : std::string()));
  }
}

void write_msh(const std::string& path, const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles,
               double unit_scale) {
  std::ofstream out(path, std::ios::out | std::ios::trunc);
  if (!out) throw std::runtime_error(path + ": cannot open for writing (" + std::strerror(errno) + ")");
  out.precision(17);
  out << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 1 \"surface\"\n$EndPhysicalNames\n";
  out << "$Nodes\n" << vertices.size() << "\n";
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    const Vector3d x = vertices[v] / unit_scale;
    out << v + 1 << ' ' << x[0] << ' ' << x[1] << ' ' << x[2] << '\n';
  }
  out << "$EndNodes\n$Elements\n" << triangles.size() << "\n";
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    // Type 2 (3-node triangle), two tags: physical group 1, elementary surface 1.
    out << t + 1 << " 2 2 1 1 " << triangles[t][0] + 1 << ' ' << triangles[t][1] + 1 << ' ' << triangles[t][2] + 1
        << '\n';
  }
  out << "$EndElements\n";
  if (!out.flush()) throw std::runtime_error(path + ": writing the surface failed");
}

}  // namespace

// ---------------------------------------------------------------------------------------------

SurfaceFormat surface_format_of(const std::string& path) {
  const std::string extension = lower_case(std::filesystem::path(path).extension().string());
  if (extension == ".msh") return SurfaceFormat::msh;
  if (extension == ".obj") return SurfaceFormat::obj;
  if (extension == ".stl") return SurfaceFormat::stl;
  if (extension == ".vtk") return SurfaceFormat::vtk;
  if (extension == ".vtp") return SurfaceFormat::vtp;
  fail(path, "unsupported surface mesh format '" + extension +
                 "' (supported extensions: .msh, .obj, .stl, .vtk, .vtp; case does not matter)");
}

std::string to_string(SurfaceFormat format) {
  switch (format) {
    case SurfaceFormat::msh: return "msh";
    case SurfaceFormat::obj: return "obj";
    case SurfaceFormat::stl: return "stl";
    case SurfaceFormat::vtk: return "vtk";
    case SurfaceFormat::vtp: return "vtp";
  }
  throw std::invalid_argument("unknown SurfaceFormat value " + std::to_string(static_cast<int>(format)));
}

void SurfaceReadOptions::validate() const {
  if (!std::isfinite(unit_scale) || !(unit_scale > 0)) {
    throw std::invalid_argument("SurfaceReadOptions.unit_scale = " + text_of(unit_scale) + " must be finite and > 0");
  }
  if (!std::isfinite(weld_relative_tolerance) || weld_relative_tolerance < 0 || weld_relative_tolerance >= 1e-2) {
    throw std::invalid_argument("SurfaceReadOptions.weld_relative_tolerance = " + text_of(weld_relative_tolerance) +
                                " must be in [0, 1e-2)");
  }
}

void SurfaceWriteOptions::validate() const {
  if (!std::isfinite(unit_scale) || !(unit_scale > 0)) {
    throw std::invalid_argument("SurfaceWriteOptions.unit_scale = " + text_of(unit_scale) + " must be finite and > 0");
  }
}

SurfaceMesh read_surface_mesh(const std::string& path, const SurfaceReadOptions& options) {
  options.validate();
  SurfaceMesh mesh;
  mesh.path = path;
  mesh.format = surface_format_of(path);
  if (!options.msh_groups.empty() && mesh.format != SurfaceFormat::msh) {
    fail(path, "physical groups (msh_groups) can be selected in .msh files only");
  }
  // A corrupt count in a binary file makes VTK (or the copy out of it) ask for absurd sizes.
  try {
    switch (mesh.format) {
      case SurfaceFormat::msh: {
        geometry::SurfaceData data = read_msh_surface(path, options.msh_groups);
        mesh.vertices = std::move(data.vertices);
        mesh.triangles = std::move(data.triangles);
        mesh.labels = std::move(data.labels);
        break;
      }
      case SurfaceFormat::obj: read_obj(path, mesh); break;
      case SurfaceFormat::stl: read_stl(path, mesh); break;
      case SurfaceFormat::vtk: read_vtk(path, mesh); break;
      case SurfaceFormat::vtp: read_vtp(path, mesh); break;
    }
  } catch (const std::bad_alloc&) {
    fail(path, "cannot read the " + to_string(mesh.format) + " file: out of memory (a count in the file is corrupt?)");
  } catch (const std::length_error& error) {
    fail(path, "cannot read the " + to_string(mesh.format) + " file: " + error.what() +
                   " (a count in the file is corrupt?)");
  }
  if (mesh.triangles.empty()) {
    fail(path, "no polygons in the file (" + std::to_string(mesh.vertices.size()) + " vertices)");
  }
  if (options.unit_scale != 1.0) {
    for (Vector3d& x : mesh.vertices) x *= options.unit_scale;
  }
  if (mesh.format == SurfaceFormat::stl || options.weld_vertices) weld(mesh, options.weld_relative_tolerance);
  std::vector<char> used(mesh.vertices.size(), 0);
  for (const Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) used[static_cast<std::size_t>(t[k])] = 1;
  }
  mesh.unused_vertices = static_cast<std::size_t>(std::count(used.begin(), used.end(), 0));
  return mesh;
}

std::vector<geometry::SurfaceDefect> validate_surface_mesh(const SurfaceMesh& mesh) {
  return geometry::validate_surface(mesh.vertices, mesh.triangles, mesh.path, mesh.labels);
}

SurfaceStatistics surface_statistics(const std::vector<Vector3d>& vertices, const std::vector<Vector3i>& triangles) {
  SurfaceStatistics statistics;
  statistics.vertex_count = vertices.size();
  statistics.triangle_count = triangles.size();
  const auto usable = [&](const Vector3i& t) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || static_cast<std::size_t>(t[k]) >= vertices.size() || !vertices[t[k]].allFinite()) return false;
    }
    return true;
  };
  Vector3d lower = Vector3d::Constant(std::numeric_limits<double>::infinity());
  Vector3d upper = -lower;
  for (const Vector3i& t : triangles) {
    if (!usable(t)) continue;
    for (int k = 0; k < 3; ++k) {
      lower = lower.cwiseMin(vertices[t[k]]);
      upper = upper.cwiseMax(vertices[t[k]]);
    }
  }
  if (!(lower[0] <= upper[0])) return statistics;
  statistics.lower = lower;
  statistics.upper = upper;
  // About the box centre, which keeps the triple products well scaled.
  const Vector3d origin = 0.5 * (lower + upper);
  statistics.min_edge_m = std::numeric_limits<double>::infinity();
  for (const Vector3i& t : triangles) {
    if (!usable(t)) continue;
    const Vector3d a = vertices[t[0]] - origin;
    const Vector3d b = vertices[t[1]] - origin;
    const Vector3d c = vertices[t[2]] - origin;
    statistics.area_m2 += 0.5 * (b - a).cross(c - a).norm();
    statistics.volume_m3 += a.dot(b.cross(c)) / 6;
    for (const double length : {(b - a).norm(), (c - b).norm(), (a - c).norm()}) {
      statistics.min_edge_m = std::min(statistics.min_edge_m, length);
      statistics.max_edge_m = std::max(statistics.max_edge_m, length);
    }
  }
  return statistics;
}

geometry::TriangleSurface load_surface(const std::string& path, const SurfaceReadOptions& options) {
  SurfaceMesh mesh = read_surface_mesh(path, options);
  return geometry::TriangleSurface(std::move(mesh.vertices), std::move(mesh.triangles), path, mesh.labels);
}

void write_surface_mesh(const std::string& path, const std::vector<Vector3d>& vertices,
                        const std::vector<Vector3i>& triangles, const SurfaceWriteOptions& options) {
  options.validate();
  const SurfaceFormat format = surface_format_of(path);
  const int vertex_count = static_cast<int>(std::min<std::size_t>(vertices.size(), std::numeric_limits<int>::max()));
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      if (triangles[t][k] < 0 || triangles[t][k] >= vertex_count) {
        fail(path, "cannot write triangle " + std::to_string(t) + ": vertex " + std::to_string(triangles[t][k]) +
                       " out of range [0, " + std::to_string(vertex_count) + ")");
      }
    }
  }
  if (format == SurfaceFormat::msh) {
    write_msh(path, vertices, triangles, options.unit_scale);
    return;
  }
  if (!options.point_vectors.empty() && format != SurfaceFormat::vtp && format != SurfaceFormat::vtk)
    throw std::invalid_argument(path + ": point vectors can only be written to .vtp or .vtk");
  const vtkSmartPointer<vtkPolyData> data = to_polydata(vertices, triangles, options.unit_scale);
  for (const auto& [name, values] : options.point_vectors) {
    if (values.size() != vertices.size())
      throw std::invalid_argument(path + ": point vector '" + name + "' has " + std::to_string(values.size()) +
                                  " values for " + std::to_string(vertices.size()) + " vertices");
    vtkNew<vtkDoubleArray> array;
    array->SetName(name.c_str());
    array->SetNumberOfComponents(3);
    array->SetNumberOfTuples(static_cast<vtkIdType>(values.size()));
    for (std::size_t i = 0; i < values.size(); ++i) array->SetTuple(static_cast<vtkIdType>(i), values[i].data());
    data->GetPointData()->AddArray(array);
  }
  switch (format) {
    case SurfaceFormat::msh: break;
    case SurfaceFormat::obj: {
      vtkNew<vtkOBJWriter> writer;
      run_writer(writer.Get(), data, path);
      break;
    }
    case SurfaceFormat::stl: {
      vtkNew<vtkSTLWriter> writer;
      if (options.ascii_stl) {
        writer->SetFileTypeToASCII();
      } else {
        writer->SetFileTypeToBinary();
      }
      run_writer(writer.Get(), data, path);
      break;
    }
    case SurfaceFormat::vtk: {
      vtkNew<vtkPolyDataWriter> writer;
      writer->SetFileTypeToBinary();
      run_writer(writer.Get(), data, path);
      break;
    }
    case SurfaceFormat::vtp: {
      vtkNew<vtkXMLPolyDataWriter> writer;
      writer->SetDataModeToAppended();
      writer->EncodeAppendedDataOff();
      run_writer(writer.Get(), data, path);
      break;
    }
  }
}

}  // namespace touchstone::meshes
