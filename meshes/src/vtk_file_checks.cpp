// What is checked in a surface file before a VTK reader sees it (vtk_file_checks.hpp).
#include "vtk_file_checks.hpp"

#include "text_of.hpp"

#include <vtkBase64Utilities.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::meshes::internal {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::invalid_argument(path + ": " + what);
}

/// VTK 9.1's legacy reader trusts a file's cell lists: a list cut short or holding a word makes
/// it read on from a closed stream (a null dereference), and a cell that claims more points than
/// its list holds makes it read past its buffer. Every list is checked first: the values its
/// header declares are there and are integers, and the cells fit the list exactly (`size`
/// values of "n id…" records before version 5; `count` offsets from 0 to `size` and `size`
/// connectivity entries from version 5). ASCII files are read word by word, binary ones skip
/// their point coordinates and read the lists' big-endian integers. Cell lists come before the
/// point and cell data, where names are free text: the scan stops there.
class LegacyCellLists {
 public:
  LegacyCellLists(const std::string& path, bool binary) : path_(path), binary_(binary) {
    std::ifstream in(path, std::ios::binary);
    bytes_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    for (int line = 0; line < 2; ++line) {  // the signature and the title (free text)
      const std::size_t end = bytes_.find('\n', at_);
      at_ = end == std::string::npos ? bytes_.size() : end + 1;
    }
  }

  void check() {
    for (;;) {
      skip_space();
      const std::size_t start = at_;
      std::string keyword = word();
      if (keyword.empty()) return;
      keyword = as_vtk_reads(keyword);
      if (keyword == "POINT_DATA" || keyword == "CELL_DATA") {
        attributes_start_ = start;
        return;
      }
      if (keyword == "FIELD") {
        skip_field_data();
        field_blocks_.emplace_back(start, at_);
        continue;
      }
      if (keyword == "POINTS" && binary_) {
        const unsigned long long count = counted(keyword, word());
        const std::string type = word();
        const std::size_t width = type_width(type);
        if (width == 0) fail(path_, "malformed legacy VTK file: POINTS of an unknown data type '" + type + "'");
        skip_binary(keyword, static_cast<double>(count) * 3 * static_cast<double>(width));
        continue;
      }
      if (keyword == "POINTS") {
        // ASCII coordinates cut short or holding a word send VTK reading on from a failed
        // stream, as cell lists do.
        const unsigned long long count = counted(keyword, word());
        const std::string type = word();
        if (type_width(type) == 0) fail(path_, "malformed legacy VTK file: POINTS of an unknown data type '" + type + "'");
        for (unsigned long long k = 0; k < 3 * count; ++k) {
          const std::string text = word();
          double value = 0;
          const auto [stop, error] = std::from_chars(text.data(), text.data() + text.size(), value);
          if (text.empty() || stop != text.data() + text.size() || (error != std::errc() && error != std::errc::result_out_of_range))
            fail(path_, "malformed legacy VTK file: POINTS declares " + std::to_string(count) + " points, coordinate " +
                            std::to_string(k + 1) + " is " + (text.empty() ? std::string("missing") : "'" + text + "'"));
        }
        continue;
      }
      if (keyword != "VERTICES" && keyword != "LINES" && keyword != "POLYGONS" && keyword != "TRIANGLE_STRIPS") continue;
      const unsigned long long count = counted(keyword, word());
      const unsigned long long size = counted(keyword, word());
      const std::size_t before_layout = at_;
      if (word() == "OFFSETS") {
        const std::vector<long long> offsets = values("OFFSETS of " + keyword, count, type_width(word()));
        if (word() != "CONNECTIVITY") fail(path_, "malformed legacy VTK file: " + keyword + " has OFFSETS but no CONNECTIVITY after them");
        values("CONNECTIVITY of " + keyword, size, type_width(word()));
        for (std::size_t k = 0; k < offsets.size(); ++k) {
          if ((k == 0 && offsets[k] != 0) || (k > 0 && offsets[k] < offsets[k - 1]) ||
              offsets[k] > static_cast<long long>(size) || (k + 1 == offsets.size() && offsets[k] != static_cast<long long>(size))) {
            fail(path_, "malformed legacy VTK file: OFFSETS of " + keyword + ": offset " + std::to_string(k + 1) + " is " +
                            std::to_string(offsets[k]) + "; offsets must rise from 0 to the connectivity size " +
                            std::to_string(size));
          }
        }
        continue;
      }
      at_ = before_layout;
      const std::vector<long long> list = values(keyword, size, 4);
      unsigned long long cells = 0;
      for (std::size_t k = 0; k < list.size(); k += static_cast<std::size_t>(list[k]) + 1) {
        ++cells;
        if (list[k] < 0 || static_cast<unsigned long long>(list[k]) >= list.size() - k) {
          fail(path_, "malformed legacy VTK file: " + keyword + " cell " + std::to_string(cells) + " claims " +
                          std::to_string(list[k]) + " points, the list has " + std::to_string(list.size() - k - 1) +
                          " values left");
        }
      }
      if (cells != count) {
        fail(path_, "malformed legacy VTK file: " + keyword + " declares " + std::to_string(count) + " cells, its " +
                        std::to_string(size) + " values hold " + std::to_string(cells));
      }
    }
  }

