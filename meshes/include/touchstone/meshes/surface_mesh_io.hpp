#pragma once
/// @file
/// Reading and writing triangle surface meshes (organ boundaries for collision detection) in the
/// formats organ models come in: gmsh .msh, Wavefront .obj, STL (ASCII and binary), legacy VTK
/// .vtk (POLYDATA) and VTK XML .vtp.
///
/// Reading returns plain arrays plus the file's own numbering, so that validation
/// (geometry::validate_surface, or the TriangleSurface constructor) names the element
/// of the file: "triangle 12 (STL facet 12)", "edge (3, 5) (OBJ vertices 4, 6)".
///
/// Element numbers, as the usual viewers show them:
/// - .msh: gmsh element and node tags (read by msh_reader.hpp, as load_msh_surface reads it:
///   MSH 2.2/4.1 ASCII, 3-node triangles only; quadrangles are rejected naming the element,
///   since gmsh can mesh with triangles directly).
/// - .obj: face and vertex numbers counted from 1 in file order, as the file's `f` lines use them.
/// - .stl: facet numbers counted from 0; STL has no vertex numbers (messages give coordinates).
/// - .vtk/.vtp: VTK cell ids counted from 0 over verts, lines, polys and strips (as ParaView
///   shows them) and point ids counted from 0.
///
/// Polygons are triangulated (quadrilaterals and larger polygons by VTK's ear cutting,
/// triangle strips into their triangles); every piece keeps the number of its polygon.
/// Points and lines are ignored, and so are point, cell and field data (a legacy .vtk file's
/// FIELD blocks and the sections after its cells are not even given to VTK). STL coordinates are 32-bit floats in the file (VTK reads ASCII
/// STL as floats too); the other formats keep doubles.

#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::meshes {

/// The formats, chosen by the file name's extension (case-insensitive).
enum class SurfaceFormat {
  msh,  ///< .msh
  obj,  ///< .obj
  stl,  ///< .stl (ASCII or binary, detected by VTK)
  vtk,  ///< .vtk, legacy VTK POLYDATA
  vtp,  ///< .vtp, VTK XML PolyData
};

/// The format of `path` by its extension; throws std::invalid_argument naming the path and the
/// supported extensions.
SurfaceFormat surface_format_of(const std::string& path);

/// "msh", "obj", "stl", "vtk", "vtp".
std::string to_string(SurfaceFormat format);

/// How to read a surface file.
struct SurfaceReadOptions {
  /// Metres per file unit: coordinates are multiplied by it (1e-3 for a millimetre file).
  double unit_scale = 1.0;
  /// Merge coincident vertices in .msh, .obj, .vtk and .vtp files too. STL files are always
  /// welded: a facet soup has no connectivity otherwise.
  bool weld_vertices = false;
  /// Welding merges vertices closer than this times the bounding-box diagonal (dimensionless).
  /// The default merges what was written as one point (STL floats round identically) and
  /// nothing a mesh could mean as two points.
  double weld_relative_tolerance = 1e-9;
  /// .msh only: the physical surface groups to read (empty: every 2-D element).
  std::vector<std::string> msh_groups;

  /// Throws std::invalid_argument naming the offending field and value.
  void validate() const;
};

/// A surface as read, before validation.
struct SurfaceMesh {
  std::string path;
  SurfaceFormat format = SurfaceFormat::msh;
  std::vector<Eigen::Vector3d> vertices;                 ///< [m], after unit_scale
  std::vector<Eigen::Vector3i> triangles;                ///< as in the file (not reoriented)
  geometry::SurfaceLabels labels;              ///< the file's numbers, see the file comment
  std::size_t polygons_triangulated = 0;  ///< quadrilaterals, larger polygons and strips split into triangles
  std::size_t vertices_welded = 0;        ///< vertices merged into an earlier one by welding
  std::size_t unused_vertices = 0;        ///< vertices no triangle refers to (kept: numbering stays the file's)
};

/// Reads the triangles of a surface file by its extension. Throws std::invalid_argument naming
/// the file (and the line, face or cell when the format tells) for a missing, empty, truncated
/// or malformed file, a file without polygons, or a face with an index out of range. Geometric
/// and topological defects are not checked here: see validate_surface and load_surface.
/// VTK's own messages are captured into the exception text, never printed.
SurfaceMesh read_surface_mesh(const std::string& path, const SurfaceReadOptions& options = {});

/// read_surface_mesh followed by the TriangleSurface constructor: a validated surface, or
/// std::invalid_argument naming the file, the defect and the file's element.
geometry::TriangleSurface load_surface(const std::string& path, const SurfaceReadOptions& options = {});

/// Every defect of a surface as read (empty: valid), its messages naming the file's elements.
std::vector<geometry::SurfaceDefect> validate_surface_mesh(const SurfaceMesh& mesh);

/// Sizes of a triangle surface, for reports; computable for any input: triangles with an index
/// out of range or a non-finite corner are left out.
struct SurfaceStatistics {
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  double area_m2 = 0;
  /// Σ (a · (b × c)) / 6 over the triangles: the enclosed volume of a closed, outward surface.
  double volume_m3 = 0;
  double min_edge_m = 0;  ///< shortest triangle edge
  double max_edge_m = 0;  ///< longest triangle edge
  Eigen::Vector3d lower = Eigen::Vector3d::Zero();  ///< bounding box of the used vertices [m]
  Eigen::Vector3d upper = Eigen::Vector3d::Zero();
};

SurfaceStatistics surface_statistics(const std::vector<Eigen::Vector3d>& vertices,
                                     const std::vector<Eigen::Vector3i>& triangles);

/// How to write a surface file.
struct SurfaceWriteOptions {
  /// Metres per file unit: coordinates are divided by it (1e-3 writes millimetres).
  double unit_scale = 1.0;
  /// STL only: ASCII instead of binary. (STL stores 32-bit floats either way.)
  bool ascii_stl = false;
  /// .vtp and .vtk only: named vector fields, one value per vertex (e.g. displacements [m], for
  /// ParaView's Warp By Vector); written as they are, not scaled by unit_scale.
  std::vector<std::pair<std::string, std::vector<Eigen::Vector3d>>> point_vectors;

  /// Throws std::invalid_argument naming the offending field and value.
  void validate() const;
};

/// Writes triangles (vertices [m]) in the format of `path`'s extension: .vtp (binary, Float64
/// points), .vtk (legacy binary, doubles), .stl (binary or ASCII, floats), .obj (17 significant
/// digits), .msh (MSH 2.2 ASCII, 17 digits, one physical surface group "surface" with tag 1).
/// Everything but STL round-trips exactly. Throws std::invalid_argument for an unsupported
/// extension, an index out of range, or point vectors on another format or of the wrong length;
/// std::runtime_error naming the path when writing fails.
void write_surface_mesh(const std::string& path, const std::vector<Eigen::Vector3d>& vertices,
                        const std::vector<Eigen::Vector3i>& triangles, const SurfaceWriteOptions& options = {});

}  // namespace touchstone::meshes
