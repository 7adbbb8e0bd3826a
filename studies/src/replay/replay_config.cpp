// A palpation replay study file: its settings table (one definition per setting for the reader,
// config.resolved.toml and results.json params), the defaults and the validation.
#include "touchstone/studies/palpation_replay.hpp"

#include "../fem_reference/setting_fields.hpp"
#include "touchstone/studies/output_files.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace touchstone::studies {

namespace {

using S = PalpationReplayStudy;

const std::vector<Named<ContactSelection>> selections{
    {"all", ContactSelection::all}, {"every", ContactSelection::every}, {"frames", ContactSelection::frames}};

std::vector<SettingField<S>> make_fields() {
  const auto length = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::length, get); };
  std::vector<SettingField<S>> f;
  f.push_back(field::text<S>({"", "study", "", "the study's name"}, [](auto& s) -> auto& { return s.name; }));
  f.push_back(field::file<S>({"replay", "scene", "", "the scene replayed: organ, material, tool, model, organ atlas, device"},
                             [](auto& s) -> auto& { return s.scene_path; }));
  f.push_back(field::file<S>({"replay", "recording", "", "a `touchstone sim --record` CSV played in place of the scene's device"},
                             [](auto& s) -> auto& { return s.recording_path; }));
  f.push_back(field::quantity<S>({"replay", "duration", "s", "run length (0: the scene's)"}, Dimension::time,
                                 [](auto& s) -> auto& { return s.duration_s; }));
  f.push_back(field::choice<S>({"replay", "contacts", "", "all, every (every k-th contact) or frames (the contacts in use at listed times)"},
                               selections, [](auto& s) -> auto& { return s.selection; }));
  f.push_back(field::integer<S>({"replay", "every", "", "contacts = every: verify every k-th contact"},
                                [](auto& s) -> auto& { return s.every; }));
  f.push_back(field::quantity_list<S>({"replay", "frames", "s", "contacts = frames: run times whose contact is verified"},
                                      Dimension::time, [](auto& s) -> auto& { return s.frame_times_s; }));

  f.push_back(field::vector3<S>({"organ", "attachment_plane_point", "m", "the organ is held below the plane through this point"},
                                Dimension::length, [](auto& s) -> auto& { return s.attachment.plane_point_m; }));
  f.push_back(field::vector3<S>({"organ", "attachment_plane_normal", "", "… with this normal (zero: no plane rule)"},
                                Dimension::dimensionless, [](auto& s) -> auto& { return s.attachment.plane_normal; }));
  f.push_back(field::text<S>({"organ", "attachment_group", "", "a .msh organ: the physical group held"},
                             [](auto& s) -> auto& { return s.attachment.msh_group; }));
  f.push_back(field::file<S>({"organ", "attachment_triangles", "", "a file of the held triangles' numbers (from 0)"},
                             [](auto& s) -> auto& { return s.attachment.triangles_path; }));
  f.push_back(field::quantity<S>({"organ", "feature_angle", "rad", "creases sharper than this are kept by the remesher"},
                                 Dimension::angle, [](auto& s) -> auto& { return s.feature_angle_rad; }));

  f.push_back(length({"mesh", "edge_size", "m", "element size at the patch rim, level 0"}, [](auto& s) -> auto& { return s.edge_size_m; }));
  f.push_back(field::real<S>({"mesh", "size_growth", "", "g of the size law h_e + g a (d/a)^beta"},
                             [](auto& s) -> auto& { return s.size_growth; }));
  f.push_back(field::real<S>({"mesh", "size_exponent", "", "beta of the size law"}, [](auto& s) -> auto& { return s.size_exponent; }));
  f.push_back(length({"mesh", "max_size", "m", "largest element, level 0"}, [](auto& s) -> auto& { return s.max_size_m; }));
  f.push_back(field::integer<S>({"mesh", "levels", "", "mesh levels, every size halved per level (>= 3: Richardson)"},
                                [](auto& s) -> auto& { return s.levels; }));
  f.push_back(length({"tool", "unit_depth", "m", "the push of the unit solves"}, [](auto& s) -> auto& { return s.unit_depth_m; }));

  f.push_back({"solver", "degree", "", "", "polynomial degree of the displacement",
               [](ConfigTable& t, S& s) { s.solver.degree = static_cast<unsigned int>(read_int(t, "degree", static_cast<int>(s.solver.degree))); },
               [](const S& s) { return nlohmann::json(s.solver.degree); }});
  f.push_back(field::choice<S>({"solver", "method", "", "linear solver"}, linear_solvers,
                               [](auto& s) -> auto& { return s.solver.solver; }));
  f.push_back(field::real<S>({"solver", "relative_tolerance", "", "iterative solvers' relative residual"},
                             [](auto& s) -> auto& { return s.solver.relative_tolerance; }));
  assign_params_keys(f, "palpation replay");
  return f;
}