  /// The bytes VTK is given after check(): the file without its FIELD blocks and without the
  /// point and cell data that follow the geometry. A surface needs neither, and VTK 9.1 reads
  /// them unchecked (a FIELD block it cannot read is a null dereference; POINT_DATA sizes its
  /// arrays by a count the file declares).
  std::string geometry() const {
    std::string kept;
    std::size_t from = 0;
    for (const auto& [begin, end] : field_blocks_) {
      kept.append(bytes_, from, begin - from);
      from = end;
    }
    kept.append(bytes_, from, std::min(attributes_start_, bytes_.size()) - from);
    return kept;
  }

 private:
  /// A FIELD block of the dataset section, from its name on: "FIELD name arrays", then per
  /// array "name components tuples type" and its values (or the word NULL_ARRAY), each array
  /// perhaps followed by a METADATA block that ends at an empty line. Only numeric arrays are
  /// accepted: they are skipped, not read, and their extent must be certain.
  void skip_field_data() {
    const std::string name = word();
    long long arrays = 0;
    if (name.empty() || !integer(word(), arrays) || arrays < 0)
      fail(path_, "malformed legacy VTK file: FIELD must be followed by a name and its number of arrays");
    for (long long a = 0; a < arrays; ++a) {
      const std::string array = word();
      if (array.empty()) {
        fail(path_, "truncated legacy VTK file: FIELD '" + name + "' declares " + std::to_string(arrays) +
                        " arrays, the file ends after " + std::to_string(a));
      }
      if (array == "NULL_ARRAY") continue;
      const std::string what = "FIELD '" + name + "' array '" + array + "'";
      const unsigned long long components = counted(what, word());
      const unsigned long long tuples = counted(what, word());
      const std::string type = word();
      const std::size_t width = type_width(type);
      if (width == 0) {
        fail(path_, "unsupported legacy VTK file: " + what + " is of type '" + type +
                        "'; only numeric FIELD arrays can be skipped (a surface's field data is not read)");
      }
      const double values = static_cast<double>(components) * static_cast<double>(tuples);
      if (binary_) {
        skip_binary(what, type == "bit" ? std::ceil(values / 8) : values * static_cast<double>(width));
      } else {
        for (double k = 0; k < values; ++k) {
          const std::string text = word();
          double value = 0;
          const auto [stop, error] = std::from_chars(text.data(), text.data() + text.size(), value);
          if (text.empty() || stop != text.data() + text.size() ||
              (error != std::errc() && error != std::errc::result_out_of_range)) {
            fail(path_, "malformed legacy VTK file: " + what + " declares " + text_of(values) + " values, value " +
                            text_of(k + 1) + " is " + (text.empty() ? std::string("missing") : "'" + text + "'"));
          }
        }
      }
      skip_metadata();
    }
  }

  /// A METADATA block after an array, if there is one: to the first empty line.
  void skip_metadata() {
    const std::size_t before = at_;
    std::string next = word();
    for (char& c : next) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (next.rfind("metadata", 0) != 0) {
      at_ = before;
      return;
    }
    // Its lines follow the keyword's line; the first empty one ends it.
    bool keyword_line = true;
    for (std::size_t end = bytes_.find('\n', at_); end != std::string::npos; end = bytes_.find('\n', at_)) {
      std::size_t length = end - at_;
      if (length > 0 && bytes_[end - 1] == '\r') --length;
      at_ = end + 1;
      if (length == 0 && !keyword_line) return;
      keyword_line = false;
    }
    at_ = bytes_.size();
  }

