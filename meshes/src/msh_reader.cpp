#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/geometry/regular_file.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

namespace touchstone::meshes {

namespace {

using Eigen::Vector3d;

std::string format_number(double value) {
  std::ostringstream text;
  text.precision(6);
  text << value;
  return text.str();
}

/// The file's lines, with the line number in every error.
class MshText {
 public:
  explicit MshText(const std::string& path) : path_(path) {
    if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
      throw std::invalid_argument(path + ": cannot open the mesh file (" + reason + ")");
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      throw std::invalid_argument(path + ": cannot open the mesh file (" + std::strerror(errno) + ")");
    }
    text_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) throw std::invalid_argument(path + ": cannot read the mesh file");
  }

  /// Next line without its line break; false at the end of the file.
  bool next(std::string_view& line) {
    if (position_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', position_);
    if (end == std::string::npos) end = text_.size();
    line = std::string_view(text_).substr(position_, end - position_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    position_ = end + 1;
    ++line_number_;
    return true;
  }
  /// Next line, which must exist (`where` names the section for the error).
  std::string_view require(const std::string& where) {
    std::string_view line;
    if (!next(line)) fail("unexpected end of file in " + where);
    return line;
  }
  void expect(std::string_view wanted) {
    const std::string_view line = require(std::string(wanted));
    if (trim(line) != wanted) {
      fail("expected " + std::string(wanted) + ", found '" + shorten(line) + "'");
    }
  }
  /// Bytes after the current line.
  std::size_t bytes_left() const { return position_ < text_.size() ? text_.size() - position_ : 0; }
  /// Refuses a count of nodes that the rest of the file cannot hold, before anything is reserved
  /// for it: a node takes at least 8 bytes ("1 0 0 0\n" in MSH 2.2; "1\n" and "0 0 0\n" in 4.1).
  void check_node_count(long long count) const {
    constexpr std::size_t shortest_node_bytes = 8;
    if (count < 0) fail("negative node count in $Nodes");
    if (static_cast<unsigned long long>(count) > bytes_left() / shortest_node_bytes)
      fail("$Nodes claims " + std::to_string(count) + " nodes, more than the " + std::to_string(bytes_left()) +
           " bytes left in the file can hold");
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument(path_ + ", line " + std::to_string(line_number_) + ": " + what);
  }
  const std::string& path() const { return path_; }

  static std::string_view trim(std::string_view text) {
    const std::size_t begin = text.find_first_not_of(" \t");
    if (begin == std::string_view::npos) return {};
    const std::size_t end = text.find_last_not_of(" \t");
    return text.substr(begin, end - begin + 1);
  }
  /// A printable excerpt of a (possibly binary) line.
  static std::string shorten(std::string_view line) {
    std::string text;
    for (char c : line.substr(0, 40)) text += (c >= 32 && c < 127) ? c : '?';
    if (line.size() > 40) text += "...";
    return text;
  }

 private:
  std::string path_;
  std::string text_;
  std::size_t position_ = 0;
  int line_number_ = 0;
};

/// Whitespace-separated numbers of one line.
class Fields {
 public:
  Fields(const MshText& text, std::string_view line, const char* section)
      : text_(text), rest_(line), section_(section) {}

  template <typename Number>
  Number next(const char* what) {
    const std::size_t begin = rest_.find_first_not_of(" \t");
    if (begin == std::string_view::npos) {
      text_.fail(std::string("missing ") + what + " in " + section_);
    }
    rest_.remove_prefix(begin);
    const std::size_t end = std::min(rest_.find_first_of(" \t"), rest_.size());
    const std::string_view token = rest_.substr(0, end);
    rest_.remove_prefix(end);
    Number value{};
    const auto [stop, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (error != std::errc() || stop != token.data() + token.size()) {
      text_.fail(std::string("expected ") + what + " in " + section_ + ", found '" +
                 MshText::shorten(token) + "'");
    }
    return value;
  }
  bool empty() const { return MshText::trim(rest_).empty(); }

 private:
  const MshText& text_;
  std::string_view rest_;
  const char* section_;
};

/// A 2-D element as read, before group selection.
struct RawElement {
  long long tag = 0;
  int type = 0;
  int entity = 0;
  int physical = 0;  // MSH 2 only: the first element tag
  std::array<long long, 3> nodes{};
};

/// gmsh element types of dimension 2 (triangles and quadrangles of any order).
bool is_two_dimensional(int type) {
  static constexpr std::array<int, 16> types{2, 3, 9, 10, 16, 20, 21, 22, 23, 24, 25, 36, 37, 38, 39, 40};
  return std::find(types.begin(), types.end(), type) != types.end();
}

struct MshContent {
  std::vector<MshPhysicalName> physical_names;           // in file order
  std::map<int, std::string> surface_names;              // physical tag → name (dimension 2)
  std::map<std::string, int> other_names;                // name → dimension, for groups of dimension ≠ 2
  std::map<int, std::vector<int>> surface_physicals;     // MSH 4: surface entity → physical tags
  std::unordered_map<long long, Vector3d> nodes;
  std::vector<RawElement> elements;                      // every 2-D element
  bool version4 = false;
  bool has_nodes = false;
  bool has_elements = false;
  bool has_entities = false;
};

void read_physical_names(MshText& text, MshContent& content) {
  const char* section = "$PhysicalNames";
  Fields header(text, text.require(section), section);
  const int count = header.next<int>("the number of names");
  for (int i = 0; i < count; ++i) {
    const std::string_view line = text.require(section);
    Fields fields(text, line, section);
    const int dimension = fields.next<int>("a dimension");
    const int tag = fields.next<int>("a physical tag");
    const std::size_t open = line.find('"');
    const std::size_t close = line.rfind('"');
    if (open == std::string_view::npos || close == open) text.fail("expected a quoted name in $PhysicalNames");
    std::string name(line.substr(open + 1, close - open - 1));
    content.physical_names.push_back({dimension, tag, name});
    if (dimension == 2) {
      content.surface_names[tag] = std::move(name);
    } else {
      content.other_names[std::move(name)] = dimension;
    }
  }
  text.expect("$EndPhysicalNames");
}

void read_entities(MshText& text, MshContent& content) {
  const char* section = "$Entities";
  Fields header(text, text.require(section), section);
  std::array<long long, 4> counts{};
  for (long long& count : counts) count = header.next<long long>("an entity count");
  for (int dimension = 0; dimension < 4; ++dimension) {
    for (long long i = 0; i < counts[dimension]; ++i) {
      Fields fields(text, text.require(section), section);
      const int tag = fields.next<int>("an entity tag");
      // Points carry X Y Z, the others a bounding box.
      for (int j = 0; j < (dimension == 0 ? 3 : 6); ++j) fields.next<double>("a coordinate");
      const int physical_count = fields.next<int>("the number of physical tags");
      std::vector<int> physicals;
      for (int j = 0; j < physical_count; ++j) physicals.push_back(fields.next<int>("a physical tag"));
      if (dimension == 2) content.surface_physicals[tag] = std::move(physicals);
    }
  }
  text.expect("$EndEntities");
  content.has_entities = true;
}

void read_nodes_v2(MshText& text, MshContent& content) {
  const char* section = "$Nodes";
  Fields header(text, text.require(section), section);
  const long long count = header.next<long long>("the number of nodes");
  text.check_node_count(count);
  content.nodes.reserve(static_cast<std::size_t>(count));
  for (long long i = 0; i < count; ++i) {
    Fields fields(text, text.require(section), section);
    const long long tag = fields.next<long long>("a node tag");
    Vector3d x;
    for (int j = 0; j < 3; ++j) x[j] = fields.next<double>("a coordinate");
    content.nodes[tag] = x;
  }
  text.expect("$EndNodes");
  content.has_nodes = true;
}

void read_nodes_v4(MshText& text, MshContent& content) {
  const char* section = "$Nodes";
  Fields header(text, text.require(section), section);
  const long long blocks = header.next<long long>("the number of entity blocks");
  const long long count = header.next<long long>("the number of nodes");
  if (blocks < 0) text.fail("negative count in $Nodes");
  text.check_node_count(count);
  content.nodes.reserve(static_cast<std::size_t>(count));
  std::vector<long long> tags;
  for (long long b = 0; b < blocks; ++b) {
    Fields block(text, text.require(section), section);
    block.next<int>("an entity dimension");
    block.next<int>("an entity tag");
    block.next<int>("the parametric flag");
    const long long size = block.next<long long>("the number of nodes in the block");
    if (size < 0) text.fail("negative block size in $Nodes");
    tags.clear();
    for (long long i = 0; i < size; ++i) {
      tags.push_back(Fields(text, text.require(section), section).next<long long>("a node tag"));
    }
    // Parametric coordinates, when present, follow x y z on the same line and are not needed.
    for (long long i = 0; i < size; ++i) {
      Fields fields(text, text.require(section), section);
      Vector3d x;
      for (int j = 0; j < 3; ++j) x[j] = fields.next<double>("a coordinate");
      content.nodes[tags[i]] = x;
    }
  }
  text.expect("$EndNodes");
  content.has_nodes = true;
}

void read_elements_v2(MshText& text, MshContent& content) {
  const char* section = "$Elements";
  Fields header(text, text.require(section), section);
  const long long count = header.next<long long>("the number of elements");
  for (long long i = 0; i < count; ++i) {
    Fields fields(text, text.require(section), section);
    RawElement element;
    element.tag = fields.next<long long>("an element tag");
    element.type = fields.next<int>("an element type");
    const int tag_count = fields.next<int>("the number of element tags");
    for (int j = 0; j < tag_count; ++j) {
      const int tag = fields.next<int>("an element tag");
      if (j == 0) element.physical = tag;
      if (j == 1) element.entity = tag;
    }
    if (!is_two_dimensional(element.type)) continue;
    if (element.type == 2) {
      for (long long& node : element.nodes) node = fields.next<long long>("a node tag");
      if (!fields.empty()) text.fail("a triangle (type 2) with more than 3 nodes in $Elements");
    }
    content.elements.push_back(element);
  }
  text.expect("$EndElements");
  content.has_elements = true;
}

void read_elements_v4(MshText& text, MshContent& content) {
  const char* section = "$Elements";
  Fields header(text, text.require(section), section);
  const long long blocks = header.next<long long>("the number of entity blocks");
  for (long long b = 0; b < blocks; ++b) {
    Fields block(text, text.require(section), section);
    const int dimension = block.next<int>("an entity dimension");
    const int entity = block.next<int>("an entity tag");
    const int type = block.next<int>("an element type");
    const long long size = block.next<long long>("the number of elements in the block");
    for (long long i = 0; i < size; ++i) {
      const std::string_view line = text.require(section);
      if (dimension != 2) continue;
      Fields fields(text, line, section);
      RawElement element;
      element.tag = fields.next<long long>("an element tag");
      element.type = type;
      element.entity = entity;
      if (type == 2) {
        for (long long& node : element.nodes) node = fields.next<long long>("a node tag");
        if (!fields.empty()) text.fail("a triangle (type 2) with more than 3 nodes in $Elements");
      }
      content.elements.push_back(element);
    }
  }
  text.expect("$EndElements");
  content.has_elements = true;
}

/// Skips the section that `name` ("$Name") opened, up to its "$EndName".
void skip_section(MshText& text, std::string_view name) {
  const std::string end = "$End" + std::string(name.substr(1));
  std::string_view inner;
  do {
    inner = text.require(std::string(name));
  } while (MshText::trim(inner) != end);
}

/// The sections a reader needs: everything, or $PhysicalNames alone.
enum class Sections { all, physical_names };

MshContent read_msh(const std::string& path, Sections sections) {
  MshText text(path);
  MshContent content;
  std::string_view line;
  while (text.next(line) && MshText::trim(line).empty()) {
  }
  if (MshText::trim(line).empty()) throw std::invalid_argument(path + ": not a gmsh MSH file (it is empty)");
  if (MshText::trim(line) != "$MeshFormat") {
    throw std::invalid_argument(path + ": not a gmsh MSH file (it does not start with $MeshFormat)");
  }
  {
    Fields format(text, text.require("$MeshFormat"), "$MeshFormat");
    const double version = format.next<double>("the format version");
    const int file_type = format.next<int>("the file type");
    if (file_type != 0) {
      text.fail("binary MSH files are not supported: save the mesh as ASCII (Mesh.Binary = 0)");
    }
    if (version >= 2 && version < 3) {
      content.version4 = false;
    } else if (version == 4.1) {
      content.version4 = true;
    } else {
      text.fail("MSH version " + format_number(version) + " is not supported (2.2 or 4.1 ASCII)");
    }
    text.expect("$EndMeshFormat");
  }
  while (text.next(line)) {
    const std::string_view name = MshText::trim(line);
    if (name.empty()) continue;
    if (name.front() != '$') text.fail("expected a section ($Name), found '" + MshText::shorten(line) + "'");
    if (name == "$PhysicalNames") {
      read_physical_names(text, content);
    } else if (sections == Sections::physical_names) {
      skip_section(text, name);
    } else if (name == "$Entities" && content.version4) {
      read_entities(text, content);
    } else if (name == "$Nodes") {
      content.version4 ? read_nodes_v4(text, content) : read_nodes_v2(text, content);
    } else if (name == "$Elements") {
      content.version4 ? read_elements_v4(text, content) : read_elements_v2(text, content);
    } else {
      skip_section(text, name);  // $Periodic, $NodeData, ...: not needed here
    }
  }
  if (sections == Sections::physical_names) return content;
  if (!content.has_nodes) throw std::invalid_argument(path + ": no $Nodes section");
  if (!content.has_elements) throw std::invalid_argument(path + ": no $Elements section");
  return content;
}

std::string element_type_name(int type) {
  switch (type) {
    case 3: return "4-node quadrangle";
    case 9: return "6-node triangle";
    case 10: return "9-node quadrangle";
    case 16: return "8-node quadrangle";
    default: return "higher-order 2-D element";
  }
}

}  // namespace

geometry::SurfaceData read_msh_surface(const std::string& path, const std::vector<std::string>& groups) {
  const MshContent content = read_msh(path, Sections::all);

  std::set<int> selected;
  for (const std::string& group : groups) {
    bool found = false;
    for (const auto& [tag, name] : content.surface_names) {
      if (name == group) {
        selected.insert(tag);
        found = true;
      }
    }
    if (!found) {
      std::string available;
      for (const auto& [tag, name] : content.surface_names) {
        available += (available.empty() ? "" : ", ") + name;
      }
      const auto other = content.other_names.find(group);
      const std::string hint = other == content.other_names.end()
                                   ? std::string()
                                   : " ('" + group + "' is a " + std::to_string(other->second) + "-D group)";
      throw std::invalid_argument(path + ": no physical surface group named '" + group + "'" + hint +
                                  " (available: " + (available.empty() ? "none" : available) + ")");
    }
  }
  if (!selected.empty() && content.version4 && !content.has_entities) {
    throw std::invalid_argument(path + ": an MSH 4.1 file without $Entities has no physical groups");
  }
  const auto is_selected = [&](const RawElement& element) {
    if (selected.empty()) return true;
    if (!content.version4) return selected.count(element.physical) > 0;
    const auto entity = content.surface_physicals.find(element.entity);
    if (entity == content.surface_physicals.end()) return false;
    return std::any_of(entity->second.begin(), entity->second.end(),
                       [&](int tag) { return selected.count(tag) > 0; });
  };

  // MSH 2 repeats an element once per physical group it belongs to: keep one copy.
  std::set<std::tuple<int, long long, long long, long long>> seen;
  std::vector<const RawElement*> kept;
  for (const RawElement& element : content.elements) {
    if (!is_selected(element)) continue;
    if (element.type != 2) {
      throw std::invalid_argument(path + ": element " + std::to_string(element.tag) + " is a " +
                                  element_type_name(element.type) + " (type " + std::to_string(element.type) +
                                  "): only 3-node triangles (type 2) are supported");
    }
    if (seen.insert({element.entity, element.nodes[0], element.nodes[1], element.nodes[2]}).second) {
      kept.push_back(&element);
    }
  }
  if (kept.empty()) {
    std::string names;
    for (const std::string& group : groups) names += (names.empty() ? "" : ", ") + group;
    throw std::invalid_argument(path + ": no triangles (type 2 elements)" +
                                (names.empty() ? std::string() : " in the groups " + names));
  }

  // Only the nodes the triangles use, numbered in increasing gmsh tag order.
  geometry::SurfaceData data;
  data.labels.vertex_kind = "gmsh node";
  data.labels.triangle_kind = "gmsh element";
  std::vector<long long>& vertex_tags = data.labels.vertex_tags;
  vertex_tags.reserve(3 * kept.size());
  for (const RawElement* element : kept) {
    vertex_tags.insert(vertex_tags.end(), element->nodes.begin(), element->nodes.end());
  }
  std::sort(vertex_tags.begin(), vertex_tags.end());
  vertex_tags.erase(std::unique(vertex_tags.begin(), vertex_tags.end()), vertex_tags.end());
  data.vertices.reserve(vertex_tags.size());
  std::unordered_map<long long, int> index_of;
  index_of.reserve(vertex_tags.size());
  for (long long tag : vertex_tags) {
    const auto node = content.nodes.find(tag);
    if (node == content.nodes.end()) {
      throw std::invalid_argument(path + ": node " + std::to_string(tag) +
                                  " is used by a triangle but missing from $Nodes");
    }
    index_of[tag] = static_cast<int>(data.vertices.size());
    data.vertices.push_back(node->second);
  }
  data.triangles.reserve(kept.size());
  data.labels.triangle_tags.reserve(kept.size());
  for (const RawElement* element : kept) {
    data.triangles.emplace_back(index_of[element->nodes[0]], index_of[element->nodes[1]], index_of[element->nodes[2]]);
    data.labels.triangle_tags.push_back(element->tag);
  }
  return data;
}

geometry::TriangleSurface load_msh_surface(const std::string& path, const std::vector<std::string>& groups) {
  geometry::SurfaceData data = read_msh_surface(path, groups);
  return geometry::TriangleSurface(std::move(data.vertices), std::move(data.triangles), path, data.labels);
}

std::vector<MshPhysicalName> read_msh_physical_names(const std::string& path) {
  return read_msh(path, Sections::physical_names).physical_names;
}

}  // namespace touchstone::meshes
