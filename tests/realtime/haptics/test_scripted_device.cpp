// The scripted hand (realtime/haptics/palpation_trajectory, scripted_device, palpation_device) and the recorder
// and replay devices (device_recorder, replay_device).
#include "touchstone/realtime/haptics/device_recorder.hpp"
#include "touchstone/realtime/haptics/palpation_device.hpp"
#include "touchstone/realtime/haptics/palpation_trajectory.hpp"
#include "touchstone/realtime/haptics/replay_device.hpp"
#include "touchstone/realtime/haptics/scripted_device.hpp"

#include "support/expect_invalid_argument.hpp"
#include "support/temporary_directory.hpp"
#include "touchstone/geometry/icosphere.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

namespace touchstone::realtime::haptics {
namespace {

const geometry::TriangleSurface& sphere() {
  static const geometry::TriangleSurface organ = [] {
    auto mesh = geometry::icosphere(4, 0.04);
    return geometry::TriangleSurface(mesh.vertices, mesh.triangles, "icosphere");
  }();
  return organ;
}

PalpationSettings settings() {
  PalpationSettings p;
  p.generated_sites = 3;
  p.duration_s = 20;
  p.seed = 3;
  return p;
}

TEST(PalpationTrajectory, PressesToTheDepthAtEverySiteAndEndsOutside) {
  const PalpationSettings p = settings();
  const PalpationTrajectory path = make_palpation_trajectory(sphere(), p);
  ASSERT_EQ(path.tip.size(), 20000U);  // duration × rate
  ASSERT_EQ(path.site_points.size(), 3U);
  EXPECT_GE(path.palpations, 3);
  int holds = 0;
  for (const PalpationSegment& segment : path.segments) {
    const Eigen::Vector3d& site = path.site_points[segment.site];
    const Eigen::Vector3d& n = path.site_normals[segment.site];
    if (segment.phase == PalpationPhase::hold) {
      // Pressed: the smooth hand is press_depth below the site along its normal.
      const Eigen::Vector3d x = path.smooth[segment.begin];
      EXPECT_NEAR((site - x).dot(n), p.press_depth_m, 1e-12);
      ++holds;
    }
    if (segment.phase == PalpationPhase::transfer || segment.phase == PalpationPhase::rest) {
      for (long long k = segment.begin; k < segment.end; k += 50) {
        EXPECT_GT(sphere().signed_distance(path.smooth[k]), 0.0) << "sample " << k << " is inside while free";
      }
    }
  }
  EXPECT_EQ(holds, 2 * path.palpations);  // before and after each slide
  EXPECT_GT(sphere().signed_distance(path.smooth.back()), 0.0);
  // Tremor on top: the tip differs from the smooth hand by about its RMS.
  double sum = 0;
  for (std::size_t k = 0; k < path.tip.size(); ++k) sum += (path.tip[k] - path.smooth[k]).squaredNorm();
  EXPECT_NEAR(std::sqrt(sum / path.tip.size() / 3), p.tremor.rms_per_axis_m, 0.3 * p.tremor.rms_per_axis_m);
}

TEST(PalpationTrajectory, IsDeterministicForASeed) {
  const PalpationTrajectory a = make_palpation_trajectory(sphere(), settings());
  const PalpationTrajectory b = make_palpation_trajectory(sphere(), settings());
  PalpationSettings other = settings();
  other.seed = 4;
  const PalpationTrajectory c = make_palpation_trajectory(sphere(), other);
  EXPECT_EQ(a.tip, b.tip);
  EXPECT_NE(a.tip, c.tip);
}

TEST(PalpationTrajectory, RefusesWhatCannotBeDone) {
  PalpationSettings p = settings();
  p.duration_s = 1.0;  // one palpation takes 0.8 + 2 × 0.5 + 1.0 + 0.8 + 2 × 0.4 = 4.4 s
  EXPECT_DOUBLE_EQ(p.first_palpation_s(), 4.4);
  testing::expect_invalid_argument([&] { make_palpation_trajectory(sphere(), p); }, {"duration_s", "shorter than one palpation"});
  p.duration_s = 4.4;
  EXPECT_EQ(make_palpation_script(sphere(), p).palpations, 1);
  p = settings();
  p.sites = {Eigen::Vector3d(0, 0, 0.05), Eigen::Vector3d(0, 0, -0.05)};  // opposite poles
  p.lift_m = 0.0;
  try {
    make_palpation_trajectory(sphere(), p);
    ADD_FAILURE() << "a transfer through the organ was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("lift_m"), std::string::npos) << e.what();
  }
  p = settings();
  p.press_depth_m = -1;
  testing::expect_invalid_argument([&] { make_palpation_trajectory(sphere(), p); }, {"press_depth_m"});
}

TEST(ScriptedDevice, PlaysSamplesAtTheirTimesAndFinishes) {
  std::vector<Eigen::Vector3d> path{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  ScriptedDevice device(path, {}, 1e-3);
  EXPECT_EQ(device.read(0.0).tip_position_m.x(), 0);
  EXPECT_EQ(device.read(1e-3).tip_position_m.x(), 1);
  EXPECT_EQ(device.read(2e-3).tip_position_m.x(), 2);
  EXPECT_FALSE(device.read(2e-3).finished);
  EXPECT_TRUE(device.read(3e-3).finished);
  EXPECT_EQ(device.read(3e-3).tip_position_m.x(), 2);
  EXPECT_FALSE(device.read(std::numeric_limits<double>::quiet_NaN()).finished);
  testing::expect_invalid_argument([] { ScriptedDevice d({}, {}, 1e-3); }, {"empty"});
  testing::expect_invalid_argument([] { ScriptedDevice d({{0, 0, std::nan("")}}, {}, 1e-3); }, {"tip position 0"});
}

TEST(PalpationDevice, PlaysTheSampledScriptBitForBitInConstantMemory) {
  PalpationSettings p = settings();
  p.duration_s = 30;
  const PalpationScript script = make_palpation_script(sphere(), p);
  const PalpationTrajectory path = sample_palpation_script(script);
  ASSERT_EQ(static_cast<long long>(path.tip.size()), script.sample_count);
  ScriptedDevice scripted(path.tip, path.tool_axis, path.sample_period_s);
  PalpationDevice device(script);
  EXPECT_EQ(device.duration_s(), scripted.duration_s());
  const auto expect_same = [&](double t) {
    const DeviceSample a = scripted.read(t), b = device.read(t);
    EXPECT_EQ(a.tip_position_m, b.tip_position_m) << "t = " << t;
    EXPECT_EQ(a.orientation.coeffs(), b.orientation.coeffs()) << "t = " << t;
    EXPECT_EQ(a.finished, b.finished) << "t = " << t;
  };
  // Every tick in order, as the haptic loop reads, then past the end.
  for (long long k = 0; k <= script.sample_count + 2; ++k) expect_same(static_cast<double>(k) * path.sample_period_s);
  // Backwards (the tremor restarts), between samples, and nonsense times.
  for (const double t : {12.3456, 0.0, 29.9995, 7.0, 7.0, -1.0, std::numeric_limits<double>::quiet_NaN(), 1e300})
    expect_same(t);
  // The script grows with the moves (about ten per palpation), not with the samples.
  EXPECT_LE(script.moves.size(), 12U * static_cast<std::size_t>(script.palpations) + 4U);
  EXPECT_LT(script.moves.size() * sizeof(PalpationMove), path.tip.size() * sizeof(Eigen::Vector3d) / 100);
  // Without tremor the pose is the smooth hand.
  p.tremor.rms_per_axis_m = 0;
  const PalpationScript calm = make_palpation_script(sphere(), p);
  PalpationDevice still(calm);
  EXPECT_EQ(still.read(1.0).tip_position_m, sample_palpation_script(calm).smooth[1000]);
}

TEST(PalpationDevice, RefusesABrokenScript) {
  PalpationScript script = make_palpation_script(sphere(), settings());
  PalpationScript gap = script;
  gap.moves[1].begin += 1;
  testing::expect_invalid_argument([&] { PalpationDevice d(gap); }, {"move 1", "does not continue"});
  PalpationScript nan = script;
  nan.moves[2].to_m.x() = std::nan("");
  testing::expect_invalid_argument([&] { PalpationDevice d(nan); }, {"move 2", "non-finite"});
  testing::expect_invalid_argument([] { PalpationDevice d(PalpationScript{}); }, {"no samples"});
  testing::expect_invalid_argument([&] { PalpationDevice d(script, 0.0); }, {"max_force_N"});
}

TEST(Recording, RoundTripsThroughCsvAndReplays) {
  touchstone::testing::TemporaryDirectory directory("recording");
  const PalpationTrajectory path = make_palpation_trajectory(sphere(), settings());
  ScriptedDevice scripted(path.tip, path.tool_axis, path.sample_period_s);
  RecordingDevice recorder(scripted, 5000);
  for (int k = 0; k < 6000; ++k) {
    const DeviceSample s = recorder.read(k * 1e-3);
    recorder.write_force(Eigen::Vector3d(0, 0, 1e-3 * k), k * 1e-3);
    (void)s;
  }
  EXPECT_EQ(recorder.samples().size(), 5000U);
  EXPECT_EQ(recorder.dropped(), 1000);
  const std::string file = directory.path("recording.csv");
  recorder.write_csv(file);
  ReplayDevice replay = ReplayDevice::from_csv(file);
  ASSERT_EQ(replay.samples().size(), 5000U);
  for (int k = 0; k < 5000; k += 7) {
    EXPECT_EQ(replay.read(k * 1e-3).tip_position_m, path.tip[k]) << "sample " << k;  // 17 digits: exact
    EXPECT_EQ(replay.samples()[k].force_N.z(), 1e-3 * k);
  }
  // Between samples: linear interpolation.
  const Eigen::Vector3d middle = replay.read(10.5e-3).tip_position_m;
  EXPECT_TRUE(middle.isApprox(0.5 * (path.tip[10] + path.tip[11]), 1e-12));
  EXPECT_TRUE(replay.read(6.0).finished);
}

TEST(Recording, MalformedFilesNameTheFileAndLine) {
  touchstone::testing::TemporaryDirectory directory("recording");
  const auto write = [&](const std::string& text) {
    return directory.file("bad.csv", text);
  };
  const std::string header = "time_s,x_m,y_m,z_m,qw,qx,qy,qz,connected,fx_N,fy_N,fz_N\n";
  const auto expect_error = [](const std::string& file, const std::string& fragment) {
    try {
      read_recording_csv(file);
      ADD_FAILURE() << "accepted; expected an error mentioning " << fragment;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
    }
  };
  expect_error(write("x,y\n"), "header");
  expect_error("/dev/zero", "not a regular file");  // would be read forever
  expect_error(write(header + "0,1,2,3,1,0,0,0,1,0,0,0\n0.001,1,2,3,1,0,0,0,1,0,0\n"), "line 3");
  expect_error(write(header + "0,1,2,nan,1,0,0,0,1,0,0,0\n"), "not finite");
  expect_error(write(header + "0,1,2,abc,1,0,0,0,1,0,0,0\n"), "'abc'");
  expect_error(write(header + "0.1,1,2,3,1,0,0,0,1,0,0,0\n0.05,1,2,3,1,0,0,0,1,0,0,0\n"), "does not increase");
  expect_error(write(header + "0,1,2,3,2,0,0,0,1,0,0,0\n"), "unit quaternion");
  expect_error(write(header + "0,1,2,3,1,0,0,0,0.5,0,0,0\n"), "connected = 0.5 must be 0 or 1");
  expect_error(write(header + "0,1,2,3,1,0,0,0,-1,0,0,0\n"), "connected = -1 must be 0 or 1");
  expect_error(write(header), "no samples");
  expect_error(directory.path("missing.csv"), "cannot open");
}

}  // namespace
}  // namespace touchstone::realtime::haptics
