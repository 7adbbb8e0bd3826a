// The palpation replay (studies/palpation_replay.hpp) on a small palpation of a hemisphere
// (tiny_scene.toml, tiny_replay.toml): the reader's named errors, the run's refusals of input
// that cannot be verified, and a run's own consistency — every verified tick's reference force
// is K_ref (tip − c) of its contact, K_ref's axial entry is the FEM's own (Richardson aside), and
// the real-time model rebuilt at a contact gives the run's K_t bit for bit.
#include "touchstone/studies/palpation_replay.hpp"

#include "support/temporary_directory.hpp"
#include "touchstone/studies/organ_atlas.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/sim_scene.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace touchstone::studies {
namespace {

const std::string replay_folder = std::string(TOUCHSTONE_SOURCE_DIR) + "/tests/studies/replay";

/// The tiny replay study with `extra` appended and every path absolute.
std::string study_text(const std::string& extra, const std::string& organ_table = R"([organ]
attachment_plane_point = [0, 0, 0]
attachment_plane_normal = [0, 0, 1]
)") {
  return "study = \"tiny_replay\"\n[replay]\nscene = \"" + replay_folder + "/tiny_scene.toml\"\n" + extra + "\n" +
         organ_table + "[mesh]\nedge_size = \"1.25 mm\"\nmax_size = \"20 mm\"\nlevels = 2\n";
}

PalpationReplayStudy read_text(const std::string& text) {
  ConfigTable config = ConfigTable::from_string(text, "replay.toml");
  return read_palpation_replay_study(config);
}

