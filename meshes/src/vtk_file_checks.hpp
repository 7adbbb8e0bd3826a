#pragma once
// Internal to touchstone::meshes: what is checked in a surface file before a VTK reader sees it.
// VTK 9.1's readers trust what a file declares: they allocate every count a header gives before
// reading a value, and read on past a cell list that is cut short. Each check reads the file
// itself and throws std::invalid_argument "<path>: <what>", naming the count or the list.

#include <cstdint>
#include <string>

namespace touchstone::meshes::internal {

/// zlib, VTK's default compressor, shrinks data by at most 1032:1: a VTK XML file that declares
/// more than this many bytes of values per byte of file holds a corrupt count, not a surface.
constexpr double max_xml_bytes_per_file_byte = 1100;

/// Binary STL of `size` bytes: its facet count against its size.
void check_binary_stl_size(const std::string& path, std::uintmax_t size);
/// Legacy VTK of `size` bytes: the version line, every cell list, the point count, the extent of
/// every FIELD block. Returns the bytes to give VTK: the file without its FIELD blocks and
/// without the point and cell data after the geometry (a surface reads neither).
std::string check_legacy_declared_sizes(const std::string& path, std::uintmax_t size);
/// VTK XML PolyData of `size` bytes: the pieces' counts, the arrays' sizes, compressed arrays'
/// block counts and block sizes. (The offsets that size the connectivity are checked as VTK decodes them, by the
/// reader in surface_mesh_io.cpp.)
void check_xml_declared_sizes(const std::string& path, std::uintmax_t size);

}  // namespace touchstone::meshes::internal
