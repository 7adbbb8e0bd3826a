// The MFS settings table: every engine setting is read, resolved and reported from one
// definition. A setting written by the resolved-config writer must read back to the same value,
// and the reader must consume every key the writer wrote (no unknown keys), with non-default
// values in every section.
#include "mfs_settings_fields.hpp"

#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <set>
#include <sstream>

namespace touchstone::studies {
namespace {

namespace mfs = realtime::mfs;

TEST(MfsSettingsFields, EveryFieldIsNamedDocumentedAndReadable) {
  std::set<std::string> keys, params;
  for (const auto& f : local_model_fields()) {
    EXPECT_TRUE(keys.insert(f.section + "." + f.key).second) << f.section << "." << f.key << " twice";
    EXPECT_TRUE(params.insert(f.params_key).second) << "params key " << f.params_key << " twice";
    EXPECT_FALSE(f.doc.empty()) << f.key;
    EXPECT_TRUE(f.value) << f.key;
    EXPECT_TRUE(f.read) << f.key;
  }
  // The names other code reads from results.json params.
  for (const char* name : {"formulation", "exterior", "layout", "seed", "radius_factor", "boundary_radius_factor",
                           "max_support_scale", "min_rcond_threshold", "solver", "haptic_method"})
    EXPECT_EQ(params.count(name), 1u) << name;
  EXPECT_GE(local_model_fields().size(), 50u);
}

/// Writes `settings` as the resolved config does and reads the text back into defaults.
mfs::LocalModelSettings round_trip(const mfs::LocalModelSettings& settings) {
  toml::table document;
  write_local_model_settings(document, settings);
  std::ostringstream text;
  text << document << "\n";
  ConfigTable config = ConfigTable::from_string(text.str(), "round_trip.toml");
  mfs::LocalModelSettings read;
  read.paper_mode = settings.paper_mode;
  read_local_model_settings(config, read);
  config.finish();  // throws on a key the reader did not take
  return read;
}

TEST(MfsSettingsFields, ResolvedSettingsReadBackToTheSameValues) {
  // A setting away from its default in every section.
  mfs::LocalModelSettings s;
  s.formulation = mfs::Formulation::collocation;
  s.galerkin.penalty_factor = 37.5;
  s.galerkin.constraint = mfs::Constraint::nitsche;
  s.enriched.exterior = mfs::ExteriorCondition::half_space;
  s.enriched.volume_polar_points = 11;
  s.enriched.cut_multiplier_degree = 2;
  s.sprinkling.layout = mfs::Layout::lattice;
  s.sprinkling.radius_factor = 2.75;
  s.sprinkling.oversampling = 2.5;
  s.sprinkling.tip_node_only = true;
  s.sprinkling.seed = 123456789012345ull;
  s.collocation.scale_rows = !s.collocation.scale_rows;
  s.collocation.mls.basis = mfs::Basis::linear;
  s.collocation.mls.min_rcond = 3e-11;
  s.solver.kind = mfs::SolverKind::gmres_ilut;
  s.solver.gmres_restart = 77;
  s.force.extraction_inner_tool_radii = 1.7;
  s.force.haptic_method = mfs::ForceMethod::paper_partition;
  s.force.traction = !s.force.traction;
  const mfs::LocalModelSettings back = round_trip(s);
  for (const auto& f : local_model_fields())
    EXPECT_EQ(f.value(back), f.value(s)) << f.section << "." << f.key;
  // The formulation's side effect (the haptic default) must not override an explicit method.
  EXPECT_EQ(back.force.haptic_method, mfs::ForceMethod::paper_partition);
}

TEST(MfsSettingsFields, ParamsHoldEveryFieldUnderItsKey) {
  nlohmann::json params = nlohmann::json::object();
  const mfs::LocalModelSettings s;
  add_local_model_params(params, s);
  EXPECT_EQ(params.size(), local_model_fields().size());
  EXPECT_EQ(params.at("formulation"), "enriched");
  EXPECT_EQ(params.at("min_rcond_threshold"), s.collocation.mls.min_rcond);
  EXPECT_EQ(params.at("enriched_volume_radial_points"), s.enriched.volume_radial_points);
  EXPECT_EQ(params.at("force_volume_radial_points"), s.force.volume_radial_points);
}

TEST(MfsSettingsFields, BadValuesAreNamed) {
  ConfigTable config = ConfigTable::from_string("[sprinkling]\nseed = -3\n", "bad_seed.toml");
  mfs::LocalModelSettings s;
  try {
    read_local_model_settings(config, s);
    FAIL() << "a negative seed was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bad_seed.toml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("seed"), std::string::npos) << e.what();
  }
  ConfigTable layout = ConfigTable::from_string("[sprinkling]\nlayout = \"hexagonal\"\n", "bad_layout.toml");
  EXPECT_THROW(read_local_model_settings(layout, s), ConfigError);
}

}  // namespace
}  // namespace touchstone::studies
