#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/geometry/regular_file.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>

namespace touchstone::studies {

namespace {

struct Unit {
  std::string_view symbol;
  double factor;  // SI value of one unit
};

struct DimensionInfo {
  const char* name;       // "a length", used in "cannot read ... as a length"
  const char* si_unit;    // what a bare number means
  const char* example;    // a typical spelling, shown in type errors
  std::vector<Unit> units;
};

constexpr double pi = 3.14159265358979323846;

// Micro is accepted as "u", as the micro sign U+00B5 and as Greek mu U+03BC, because editors and
// keyboards produce all three.
const DimensionInfo& dimension_info(Dimension dimension) {
  static const std::map<Dimension, DimensionInfo> table = {
      {Dimension::dimensionless,
       {"a number", "", "\"5 %\"", {{"%", 1e-2}}}},
      {Dimension::length,
       {"a length", "m", "\"2.5 mm\"",
        {{"m", 1.0}, {"cm", 1e-2}, {"mm", 1e-3}, {"um", 1e-6}, {"\xC2\xB5m", 1e-6},
         {"\xCE\xBCm", 1e-6}}}},
      {Dimension::pressure,
       {"a pressure", "Pa", "\"10 kPa\"",
        {{"Pa", 1.0}, {"kPa", 1e3}, {"MPa", 1e6}, {"GPa", 1e9}}}},
      {Dimension::angle,
       {"an angle", "rad", "\"30 deg\"",
        {{"rad", 1.0}, {"deg", pi / 180.0}, {"\xC2\xB0", pi / 180.0}}}},
      {Dimension::time,
       {"a time", "s", "\"5 ms\"",
        {{"s", 1.0}, {"ms", 1e-3}, {"us", 1e-6}, {"\xC2\xB5s", 1e-6}, {"\xCE\xBCs", 1e-6},
         {"ns", 1e-9}}}},
      {Dimension::force,
       {"a force", "N", "\"1.5 N\"", {{"N", 1.0}, {"mN", 1e-3}}}},
      {Dimension::stiffness,
       {"a stiffness", "N/m", "\"200 N/m\"", {{"N/m", 1.0}, {"N/mm", 1e3}}}},
  };
  return table.at(dimension);
}

// The unit list shown in errors; the Greek-mu duplicate spellings are left out to keep it short.
std::string unit_list(const DimensionInfo& info) {
  if (info.units.size() == 1 && info.units.front().symbol == "%") return "a plain number or %";
  std::string list;
  for (const Unit& unit : info.units) {
    if (unit.symbol.rfind("\xCE\xBC", 0) == 0) continue;
    if (!list.empty()) list += ", ";
    list += unit.symbol;
  }
  return "units: " + list;
}

std::string prefixed(const std::string& where, const std::string& message) {
  return where.empty() ? message : where + ": " + message;
}

std::string_view trim(std::string_view text) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  return text;
}

std::string type_name(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a floating-point number";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::date: return "a date";
    case toml::node_type::time: return "a time of day";
    case toml::node_type::date_time: return "a date-time";
    case toml::node_type::none: break;
  }
  return "nothing";
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// The candidate spelled closest to `key`, if close enough to be a misspelling of it ("" if
/// none). Short keys get little slack, or every one-letter key would "mean" every other.
std::string closest_spelling(const std::string& key, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_distance = (key.size() <= 3 ? std::size_t{1} : std::max<std::size_t>(2, key.size() / 4)) + 1;
  for (const std::string& candidate : candidates) {
    const std::size_t distance = edit_distance(key, candidate);
    if (distance < best_distance) {
      best = candidate;
      best_distance = distance;
    }
  }
  return best;
}

}  // namespace

