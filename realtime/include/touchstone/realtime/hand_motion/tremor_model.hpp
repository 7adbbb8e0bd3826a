#pragma once
/// @file
/// Physiological hand tremor for studies (paper §3.2): band-limited noise in the
/// 7–12 Hz band, of a chosen RMS amplitude, in 3-D, sampled at the haptic rate (1 kHz), to add
/// to smooth hand motion (≤ 10 Hz; see approach_trajectory.hpp). Deterministic for a seed and
/// bit-reproducible across platforms up to libm (own random number generator).
///
/// Two spectra:
/// - `band_noise` (default): Gaussian white noise through a Butterworth band-pass (order n
///   prototype, so 2n poles in n cascaded biquads, bilinear transform with pre-warped band
///   edges: −3 dB at 7 and 12 Hz). A random process with a random amplitude envelope, like a
///   real tremor; its RMS equals the requested amplitude in expectation (the input is scaled
///   by the filter's noise gain, Σ h[k]²), a finite record fluctuates by about 1/√(2 B T).
/// - `sinusoids`: per axis K sinusoids of equal amplitude, one at a random frequency in each
///   of K equal sub-bands, random phases. Every line is in the band and the RMS is exact up to
///   beats between lines (a few per cent over a few seconds).

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <complex>
#include <cstdint>

namespace touchstone::realtime::hand_motion {

/// A small deterministic random stream (xoshiro256** seeded through splitmix64), independent of
/// the standard library's distributions so that a seed means the same numbers everywhere.
class RandomStream {
 public:
  explicit RandomStream(std::uint64_t seed) noexcept {
    for (auto& word : state_) {
      seed += 0x9e3779b97f4a7c15ULL;
      std::uint64_t z = seed;
      z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
      z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
      word = z ^ (z >> 31);
    }
  }
  std::uint64_t next_u64() noexcept {
    const std::uint64_t result = rotl(state_[1] * 5, 7) * 9;
    const std::uint64_t t = state_[1] << 17;
    state_[2] ^= state_[0];
    state_[3] ^= state_[1];
    state_[1] ^= state_[2];
    state_[0] ^= state_[3];
    state_[2] ^= t;
    state_[3] = rotl(state_[3], 45);
    return result;
  }
  /// Uniform in [0, 1).
  double uniform() noexcept { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  /// Standard normal (Box–Muller; the second value of each pair is kept for the next call).
  double gaussian() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    const double radius = std::sqrt(-2.0 * std::log(u1));
    const double angle = 6.283185307179586 * u2;
    spare_ = radius * std::sin(angle);
    has_spare_ = true;
    return radius * std::cos(angle);
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept { return (x << k) | (x >> (64 - k)); }
  std::array<std::uint64_t, 4> state_{};
  double spare_ = 0;
  bool has_spare_ = false;
};

enum class TremorSpectrum : std::uint8_t {
  band_noise,  ///< white noise through a Butterworth band-pass (cascaded biquads)
  sinusoids,   ///< random-phase sinusoids, one per sub-band
};

/// Largest Butterworth prototype order (biquads per axis).
inline constexpr int max_tremor_filter_order = 8;
/// Largest number of sinusoids per axis.
inline constexpr int max_tremor_sinusoids = 128;

struct TremorSettings {
  /// RMS of the tremor displacement along each axis [m] (the 3-D RMS is √3 times it). 0: none.
  double rms_per_axis_m = 1e-4;
  double band_low_hz = 7.0;    ///< physiological tremor band (paper, ref. [9])
  double band_high_hz = 12.0;
  double sample_rate_hz = 1000.0;
  TremorSpectrum spectrum = TremorSpectrum::band_noise;
  /// Butterworth prototype order n (band_noise): n biquads per axis. 6 keeps ≥ 90 % of the power
  /// between the −3 dB edges and ≥ 99 % within 5–15 Hz (asserted in test_tremor_model); lower
  /// orders leak more of it out of the band.
  int filter_order = 6;
  int sinusoid_count = 32;     ///< sinusoids per axis (sinusoids)
  std::uint64_t seed = 1;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Generates tremor samples one at a time: constant cost, no allocation, any length.
class TremorGenerator {
 public:
  /// Builds the filter (or draws the sinusoids) and lets the filter settle, so that the
  /// first sample is already from the stationary process. Throws on invalid settings.
  explicit TremorGenerator(const TremorSettings& settings);

  /// The next sample (x, y, z) [m].
  Eigen::Vector3d next() noexcept;
  /// Back to the first sample of the same sequence.
  void reset() noexcept;

  const TremorSettings& settings() const noexcept { return settings_; }
  /// |H(f)| of the band-pass (band_noise; 1 at the centre √(f_low f_high), 1/√2 at the edges).
  double filter_gain(double frequency_hz) const noexcept;
  /// Standard deviation of the white noise fed to the filter [m] (band_noise).
  double input_sigma_m() const noexcept { return input_sigma_m_; }

 private:
  struct Biquad {
    double b0 = 1, b1 = 0, b2 = -1, a1 = 0, a2 = 0;
  };
  double filter(int axis, double x) noexcept;

  TremorSettings settings_;
  RandomStream random_;
  // band_noise
  std::array<Biquad, max_tremor_filter_order> biquads_{};
  std::array<std::array<std::array<double, 2>, max_tremor_filter_order>, 3> state_{};
  double input_sigma_m_ = 0;
  int warm_up_samples_ = 0;
  // sinusoids
  std::array<std::array<std::complex<double>, max_tremor_sinusoids>, 3> phasors_{};
  std::array<std::array<std::complex<double>, max_tremor_sinusoids>, 3> rotations_{};
  double sinusoid_amplitude_m_ = 0;
  long long samples_ = 0;
};

}  // namespace touchstone::realtime::hand_motion
