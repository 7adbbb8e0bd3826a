// The organ atlas file and its lookup (realtime/mfs/organ_atlas): round trip, errors that name the
// file and the key, the lookup's statuses, the E scaling and the frame rotation. No FEM.
#include "touchstone/realtime/mfs/organ_atlas.hpp"

#include "support/temporary_directory.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include <unistd.h>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;
constexpr double body_radius_m = 0.05, a = 0.0025, l = 0.0125;

/// A file in this test program's scratch folder, which is removed when the program exits.
std::string scratch(const std::string& name) {
  static const struct Folder {
    std::filesystem::path path = std::filesystem::path(::testing::TempDir()) / ("organ_atlas_" + std::to_string(::getpid()));
    Folder() { std::filesystem::create_directories(path); }
    ~Folder() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  } folder;
  return (folder.path / name).string();
}

/// A sample on the hemisphere at polar angle θ (meridian y = 0), tool along the inward normal,
/// with a made-up but symmetric positive definite K whose tangential block is anisotropic, so a
/// wrong rotation shows.
OrganAtlasSample hemisphere_sample(double theta, double k_normal) {
  OrganAtlasSample s;
  s.label = "theta=" + std::to_string(theta);
  const Eigen::Vector3d n(std::sin(theta), 0, std::cos(theta));
  s.contact_point_m = body_radius_m * n;
  s.direction = -n;
  s.frame = PunchFrame::along(s.contact_point_m - (body_radius_m - std::sqrt(body_radius_m * body_radius_m - a * a)) * n, -n);
  s.tool_radius_m = a;
  s.local_radius_m = l;
  s.youngs_modulus_Pa = 10e3;
  s.poisson_ratio = 0.45;
  s.stiffness_N_per_m.topLeftCorner<3, 3>() << k_normal, 0.01, 0.002, 0.01, 0.8 * k_normal, 0.05, 0.002, 0.05, 0.6 * k_normal;
  s.half_space_stiffness_N_per_m << 0.95 * k_normal, 0, 0, 0, 0.77 * k_normal, 0, 0, 0, 0.77 * k_normal;
  s.relative_error = 1e-3;
  s.dofs = 123456;
  s.seconds = 12.5;
  return s;
}

OrganAtlas hemisphere_atlas() {
  OrganAtlas atlas;
  atlas.organ = "B2 hemisphere R = 0.05 m, base z = 0 clamped";
  atlas.axisymmetric_about_z = true;
  atlas.mode_count = 3;
  atlas.samples = {hemisphere_sample(0, 1.0), hemisphere_sample(15 * pi / 180, 1.2)};
  return atlas;
}

OrganAtlasQuery query_at(const OrganAtlasSample& s) {
  OrganAtlasQuery q;
  q.contact_point_m = s.contact_point_m;
  q.direction = s.direction;
  q.tool_radius_m = a;
  q.local_radius_m = l;
  q.material.youngs_modulus_Pa = 10e3;
  q.material.poisson_ratio = 0.45;
  return q;
}

TEST(OrganAtlasFile, WritesAndReadsBackExactly) {
  const OrganAtlas atlas = hemisphere_atlas();
  const std::string path = scratch("round_trip.json");
  write_organ_atlas(atlas, path);
  const OrganAtlas back = read_organ_atlas(path);
  EXPECT_EQ(back.organ, atlas.organ);
  EXPECT_EQ(back.axisymmetric_about_z, true);
  EXPECT_EQ(back.mode_count, 3);
  ASSERT_EQ(back.samples.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const auto& x = atlas.samples[i];
    const auto& y = back.samples[i];
    EXPECT_EQ(y.label, x.label);
    EXPECT_EQ(y.contact_point_m, x.contact_point_m);
    EXPECT_EQ(y.direction, x.direction);
    EXPECT_EQ(y.frame.origin, x.frame.origin);
    EXPECT_EQ(y.frame.axes, x.frame.axes);
    EXPECT_EQ(y.tool_radius_m, x.tool_radius_m);
    EXPECT_EQ(y.local_radius_m, x.local_radius_m);
    EXPECT_EQ(y.youngs_modulus_Pa, x.youngs_modulus_Pa);
    EXPECT_EQ(y.poisson_ratio, x.poisson_ratio);
    EXPECT_EQ(y.stiffness_N_per_m, x.stiffness_N_per_m);  // doubles are written with 17 digits
    EXPECT_EQ(y.half_space_stiffness_N_per_m, x.half_space_stiffness_N_per_m);
    EXPECT_EQ(y.relative_error, x.relative_error);
    EXPECT_EQ(y.dofs, x.dofs);
    EXPECT_EQ(y.seconds, x.seconds);
  }
}

