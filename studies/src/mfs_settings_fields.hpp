#pragma once
// One definition per setting of the MFS engine: a table of fields (TOML section and key, unit,
// results.json params key, doc, how to read it, its value). The reader of `touchstone mfs`
// files, the resolved-config writer and results.json's params all walk this table, so a new
// setting is one line here and appears, with the same name and unit, in all three.

#include "touchstone/realtime/mfs/local_model.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace touchstone::studies {

struct SettingField {
  std::string section;     ///< the TOML table ("" for the top level)
  std::string key;         ///< the key in that table
  std::string params_key;  ///< its name in results.json params (unique over the table)
  std::string unit;        ///< SI unit or what it counts ("" for a plain dimensionless number)
  std::string doc;         ///< one line: what it sets
  /// Reads the key from its section (absent: keeps the current value).
  std::function<void(ConfigTable& section, realtime::mfs::LocalModelSettings& settings)> read;
  /// Its value as results.json and the resolved config write it (a name for an enum).
  std::function<nlohmann::json(const realtime::mfs::LocalModelSettings& settings)> value;
};

/// The engine's settings in the order the reader visits them (formulation first: it picks the
/// haptic method's and the oversampling's defaults).
const std::vector<SettingField>& local_model_fields();

/// Reads every field of the table from `config` into `settings` (defaults: its current values).
void read_local_model_settings(ConfigTable& config, realtime::mfs::LocalModelSettings& settings);
/// Adds every field to `document`, in its section, as the resolved config writes it.
void write_local_model_settings(toml::table& document, const realtime::mfs::LocalModelSettings& settings);
/// Adds every field to results.json params under its params key.
void add_local_model_params(nlohmann::json& params, const realtime::mfs::LocalModelSettings& settings);

}  // namespace touchstone::studies
