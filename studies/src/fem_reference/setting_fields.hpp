#pragma once
// One definition per setting: a table of fields per settings struct (TOML section and key, unit,
// results.json params key, doc, how to read it, its value). A study's config reader, its
// resolved-config writer and its results.json params all walk the table, so a new setting is one
// line in its table and appears, with the same name and unit, in all three.
//
// A field's section is a dotted path of TOML tables below the table the walk starts from
// ("" for that table itself, "approach.tremor" for [approach.tremor]). Quantities are read with
// their units ("2 mm") and written back in SI, so a resolved config reads back to the same values.
// It lives with the config reader in the folder the FEM cache key hashes: it reads FEM studies too.

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/geometry/contact_condition.hpp"
#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::studies {

template <class Settings>
struct SettingField {
  std::string section;     ///< dotted TOML table path ("" for the table the walk starts from)
  std::string key;         ///< the key in that table
  std::string params_key;  ///< its name in results.json params (unique over the table)
  std::string unit;        ///< SI unit or what it counts ("" for a plain dimensionless number)
  std::string doc;         ///< one line: what it sets
  /// Reads the key from its section (absent: keeps the current value).
  std::function<void(ConfigTable& section, Settings& settings)> read;
  /// Its value as results.json and the resolved config write it (a name for an enum, SI numbers).
  std::function<nlohmann::json(const Settings& settings)> value;
};

/// An enum value and its spelling in configs, results.json and resolved configs.
template <class E>
struct Named {
  const char* name;
  E value;
};

template <class E>
std::vector<std::string> names(const std::vector<Named<E>>& table) {
  std::vector<std::string> result;
  for (const auto& entry : table) result.push_back(entry.name);
  return result;
}

template <class E>
std::string name_of(const std::vector<Named<E>>& table, E value) {
  for (const auto& entry : table)
    if (entry.value == value) return entry.name;
  return "unknown";
}

/// The value named `name` (ConfigTable::choice has already checked that it is one of them).
template <class E>
E value_of(const std::vector<Named<E>>& table, const std::string& name) {
  for (const auto& entry : table)
    if (name == entry.name) return entry.value;
  throw std::invalid_argument("unknown name '" + name + "'");
}

/// The spellings of the enums several study files share.
inline const std::vector<Named<meshes::OrganShape>> organ_shapes{{"stomach", meshes::OrganShape::stomach},
                                                                 {"hemisphere", meshes::OrganShape::hemisphere}};
inline const std::vector<Named<geometry::ContactCondition>> contact_conditions{
    {"frictionless", geometry::ContactCondition::frictionless}, {"bonded", geometry::ContactCondition::bonded}};
/// The FEM's linear solvers, spelled as fem::to_string spells them.
inline const std::vector<Named<fem::LinearSolver>> linear_solvers{{"cg_amg_trilinos", fem::LinearSolver::cg_amg_trilinos},
                                                                  {"cg_gamg_petsc", fem::LinearSolver::cg_gamg_petsc},
                                                                  {"direct_mumps", fem::LinearSolver::direct_mumps}};

/// The naming part of a field; the field makers below add how it is read and written.
struct FieldNames {
  const char* section;
  const char* key;
  const char* unit;
  const char* doc;
  const char* params_key = "";  ///< "" → derived by assign_params_keys
};