  /// The keyword VTK's reader takes a word for: it lower-cases the word and compares only the
  /// keyword's length of it ("POLYGONSxyz" is POLYGONS), so the check must too.
  static std::string as_vtk_reads(const std::string& word) {
    std::string lower = word;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (const char* keyword :
         {"point_data", "cell_data", "field", "points", "vertices", "lines", "polygons", "triangle_strips"}) {
      if (lower.rfind(keyword, 0) == 0) {
        std::string upper = keyword;
        for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
        return upper;
      }
    }
    return word;
  }

  void skip_space() {
    while (at_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[at_]))) ++at_;
  }

  /// The next whitespace-separated word ("" at the end of the file).
  std::string word() {
    skip_space();
    const std::size_t begin = at_;
    while (at_ < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[at_]))) ++at_;
    return bytes_.substr(begin, at_ - begin);
  }

  static bool integer(const std::string& text, long long& value) {
    const char* begin = text.data() + (!text.empty() && text[0] == '+' ? 1 : 0);
    const auto [stop, error] = std::from_chars(begin, text.data() + text.size(), value);
    return error == std::errc() && stop == text.data() + text.size() && begin != stop;
  }

  unsigned long long counted(const std::string& keyword, const std::string& text) const {
    long long value = 0;
    if (!integer(text, value) || value < 0)
      fail(path_, "malformed legacy VTK file: " + keyword + " must be followed by counts, found '" + text + "'");
    return static_cast<unsigned long long>(value);
  }

  /// Bytes per value of a legacy data type; 0 for a type name VTK does not know either.
  static std::size_t type_width(const std::string& type) {
    if (type == "bit" || type == "char" || type == "unsigned_char") return 1;
    if (type == "short" || type == "unsigned_short") return 2;
    if (type == "int" || type == "unsigned_int" || type == "float") return 4;
    if (type == "long" || type == "unsigned_long" || type == "double" || type == "vtkIdType" ||
        type == "vtktypeint64" || type == "vtktypeuint64")
      return 8;
    return 0;
  }

  /// Binary data starts after the end of its header line.
  void skip_binary(const std::string& what, double byte_count) {
    const std::size_t end = bytes_.find('\n', at_);
    at_ = end == std::string::npos ? bytes_.size() : end + 1;
    if (byte_count > static_cast<double>(bytes_.size() - at_))
      fail(path_, "truncated legacy VTK file: " + what + " needs " + text_of(byte_count) + " bytes, the file has " +
                      std::to_string(bytes_.size() - at_) + " left");
    at_ += static_cast<std::size_t>(byte_count);
  }

  /// `declared` integers: words of an ASCII file, big-endian values of `width` bytes (a signed
  /// 32- or 64-bit type: VTK's cell lists) in a binary one.
  std::vector<long long> values(const std::string& list, unsigned long long declared, std::size_t width) {
    std::vector<long long> read;
    if (binary_) {
      if (width != 4 && width != 8) fail(path_, "malformed legacy VTK file: " + list + " is not of an integer type");
      const std::size_t start = bytes_.find('\n', at_) == std::string::npos ? bytes_.size() : bytes_.find('\n', at_) + 1;
      const std::size_t left = (bytes_.size() - start) / width;
      if (declared > left) {
        fail(path_, "truncated legacy VTK file: " + list + " declares " + std::to_string(declared) +
                        " values, the file ends after " + std::to_string(left));
      }
      at_ = start;
      read.reserve(static_cast<std::size_t>(declared));
      for (unsigned long long k = 0; k < declared; ++k) {
        unsigned long long word = 0;
        for (std::size_t b = 0; b < width; ++b) word = (word << 8) | static_cast<unsigned char>(bytes_[at_++]);
        read.push_back(width == 4 ? static_cast<long long>(static_cast<std::int32_t>(word)) : static_cast<long long>(word));
      }
      return read;
    }
    for (unsigned long long k = 0; k < declared; ++k) {
      const std::string text = word();
      long long value = 0;
      if (text.empty()) {
        fail(path_, "truncated legacy VTK file: " + list + " declares " + std::to_string(declared) +
                        " values, the file ends after " + std::to_string(k));
      }
      if (!integer(text, value)) {
        fail(path_, "malformed legacy VTK file: " + list + " declares " + std::to_string(declared) + " values, value " +
                        std::to_string(k + 1) + " is '" + text + "', not an integer");
      }
      // VTK reads a 4-byte list (the cell lists before version 5) into ints: a value beyond
      // them fails its stream, which it closes and then reads on from (a null dereference).
      if (width == 4 && (value > std::numeric_limits<std::int32_t>::max() || value < std::numeric_limits<std::int32_t>::min())) {
        fail(path_, "malformed legacy VTK file: " + list + " value " + std::to_string(k + 1) + " is " + text +
                        ", outside the 32-bit integers VTK reads it as");
      }
      read.push_back(value);
    }
    return read;
  }

  const std::string& path_;
  bool binary_;
  std::string bytes_;
  std::size_t at_ = 0;
  std::vector<std::pair<std::size_t, std::size_t>> field_blocks_;  // [begin, end) in bytes_
  std::size_t attributes_start_ = std::string::npos;
};

