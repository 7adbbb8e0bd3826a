// libFuzzer harness of the recording reader (the CSV `touchstone sim --record` writes and the
// replay device plays): the bytes as a recording, read, then replayed at its first and last
// sample times and between them. std::runtime_error naming the file and line is the reader's
// documented answer to a bad recording. A recording it accepts must replay to finite poses and
// unit orientations, as the haptic loop takes them on trust: anything else is a finding, as is
// another exception, a sanitizer report or a hang.
#include "touchstone/realtime/haptics/device_recorder.hpp"
#include "touchstone/realtime/haptics/replay_device.hpp"

#include "fuzz_input_file.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace {

void require_usable(const touchstone::realtime::haptics::DeviceSample& sample, double time_s) {
  if (sample.tip_position_m.allFinite() && sample.orientation.coeffs().allFinite() &&
      std::abs(sample.orientation.norm() - 1.0) < 1e-6)
    return;
  std::fprintf(stderr, "replay at t = %.17g s: position (%g, %g, %g), orientation norm %g\n", time_s,
               sample.tip_position_m.x(), sample.tip_position_m.y(), sample.tip_position_m.z(),
               sample.orientation.norm());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace haptics = touchstone::realtime::haptics;
  const std::string path = touchstone::fuzz::write_input_file("recording.csv", data, size);
  try {
    haptics::ReplayDevice replay = haptics::ReplayDevice::from_csv(path);
    replay.start();
    const double begin_s = replay.begin_s();
    const double end_s = replay.end_s();
    for (const double t : {begin_s, begin_s + 0.25 * (end_s - begin_s), 0.5 * (begin_s + end_s), end_s})
      require_usable(replay.read(t), t);
  } catch (const std::runtime_error&) {
  }
  return 0;
}