TEST(OrganAtlasFile, NormalOnlyAtlasHoldsOneByOneMatrices) {
  OrganAtlas atlas = hemisphere_atlas();
  atlas.mode_count = 1;
  const std::string path = scratch("normal_only.json");
  write_organ_atlas(atlas, path);
  const nlohmann::json document = nlohmann::json::parse(std::ifstream(path));
  EXPECT_EQ(document.at("modes"), "normal");
  EXPECT_EQ(document.at("samples").at(0).at("stiffness_N_per_m").size(), 1u);
  const OrganAtlas back = read_organ_atlas(path);
  EXPECT_EQ(back.mode_count, 1);
  EXPECT_EQ(back.samples[0].stiffness_N_per_m(0, 0), 1.0);
  EXPECT_EQ(back.samples[0].stiffness_N_per_m(1, 1), 0.0);
}

// An atlas with the cut's rigid shifts holds (n + 3) × (n + 3) matrices; it reads back exactly,
// an atlas without the key reads as one without shifts, a wrongly sized or indefinite matrix is
// refused by name, and a lookup turns the shift block with the same rotation as the modes (the
// shifts are vectors in the frame's e₃, e₁, e₂ order).
TEST(OrganAtlasFile, CutTranslationsRoundTripAndTurnWithTheFrame) {
  OrganAtlas atlas = hemisphere_atlas();
  atlas.cut_translations = true;
  atlas.samples.resize(1);
  OrganAtlasSample& s = atlas.samples[0];
  s.stiffness_N_per_m.block<3, 3>(3, 3) << 26.0, 0.3, 0.1, 0.3, 13.0, 0.2, 0.1, 0.2, 11.0;
  s.stiffness_N_per_m(0, 3) = s.stiffness_N_per_m(3, 0) = 4.6;   // normal mode with the shift along e₃
  s.stiffness_N_per_m(1, 4) = s.stiffness_N_per_m(4, 1) = 1.4;   // tangential_1 with the shift along e₁
  const std::string path = scratch("cut_translations.json");
  write_organ_atlas(atlas, path);
  nlohmann::json document = nlohmann::json::parse(std::ifstream(path));
  EXPECT_EQ(document.at("cut_translations"), true);
  EXPECT_EQ(document.at("samples").at(0).at("stiffness_N_per_m").size(), 6u);
  EXPECT_EQ(document.at("samples").at(0).at("half_space_stiffness_N_per_m").size(), 3u);
  const OrganAtlas back = read_organ_atlas(path);
  EXPECT_TRUE(back.cut_translations);
  EXPECT_EQ(back.matrix_size(), 6);
  EXPECT_EQ(back.samples[0].stiffness_N_per_m, s.stiffness_N_per_m);

  // Without the key: no shifts (the atlases written before them); with it, the sizes must follow.
  nlohmann::json old = nlohmann::json::parse(std::ifstream(scratch("cut_translations.json")));
  old.erase("cut_translations");
  const auto read_error = [](const nlohmann::json& written, const std::string& name) -> std::string {
    std::ofstream(scratch(name)) << written.dump();
    try {
      read_organ_atlas(scratch(name));
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "(read without an error)";
  };
  const std::string unkeyed = read_error(old, "no_key.json");
  EXPECT_NE(unkeyed.find("samples[0].stiffness_N_per_m: has 6 entries, expected 3"), std::string::npos) << unkeyed;
  document["samples"][0]["stiffness_N_per_m"][3][3] = -26.0;
  const std::string negative = read_error(document, "negative.json");
  EXPECT_NE(negative.find("samples[0].stiffness_N_per_m[3][3]: = -26 must be > 0"), std::string::npos) << negative;
  // Positive diagonal, but a coupling too strong for an energy: the normal mode and the shift
  // along e₃ (1 × 26 against 6²).
  document["samples"][0]["stiffness_N_per_m"][3][3] = 26.0;
  document["samples"][0]["stiffness_N_per_m"][0][3] = 6.0;
  document["samples"][0]["stiffness_N_per_m"][3][0] = 6.0;
  const std::string indefinite = read_error(document, "indefinite.json");
  EXPECT_NE(indefinite.find("samples[0].stiffness_N_per_m: is not positive definite"), std::string::npos) << indefinite;

  // Stored in a frame turned by 40° about e₃: the query's amplitudes and shifts are the sample's
  // turned back, T = diag(1, R(−40°)) on each block, and E scales the whole matrix.
  const double turn = 40 * pi / 180;
  const Eigen::Matrix3d along = s.frame.axes;
  s.frame.axes = Eigen::AngleAxisd(turn, along.col(2)).toRotationMatrix() * along;
  OrganAtlasQuery q = query_at(s);
  q.material.youngs_modulus_Pa = 20e3;
  const OrganAtlasLookup r = lookup_exterior_stiffness(atlas, q);
  ASSERT_EQ(r.status, OrganAtlasStatus::ok) << r.message;
  EXPECT_TRUE(r.cut_translations);
  Eigen::Matrix3d t = Eigen::Matrix3d::Identity();
  t.block<2, 2>(1, 1) << std::cos(turn), std::sin(turn), -std::sin(turn), std::cos(turn);
  ExteriorMatrix carried = ExteriorMatrix::Zero();
  carried.topLeftCorner<3, 3>() = t;
  carried.bottomRightCorner<3, 3>() = t;
  const ExteriorMatrix expected = 2.0 * carried.transpose() * s.stiffness_N_per_m * carried;
  EXPECT_LT((r.stiffness_N_per_m - expected).cwiseAbs().maxCoeff(), 1e-12);
}

// Where the organ was held and which surface file it came from are recorded for a user's organ
// (a reference must hold it the same way) and optional, so that older atlases still read.
TEST(OrganAtlasFile, AttachmentAndSurfaceAreKeptAndOptional) {
  OrganAtlas atlas = hemisphere_atlas();
  atlas.attachment = "below the plane through (0, 0, 0) m with unit normal (0, 0, 1)";
  atlas.surface_sha256 = std::string(64, 'a');
  const std::string path = scratch("held.json");
  write_organ_atlas(atlas, path);
  const OrganAtlas back = read_organ_atlas(path);
  EXPECT_EQ(back.attachment, atlas.attachment);
  EXPECT_EQ(back.surface_sha256, atlas.surface_sha256);

  const std::string bare = scratch("not_held.json");
  write_organ_atlas(hemisphere_atlas(), bare);
  const nlohmann::json document = nlohmann::json::parse(std::ifstream(bare));
  EXPECT_FALSE(document.contains("attachment"));
  EXPECT_FALSE(document.contains("surface_sha256"));
  EXPECT_TRUE(read_organ_atlas(bare).attachment.empty());

  nlohmann::json mistyped = document;
  mistyped["attachment"] = 3;
  std::ofstream(scratch("mistyped_attachment.json")) << mistyped.dump(1);
  try {
    read_organ_atlas(scratch("mistyped_attachment.json"));
    ADD_FAILURE() << "a number accepted as the attachment";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("mistyped_attachment.json: attachment"), std::string::npos) << error.what();
  }
}