/// The integer value of attribute `name` in the XML start tag `tag` (either quote), or false
/// when it is absent or not a non-negative integer (the XML reader then says what is wrong).
bool xml_count_attribute(const std::string& tag, const std::string& name, unsigned long long& value) {
  for (std::size_t at = tag.find(name); at != std::string::npos; at = tag.find(name, at + 1)) {
    if (at == 0 || !std::isspace(static_cast<unsigned char>(tag[at - 1]))) continue;
    std::size_t k = at + name.size();
    while (k < tag.size() && std::isspace(static_cast<unsigned char>(tag[k]))) ++k;
    if (k >= tag.size() || tag[k] != '=') continue;
    ++k;
    while (k < tag.size() && std::isspace(static_cast<unsigned char>(tag[k]))) ++k;
    if (k >= tag.size() || (tag[k] != '"' && tag[k] != '\'')) continue;
    ++k;
    const auto [stop, error] = std::from_chars(tag.data() + k, tag.data() + tag.size(), value);
    return error == std::errc() && stop != tag.data() + k;
  }
  return false;
}

/// Compressed VTK XML data starts with a header of [block count, block size, last block size,
/// compressed size of each block], and VTK allocates the per-block sizes before it reads them:
/// a corrupt block count claims gigabytes. Each array's count is checked against the bytes its
/// header can occupy, inline (base64 after the tag) or at its offset in the appended data.
class CompressedBlockCounts {
 public:
  CompressedBlockCounts(const std::string& path, const std::string& text) : path_(path), text_(text) {}

  void read_file_attributes(const std::string& tag) {
    compressed_ = tag.find("compressor=") != std::string::npos;
    word_ = tag.find("UInt64") != std::string::npos ? 8 : 4;  // header_type; VTK's default is UInt32
    big_endian_ = tag.find("BigEndian") != std::string::npos;
  }

  /// A DataArray start tag whose content begins at `content`.
  void check_array(const std::string& tag, std::size_t content, int piece) {
    if (!compressed_) return;
    if (tag.find("\"binary\"") != std::string::npos || tag.find("'binary'") != std::string::npos) {
      const std::size_t stop = std::min(text_.find('<', content), text_.size());
      // VTK starts inline data at its first character that is not white space.
      while (content < stop && std::isspace(static_cast<unsigned char>(text_[content]))) ++content;
      check(content, stop, true, "an inline compressed DataArray of piece " + std::to_string(piece));
    } else if (unsigned long long offset = 0; xml_count_attribute(tag, "offset", offset)) {
      appended_.push_back({offset, piece});
    } else if (tag.find("\"appended\"") != std::string::npos || tag.find("'appended'") != std::string::npos) {
      // VTK reads an offset that is not a number as 0, and the header there is another array's.
      const std::size_t at = tag.find(" offset=");
      std::string given;
      if (at != std::string::npos) {
        // The value after its opening quote; the tag may end right after "offset=".
        std::size_t begin = at + 8;
        if (begin < tag.size() && (tag[begin] == '"' || tag[begin] == '\'')) ++begin;
        given = tag.substr(begin, tag.find_first_of("\"'", begin) - begin);
      }
      fail(path_, "corrupt file: an appended compressed DataArray of piece " + std::to_string(piece) +
                      (at == std::string::npos ? " has no offset" : " has offset '" + given + "'") +
                      ", not a byte offset into the appended data");
    }
  }