double parse_quantity(const std::string& text, Dimension dimension, const std::string& where) {
  const DimensionInfo& info = dimension_info(dimension);
  const auto fail = [&]() -> ConfigError {
    return ConfigError(prefixed(where, "cannot read '" + text + "' as " + info.name + " (" +
                                           unit_list(info) + ")"));
  };

  std::string_view rest = trim(text);
  // from_chars takes no '+', but people write "+3 mm"; a sign after it stays an error.
  if (!rest.empty() && rest.front() == '+' && rest.size() > 1 && rest[1] != '-' &&
      rest[1] != '+') {
    rest.remove_prefix(1);
  }
  double value = 0.0;
  const auto [end, error] = std::from_chars(rest.data(), rest.data() + rest.size(), value);
  if (error == std::errc::result_out_of_range) {
    throw ConfigError(prefixed(where, "'" + text + "' is out of the range of a double"));
  }
  if (error != std::errc()) throw fail();
  if (!std::isfinite(value)) {
    throw ConfigError(prefixed(where, "'" + text + "' is not a finite number"));
  }

  const std::string_view symbol = trim(rest.substr(static_cast<std::size_t>(end - rest.data())));
  double factor = 1.0;
  if (!symbol.empty()) {
    const auto unit = std::find_if(info.units.begin(), info.units.end(),
                                   [&](const Unit& u) { return u.symbol == symbol; });
    if (unit == info.units.end()) throw fail();
    factor = unit->factor;
  }
  const double si = value * factor;
  if (!std::isfinite(si)) {
    throw ConfigError(prefixed(where, "'" + text + "' is out of the range of a double"));
  }
  return si;
}

struct ConfigTable::State {
  std::string source;  // file name shown in messages
  // The text the whole document was parsed from (shared by the sub-tables).
  std::shared_ptr<const std::string> text;
  std::string path;    // dotted path of this table, empty at the top level
  // Aliases the whole parsed document, so a sub-table keeps it alive.
  std::shared_ptr<const toml::table> table;
  std::set<std::string> used;
  // Every key an accessor asked for, present or not: candidates for "did you mean".
  std::set<std::string> asked;
  std::map<std::string, std::shared_ptr<State>> children;
  // Keys read with a default the file does not set ("section.key = value"), shared by the file.
  struct Defaults {
    std::vector<std::string> filled;
    std::set<std::string> keys;
  };
  std::shared_ptr<Defaults> defaults = std::make_shared<Defaults>();

  void note_default(const std::string& key, const std::string& value_text) {
    if (defaults->keys.insert(dotted(key)).second) defaults->filled.push_back(dotted(key) + " = " + value_text);
  }

  std::string dotted(const std::string& key) const { return path.empty() ? key : path + "." + key; }
  std::string where(const std::string& key) const { return source + ": " + dotted(key); }

  // The node under `key`, marking it used; nullptr when absent.
  const toml::node* get(const std::string& key) {
    asked.insert(key);
    const toml::node* node = table->get(key);
    if (node != nullptr) used.insert(key);
    return node;
  }

  const toml::node& require(const std::string& key) {
    const toml::node* node = get(key);
    if (node == nullptr) throw ConfigError(source + ": missing key '" + dotted(key) + "'" + misspelling_hint(key));
    return *node;
  }

  // A key the file has, spelled close to the missing `key`: " (is 'x' a misspelling of it?)".
  std::string misspelling_hint(const std::string& key) const {
    std::vector<std::string> present;
    for (const auto& [key_object, node] : *table) present.emplace_back(key_object.str());
    const std::string best = closest_spelling(key, present);
    return best.empty() ? "" : " (is '" + dotted(best) + "' a misspelling of it?)";
  }

  [[noreturn]] void type_error(const std::string& key, const toml::node& node,
                               const std::string& expected) const {
    throw ConfigError(where(key) + ": expected " + expected + ", got " + type_name(node));
  }

  void collect_unknown(std::vector<std::string>& messages) const {
    for (const auto& [key_object, node] : *table) {
      const std::string key(key_object.str());
      if (used.count(key) == 0) {
        std::string message = "'" + dotted(key) + "'";
        const std::string suggestion = closest_asked(key);
        if (!suggestion.empty()) message += " (did you mean '" + dotted(suggestion) + "'?)";
        messages.push_back(message);
      }
    }
    for (const auto& [key, child] : children) child->collect_unknown(messages);
  }

  // A key the program asked for but the file lacks, spelled close to `key`: the likely intent.
  std::string closest_asked(const std::string& key) const {
    std::vector<std::string> absent;
    for (const std::string& candidate : asked)
      if (!table->contains(candidate)) absent.push_back(candidate);
    return closest_spelling(key, absent);
  }
};

namespace {

std::string expected_quantity(const DimensionInfo& info) {
  if (info.si_unit[0] == '\0') return "a number or a string such as " + std::string(info.example);
  return std::string(info.name) + " such as " + info.example + " or a number in " + info.si_unit;
}

// A TOML number (SI) or a string with a unit; `where` names the key (and element) in messages.
std::optional<double> node_quantity(const toml::node& node, Dimension dimension,
                                    const std::string& where) {
  if (const auto* integer = node.as_integer()) return static_cast<double>(integer->get());
  if (const auto* floating = node.as_floating_point()) {
    if (!std::isfinite(floating->get())) {
      throw ConfigError(where + ": " + std::to_string(floating->get()) + " is not a finite number");
    }
    return floating->get();
  }
  if (const auto* string = node.as_string()) return parse_quantity(string->get(), dimension, where);
  return std::nullopt;
}

}  // namespace

