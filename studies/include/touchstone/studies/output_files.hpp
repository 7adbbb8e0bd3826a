#pragma once
/// @file
/// What every subcommand needs to write its outputs: results.json numbers that never hold NaN,
/// numbers for the console and CSV cells, JSON look-ups that tolerate missing fields, and files
/// written atomically (a reader never sees half a file; a killed run leaves the old one).

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstddef>
#include <string>
#include <vector>

namespace touchstone::studies {

// --- JSON -------------------------------------------------------------------------------------

/// A finite number as itself, a non-finite one as null (JSON has no NaN).
nlohmann::json json_number(double value);
nlohmann::json vector_json(const Eigen::Vector3d& v);  ///< [x, y, z], non-finite → null
nlohmann::json matrix_json(const Eigen::Ref<const Eigen::MatrixXd>& m, int n = 3);  ///< rows of the top-left n×n block, non-finite → null
/// The inverses of vector_json and matrix_json (3 × 3) for what this program wrote: throws
/// nlohmann::json's exception on a missing or non-numeric entry (a null written for NaN included).
Eigen::Vector3d vector_from_json(const nlohmann::json& j);
Eigen::Matrix3d matrix_from_json(const nlohmann::json& j);
/// Whether a record read back holds what this program writes for finite values: a finite number,
/// an n-vector of them, rows of an n × n matrix of them (a NaN was written as null).
bool is_finite_number(const nlohmann::json& j);
bool is_finite_vector(const nlohmann::json& j, std::size_t n = 3);
bool is_finite_matrix(const nlohmann::json& j, std::size_t n = 3);
/// A JSON number, or NaN when it is null, absent or not a number.
double value_or_nan(const nlohmann::json& j);
double value_or_nan(const nlohmann::json& object, const char* key);
/// F·d of a JSON 3-vector; NaN when it is not one.
double axial(const nlohmann::json& vector, const Eigen::Vector3d& d);
/// The node at `path` below `j`, or a null node when any step is missing.
const nlohmann::json& json_at_path(const nlohmann::json& j, const std::vector<std::string>& path);

// --- Text -------------------------------------------------------------------------------------

/// A number for the console and for labels; "-" for a missing one (a failed case has no force:
/// "nan" would read like a numerical failure of a case that reported its status instead).
std::string format_number(double value);
/// A fixed-width table cell: `value` with `decimals`, or "-" right-aligned when it is missing.
std::string table_cell(double value, int width, int decimals);
/// A CSV field: quoted (with doubled quotes) only when it holds a comma, a quote or a newline.
std::string csv_escape(const std::string& text);
/// A CSV cell of a JSON value: empty for null, 10 significant digits for a float.
std::string csv_value(const nlohmann::json& j);

double seconds_since(std::chrono::steady_clock::time_point start);

// --- Files ------------------------------------------------------------------------------------

/// Writes `text` to `path` through a temporary file in the same folder and a rename, creating
/// the folder; throws std::runtime_error naming the path and the system's reason.
void write_file_atomically(const std::string& path, const std::string& text);

/// The same for a file written piece by piece (e.g. a history streamed during a run): the
/// pieces go to the temporary file, commit() renames it to `path`; a writer destroyed without
/// commit() removes the temporary, so a failed run leaves no half file. Every failure throws
/// std::runtime_error naming the path and the system's reason.
class AtomicFileWriter {
 public:
  explicit AtomicFileWriter(std::string path);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;
  void append(const char* data, std::size_t size);
  void append(const std::string& text) { append(text.data(), text.size()); }
  void commit();
  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void fail(const std::string& what, int error_number);
  std::string path_, temporary_;
  int fd_ = -1;
};
/// The whole file; throws std::runtime_error naming the path and the system's reason.
std::string read_file(const std::string& path);
/// `path` taken relative to `directory` when it is relative (a config's files are relative to
/// the config's folder), normalised; "" stays "".
std::string path_relative_to(const std::string& directory, const std::string& path);

}  // namespace touchstone::studies