// Field makers. `get` is a generic lambda returning a reference to the member, so one accessor
// serves the reader (non-const settings) and the value (const settings).
namespace field {

template <class Settings, class Get>
SettingField<Settings> integer(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = read_int(t, key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

/// A plain number (dimensionless, or with its unit in the key's name, e.g. speed_min_m_per_s).
template <class Settings, class Get>
SettingField<Settings> real(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = t.number(key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

/// A quantity with a unit in the config ("2 mm", "30 deg"), SI in the settings and the outputs.
template <class Settings, class Get>
SettingField<Settings> quantity(FieldNames n, Dimension dimension, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key, dimension](ConfigTable& t, Settings& s) { get(s) = t.quantity(key, dimension, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

template <class Settings, class Get>
SettingField<Settings> boolean(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = t.boolean(key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

template <class Settings, class Get>
SettingField<Settings> text(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = t.string(key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

/// A file that must exist; a relative name is taken from the config file's folder.
template <class Settings, class Get>
SettingField<Settings> file(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = t.file_path(key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

/// Three numbers (or quantity strings) of one dimension, held as std::array<double, 3>.
template <class Settings, class Get>
SettingField<Settings> vector3(FieldNames n, Dimension dimension, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key, dimension](ConfigTable& t, Settings& s) { get(s) = t.vector3(key, dimension, get(s)); },
          [get](const Settings& s) {
            const auto& v = get(s);
            return nlohmann::json{v[0], v[1], v[2]};
          }};
}

/// A random seed: an integer >= 0.
template <class Settings, class Get>
SettingField<Settings> seed(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = read_seed(t, key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(static_cast<std::int64_t>(get(s))); }};
}

/// One of the names in `choices` (which must outlive the field: a static table).
template <class Settings, class E, class Get>
SettingField<Settings> choice(FieldNames n, const std::vector<Named<E>>& choices, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key, &choices](ConfigTable& t, Settings& s) {
            get(s) = value_of(choices, t.choice(key, names(choices), name_of(choices, get(s))));
          },
          [get, &choices](const Settings& s) { return nlohmann::json(name_of(choices, get(s))); }};
}

/// An integer or a list of integers.
template <class Settings, class Get>
SettingField<Settings> integer_list(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, Settings& s) { get(s) = read_int_list(t, key, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

/// A quantity or a list of quantities, SI in the settings and the outputs.
template <class Settings, class Get>
SettingField<Settings> quantity_list(FieldNames n, Dimension dimension, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key, dimension](ConfigTable& t, Settings& s) { get(s) = t.quantity_list(key, dimension, get(s)); },
          [get](const Settings& s) { return nlohmann::json(get(s)); }};
}

/// The same field, but the file must set it: a ConfigError naming the key instead of a
/// default. For what defines the problem (the material, the tool's size and depth, the body's
/// size), where a default would be a guess.
template <class Settings>
SettingField<Settings> required(SettingField<Settings> f) {
  const auto read = f.read;
  const std::string key = f.key;
  f.read = [read, key](ConfigTable& t, Settings& s) {
    t.require(key);
    read(t, s);
  };
  f.doc += " (required)";
  return f;
}

}  // namespace field

/// Appends `fields` (a table of a member struct) to `out` (the table of the struct holding it),
/// under `section` (prefixed to each field's section) and reached through `get`. params keys:
/// `params_prefix` + the member table's keys, or (empty prefix) derived again in `out`'s table.
template <class Parent, class Child, class Get>
void append_member_fields(std::vector<SettingField<Parent>>& out, const std::vector<SettingField<Child>>& fields,
                          const std::string& section, const std::string& params_prefix, Get get) {
  for (const auto& f : fields) {
    SettingField<Parent> lifted{f.section.empty() ? section : section.empty() ? f.section : section + "." + f.section,
                                f.key,
                                params_prefix.empty() ? "" : params_prefix + f.params_key,
                                f.unit,
                                f.doc,
                                nullptr,
                                nullptr};
    if (f.read) lifted.read = [read = f.read, get](ConfigTable& t, Parent& s) { read(t, get(s)); };
    lifted.value = [value = f.value, get](const Parent& s) { return value(get(s)); };
    out.push_back(std::move(lifted));
  }
}

/// Gives every field without an explicit params key one: its key where the key is unique over
/// the table, else section_key (dots → underscores). Throws std::logic_error when two fields
/// share a params key or a section.key (a table defect, caught by the table's tests).
template <class Settings>
void assign_params_keys(std::vector<SettingField<Settings>>& fields, const std::string& table_name) {
  std::map<std::string, int> uses;
  for (const auto& f : fields) ++uses[f.key];
  std::set<std::string> taken, places;
  for (auto& f : fields) {
    if (f.params_key.empty()) {
      std::string prefix = f.section;
      for (char& c : prefix)
        if (c == '.') c = '_';
      f.params_key = uses[f.key] == 1 ? f.key : prefix + "_" + f.key;
    }
    if (!taken.insert(f.params_key).second)
      throw std::logic_error(table_name + " settings table: params key '" + f.params_key + "' used twice");
    if (!places.insert(f.section + "." + f.key).second)
      throw std::logic_error(table_name + " settings table: " + f.section + "." + f.key + " listed twice");
  }
}

namespace detail {
/// The table at the dotted `path` below `root` (marked used; empty when absent).
inline ConfigTable& section_of(ConfigTable& root, const std::string& path,
                               std::map<std::string, ConfigTable>& opened) {
  if (path.empty()) return root;
  if (auto found = opened.find(path); found != opened.end()) return found->second;
  const auto dot = path.rfind('.');
  ConfigTable& parent = dot == std::string::npos ? root : section_of(root, path.substr(0, dot), opened);
  ConfigTable child = parent.table(dot == std::string::npos ? path : path.substr(dot + 1));
  return opened.emplace(path, std::move(child)).first->second;
}

inline toml::table& toml_section_of(toml::table& root, const std::string& path) {
  toml::table* table = &root;
  std::size_t begin = 0;
  while (begin < path.size()) {
    const std::size_t dot = path.find('.', begin);
    const std::string name = path.substr(begin, dot == std::string::npos ? std::string::npos : dot - begin);
    if (!table->contains(name)) table->insert(name, toml::table{});
    table = (*table)[name].as_table();
    begin = dot == std::string::npos ? path.size() : dot + 1;
  }
  return *table;
}

/// A scalar JSON value as a TOML value.
inline void insert_toml(toml::table& table, const std::string& key, const nlohmann::json& value) {
  if (value.is_boolean()) table.insert_or_assign(key, value.get<bool>());
  else if (value.is_number_integer()) table.insert_or_assign(key, value.get<std::int64_t>());
  else if (value.is_number()) table.insert_or_assign(key, value.get<double>());
  else if (value.is_string()) table.insert_or_assign(key, value.get<std::string>());
  else if (value.is_array()) {
    toml::array array;
    for (const auto& item : value) {
      if (item.is_number_integer()) array.push_back(item.get<std::int64_t>());
      else if (item.is_number()) array.push_back(item.get<double>());
      else if (item.is_boolean()) array.push_back(item.get<bool>());
      else array.push_back(item.get<std::string>());
    }
    table.insert_or_assign(key, std::move(array));
  } else {
    throw std::logic_error("settings table: '" + key + "' has a value TOML cannot hold");
  }
}
}  // namespace detail

/// Reads every field of `fields` from the tables below `root` into `settings` (absent keys keep
/// the current values). Unknown keys are left for root.finish() to report.
template <class Settings>
void read_fields(const std::vector<SettingField<Settings>>& fields, ConfigTable& root, Settings& settings) {
  std::map<std::string, ConfigTable> opened;
  for (const auto& f : fields)
    if (f.read) f.read(detail::section_of(root, f.section, opened), settings);
}

/// Adds every field to `document` (its sections created as needed), as a resolved config.
template <class Settings>
void write_fields(const std::vector<SettingField<Settings>>& fields, toml::table& document, const Settings& settings) {
  for (const auto& f : fields) detail::insert_toml(detail::toml_section_of(document, f.section), f.key, f.value(settings));
}

/// Adds every field to results.json params under its params key.
template <class Settings>
void add_params(const std::vector<SettingField<Settings>>& fields, nlohmann::json& params, const Settings& settings) {
  for (const auto& f : fields) params[f.params_key] = f.value(settings);
}

}  // namespace touchstone::studies