namespace {

std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

std::string quantity_text(double value, Dimension dimension) {
  const char* unit = dimension_info(dimension).si_unit;
  return number_text(value) + (unit[0] == '\0' ? "" : std::string(" ") + unit);
}

template <class T, class Text>
std::string list_text(const std::vector<T>& values, Text text) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) out += (i == 0 ? "" : ", ") + text(values[i]);
  return out + "]";
}

}  // namespace

ConfigTable::ConfigTable(std::shared_ptr<State> state) : state_(std::move(state)) {}
ConfigTable::ConfigTable(ConfigTable&&) noexcept = default;
ConfigTable& ConfigTable::operator=(ConfigTable&&) noexcept = default;
ConfigTable::~ConfigTable() = default;

ConfigTable ConfigTable::from_file(const std::string& path) {
  if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty()) {
    throw ConfigError(path + ": cannot open config file (" + reason + ")");
  }
  std::ifstream stream(path, std::ios::binary);
  if (!stream) {
    throw ConfigError(path + ": cannot open config file (" + std::strerror(errno) + ")");
  }
  std::ostringstream text;
  text << stream.rdbuf();
  if (stream.bad()) {
    throw ConfigError(path + ": cannot read config file (" + std::strerror(errno) + ")");
  }
  return from_string(text.str(), path);
}

ConfigTable ConfigTable::from_string(const std::string& text, const std::string& source_name) {
  auto state = std::make_shared<State>();
  state->source = source_name;
  state->text = std::make_shared<const std::string>(text);
  try {
    state->table = std::make_shared<const toml::table>(toml::parse(text, source_name));
  } catch (const toml::parse_error& error) {
    const toml::source_position& begin = error.source().begin;
    throw ConfigError(source_name + ":" + std::to_string(begin.line) + ":" +
                      std::to_string(begin.column) + ": " + std::string(error.description()));
  }
  return ConfigTable(std::move(state));
}

bool ConfigTable::has(const std::string& key) const { return state_->table->contains(key); }

ConfigTable ConfigTable::table(const std::string& key, bool required) {
  State& state = *state_;
  // Asking twice gives the same state, so keys read through either copy count as used.
  if (const auto found = state.children.find(key); found != state.children.end()) {
    state.get(key);
    return ConfigTable(found->second);
  }
  const toml::node* node = required ? &state.require(key) : state.get(key);
  auto child = std::make_shared<State>();
  child->source = state.source;
  child->text = state.text;
  child->path = state.dotted(key);
  child->defaults = state.defaults;
  if (node == nullptr) {
    child->table = std::make_shared<const toml::table>();
  } else if (const toml::table* sub_table = node->as_table()) {
    child->table = std::shared_ptr<const toml::table>(state.table, sub_table);
  } else {
    state.type_error(key, *node, "a table");
  }
  state.children.emplace(key, child);
  return ConfigTable(std::move(child));
}

double ConfigTable::quantity(const std::string& key, Dimension dimension, double default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, quantity_text(default_value, dimension));
    return default_value;
  }
  const auto value = node_quantity(*node, dimension, where(key));
  if (!value) state_->type_error(key, *node, expected_quantity(dimension_info(dimension)));
  return *value;
}

double ConfigTable::quantity(const std::string& key, Dimension dimension) {
  const toml::node& node = state_->require(key);
  const auto value = node_quantity(node, dimension, where(key));
  if (!value) state_->type_error(key, node, expected_quantity(dimension_info(dimension)));
  return *value;
}

double ConfigTable::number(const std::string& key, double default_value) {
  if (!has(key)) {
    state_->get(key);  // asked: a candidate for "did you mean"
    state_->note_default(key, number_text(default_value));
    return default_value;
  }
  return number(key);
}

double ConfigTable::number(const std::string& key) {
  const toml::node& node = state_->require(key);
  if (node.is_string()) state_->type_error(key, node, "a number (without quotes)");
  const auto value = node_quantity(node, Dimension::dimensionless, where(key));
  if (!value) state_->type_error(key, node, "a number");
  return *value;
}

