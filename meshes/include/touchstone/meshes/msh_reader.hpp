#pragma once
/// @file
/// The one reader of gmsh MSH files (2.2 and 4.1, ASCII) in the project: the triangles of a
/// surface for the geometry core (surface_mesh_io, the MFS studies, the tests), and the
/// $PhysicalNames that the finite element reference needs next to deal.II's GridIn (which keeps
/// only the numeric tags). Every syntax error names the file and line.

#include "touchstone/geometry/triangle_surface.hpp"

#include <string>
#include <vector>

namespace touchstone::meshes {

/// The triangles of a gmsh MSH 2.2/4.1 ASCII file (all 2-D elements, or the physical surface
/// groups in `groups`; MSH 2 repeats of one element for several groups kept once; only the
/// nodes in use, numbered in increasing tag order), labelled with the gmsh node and element
/// tags, not validated. Throws std::invalid_argument naming the file and line for syntax
/// errors, the group for an unknown group name (listing the file's surface groups), and the
/// element for anything but 3-node triangles.
geometry::SurfaceData read_msh_surface(const std::string& path, const std::vector<std::string>& groups = {});

/// read_msh_surface followed by the TriangleSurface constructor: a validated surface, or
/// std::invalid_argument naming the file, the defect and the gmsh element or nodes.
geometry::TriangleSurface load_msh_surface(const std::string& path, const std::vector<std::string>& groups = {});

/// One entry of a file's $PhysicalNames section.
struct MshPhysicalName {
  int dimension = 0;  ///< 0 point, 1 curve, 2 surface, 3 volume
  int tag = 0;        ///< the physical tag the elements carry
  std::string name;
};

/// The $PhysicalNames of a gmsh MSH 2.2/4.1 ASCII file in file order (empty when the file has
/// no such section). The format line and the section are checked; the other sections are
/// skipped unparsed. Throws std::invalid_argument naming the file (and line) when the file
/// cannot be read, is not an ASCII MSH 2.2/4.1 file, or the section is malformed.
std::vector<MshPhysicalName> read_msh_physical_names(const std::string& path);

}  // namespace touchstone::meshes
