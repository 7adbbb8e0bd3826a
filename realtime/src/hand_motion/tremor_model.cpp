#include "touchstone/realtime/hand_motion/tremor_model.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::realtime::hand_motion {

namespace {

using Complex = std::complex<double>;
constexpr double pi = 3.14159265358979323846;

}  // namespace

void TremorSettings::validate() const {
  const auto reject = [](const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("TremorSettings." + field + " = " + std::to_string(value) + " " + rule);
  };
  if (!(rms_per_axis_m >= 0) || !std::isfinite(rms_per_axis_m))
    reject("rms_per_axis_m", rms_per_axis_m, "must be finite and >= 0");
  if (!(sample_rate_hz > 0) || !std::isfinite(sample_rate_hz))
    reject("sample_rate_hz", sample_rate_hz, "must be finite and > 0");
  if (!(band_low_hz > 0)) reject("band_low_hz", band_low_hz, "must be > 0");
  if (!(band_high_hz > band_low_hz)) reject("band_high_hz", band_high_hz, "must be > band_low_hz");
  if (!(band_high_hz < 0.45 * sample_rate_hz)) reject("band_high_hz", band_high_hz, "must be < 0.45 sample_rate_hz");
  // A band wider than about 3.5 octaves gives real band-pass poles, which this filter does not handle.
  if (!(band_high_hz < 10 * band_low_hz)) reject("band_high_hz", band_high_hz, "must be < 10 band_low_hz");
  if (filter_order < 1 || filter_order > max_tremor_filter_order)
    reject("filter_order", filter_order, "must be in [1, " + std::to_string(max_tremor_filter_order) + "]");
  if (sinusoid_count < 1 || sinusoid_count > max_tremor_sinusoids)
    reject("sinusoid_count", sinusoid_count, "must be in [1, " + std::to_string(max_tremor_sinusoids) + "]");
}

TremorGenerator::TremorGenerator(const TremorSettings& settings) : settings_(settings), random_(settings.seed) {
  settings_.validate();
  const double rate = settings_.sample_rate_hz;
  const int n = settings_.filter_order;

  // Butterworth band-pass by the bilinear transform: pre-warp the edges, map each prototype
  // pole p to the two band-pass poles of s² − p B s + Ω0² = 0, map those to z, and keep the
  // upper-half-plane pole of each conjugate pair as one biquad with zeros at z = ±1.
  const double warped_low = 2 * rate * std::tan(pi * settings_.band_low_hz / rate);
  const double warped_high = 2 * rate * std::tan(pi * settings_.band_high_hz / rate);
  const double centre2 = warped_low * warped_high;
  const double width = warped_high - warped_low;
  std::vector<Complex> poles;
  for (int k = 1; k <= n; ++k) {
    const Complex prototype = std::polar(1.0, pi * (2.0 * k + n - 1) / (2.0 * n));
    const Complex root = std::sqrt(prototype * prototype * width * width - 4.0 * centre2);
    for (const Complex s : {(prototype * width + root) / 2.0, (prototype * width - root) / 2.0}) {
      const Complex z = (1.0 + s / (2 * rate)) / (1.0 - s / (2 * rate));
      if (z.imag() > 1e-12) poles.push_back(z);
    }
  }
  if (static_cast<int>(poles.size()) != n)
    throw std::invalid_argument("TremorSettings: the band [" + std::to_string(settings_.band_low_hz) + ", " +
                                std::to_string(settings_.band_high_hz) + "] Hz gives real band-pass poles");
  for (int k = 0; k < n; ++k) {
    biquads_[k].a1 = -2 * poles[k].real();
    biquads_[k].a2 = std::norm(poles[k]);
  }
  // Unit gain at the centre frequency.
  const double centre_hz = std::sqrt(settings_.band_low_hz * settings_.band_high_hz);
  const double scale = std::pow(filter_gain(centre_hz), -1.0 / n);
  for (int k = 0; k < n; ++k) {
    biquads_[k].b0 = scale;
    biquads_[k].b2 = -scale;
  }

  // Noise gain Σ h[k]² from the impulse response, so that the output RMS is the requested one.
  const double bandwidth_hz = settings_.band_high_hz - settings_.band_low_hz;
  const int impulse_samples = static_cast<int>(std::ceil(60.0 * rate / bandwidth_hz)) + 1000;
  double energy = 0;
  for (int i = 0; i < impulse_samples; ++i) {
    const double h = filter(0, i == 0 ? 1.0 : 0.0);
    energy += h * h;
  }
  input_sigma_m_ = settings_.rms_per_axis_m / std::sqrt(energy);
  // Ten time constants of the narrowest pole pair, about 10 / B.
  warm_up_samples_ = static_cast<int>(std::ceil(10.0 * rate / bandwidth_hz));
  sinusoid_amplitude_m_ = settings_.rms_per_axis_m * std::sqrt(2.0 / settings_.sinusoid_count);
  reset();
}

