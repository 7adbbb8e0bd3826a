#pragma once
// One definition per setting of the MFS engine (the settings-table pattern of setting_fields.hpp):
// the reader of `touchstone mfs` files and of a scene's [model], the resolved-config writer and
// results.json's params all walk this table.

#include "fem_reference/setting_fields.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"

namespace touchstone::studies {

/// The engine's settings in the order the reader visits them (formulation first: it picks the
/// haptic method's and the oversampling's defaults).
const std::vector<SettingField<realtime::mfs::LocalModelSettings>>& local_model_fields();

/// Reads every field of the table from `config` into `settings` (defaults: its current values).
void read_local_model_settings(ConfigTable& config, realtime::mfs::LocalModelSettings& settings);
/// Adds every field to `document`, in its section, as the resolved config writes it.
void write_local_model_settings(toml::table& document, const realtime::mfs::LocalModelSettings& settings);
/// Adds every field to results.json params under its params key.
void add_local_model_params(nlohmann::json& params, const realtime::mfs::LocalModelSettings& settings);

}  // namespace touchstone::studies