/// Writes the round-trip atlas with one edit and returns the reader's message.
std::string read_error(const std::string& name, const std::function<void(nlohmann::json&)>& edit) {
  const std::string path = scratch(name + ".json");
  write_organ_atlas(hemisphere_atlas(), path);
  nlohmann::json document = nlohmann::json::parse(std::ifstream(path));
  edit(document);
  std::ofstream(path) << document.dump(1);
  try {
    read_organ_atlas(path);
  } catch (const std::runtime_error& error) {
    return error.what();
  }
  return "(no error)";
}

TEST(OrganAtlasFile, EveryErrorNamesTheFileAndTheKey) {
  struct Case {
    const char* name;
    std::function<void(nlohmann::json&)> edit;
    const char* key;
  };
  const Case cases[] = {
      {"missing_samples", [](nlohmann::json& d) { d.erase("samples"); }, "samples: missing"},
      {"missing_dofs", [](nlohmann::json& d) { d["samples"][1].erase("dofs"); }, "samples[1].dofs: missing"},
      {"null_entry", [](nlohmann::json& d) { d["samples"][0]["stiffness_N_per_m"][1][2] = nullptr; },
       "samples[0].stiffness_N_per_m[1][2]: is not a number"},
      {"string_entry", [](nlohmann::json& d) { d["samples"][0]["poisson_ratio"] = "0.45"; },
       "samples[0].poisson_ratio: is not a number"},
      {"short_vector", [](nlohmann::json& d) { d["samples"][0]["frame"]["e1"] = {1.0, 0.0}; },
       "samples[0].frame.e1: has 2 entries"},
      {"wrong_size", [](nlohmann::json& d) { d["samples"][1]["half_space_stiffness_N_per_m"].erase(2); },
       "samples[1].half_space_stiffness_N_per_m: has 2 entries"},
      {"bad_modes", [](nlohmann::json& d) { d["modes"] = "some"; }, "modes: is 'some'"},
      {"negative_radius", [](nlohmann::json& d) { d["samples"][0]["tool_radius_m"] = -1.0; },
       "samples[0].tool_radius_m: = -1 must be > 0"},
      {"asymmetric", [](nlohmann::json& d) { d["samples"][0]["stiffness_N_per_m"][0][1] = 0.5; },
       "samples[0].stiffness_N_per_m: is not symmetric"},
      {"not_unit", [](nlohmann::json& d) { d["samples"][0]["direction"] = {0.0, 0.0, -2.0}; },
       "samples[0].direction: has length 2"},
      {"bad_version", [](nlohmann::json& d) { d["version"] = 7; }, "version: = 7"},
      // A fuzz finding: a whole number beyond what a size_t holds was converted to one.
      {"huge_dofs", [](nlohmann::json& d) { d["samples"][0]["dofs"] = 3.17111e128; },
       "samples[0].dofs: = 3.17111e+128 is too large"},
  };
  for (const auto& c : cases) {
    const std::string message = read_error(c.name, c.edit);
    EXPECT_NE(message.find(std::string(c.name) + ".json: "), std::string::npos) << c.name << ": " << message;
    EXPECT_NE(message.find(c.key), std::string::npos) << c.name << ": " << message;
  }
  // A file that is not JSON, and one that is not there.
  const std::string garbage = scratch("garbage.json");
  std::ofstream(garbage) << "{ not json";
  EXPECT_THROW(read_organ_atlas(garbage), std::runtime_error);
  try {
    read_organ_atlas(scratch("absent.json"));
    FAIL();
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("absent.json"), std::string::npos);
  }
}