double TremorGenerator::filter_gain(double frequency_hz) const noexcept {
  const Complex z1 = std::polar(1.0, -2 * pi * frequency_hz / settings_.sample_rate_hz);  // z⁻¹
  const Complex z2 = z1 * z1;
  double gain = 1;
  for (int k = 0; k < settings_.filter_order; ++k) {
    const Biquad& q = biquads_[k];
    gain *= std::abs((q.b0 + q.b1 * z1 + q.b2 * z2) / (1.0 + q.a1 * z1 + q.a2 * z2));
  }
  return gain;
}

double TremorGenerator::filter(int axis, double x) noexcept {
  // Transposed direct form II, one biquad after the other.
  for (int k = 0; k < settings_.filter_order; ++k) {
    const Biquad& q = biquads_[k];
    std::array<double, 2>& w = state_[axis][k];
    const double y = q.b0 * x + w[0];
    w[0] = q.b1 * x - q.a1 * y + w[1];
    w[1] = q.b2 * x - q.a2 * y;
    x = y;
  }
  return x;
}

void TremorGenerator::reset() noexcept {
  random_ = RandomStream(settings_.seed);
  samples_ = 0;
  for (auto& axis : state_)
    for (auto& w : axis) w = {0, 0};
  if (settings_.spectrum == TremorSpectrum::band_noise) {
    for (int i = 0; i < warm_up_samples_; ++i)
      for (int axis = 0; axis < 3; ++axis) filter(axis, input_sigma_m_ * random_.gaussian());
    return;
  }
  // One line in each of K equal sub-bands, at a random frequency, with a random phase.
  const int count = settings_.sinusoid_count;
  const double step = (settings_.band_high_hz - settings_.band_low_hz) / count;
  for (int axis = 0; axis < 3; ++axis) {
    for (int k = 0; k < count; ++k) {
      const double frequency = settings_.band_low_hz + (k + random_.uniform()) * step;
      phasors_[axis][k] = std::polar(1.0, 2 * pi * random_.uniform());
      rotations_[axis][k] = std::polar(1.0, 2 * pi * frequency / settings_.sample_rate_hz);
    }
  }
}

Eigen::Vector3d TremorGenerator::next() noexcept {
  Eigen::Vector3d sample;
  if (settings_.spectrum == TremorSpectrum::band_noise) {
    for (int axis = 0; axis < 3; ++axis) sample[axis] = filter(axis, input_sigma_m_ * random_.gaussian());
    ++samples_;
    return sample;
  }
  const int count = settings_.sinusoid_count;
  // Phasors rotate by multiplication; renormalised now and then against rounding drift.
  const bool renormalise = (++samples_ & 1023) == 0;
  for (int axis = 0; axis < 3; ++axis) {
    double sum = 0;
    for (int k = 0; k < count; ++k) {
      Complex& z = phasors_[axis][k];
      const Complex& w = rotations_[axis][k];
      sum += z.imag();
      // Written out: std::complex's operator* checks for infinities (a libcall on every product).
      z = Complex(z.real() * w.real() - z.imag() * w.imag(), z.real() * w.imag() + z.imag() * w.real());
      if (renormalise) z /= std::abs(z);
    }
    sample[axis] = sinusoid_amplitude_m_ * sum;
  }
  return sample;
}

}  // namespace touchstone::realtime::hand_motion