  /// The AppendedData element starting at `at`.
  void check_appended(std::size_t at) {
    if (!compressed_) return;
    const std::size_t tag_end = text_.find('>', at);
    if (tag_end == std::string::npos) return;
    const std::string tag = text_.substr(at, tag_end - at);
    const bool base64 = tag.find("\"base64\"") != std::string::npos || tag.find("'base64'") != std::string::npos;
    // Where VTK's parser starts the data: at the first character after the tag that is not white
    // space (isspace, as VTK tests it), past it when it is the '_' that marks the data. Any other
    // character, say a stray byte, counts as data, and every header then reads shifted.
    std::size_t data = tag_end + 1;
    while (data < text_.size() && std::isspace(static_cast<unsigned char>(text_[data]))) ++data;
    if (data == text_.size()) return;
    if (text_[data] == '_') ++data;
    for (const auto& [offset, piece] : appended_) {
      if (offset >= text_.size() - data) continue;  // VTK says the offset is wrong
      check(data + static_cast<std::size_t>(offset), text_.size(), base64,
            "an appended compressed DataArray of piece " + std::to_string(piece));
    }
  }

 private:
  /// The compression header of the data in [from, stop).
  void check(std::size_t from, std::size_t stop, bool base64, const std::string& what) const {
    // Every header word is at least word_ bytes of data; base64 stores 3 bytes in 4 characters.
    const long double available = static_cast<long double>(stop - from) * (base64 ? 0.75L : 1.0L);
    std::vector<unsigned char> bytes = header_bytes(from, stop, base64, 3);
    const std::size_t words = bytes.size() / word_;
    if (words == 0) return;
    const unsigned long long count = header_word(bytes, 0);
    if (static_cast<long double>(count) * static_cast<long double>(word_) > available) {
      fail(path_, "corrupt file: " + what + " declares " + std::to_string(count) +
                      " compressed blocks, more block sizes than its data holds");
    }
    if (words < 3) return;
    // VTK takes the data's size as count · block size, with the last block's size in place of a
    // full one: no blocks and a last block underflow to an enormous size it then reads block 0
    // of (a null dereference), and blocks of size 0 divide by zero.
    const unsigned long long block_size = header_word(bytes, 1), last_block_size = header_word(bytes, 2);
    if (count == 0 && last_block_size != 0) {
      fail(path_, "corrupt file: " + what + " declares no compressed blocks but a last block of " +
                      std::to_string(last_block_size) + " bytes");
    }
    if (count > 0 && (block_size == 0 || last_block_size > block_size)) {
      fail(path_, "corrupt file: " + what + " declares compressed blocks of " + std::to_string(block_size) +
                      " bytes with a last block of " + std::to_string(last_block_size) + " bytes");
    }
    // VTK allocates a block's uncompressed size to decompress it into, and its compressed size to
    // read it into, before it reads a byte of it.
    const long double uncompressed_limit = max_xml_bytes_per_file_byte * static_cast<long double>(text_.size());
    if (count > 0 && static_cast<long double>(block_size) > uncompressed_limit) {
      fail(path_, "corrupt file: " + what + " declares compressed blocks of " + std::to_string(block_size) +
                      " bytes uncompressed, more than the file's " + std::to_string(text_.size()) + " bytes can hold");
    }
    bytes = header_bytes(from, stop, base64, 3 + static_cast<std::size_t>(count));
    for (std::size_t block = 0; block < count && 3 + block < bytes.size() / word_; ++block) {
      const unsigned long long compressed = header_word(bytes, 3 + block);
      if (static_cast<long double>(compressed) > available) {
        fail(path_, "corrupt file: " + what + " declares a compressed block " + std::to_string(block) + " of " +
                        std::to_string(compressed) + " bytes, more than its data holds");
      }
    }
  }

  /// The first `words` header words (fewer when the data holds fewer), as bytes.
  std::vector<unsigned char> header_bytes(std::size_t from, std::size_t stop, bool base64, std::size_t words) const {
    std::vector<unsigned char> bytes(words * word_ + 3);
    std::size_t decoded = 0;
    if (base64) {
      // The header is encoded on its own: whole 4-character quanta, 3 bytes each.
      const std::size_t wanted = (words * word_ + 2) / 3 * 4;
      const std::size_t characters = std::min((stop - from) / 4 * 4, wanted);
      decoded = vtkBase64Utilities::DecodeSafely(reinterpret_cast<const unsigned char*>(text_.data() + from), characters,
                                                 bytes.data(), bytes.size());
    } else {
      decoded = std::min(words * word_, stop - from);
      std::memcpy(bytes.data(), text_.data() + from, decoded);
    }
    bytes.resize(std::min(decoded, words * word_) / word_ * word_);
    return bytes;
  }

