#include "touchstone/realtime/mfs/organ_atlas.hpp"
#include "touchstone/geometry/regular_file.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace touchstone::realtime::mfs {
namespace {

using nlohmann::json;

constexpr const char* format_name = "touchstone.organ_atlas";
constexpr int format_version = 1;

std::string text_of(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

/// Reads one atlas document; every error names the file and the key path ("samples[2].frame.e1").
class AtlasReader {
 public:
  explicit AtlasReader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& message) const {
    throw std::runtime_error(path_ + ": " + (key.empty() ? std::string() : key + ": ") + message);
  }

  const json& member(const json& object, const std::string& where, const std::string& key) const {
    const std::string name = where.empty() ? key : where + "." + key;
    if (!object.is_object()) fail(where, "is not an object");
    const auto it = object.find(key);
    if (it == object.end()) fail(name, "missing");
    return *it;
  }
  static std::string child(const std::string& where, const std::string& key) {
    return where.empty() ? key : where + "." + key;
  }

  double number(const json& value, const std::string& name) const {
    if (!value.is_number()) fail(name, "is not a number (" + std::string(value.type_name()) + ")");
    const double x = value.get<double>();
    if (!std::isfinite(x)) fail(name, "is not finite");
    return x;
  }
  double number(const json& object, const std::string& where, const std::string& key) const {
    return number(member(object, where, key), child(where, key));
  }
  double positive(const json& object, const std::string& where, const std::string& key) const {
    const double x = number(object, where, key);
    if (!(x > 0)) fail(child(where, key), "= " + text_of(x) + " must be > 0");
    return x;
  }
  double non_negative(const json& object, const std::string& where, const std::string& key) const {
    const double x = number(object, where, key);
    if (!(x >= 0)) fail(child(where, key), "= " + text_of(x) + " must be >= 0");
    return x;
  }
  std::string string(const json& object, const std::string& where, const std::string& key) const {
    const json& value = member(object, where, key);
    if (!value.is_string()) fail(child(where, key), "is not a string");
    return value.get<std::string>();
  }
  bool boolean(const json& object, const std::string& where, const std::string& key) const {
    const json& value = member(object, where, key);
    if (!value.is_boolean()) fail(child(where, key), "is not true or false");
    return value.get<bool>();
  }
  const json& array(const json& value, const std::string& name, std::size_t size) const {
    if (!value.is_array()) fail(name, "is not an array");
    if (size != 0 && value.size() != size)
      fail(name, "has " + std::to_string(value.size()) + " entries, expected " + std::to_string(size));
    return value;
  }
  Eigen::Vector3d vector3(const json& object, const std::string& where, const std::string& key) const {
    const std::string name = child(where, key);
    const json& value = array(member(object, where, key), name, 3);
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v[i] = number(value[i], name + "[" + std::to_string(i) + "]");
    return v;
  }
  Eigen::Vector3d unit_vector(const json& object, const std::string& where, const std::string& key) const {
    const Eigen::Vector3d v = vector3(object, where, key);
    if (std::abs(v.norm() - 1) > 1e-6) fail(child(where, key), "has length " + text_of(v.norm()) + ", not 1");
    return v;
  }
  /// An n×n array of rows (n ≤ 6), in the top-left block.
  ExteriorMatrix matrix(const json& object, const std::string& where, const std::string& key, int n) const {
    const std::string name = child(where, key);
    const json& rows = array(member(object, where, key), name, static_cast<std::size_t>(n));
    ExteriorMatrix m = ExteriorMatrix::Zero();
    for (int i = 0; i < n; ++i) {
      const std::string row_name = name + "[" + std::to_string(i) + "]";
      const json& row = array(rows[i], row_name, static_cast<std::size_t>(n));
      for (int j = 0; j < n; ++j) m(i, j) = number(row[j], row_name + "[" + std::to_string(j) + "]");
    }
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j)
        if (std::abs(m(i, j) - m(j, i)) > 1e-6 * m.diagonal().cwiseAbs().maxCoeff())
          fail(name, "is not symmetric (entries [" + std::to_string(i) + "][" + std::to_string(j) + "] and [" +
                         std::to_string(j) + "][" + std::to_string(i) + "])");
    return m;
  }