std::int64_t ConfigTable::integer(const std::string& key, std::int64_t default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, std::to_string(default_value));
    return default_value;
  }
  if (const auto* integer = node->as_integer()) return integer->get();
  state_->type_error(key, *node, "an integer");
}

bool ConfigTable::boolean(const std::string& key, bool default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, default_value ? "true" : "false");
    return default_value;
  }
  if (const auto* boolean = node->as_boolean()) return boolean->get();
  state_->type_error(key, *node, "true or false");
}

std::string ConfigTable::string(const std::string& key, const std::string& default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    // An empty default is "not set" (an optional file or name), not a value filled in.
    if (!default_value.empty()) state_->note_default(key, "\"" + default_value + "\"");
    return default_value;
  }
  if (const auto* string = node->as_string()) return string->get();
  state_->type_error(key, *node, "a string");
}

std::string ConfigTable::string(const std::string& key) {
  const toml::node& node = state_->require(key);
  if (const auto* string = node.as_string()) return string->get();
  state_->type_error(key, node, "a string");
}

std::string ConfigTable::file_path(const std::string& key, const std::string& default_value) {
  const std::string name = string(key, default_value);
  if (name.empty()) return name;
  std::filesystem::path path(name);
  if (path.is_relative()) path = std::filesystem::path(state_->source).parent_path() / path;
  require_input_file(state_->where(key), path.string());
  return std::filesystem::absolute(path).lexically_normal().string();
}

void require_input_file(const std::string& where, const std::string& path, const std::string& hint) {
  if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
    throw ConfigError(where + ": cannot read '" + path + "' (" + reason + ")");
  std::error_code ignored;
  if (!std::filesystem::is_regular_file(path, ignored))
    throw ConfigError(where + ": no such file '" + path + "'" + (hint.empty() ? "" : " (" + hint + ")"));
}

std::string ConfigTable::choice(const std::string& key, const std::vector<std::string>& choices,
                                const std::string& default_value) {
  std::string list;
  for (const std::string& choice : choices) list += (list.empty() ? "'" : ", '") + choice + "'";
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, "\"" + default_value + "\"");
    return default_value;
  }
  const auto* string = node->as_string();
  if (string == nullptr) state_->type_error(key, *node, "one of " + list);
  if (std::find(choices.begin(), choices.end(), string->get()) == choices.end()) {
    throw ConfigError(where(key) + ": '" + string->get() + "' is not one of " + list);
  }
  return string->get();
}

std::vector<std::string> ConfigTable::choice_list(const std::string& key,
                                                 const std::vector<std::string>& choices,
                                                 const std::vector<std::string>& default_value) {
  std::string list;
  for (const std::string& choice : choices) list += (list.empty() ? "'" : ", '") + choice + "'";
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, list_text(default_value, [](const std::string& v) { return "\"" + v + "\""; }));
    return default_value;
  }
  std::vector<const toml::node*> elements;
  if (node->is_string()) {
    elements.push_back(node);
  } else if (const toml::array* array = node->as_array()) {
    for (std::size_t i = 0; i < array->size(); ++i) elements.push_back(array->get(i));
  } else {
    state_->type_error(key, *node, "one of " + list + " or an array of them");
  }
  std::vector<std::string> result;
  for (std::size_t i = 0; i < elements.size(); ++i) {
    const auto* string = elements[i]->as_string();
    const std::string element = where(key) + (node->is_array() ? "[" + std::to_string(i) + "]" : "");
    if (string == nullptr || std::find(choices.begin(), choices.end(), string->get()) == choices.end())
      throw ConfigError(element + ": expected one of " + list);
    result.push_back(string->get());
  }
  return result;
}

std::array<double, 3> ConfigTable::vector3(const std::string& key, Dimension dimension,
                                           const std::array<double, 3>& default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, list_text(std::vector<double>(default_value.begin(), default_value.end()),
                                        [dimension](double v) { return quantity_text(v, dimension); }));
    return default_value;
  }
  const DimensionInfo& info = dimension_info(dimension);
  const std::string expected = std::string("an array of 3 numbers (in ") +
                               (info.si_unit[0] == '\0' ? "SI" : info.si_unit) +
                               ") or strings such as " + info.example;
  const toml::array* array = node->as_array();
  if (array == nullptr) state_->type_error(key, *node, expected);
  if (array->size() != 3) {
    throw ConfigError(where(key) + ": expected an array of 3 elements, got " +
                      std::to_string(array->size()));
  }
  std::array<double, 3> result{};
  for (std::size_t i = 0; i < 3; ++i) {
    const std::string element_where = where(key) + "[" + std::to_string(i) + "]";
    const auto value = node_quantity(*array->get(i), dimension, element_where);
    if (!value) {
      throw ConfigError(element_where + ": expected " + expected_quantity(info) + ", got " +
                        type_name(*array->get(i)));
    }
    result[i] = *value;
  }
  return result;
}

