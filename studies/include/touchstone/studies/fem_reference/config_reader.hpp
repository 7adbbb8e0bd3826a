#pragma once
/// @file
/// Reading TOML configs into parameter structs: quantities with units ("2.5 mm", "10 kPa"),
/// every key accounted for, and errors that name the file and the key.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace toml {
inline namespace v3 {
class table;
}
}  // namespace toml

namespace touchstone::studies {

/// Physical dimension of a quantity; decides which unit suffixes are accepted.
enum class Dimension { dimensionless, length, pressure, angle, time, force, stiffness };

/// Parses "2.5 mm", "10kPa", "30 deg", "1e-3" into SI (m, Pa, rad, s, N, N/m).
/// Throws ConfigError(where, ...) when the text is not a number with a unit of that dimension.
double parse_quantity(const std::string& text, Dimension dimension, const std::string& where);

/// An error in a config file; what() reads "<file>: <key>: <message>".
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Checks that the input file a config key names can be read: a ConfigError "<where>: no such
/// file '<path>'" (plus `hint`, e.g. how to make it) when it is missing, or naming what it is
/// instead when it is a folder, a device or a pipe (which would open and then block or never end).
void require_input_file(const std::string& where, const std::string& path, const std::string& hint = "");

/// One TOML table of a config file. Every key read is marked used; finish() throws on any key
/// that was never read, so a misspelled key is an error, not a silently ignored default.
class ConfigTable {
 public:
  /// Parses a file. Throws ConfigError naming the file (and line, for syntax errors).
  static ConfigTable from_file(const std::string& path);
  /// Parses TOML text; `source_name` stands for the file in messages.
  static ConfigTable from_string(const std::string& text, const std::string& source_name);

  ConfigTable(ConfigTable&&) noexcept;
  ConfigTable& operator=(ConfigTable&&) noexcept;
  ~ConfigTable();

  bool has(const std::string& key) const;
  /// Throws a ConfigError "missing key 'section.key'" when this table lacks it (with a key of
  /// the file spelled close to it, if any): the error of every required accessor.
  void require(const std::string& key);
  /// Sub-table (marked used). `required` false: an empty table when absent.
  ConfigTable table(const std::string& key, bool required = false);

  /// A quantity: a TOML number (taken as SI) or a string with a unit.
  double quantity(const std::string& key, Dimension dimension, double default_value);
  double quantity(const std::string& key, Dimension dimension);  ///< required
  double number(const std::string& key, double default_value);
  double number(const std::string& key);  ///< required
  std::int64_t integer(const std::string& key, std::int64_t default_value);
  bool boolean(const std::string& key, bool default_value);
  std::string string(const std::string& key, const std::string& default_value);
  std::string string(const std::string& key);  ///< required
  /// A file name: relative names are taken from the config file's folder; the file must exist
  /// (else a ConfigError naming the key and the path). Absolute and normalised; absent: the default.
  std::string file_path(const std::string& key, const std::string& default_value);
  /// A string that must be one of `choices`; the error lists them.
  std::string choice(const std::string& key, const std::vector<std::string>& choices,
                     const std::string& default_value);
  /// A choice or an array of choices (a sweep); a single string is a one-element list.
  std::vector<std::string> choice_list(const std::string& key, const std::vector<std::string>& choices,
                                       const std::vector<std::string>& default_value);
  /// Array of three numbers (or quantity strings) in SI.
  std::array<double, 3> vector3(const std::string& key, Dimension dimension,
                                const std::array<double, 3>& default_value);
  /// Array of quantities (or a single one, taken as a one-element list).
  std::vector<double> quantity_list(const std::string& key, Dimension dimension,
                                    const std::vector<double>& default_value);
  std::vector<std::int64_t> integer_list(const std::string& key,
                                         const std::vector<std::int64_t>& default_value);

  /// Throws ConfigError naming the first key of this table (recursively, of sub-tables taken
  /// with table()) that was never read.
  void finish() const;

  /// "file: section.key" for messages about a key's value found invalid after reading.
  std::string where(const std::string& key) const;

  /// Every key read with a default that the file does not set, as "section.key = value" (SI,
  /// with the unit) in the order first read; shared by the whole file, sub-tables included.
  /// The commands print it, so that nothing is filled in without a word.
  std::vector<std::string> defaults_filled() const;
  /// The text the document was parsed from (for a run's provenance: what was read, read once).
  const std::string& source_text() const;

 private:
  struct State;
  explicit ConfigTable(std::shared_ptr<State> state);
  std::shared_ptr<State> state_;
};

/// `value` as an int; ConfigError naming `where` when it does not fit.
int checked_int(const std::string& where, std::int64_t value);
/// An integer key that must fit an int.
int read_int(ConfigTable& table, const std::string& key, int default_value);
/// An integer or a list of integers, each fitting an int.
std::vector<int> read_int_list(ConfigTable& table, const std::string& key, const std::vector<int>& default_value);
/// A random seed: an integer ≥ 0.
std::uint64_t read_seed(ConfigTable& table, const std::string& key, std::uint64_t default_value);

/// The end of every study reader: every key of `config` was taken (else a ConfigError naming
/// the key), and the study's own validate() holds (else a ConfigError naming the file and field).
template <class Study>
void finish_and_validate(ConfigTable& config, const Study& study) {
  config.finish();
  try {
    study.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(config.where("") + e.what());
  }
}

}  // namespace touchstone::studies