  OrganAtlasSample sample(const json& value, const std::string& where, int modes, int size) const {
    OrganAtlasSample s;
    s.label = string(value, where, "label");
    s.contact_point_m = vector3(value, where, "contact_point_m");
    s.direction = unit_vector(value, where, "direction");
    const std::string frame = child(where, "frame");
    const json& f = member(value, where, "frame");
    s.frame.origin = vector3(f, frame, "origin_m");
    s.frame.axes.col(0) = unit_vector(f, frame, "e1");
    s.frame.axes.col(1) = unit_vector(f, frame, "e2");
    s.frame.axes.col(2) = unit_vector(f, frame, "e3");
    if ((s.frame.axes.transpose() * s.frame.axes - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
        s.frame.axes.determinant() < 0)
      fail(frame, "e1, e2, e3 are not a right-handed orthonormal frame");
    if ((s.frame.axes.col(2) - s.direction).norm() > 1e-6) fail(child(frame, "e3"), "differs from direction");
    s.tool_radius_m = positive(value, where, "tool_radius_m");
    s.local_radius_m = positive(value, where, "local_radius_m");
    if (!(s.local_radius_m > s.tool_radius_m))
      fail(child(where, "local_radius_m"), "= " + text_of(s.local_radius_m) + " must be > tool_radius_m");
    s.youngs_modulus_Pa = positive(value, where, "youngs_modulus_Pa");
    s.poisson_ratio = number(value, where, "poisson_ratio");
    if (!(s.poisson_ratio >= 0 && s.poisson_ratio < 0.5))
      fail(child(where, "poisson_ratio"), "= " + text_of(s.poisson_ratio) + " must be in [0, 0.5)");
    s.stiffness_N_per_m = matrix(value, where, "stiffness_N_per_m", size);
    for (int i = 0; i < size; ++i)
      if (!(s.stiffness_N_per_m(i, i) > 0))
        fail(child(where, "stiffness_N_per_m") + "[" + std::to_string(i) + "][" + std::to_string(i) + "]",
             "= " + text_of(s.stiffness_N_per_m(i, i)) + " must be > 0 (an energy)");
    // An energy: with the translations the cross terms matter too (a rigid shift of the trace
    // against the modes), so the whole matrix must be positive definite.
    if (size > 1 && Eigen::LLT<Eigen::MatrixXd>(s.stiffness_N_per_m.topLeftCorner(size, size)).info() != Eigen::Success)
      fail(child(where, "stiffness_N_per_m"), "is not positive definite (not an elastic energy)");
    s.half_space_stiffness_N_per_m = matrix(value, where, "half_space_stiffness_N_per_m", modes).topLeftCorner<3, 3>();
    s.relative_error = non_negative(value, where, "relative_error");
    const double dofs = non_negative(value, where, "dofs");
    if (dofs != std::floor(dofs)) fail(child(where, "dofs"), "is not a whole number");
    // 2⁵³: beyond it a double no longer counts in ones (and far beyond it a size_t overflows).
    if (dofs > 9007199254740992.0) fail(child(where, "dofs"), "= " + text_of(dofs) + " is too large");
    s.dofs = static_cast<std::size_t>(dofs);
    s.seconds = non_negative(value, where, "seconds");
    return s;
  }

  OrganAtlas atlas(const json& document) const {
    if (string(document, "", "format") != format_name)
      fail("format", "is '" + document.at("format").get<std::string>() + "', expected '" + format_name + "'");
    const double version = number(document, "", "version");
    if (version != format_version)
      fail("version", "= " + text_of(version) + ", this reader knows version " + std::to_string(format_version));
    OrganAtlas atlas;
    atlas.organ = string(document, "", "organ");
    // Optional: atlases written before they recorded these lack them.
    for (auto [key, field] : {std::pair{"surface_sha256", &atlas.surface_sha256}, std::pair{"attachment", &atlas.attachment}})
      if (document.contains(key)) *field = string(document, "", key);
    atlas.axisymmetric_about_z = boolean(document, "", "axisymmetric_about_z");
    const std::string modes = string(document, "", "modes");
    if (modes != "normal" && modes != "all") fail("modes", "is '" + modes + "', expected 'normal' or 'all'");
    atlas.mode_count = modes == "normal" ? 1 : 3;
    if (document.contains("cut_translations")) atlas.cut_translations = boolean(document, "", "cut_translations");
    const json& samples = array(member(document, "", "samples"), "samples", 0);
    if (samples.empty()) fail("samples", "is empty");
    for (std::size_t i = 0; i < samples.size(); ++i)
      atlas.samples.push_back(sample(samples[i], "samples[" + std::to_string(i) + "]", atlas.mode_count, atlas.matrix_size()));
    return atlas;
  }

 private:
  std::string path_;
};

json vector_json(const Eigen::Vector3d& v) { return json::array({v[0], v[1], v[2]}); }

template <typename Matrix>
json matrix_json(const Matrix& m, int n) {
  json rows = json::array();
  for (int i = 0; i < n; ++i) {
    json row = json::array();
    for (int j = 0; j < n; ++j) row.push_back(m(i, j));
    rows.push_back(row);
  }
  return rows;
}

/// The mode basis of a frame: the global punch translation is P c for mode amplitudes c =
/// (normal, tangential_1, tangential_2).
Eigen::Matrix3d mode_basis(const Eigen::Matrix3d& axes) {
  Eigen::Matrix3d p;
  p << axes.col(2), axes.col(0), axes.col(1);
  return p;
}

bool relatively_equal(double x, double y, double tolerance) {
  return std::abs(x - y) <= tolerance * std::max(std::abs(x), std::abs(y));
}

}  // namespace

