// The output helpers every subcommand shares (see the header).
#include "touchstone/studies/output_files.hpp"
#include "touchstone/geometry/regular_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace touchstone::studies {
using nlohmann::json;

namespace {
std::string error_text(int error_number) { return std::strerror(error_number); }
constexpr double nan_value = std::numeric_limits<double>::quiet_NaN();
}  // namespace

json json_number(double value) { return std::isfinite(value) ? json(value) : json(nullptr); }

json vector_json(const Eigen::Vector3d& v) { return json::array({json_number(v[0]), json_number(v[1]), json_number(v[2])}); }

json matrix_json(const Eigen::Ref<const Eigen::MatrixXd>& m, int n) {
  json rows = json::array();
  for (int i = 0; i < n; ++i) {
    json row = json::array();
    for (int j = 0; j < n; ++j) row.push_back(json_number(m(i, j)));
    rows.push_back(std::move(row));
  }
  return rows;
}

Eigen::Vector3d vector_from_json(const json& j) {
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}

Eigen::Matrix3d matrix_from_json(const json& j) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = j.at(r).at(c).get<double>();
  return m;
}

double value_or_nan(const json& j) { return j.is_number() ? j.get<double>() : nan_value; }

bool is_finite_number(const json& j) { return j.is_number() && std::isfinite(j.get<double>()); }

bool is_finite_vector(const json& j, std::size_t n) {
  return j.is_array() && j.size() == n && std::all_of(j.begin(), j.end(), [](const json& v) { return is_finite_number(v); });
}

bool is_finite_matrix(const json& j, std::size_t n) {
  return j.is_array() && j.size() == n &&
         std::all_of(j.begin(), j.end(), [n](const json& row) { return is_finite_vector(row, n); });
}

double value_or_nan(const json& object, const char* key) {
  return object.is_object() && object.contains(key) ? value_or_nan(object.at(key)) : nan_value;
}

double axial(const json& vector, const Eigen::Vector3d& d) {
  if (!vector.is_array() || vector.size() != 3) return nan_value;
  double sum = 0;
  for (int i = 0; i < 3; ++i) sum += value_or_nan(vector.at(i)) * d[i];
  return sum;
}

const json& json_at_path(const json& j, const std::vector<std::string>& path) {
  static const json null_json;
  const json* node = &j;
  for (const auto& key : path) {
    if (!node->is_object() || !node->contains(key)) return null_json;
    node = &node->at(key);
  }
  return *node;
}

std::string format_number(double value) {
  if (!std::isfinite(value)) return "-";
  std::ostringstream text;
  text << value;
  return text.str();
}

std::string table_cell(double value, int width, int decimals) {
  char text[64];
  if (std::isfinite(value)) std::snprintf(text, sizeof text, "%*.*f", width, decimals, value);
  else std::snprintf(text, sizeof text, "%*s", width, "-");
  return text;
}

std::string csv_escape(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string csv_value(const json& j) {
  if (j.is_null()) return "";
  if (j.is_string()) return csv_escape(j.get<std::string>());
  if (j.is_number_float()) {
    char text[40];
    std::snprintf(text, sizeof text, "%.10g", j.get<double>());
    return text;
  }
  return csv_escape(j.dump());
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

AtomicFileWriter::AtomicFileWriter(std::string path) : path_(std::move(path)) {
  const std::filesystem::path parent = std::filesystem::path(path_).parent_path();
  if (!parent.empty()) {
    std::error_code error;
    std::filesystem::create_directories(parent, error);
    if (error) {
      throw std::runtime_error("cannot write '" + path_ + "': cannot create folder '" + parent.string() + "' (" +
                               error.message() + ")");
    }
  }
  // The pid keeps concurrent writers (e.g. parallel study runs) off each other's temporary.
  temporary_ = path_ + ".tmp." + std::to_string(getpid());
  fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    const int error_number = errno;
    throw std::runtime_error("cannot write '" + path_ + "': cannot create '" + temporary_ + "' (" +
                             error_text(error_number) + ")");
  }
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlink(temporary_.c_str());
  }
}

void AtomicFileWriter::fail(const std::string& what, int error_number) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  ::unlink(temporary_.c_str());
  throw std::runtime_error("cannot write '" + path_ + "': " + what + " (" + error_text(error_number) + ")");
}

void AtomicFileWriter::append(const char* data, std::size_t size) {
  if (fd_ < 0) throw std::runtime_error("cannot write '" + path_ + "': the file is already committed or failed");
  std::size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(fd_, data + written, size - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write failed", errno);
    }
    written += static_cast<std::size_t>(n);
  }
}

void AtomicFileWriter::commit() {
  if (fd_ < 0) throw std::runtime_error("cannot write '" + path_ + "': the file is already committed or failed");
  // close() is where some file systems (NFS) report a failed write-back.
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) {
    const int error_number = errno;
    ::unlink(temporary_.c_str());
    throw std::runtime_error("cannot write '" + path_ + "': close failed (" + error_text(error_number) + ")");
  }
  if (::rename(temporary_.c_str(), path_.c_str()) != 0) {
    const int error_number = errno;
    ::unlink(temporary_.c_str());
    throw std::runtime_error("cannot write '" + path_ + "': rename failed (" + error_text(error_number) + ")");
  }
}

void write_file_atomically(const std::string& path, const std::string& text) {
  AtomicFileWriter file(path);
  file.append(text);
  file.commit();
}

std::string read_file(const std::string& path) {
  if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
    throw std::runtime_error("cannot read '" + path + "' (" + reason + ")");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int error_number = errno;
    throw std::runtime_error("cannot read '" + path + "' (" + error_text(error_number) + ")");
  }
  std::string text;
  std::array<char, 65536> buffer{};
  for (;;) {
    const ssize_t n = ::read(fd, buffer.data(), buffer.size());
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error_number = errno;
      ::close(fd);
      throw std::runtime_error("cannot read '" + path + "' (" + error_text(error_number) + ")");
    }
    text.append(buffer.data(), static_cast<std::size_t>(n));
  }
  ::close(fd);
  return text;
}

std::string path_relative_to(const std::string& directory, const std::string& path) {
  if (path.empty()) return path;
  std::filesystem::path p(path);
  if (p.is_relative()) p = std::filesystem::path(directory) / p;
  return p.lexically_normal().string();
}

}  // namespace touchstone::studies