  unsigned long long header_word(const std::vector<unsigned char>& bytes, std::size_t w) const {
    unsigned long long value = 0;
    for (std::size_t b = 0; b < word_; ++b) {
      const std::size_t byte = w * word_ + (big_endian_ ? b : word_ - 1 - b);
      value = (value << 8) | bytes[byte];
    }
    return value;
  }

  const std::string& path_;
  const std::string& text_;
  bool compressed_ = false;
  std::size_t word_ = 4;
  bool big_endian_ = false;
  std::vector<std::pair<unsigned long long, int>> appended_;  // (offset, piece)
};

}  // namespace

/// Binary STL: 80-byte header, facet count, 50 bytes per facet. VTK reads facets until the end
/// of the file and ignores a partial last one, so a truncated file would load silently.
void check_binary_stl_size(const std::string& path, std::uintmax_t size) {
  if (size < 84) fail(path, "truncated binary STL file: " + std::to_string(size) + " bytes, less than its 84-byte header");
  std::ifstream in(path, std::ios::binary);
  unsigned char bytes[84];
  in.read(reinterpret_cast<char*>(bytes), 84);
  if (!in) fail(path, "cannot read the binary STL header");
  const std::uint32_t announced = static_cast<std::uint32_t>(bytes[80]) | static_cast<std::uint32_t>(bytes[81]) << 8 |
                                  static_cast<std::uint32_t>(bytes[82]) << 16 | static_cast<std::uint32_t>(bytes[83]) << 24;
  const std::uintmax_t body = size - 84;
  if (body % 50 != 0) {
    fail(path, "truncated or malformed binary STL file: " + std::to_string(body) +
                   " bytes after the header is not a whole number of 50-byte facets (header announces " +
                   std::to_string(announced) + " facets)");
  }
  // A zero count is a common exporter bug that VTK tolerates; any other mismatch is truncation.
  if (announced != 0 && announced != body / 50) {
    fail(path, "truncated or malformed binary STL file: the header announces " + std::to_string(announced) +
                   " facets, the file holds " + std::to_string(body / 50));
  }
}