OrganAtlas read_organ_atlas(const std::string& path) {
  if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
    throw std::runtime_error(path + ": cannot open the organ atlas (" + reason + ")");
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the organ atlas");
  json document;
  try {
    document = json::parse(in);
  } catch (const json::exception& error) {
    // Every parser error, not only parse_error: a number beyond double's range is out_of_range.
    throw std::runtime_error(path + ": not valid JSON: " + error.what());
  }
  try {
    return AtlasReader(path).atlas(document);
  } catch (const json::exception& error) {
    throw std::runtime_error(path + ": " + error.what());
  }
}

void write_organ_atlas(const OrganAtlas& atlas, const std::string& path) {
  if (atlas.mode_count != 1 && atlas.mode_count != 3)
    throw std::runtime_error(path + ": OrganAtlas.mode_count = " + std::to_string(atlas.mode_count) + " must be 1 or 3");
  json samples = json::array();
  for (const auto& s : atlas.samples) {
    samples.push_back({{"label", s.label},
                       {"contact_point_m", vector_json(s.contact_point_m)},
                       {"direction", vector_json(s.direction)},
                       {"frame",
                        {{"origin_m", vector_json(s.frame.origin)},
                         {"e1", vector_json(s.frame.axes.col(0))},
                         {"e2", vector_json(s.frame.axes.col(1))},
                         {"e3", vector_json(s.frame.axes.col(2))}}},
                       {"tool_radius_m", s.tool_radius_m},
                       {"local_radius_m", s.local_radius_m},
                       {"youngs_modulus_Pa", s.youngs_modulus_Pa},
                       {"poisson_ratio", s.poisson_ratio},
                       {"stiffness_N_per_m", matrix_json(s.stiffness_N_per_m, atlas.matrix_size())},
                       {"half_space_stiffness_N_per_m", matrix_json(s.half_space_stiffness_N_per_m, atlas.mode_count)},
                       {"relative_error", s.relative_error},
                       {"dofs", s.dofs},
                       {"seconds", s.seconds}});
  }
  json document{{"format", format_name},
                      {"version", format_version},
                      {"organ", atlas.organ},
                      {"axisymmetric_about_z", atlas.axisymmetric_about_z},
                      {"modes", atlas.mode_count == 1 ? "normal" : "all"},
                      {"samples", samples}};
  if (atlas.cut_translations) document["cut_translations"] = true;
  if (!atlas.surface_sha256.empty()) document["surface_sha256"] = atlas.surface_sha256;
  if (!atlas.attachment.empty()) document["attachment"] = atlas.attachment;
  std::ofstream out(path, std::ios::out | std::ios::trunc);
  out << document.dump(2) << "\n";
  if (!out.flush()) throw std::runtime_error(path + ": cannot write the organ atlas");
}