TEST(OrganAtlasFile, ANumberBeyondDoubleIsAnErrorNamingTheFile) {
  // Found by fuzz_organ_atlas: the JSON parser reports a number overflow as out_of_range, not
  // parse_error, and it escaped the reader as a raw library exception.
  touchstone::testing::TemporaryDirectory directory("atlas_overflow");
  const std::string path = directory.file("overflow.json", "{\"format\": \"touchstone.organ_atlas\", \"version\": 1e999}");
  try {
    read_organ_atlas(path);
    ADD_FAILURE() << "accepted a number beyond double";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
  }
}

// A device or a named pipe given as the atlas would be read forever or block.
TEST(OrganAtlasFile, ADeviceIsNotReadAndIsNamed) {
  try {
    read_organ_atlas("/dev/zero");
    ADD_FAILURE() << "read /dev/zero";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("/dev/zero: cannot open the organ atlas (it is a device, pipe or socket, not a regular file)"),
              std::string::npos)
        << error.what();
  }
}

TEST(OrganAtlasLookup, AtASampleReturnsItsMatrixAndScalesWithE) {
  const OrganAtlas atlas = hemisphere_atlas();
  OrganAtlasQuery q = query_at(atlas.samples[1]);
  OrganAtlasLookup r = lookup_exterior_stiffness(atlas, q);
  ASSERT_EQ(r.status, OrganAtlasStatus::ok) << r.message;
  EXPECT_EQ(r.samples_used, 1u);
  EXPECT_EQ(r.mode_count, 3);
  // Same direction, same PunchFrame::along axes: the matrix comes back to rounding.
  EXPECT_LT((r.stiffness_N_per_m - atlas.samples[1].stiffness_N_per_m).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_DOUBLE_EQ(r.relative_error, 1e-3);
  // K ∝ E at fixed ν.
  q.material.youngs_modulus_Pa = 25e3;
  r = lookup_exterior_stiffness(atlas, q);
  ASSERT_EQ(r.status, OrganAtlasStatus::ok);
  EXPECT_LT((r.stiffness_N_per_m - 2.5 * atlas.samples[1].stiffness_N_per_m).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(OrganAtlasLookup, StatusesNameWhatIsWrong) {
  const OrganAtlas atlas = hemisphere_atlas();
  // Far from every sample: θ = 60° is 39 mm of arc from θ = 15°.
  OrganAtlasQuery q = query_at(hemisphere_sample(60 * pi / 180, 1));
  OrganAtlasLookup r = lookup_exterior_stiffness(atlas, q);
  EXPECT_EQ(r.status, OrganAtlasStatus::no_sample_nearby);
  EXPECT_NE(r.message.find("no sample within 0.0125 m of the contact"), std::string::npos) << r.message;
  // Another punch radius, local radius or Poisson ratio.
  q = query_at(atlas.samples[0]);
  q.tool_radius_m = 0.003;
  r = lookup_exterior_stiffness(atlas, q);
  EXPECT_EQ(r.status, OrganAtlasStatus::parameters_differ);
  EXPECT_NE(r.message.find("atlas made for a = 0.0025 m"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("model has a = 0.003 m"), std::string::npos) << r.message;
  q = query_at(atlas.samples[0]);
  q.material.poisson_ratio = 0.45 * (1 + 1e-4);
  EXPECT_EQ(lookup_exterior_stiffness(atlas, q).status, OrganAtlasStatus::parameters_differ);
  q.material.poisson_ratio = 0.45 * (1 + 1e-8);  // within 1e-6 relative
  EXPECT_EQ(lookup_exterior_stiffness(atlas, q).status, OrganAtlasStatus::ok);
  // A tool tilted 30° from every sample's direction.
  q = query_at(atlas.samples[0]);
  q.direction = Eigen::Vector3d(std::sin(pi / 6), 0, -std::cos(pi / 6));
  r = lookup_exterior_stiffness(atlas, q);
  EXPECT_EQ(r.status, OrganAtlasStatus::direction_differs);
  EXPECT_NE(r.message.find("deg"), std::string::npos) << r.message;
  EXPECT_EQ(to_string(r.status), "direction_differs");
}

TEST(OrganAtlasLookup, InterpolatesByInverseDistanceBetweenSamples) {
  const OrganAtlas atlas = hemisphere_atlas();
  // Half way between θ = 0 and 15° on the sphere, along the inward normal there: equal distances,
  // so the normal entry is the mean of the two (e₃ is carried onto e₃ exactly).
  const OrganAtlasSample middle = hemisphere_sample(7.5 * pi / 180, 0);
  const OrganAtlasLookup r = lookup_exterior_stiffness(atlas, query_at(middle));
  ASSERT_EQ(r.status, OrganAtlasStatus::ok) << r.message;
  EXPECT_EQ(r.samples_used, 2u);
  EXPECT_NEAR(r.stiffness_N_per_m(0, 0), 1.1, 1e-12);
  // A rotation keeps the trace of the matrix.
  EXPECT_NEAR(r.stiffness_N_per_m.trace(), 0.5 * (2.4 + 2.4 * 1.2), 1e-12);
}

TEST(OrganAtlasLookup, RotatesIntoTheQueryFrameAndUsesTheAxisymmetry) {
  OrganAtlas atlas = hemisphere_atlas();
  atlas.samples.resize(1);
  OrganAtlasSample& s = atlas.samples[0];
  // Store the sample in a frame turned by 40° about e₃ against PunchFrame::along's choice.
  const double turn = 40 * pi / 180;
  const Eigen::Matrix3d along = s.frame.axes;
  s.frame.axes = Eigen::AngleAxisd(turn, along.col(2)).toRotationMatrix() * along;
  const OrganAtlasLookup r = lookup_exterior_stiffness(atlas, query_at(s));
  ASSERT_EQ(r.status, OrganAtlasStatus::ok) << r.message;
  // Mode amplitudes of the query are those of the sample turned back by 40° in the (t1, t2) plane:
  // c_sample = T c_query with T = diag(1, R(−40°)) in the (normal, t1, t2) order.
  Eigen::Matrix3d t = Eigen::Matrix3d::Identity();
  t.block<2, 2>(1, 1) << std::cos(turn), std::sin(turn), -std::sin(turn), std::cos(turn);
  const Eigen::Matrix3d expected = t.transpose() * s.stiffness_N_per_m.topLeftCorner<3, 3>() * t;
  EXPECT_LT((r.stiffness_N_per_m.topLeftCorner<3, 3>() - expected).cwiseAbs().maxCoeff(), 1e-12);
  // On an axisymmetric atlas a contact at azimuth 90° (the pole sample turned about z) finds the
  // sample; its matrix is the same energy form, so the normal entry and the eigenvalues agree.
  atlas = hemisphere_atlas();
  const OrganAtlasSample& off = atlas.samples[1];
  const Eigen::Matrix3d quarter = Eigen::AngleAxisd(pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  OrganAtlasQuery q = query_at(off);
  q.contact_point_m = quarter * off.contact_point_m;
  q.direction = quarter * off.direction;
  const OrganAtlasLookup turned = lookup_exterior_stiffness(atlas, q);
  ASSERT_EQ(turned.status, OrganAtlasStatus::ok) << turned.message;
  EXPECT_EQ(turned.samples_used, 1u);
  EXPECT_NEAR(turned.stiffness_N_per_m(0, 0), off.stiffness_N_per_m(0, 0), 1e-12);
  const Eigen::Vector3d got = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(turned.stiffness_N_per_m.topLeftCorner<3, 3>()).eigenvalues();
  const Eigen::Vector3d want = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(off.stiffness_N_per_m.topLeftCorner<3, 3>()).eigenvalues();
  EXPECT_LT((got - want).cwiseAbs().maxCoeff(), 1e-12);
  // Without the symmetry the same query is far from every sample.
  atlas.axisymmetric_about_z = false;
  EXPECT_EQ(lookup_exterior_stiffness(atlas, q).status, OrganAtlasStatus::no_sample_nearby);
}

TEST(OrganAtlasLookup, SettingsAreValidatedNamingTheField) {
  OrganAtlasLookupSettings settings;
  settings.power = 0;
  try {
    settings.validate();
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("OrganAtlasLookupSettings.power"), std::string::npos);
  }
}

}  // namespace
}  // namespace touchstone::realtime::mfs