const std::vector<SettingField<S>>& replay_fields() {
  static const auto fields = make_fields();
  return fields;
}

}  // namespace

std::string to_string(ContactSelection selection) { return name_of(selections, selection); }

void PalpationReplayStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("PalpationReplayStudy.name is empty");
  if (scene_path.empty()) throw std::invalid_argument("PalpationReplayStudy.scene_path is empty: [replay] scene is required");
  if (!std::isfinite(duration_s) || duration_s < 0)
    throw std::invalid_argument("PalpationReplayStudy.duration_s = " + format_number(duration_s) + " must be >= 0");
  if (selection == ContactSelection::every && every < 1)
    throw std::invalid_argument("PalpationReplayStudy.every = " + std::to_string(every) + " must be >= 1");
  if (selection == ContactSelection::frames && frame_times_s.empty())
    throw std::invalid_argument("PalpationReplayStudy.frame_times_s is empty: contacts = \"frames\" needs frames = [...]");
  for (const double t : frame_times_s)
    if (!std::isfinite(t) || t < 0)
      throw std::invalid_argument("PalpationReplayStudy.frame_times_s has " + format_number(t) + ": times must be >= 0");
  if (attachment.rule_count() != 1)
    throw std::invalid_argument("PalpationReplayStudy.attachment: give exactly one rule (attachment_plane_point/normal, "
                                "attachment_group or attachment_triangles), the attachment the organ atlas was made with; " +
                                std::to_string(attachment.rule_count()) + " given");
  for (const auto& [value, field] : {std::pair{edge_size_m, "edge_size_m"}, {max_size_m, "max_size_m"}, {unit_depth_m, "unit_depth_m"}})
    if (!std::isfinite(value) || value <= 0)
      throw std::invalid_argument(std::string("PalpationReplayStudy.") + field + " = " + format_number(value) + " must be > 0");
  if (!std::isfinite(size_growth) || size_growth <= 0)
    throw std::invalid_argument("PalpationReplayStudy.size_growth = " + format_number(size_growth) + " must be > 0");
  if (!std::isfinite(size_exponent) || size_exponent <= 0)
    throw std::invalid_argument("PalpationReplayStudy.size_exponent = " + format_number(size_exponent) + " must be > 0");
  if (levels < 1 || levels > 5) throw std::invalid_argument("PalpationReplayStudy.levels = " + std::to_string(levels) + " must be in [1, 5]");
  solver.validate();
}

PalpationReplayStudy read_palpation_replay_study(ConfigTable& config) {
  PalpationReplayStudy study;
  read_fields(replay_fields(), config, study);
  finish_and_validate(config, study);
  return study;
}

std::string resolved_palpation_replay_toml(const PalpationReplayStudy& study) {
  toml::table document;
  write_fields(replay_fields(), document, study);
  std::ostringstream text;
  text << "# " << study.name << ", resolved by `touchstone study`: every default filled in, quantities in SI (m, s, rad).\n"
       << document << "\n";
  return text.str();
}

nlohmann::json palpation_replay_params(const PalpationReplayStudy& study) {
  nlohmann::json params = nlohmann::json::object();
  add_params(replay_fields(), params, study);
  return params;
}

bool is_palpation_replay_config(const std::string& path) {
  ConfigTable config = ConfigTable::from_file(path);
  return config.has("replay");
}

}  // namespace touchstone::studies