void OrganAtlasLookupSettings::validate() const {
  const auto reject = [](const char* field, double value, const char* requirement) {
    throw std::invalid_argument(std::string("OrganAtlasLookupSettings.") + field + " = " + text_of(value) + " " +
                                requirement);
  };
  if (!std::isfinite(search_radius_m) || search_radius_m < 0) reject("search_radius_m", search_radius_m, "must be >= 0");
  if (!std::isfinite(max_direction_deviation_rad) || max_direction_deviation_rad < 0 || max_direction_deviation_rad > 3.2)
    reject("max_direction_deviation_rad", max_direction_deviation_rad, "must be in [0, pi]");
  if (!std::isfinite(parameter_tolerance) || parameter_tolerance <= 0)
    reject("parameter_tolerance", parameter_tolerance, "must be > 0");
  if (!std::isfinite(power) || power <= 0) reject("power", power, "must be > 0");
}

OrganAtlasLookup lookup_exterior_stiffness(const OrganAtlas& atlas, const OrganAtlasQuery& query,
                                           const OrganAtlasLookupSettings& settings) {
  settings.validate();
  query.material.validate();
  OrganAtlasLookup result;
  result.mode_count = atlas.mode_count;
  result.cut_translations = atlas.cut_translations;
  if (atlas.samples.empty()) {
    result.message = "the atlas has no samples";
    return result;
  }

  // a, L and ν decide the fields ψ and the ball, so K_ext holds for those values only; E scales.
  const double tolerance = settings.parameter_tolerance;
  const auto same_parameters = [&](const OrganAtlasSample& s) {
    return relatively_equal(s.tool_radius_m, query.tool_radius_m, tolerance) &&
           relatively_equal(s.local_radius_m, query.local_radius_m, tolerance) &&
           relatively_equal(s.poisson_ratio, query.material.poisson_ratio, tolerance);
  };
  if (std::none_of(atlas.samples.begin(), atlas.samples.end(), same_parameters)) {
    const OrganAtlasSample& s = atlas.samples.front();
    std::ostringstream text;
    text << "atlas made for a = " << s.tool_radius_m << " m (L = " << s.local_radius_m << " m, nu = " << s.poisson_ratio
         << "), model has a = " << query.tool_radius_m << " m (L = " << query.local_radius_m
         << " m, nu = " << query.material.poisson_ratio << ")";
    result.status = OrganAtlasStatus::parameters_differ;
    result.message = text.str();
    return result;
  }

  // On an axisymmetric organ, turn the query about z onto the samples' half plane y = 0, x ≥ 0.
  Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
  if (atlas.axisymmetric_about_z) {
    const double azimuth = std::atan2(query.contact_point_m.y(), query.contact_point_m.x());
    turn = Eigen::AngleAxisd(-azimuth, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  const Eigen::Vector3d point = turn * query.contact_point_m;
  const Eigen::Vector3d direction = (turn * query.direction).normalized();
  const Eigen::Matrix3d query_axes = turn * PunchFrame::along(query.contact_point_m, query.direction).axes;
  const Eigen::Matrix3d query_modes = mode_basis(query_axes);

  const double radius = settings.search_radius_m > 0 ? settings.search_radius_m : query.local_radius_m;
  double nearest = std::numeric_limits<double>::infinity();
  double nearest_admissible_angle = std::numeric_limits<double>::infinity();
  std::vector<std::pair<double, const OrganAtlasSample*>> nearby;
  for (const auto& s : atlas.samples) {
    if (!same_parameters(s)) continue;
    const double distance = (s.contact_point_m - point).norm();
    nearest = std::min(nearest, distance);
    if (distance > radius) continue;
    const double angle = std::acos(std::clamp(s.direction.dot(direction), -1.0, 1.0));
    nearest_admissible_angle = std::min(nearest_admissible_angle, angle);
    if (angle <= settings.max_direction_deviation_rad) nearby.emplace_back(distance, &s);
  }
  result.nearest_distance_m = nearest;
  if (!(nearest <= radius)) {
    result.message = "no sample within " + text_of(radius) + " m of the contact (nearest: " + text_of(nearest) + " m)";
    return result;
  }
  if (nearby.empty()) {
    result.status = OrganAtlasStatus::direction_differs;
    result.message = "the samples within " + text_of(radius) + " m of the contact were made for push directions " +
                     text_of(nearest_admissible_angle * 180 / 3.14159265358979323846) +
                     " deg or more from the model's (allowed: " +
                     text_of(settings.max_direction_deviation_rad * 180 / 3.14159265358979323846) + " deg)";
    return result;
  }

  // A sample at the query's point is taken alone; otherwise w = 1/d^power.
  std::sort(nearby.begin(), nearby.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  if (nearby.front().first <= 1e-9 * query.local_radius_m) nearby.resize(1);
  const int n = atlas.mode_count, size = atlas.matrix_size();
  ExteriorMatrix sum = ExteriorMatrix::Zero();
  double weights = 0, error = 0;
  for (const auto& [distance, sample] : nearby) {
    const double w = nearby.size() == 1 ? 1.0 : 1.0 / std::pow(distance, settings.power);
    // Carry the sample's frame onto the query's: the smallest rotation taking its e₃ onto the
    // query's; what remains between the frames is a turn about e₃.
    const Eigen::Matrix3d carry =
        Eigen::Quaterniond::FromTwoVectors(sample->direction, direction).toRotationMatrix();
    const Eigen::Matrix3d sample_modes = mode_basis(carry * sample->frame.axes);
    // A global punch translation d has c_sample = Sᵀ d and c_query = Qᵀ d, so c_sample = T c_query
    // with T = Sᵀ Q, and ½ c_sampleᵀ K c_sample = ½ c_queryᵀ (Tᵀ K T) c_query. T₀₀ = 1 (e₃ is
    // carried onto e₃), so a normal-only matrix keeps its one entry.
    // The cut translations are vectors in the same (e₃, e₁, e₂) order: the same T.
    const Eigen::Matrix3d t = sample_modes.transpose() * query_modes;
    ExteriorMatrix carried = ExteriorMatrix::Zero();
    carried.topLeftCorner(n, n) = t.topLeftCorner(n, n);
    if (atlas.cut_translations) carried.block<3, 3>(n, n) = t;
    ExteriorMatrix k = ExteriorMatrix::Zero();
    k.topLeftCorner(size, size) = (carried.transpose() * sample->stiffness_N_per_m * carried).topLeftCorner(size, size);
    sum += w * k * (query.material.youngs_modulus_Pa / sample->youngs_modulus_Pa);
    error += w * sample->relative_error;
    weights += w;
  }
  result.status = OrganAtlasStatus::ok;
  result.stiffness_N_per_m = sum / weights;
  result.relative_error = error / weights;
  result.samples_used = nearby.size();
  return result;
}

std::string to_string(OrganAtlasStatus status) {
  switch (status) {
    case OrganAtlasStatus::ok: return "ok";
    case OrganAtlasStatus::no_sample_nearby: return "no_sample_nearby";
    case OrganAtlasStatus::parameters_differ: return "parameters_differ";
    case OrganAtlasStatus::direction_differs: return "direction_differs";
  }
  return "unknown";
}

}  // namespace touchstone::realtime::mfs