void expect_config_error(const std::string& text, const std::string& fragment) {
  try {
    read_text(text);
    ADD_FAILURE() << "accepted; expected an error naming " << fragment;
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(PalpationReplayStudy, ReaderNamesTheBadKey) {
  expect_config_error(study_text("", ""), "attachment");                         // no attachment rule
  expect_config_error(study_text("contacts = \"frames\""), "frame");             // frames without times
  expect_config_error(study_text("contacts = \"every\"\nevery = 0"), "every");
  expect_config_error(study_text("contacts = \"some\""), "contacts");
  expect_config_error(study_text("duration = \"-1 s\""), "duration");
  expect_config_error(study_text("speed = 3"), "speed");                          // unknown key
  expect_config_error("study = \"x\"\n[replay]\nscene = \"missing.toml\"\n", "scene");
  const PalpationReplayStudy study = read_text(study_text("contacts = \"every\"\nevery = 2"));
  EXPECT_EQ(study.selection, ContactSelection::every);
  EXPECT_EQ(study.every, 2);
  EXPECT_EQ(study.levels, 2);
  EXPECT_DOUBLE_EQ(study.edge_size_m, 1.25e-3);
}

TEST(PalpationReplayStudy, ResolvedConfigReadsBackTheSameStudy) {
  const PalpationReplayStudy study = read_text(study_text("contacts = \"frames\"\nframes = [\"2.5 s\", \"3 s\"]"));
  const PalpationReplayStudy again = read_text(resolved_palpation_replay_toml(study));
  EXPECT_EQ(palpation_replay_params(again), palpation_replay_params(study));
}

/// Runs the replay on `text` and returns its error message ("" when it ran).
std::string run_error(const std::string& text, const std::string& out) {
  PalpationReplayStudy study = read_text(text);
  study.config_path = "replay.toml";
  ReplayRunOptions options;
  options.output_directory = out;
  options.cache_directory.clear();
  options.quiet = true;
  try {
    run_palpation_replay(study, options);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(PalpationReplayRun, RefusesInputItCannotVerifyWithANamedError) {
  touchstone::testing::TemporaryDirectory directory("replay_errors");
  // A recording far from the organ (made on another organ, or in millimetres): no contact.
  const std::string far = directory.file("far.csv",
                                         "time_s,x_m,y_m,z_m,qw,qx,qy,qz,connected,fx_N,fy_N,fz_N\n"
                                         "0,10,10,10,1,0,0,0,1,0,0,0\n"
                                         "1,10,10,10.001,1,0,0,0,1,0,0,0\n"
                                         "2,10,10,10,1,0,0,0,1,0,0,0\n");
  const std::string never = run_error(study_text("recording = \"" + far + "\""), directory.path("far"));
  EXPECT_NE(never.find("never presses the organ"), std::string::npos) << never;
  EXPECT_NE(never.find(far), std::string::npos) << never;

  // A rim size the scene's tool cannot take (edge a at the rim: at most a/2), before the run.
  std::string coarse = study_text("");
  coarse.replace(coarse.find("1.25 mm"), 7, "2.5 mm");
  const std::string mesh = run_error(coarse, directory.path("mesh"));
  EXPECT_NE(mesh.find("[mesh]"), std::string::npos) << mesh;
  EXPECT_NE(mesh.find("edge_size"), std::string::npos) << mesh;
  EXPECT_FALSE(std::filesystem::exists(directory.path("mesh") + "/realtime")) << "refused before the real-time run";

  // A frame at which the tool does not press.
  const std::string frame = run_error(study_text("contacts = \"frames\"\nframes = [\"0.1 s\"]"), directory.path("frame"));
  EXPECT_NE(frame.find("replay.frames"), std::string::npos) << frame;

  // An attachment that selects no triangle of the organ: the mesher's named error, per contact.
  const std::string held = run_error(study_text("", R"([organ]
attachment_plane_point = [0, 0, -1]
attachment_plane_normal = [0, 0, 1]
)"),
                                     directory.path("held"));
  EXPECT_NE(held.find("attachment"), std::string::npos) << held;
  EXPECT_NE(held.find("model1"), std::string::npos) << "the error names the contact: " << held;
}

TEST(PalpationReplayAtlas, AttachmentsAreDescribedCanonically) {
  touchstone::testing::TemporaryDirectory directory("replay_attachment");
  meshes::OrganAttachment held;
  EXPECT_EQ(describe_attachment(held), "not held");
  held.plane_point_m = {0.001, 0, -0.5};
  held.plane_normal = {0, 0, 2};  // the words carry the unit normal: any length holds alike
  EXPECT_EQ(describe_attachment(held), "below the plane through (0.001, 0, -0.5) m with unit normal (0, 0, 1)");
  held = {};
  held.msh_group = "base";
  EXPECT_EQ(describe_attachment(held), "on the physical group 'base'");
  // A list of triangles is named by its content: a copy elsewhere matches, an edit does not.
  held = {};
  held.triangles_path = directory.file("held.txt", "0 1 2\n");
  const std::string listed = describe_attachment(held);
  held.triangles_path = directory.file("copy.txt", "0 1 2\n");
  EXPECT_EQ(describe_attachment(held), listed);
  held.triangles_path = directory.file("edited.txt", "0 1 3\n");
  EXPECT_NE(describe_attachment(held), listed);
}

/// An atlas of one sample at the tiny scene's pole, recording `attachment`.
void write_pole_atlas(const std::string& path, const std::string& attachment) {
  realtime::mfs::OrganAtlas atlas;
  atlas.organ = "the tiny scene's hemisphere";
  atlas.attachment = attachment;
  realtime::mfs::OrganAtlasSample sample;
  sample.label = "pole";
  sample.contact_point_m = {0, 0, 0.05};
  sample.direction = {0, 0, -1};
  sample.frame = realtime::mfs::PunchFrame::along({0, 0, 0.05}, {0, 0, -1});
  sample.tool_radius_m = 0.0025;
  sample.local_radius_m = 0.0125;
  sample.youngs_modulus_Pa = 1e4;
  sample.poisson_ratio = 0.45;
  sample.stiffness_N_per_m.topLeftCorner<3, 3>() = Eigen::Vector3d(15, 8, 8).asDiagonal();
  sample.half_space_stiffness_N_per_m = Eigen::Vector3d(14.49, 7.33, 7.33).asDiagonal();
  sample.relative_error = 1e-3;
  sample.dofs = 1000;
  sample.seconds = 1;
  atlas.samples.push_back(sample);
  realtime::mfs::write_organ_atlas(atlas, path);
}

// The real-time model's exterior knows only the attachment its atlas was made with: a replay that
// holds the organ otherwise is refused before it runs, a matching one is recorded as checked, and
// an atlas that does not record its attachment is noted.
TEST(PalpationReplayAtlas, AReferenceHeldOtherwiseThanItsAtlasIsRefused) {
  touchstone::testing::TemporaryDirectory directory("replay_atlas");
  PalpationReplayStudy study = read_text(study_text(""));
  study.config_path = "replay.toml";
  const std::string held = describe_attachment(study.attachment);
  ASSERT_EQ(held, "below the plane through (0, 0, 0) m with unit normal (0, 0, 1)");
  std::string scene_text = read_file(replay_folder + "/tiny_scene.toml");
  const std::string atlas_path = directory.path("atlas.json");
  scene_text.replace(scene_text.find("[organ]\n"), 8, "[organ]\natlas = \"" + atlas_path + "\"\n");
  const std::string scene_path = directory.file("scene.toml", scene_text);
  const auto scene_with_atlas = [&](const std::string& attachment) {
    write_pole_atlas(atlas_path, attachment);
    return read_sim_scene(scene_path);
  };

  const nlohmann::json same = replay_atlas_agreement(study, scene_with_atlas(held));
  EXPECT_EQ(same.at("attachment_checked"), true) << same.dump();
  EXPECT_EQ(same.at("atlas"), atlas_path);
  EXPECT_FALSE(same.contains("note")) << same.dump();

  const std::string other = "below the plane through (0, 0, 0.01) m with unit normal (0, 0, 1)";
  try {
    replay_atlas_agreement(study, scene_with_atlas(other));
    ADD_FAILURE() << "an atlas held at z = 0.01 m accepted for a reference held at z = 0";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    for (const std::string& fragment : {std::string("replay.toml: [organ]"), held, other, atlas_path})
      EXPECT_NE(what.find(fragment), std::string::npos) << fragment << " missing from: " << what;
  }
  // The run refuses it too, before the real-time run.
  std::string refused_study = study_text("");
  refused_study.replace(refused_study.find(replay_folder + "/tiny_scene.toml"), replay_folder.size() + 16, scene_path);
  const std::string refused = run_error(refused_study, directory.path("refused"));
  EXPECT_NE(refused.find("was made holding it " + other), std::string::npos) << refused;
  EXPECT_FALSE(std::filesystem::exists(directory.path("refused") + "/realtime/summary.json"));

  const nlohmann::json unrecorded = replay_atlas_agreement(study, scene_with_atlas(""));
  EXPECT_EQ(unrecorded.at("attachment_checked"), false);
  EXPECT_NE(unrecorded.at("note").get<std::string>().find("does not record where its organ was held"), std::string::npos);

  const nlohmann::json none = replay_atlas_agreement(study, read_sim_scene(replay_folder + "/tiny_scene.toml"));
  EXPECT_EQ(none.at("attachment_checked"), false);
  EXPECT_TRUE(none.at("atlas").is_null());
}

TEST(PalpationReplayRun, EveryTickComparesWithItsContactsStiffness) {
  touchstone::testing::TemporaryDirectory directory("replay_run");
  PalpationReplayStudy study = read_text(study_text(""));
  ReplayRunOptions options;
  options.output_directory = directory.path("out");
  options.cache_directory.clear();
  options.quiet = true;
  const nlohmann::json results = run_palpation_replay(study, options);
  const auto& contacts = results.at("contacts");
  ASSERT_GE(contacts.size(), 2u) << "a press and a slide beyond L/4: a prebuilt model and a re-sprinkle";
  EXPECT_EQ(results.at("summary").at("rebuilt_stiffness_mismatch_max").get<double>(), 0.0);
  long long ticks = 0;
  for (const auto& c : contacts) {
    ticks += c.at("frames").get<long long>();
    // The axial stiffness of two levels without Richardson: the finer level's, exactly.
    const auto& levels = c.at("reference_levels");
    ASSERT_EQ(levels.size(), 2u);
    Eigen::Matrix3d k;
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 3; ++col) k(r, col) = levels.back().at("stiffness_N_per_m").at(r).at(col).get<double>();
    const Eigen::Vector3d d(c.at("direction").at(0).get<double>(), c.at("direction").at(1).get<double>(),
                            c.at("direction").at(2).get<double>());
    EXPECT_NEAR(c.at("axial_stiffness_reference_N_per_m").get<double>(), d.dot(k * d), 1e-12 * d.dot(k * d));
    // A frictionless tool: K = k d dᵀ-like, rank one along d (the force follows the push only).
    EXPECT_LT((k - k * d * d.transpose()).norm(), 1e-12 * k.norm()) << c.at("label");
    // The reference's own error estimate is reported (two levels: their difference).
    EXPECT_GT(c.at("reference_convergence").at("relative_uncertainty").get<double>(), 0.0);
    EXPECT_GT(c.at("displacement_vertices_found").get<long long>(), c.at("displacement_vertices").get<long long>() * 3 / 4);
    EXPECT_TRUE(std::filesystem::exists(options.output_directory + "/" + c.at("paraview_surface").get<std::string>()));
  }
  EXPECT_EQ(ticks, results.at("summary").at("verified_frames").get<long long>());
  EXPECT_EQ(ticks, results.at("realtime").at("frames_with_model").get<long long>()) << "contacts = all verifies every tick";
  EXPECT_TRUE(std::filesystem::exists(options.output_directory + "/paraview/contacts.pvd"));
  // The hemisphere held at its base, pressed near the top by the half-space-exterior model: the
  // forces agree within what the coarse two-level reference can tell (its uncertainty), plus the
  // model's known −4 % of the half-space exterior on this body.
  const double uncertainty = results.at("summary").at("reference_uncertainty_max").get<double>();
  EXPECT_LT(results.at("summary").at("force_error_l2").get<double>(), 0.04 + 2 * uncertainty);
}

// A stiffness record left damaged in the replay's cache (cut short, a null stiffness: what a NaN
// becomes in JSON) is solved again with a note, not used and not the end of the run; the
// contacts' reference stiffness is the first run's.
TEST(PalpationReplayRun, ADamagedCachedStiffnessIsSolvedAgain) {
  touchstone::testing::TemporaryDirectory directory("replay_damaged_cache");
  const PalpationReplayStudy study = read_text(study_text(""));
  ReplayRunOptions options;
  options.output_directory = directory.path("first");
  options.cache_directory = directory.path("cache");
  options.quiet = true;
  const nlohmann::json first = run_palpation_replay(study, options);

  std::vector<std::filesystem::path> records;
  for (const auto& entry : std::filesystem::directory_iterator(directory.path("cache") + "/replay"))
    records.push_back(entry.path() / "stiffness.json");
  ASSERT_GE(records.size(), 2u);
  const std::string whole = read_file(records[0].string());
  write_file_atomically(records[0].string(), whole.substr(0, whole.size() / 2));
  nlohmann::json null_stiffness = nlohmann::json::parse(read_file(records[1].string()));
  null_stiffness["stiffness_N_per_m"][0][0] = nullptr;
  write_file_atomically(records[1].string(), null_stiffness.dump(1));

  options.output_directory = directory.path("second");
  const nlohmann::json second = run_palpation_replay(study, options);
  ASSERT_EQ(second.at("contacts").size(), first.at("contacts").size());
  int solved_again = 0;
  for (std::size_t c = 0; c < first.at("contacts").size(); ++c) {
    const auto& before = first.at("contacts")[c];
    const auto& after = second.at("contacts")[c];
    EXPECT_EQ(after.at("reference_stiffness_N_per_m"), before.at("reference_stiffness_N_per_m")) << c;
    for (const auto& level : after.at("reference_levels")) solved_again += level.at("cached").get<bool>() ? 0 : 1;
  }
  EXPECT_EQ(solved_again, 2);
}

}  // namespace
}  // namespace touchstone::studies