std::vector<double> ConfigTable::quantity_list(const std::string& key, Dimension dimension,
                                               const std::vector<double>& default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, list_text(default_value, [dimension](double v) { return quantity_text(v, dimension); }));
    return default_value;
  }
  const DimensionInfo& info = dimension_info(dimension);
  const toml::array* array = node->as_array();
  if (array == nullptr) {
    const auto value = node_quantity(*node, dimension, where(key));
    if (!value) {
      state_->type_error(key, *node, expected_quantity(info) + ", or an array of them");
    }
    return {*value};
  }
  std::vector<double> result;
  result.reserve(array->size());
  for (std::size_t i = 0; i < array->size(); ++i) {
    const std::string element_where = where(key) + "[" + std::to_string(i) + "]";
    const auto value = node_quantity(*array->get(i), dimension, element_where);
    if (!value) {
      throw ConfigError(element_where + ": expected " + expected_quantity(info) + ", got " +
                        type_name(*array->get(i)));
    }
    result.push_back(*value);
  }
  return result;
}

std::vector<std::int64_t> ConfigTable::integer_list(
    const std::string& key, const std::vector<std::int64_t>& default_value) {
  const toml::node* node = state_->get(key);
  if (node == nullptr) {
    state_->note_default(key, list_text(default_value, [](std::int64_t v) { return std::to_string(v); }));
    return default_value;
  }
  if (const auto* integer = node->as_integer()) return {integer->get()};
  const toml::array* array = node->as_array();
  if (array == nullptr) state_->type_error(key, *node, "an integer or an array of integers");
  std::vector<std::int64_t> result;
  result.reserve(array->size());
  for (std::size_t i = 0; i < array->size(); ++i) {
    const auto* integer = array->get(i)->as_integer();
    if (integer == nullptr) {
      throw ConfigError(where(key) + "[" + std::to_string(i) + "]: expected an integer, got " +
                        type_name(*array->get(i)));
    }
    result.push_back(integer->get());
  }
  return result;
}

void ConfigTable::finish() const {
  std::vector<std::string> unknown;
  state_->collect_unknown(unknown);
  if (unknown.empty()) return;
  std::string message = state_->source + (unknown.size() == 1 ? ": unknown key " : ": unknown keys ");
  for (std::size_t i = 0; i < unknown.size(); ++i) message += (i == 0 ? "" : ", ") + unknown[i];
  throw ConfigError(message);
}

std::string ConfigTable::where(const std::string& key) const { return state_->where(key); }

std::vector<std::string> ConfigTable::defaults_filled() const { return state_->defaults->filled; }

const std::string& ConfigTable::source_text() const { return *state_->text; }

void ConfigTable::require(const std::string& key) { state_->require(key); }

int checked_int(const std::string& where, std::int64_t value) {
  if (value < INT_MIN || value > INT_MAX)
    throw ConfigError(where + ": " + std::to_string(value) + " is out of the range of an int");
  return static_cast<int>(value);
}

int read_int(ConfigTable& table, const std::string& key, int default_value) {
  return checked_int(table.where(key), table.integer(key, default_value));
}

std::vector<int> read_int_list(ConfigTable& table, const std::string& key, const std::vector<int>& default_value) {
  const std::vector<std::int64_t> values =
      table.integer_list(key, std::vector<std::int64_t>(default_value.begin(), default_value.end()));
  std::vector<int> result;
  for (std::size_t i = 0; i < values.size(); ++i)
    result.push_back(checked_int(table.where(key) + "[" + std::to_string(i) + "]", values[i]));
  return result;
}

std::uint64_t read_seed(ConfigTable& table, const std::string& key, std::uint64_t default_value) {
  const std::int64_t seed = table.integer(key, static_cast<std::int64_t>(default_value));
  if (seed < 0) throw ConfigError(table.where(key) + ": " + std::to_string(seed) + " must be >= 0");
  return static_cast<std::uint64_t>(seed);
}

}  // namespace touchstone::studies