/// The XML reader allocates, before it reads a value, every piece's NumberOfPoints coordinates
/// and an offset per declared cell, and for every data array NumberOfComponents values per tuple
/// of its piece. Their sum is checked against what the file can hold. It overestimates (a data
/// array counts the largest of its piece's counts, and the coordinates count twice, with the piece
/// and with its Points array); real surfaces compress by a few to one, far inside the bound.
void check_xml_declared_sizes(const std::string& path, std::uintmax_t size) {
  std::ifstream in(path, std::ios::binary);
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  // Raw appended data follows this tag; it holds bytes, not tags.
  const std::size_t appended_data = text.find("<AppendedData");
  const std::size_t tags_end = appended_data == std::string::npos ? text.size() : appended_data;
  CompressedBlockCounts blocks{path, text};
  const long double limit = max_xml_bytes_per_file_byte * static_cast<long double>(size);
  long double declared = 0;
  unsigned long long piece_points = 0;
  unsigned long long piece_cells = 0;
  int piece = 0;
  const auto refuse = [&](const std::string& what) {
    fail(path, "corrupt file: " + what + "; the whole file declares more data than its " + std::to_string(size) +
                   " bytes can hold");
  };
  for (std::size_t at = text.find('<'); at < tags_end; at = text.find('<', at + 1)) {
    const std::size_t end = text.find('>', at);
    if (end == std::string::npos) break;
    const std::string tag = text.substr(at, end - at);
    at = end;
    const auto is = [&](const char* element) {
      const std::size_t n = std::strlen(element);
      return tag.compare(1, n, element) == 0 && tag.size() > n + 1 && std::isspace(static_cast<unsigned char>(tag[n + 1]));
    };
    if (is("VTKFile")) {
      blocks.read_file_attributes(tag);
    } else if (is("Piece")) {
      ++piece;
      piece_points = 0;
      piece_cells = 0;
      (void)xml_count_attribute(tag, "NumberOfPoints", piece_points);
      // One offset per cell and one more per cell kind.
      long double cells = 0;
      long double offsets = 0;
      for (const char* kind : {"NumberOfVerts", "NumberOfLines", "NumberOfStrips", "NumberOfPolys"}) {
        unsigned long long count = 0;
        if (!xml_count_attribute(tag, kind, count)) continue;
        cells += static_cast<long double>(count);
        offsets += static_cast<long double>(count) + 1;
      }
      piece_cells = cells > 1.8e19L ? ~0ULL : static_cast<unsigned long long>(cells);
      declared += 24.0L * static_cast<long double>(piece_points) + 8.0L * offsets;
      if (declared > limit) {
        refuse("piece " + std::to_string(piece) + " declares " + std::to_string(piece_points) + " points and " +
               std::to_string(piece_cells) + " cells");
      }
    } else if (is("DataArray")) {
      unsigned long long components = 1;
      unsigned long long tuples = 0;
      (void)xml_count_attribute(tag, "NumberOfComponents", components);
      (void)xml_count_attribute(tag, "NumberOfTuples", tuples);
      // The value type's width: Int8 … Float64 name their bits; 8 bytes when it cannot be told.
      long double width = 8;
      if (const std::size_t type = tag.find("type="); type != std::string::npos) {
        const std::size_t digit = tag.find_first_of("0123456789", type);
        unsigned bits = 0;
        if (digit != std::string::npos && digit < tag.find_first_of(" \t\r\n", type) &&
            std::from_chars(tag.data() + digit, tag.data() + tag.size(), bits).ec == std::errc() && bits >= 8 && bits <= 64)
          width = bits / 8.0L;
      }
      blocks.check_array(tag, end + 1, piece);
      const unsigned long long count = std::max({tuples, piece_points, piece_cells});
      declared += static_cast<long double>(components) * static_cast<long double>(count) * std::max(width, 1.0L);
      if (declared > limit) {
        refuse("a DataArray of piece " + std::to_string(piece) + " declares " + std::to_string(components) +
               " components of " + std::to_string(count) + " tuples");
      }
    }
  }
  if (appended_data != std::string::npos) blocks.check_appended(appended_data);
}

/// VTK allocates what a header declares before it reads the data: a corrupt count would claim
/// gigabytes. The counts of a legacy file are checked against its size first: it stores at least
/// 6 bytes (ASCII "0 0 0 ") or 12 bytes (binary floats) per point.
std::string check_legacy_declared_sizes(const std::string& path, std::uintmax_t size) {
  std::ifstream in(path, std::ios::binary);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  // The version chooses how VTK reads the cells; a mangled one makes it read version 5 cell
  // arrays as the older format, out of bounds.
  const std::string signature = "# vtk DataFile Version ";
  std::size_t end = head.find('\n');
  if (end != std::string::npos && end > 0 && head[end - 1] == '\r') --end;
  const std::string version = head.rfind(signature, 0) == 0 && end != std::string::npos
                                  ? head.substr(signature.size(), end - signature.size())
                                  : std::string();
  const std::size_t dot = version.find('.');
  const auto digits = [](const std::string& text) {
    return !text.empty() && std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c); });
  };
  if (dot == std::string::npos || !digits(version.substr(0, dot)) || !digits(version.substr(dot + 1))) {
    fail(path, "not a legacy VTK file: the first line must be '# vtk DataFile Version <major>.<minor>'");
  }
  // The file type is the third line: "BINARY" anywhere else (a second header pasted into the
  // file) must not switch how the lists are read.
  std::size_t third = head.find('\n');
  third = third == std::string::npos ? third : head.find('\n', third + 1);
  const bool binary = third != std::string::npos && head.compare(third + 1, 6, "BINARY") == 0;
  LegacyCellLists lists(path, binary);
  lists.check();
  std::string geometry = lists.geometry();
  const std::size_t key = head.find("\nPOINTS ");
  if (key == std::string::npos) return geometry;  // VTK will say what is wrong
  unsigned long long points = 0;
  const char* begin = head.data() + key + 8;
  if (std::from_chars(begin, head.data() + head.size(), points).ec != std::errc()) return geometry;
  if (static_cast<double>(points) * (binary ? 12 : 6) > static_cast<double>(size)) {
    fail(path, "corrupt or truncated file: it declares " + std::to_string(points) + " points, more than " +
                   std::to_string(size) + " bytes can hold");
  }
  return geometry;
}

}  // namespace touchstone::meshes::internal
