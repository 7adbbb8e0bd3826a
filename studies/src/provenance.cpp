#include "touchstone/studies/provenance.hpp"

#include <touchstone/version.hpp>

#include <openssl/evp.h>

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <thread>

namespace touchstone::studies {

namespace {

std::string error_text(int error_number) { return std::strerror(error_number); }

std::string host_name() {
  std::array<char, 256> buffer{};
  if (gethostname(buffer.data(), buffer.size() - 1) != 0) return "unknown host";
  return buffer.data();
}

// x86 kernels say "model name"; some ARM kernels only "Hardware" or "Processor".
std::string cpu_model() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  std::string fallback;
  while (std::getline(cpuinfo, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string_view name(line.data(), colon);
    while (!name.empty() && (name.back() == ' ' || name.back() == '\t')) name.remove_suffix(1);
    std::string value = line.substr(colon + 1);
    value.erase(0, value.find_first_not_of(" \t"));
    if (name == "model name" && !value.empty()) return value;
    if ((name == "Hardware" || name == "Processor") && fallback.empty()) fallback = value;
  }
  return fallback.empty() ? "unknown CPU" : fallback;
}

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::array<char, 32> buffer{};
  std::strftime(buffer.data(), buffer.size(), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buffer.data();
}

}  // namespace

std::string sha256_hex(const std::string& text) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int length = 0;
  if (EVP_Digest(text.data(), text.size(), digest.data(), &length, EVP_sha256(), nullptr) != 1) {
    throw std::runtime_error("sha256_hex: OpenSSL EVP_Digest failed");
  }
  static constexpr char hex[] = "0123456789abcdef";
  std::string result;
  result.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) {
    result += hex[digest[i] >> 4];
    result += hex[digest[i] & 0x0f];
  }
  return result;
}

nlohmann::json provenance(const std::string& config_text) {
  const unsigned cores = std::thread::hardware_concurrency();
  return {
      {"git", version::git_hash},
      {"build_type", version::build_type},
      {"compiler", version::compiler},
      {"machine", host_name() + ", " + cpu_model() + ", " +
                      (cores == 0 ? std::string("unknown number of") : std::to_string(cores)) +
                      " cores"},
      {"config_sha256", sha256_hex(config_text)},
      {"time_utc", utc_now_iso8601()},
      {"touchstone_version", touchstone::version::project_version},
  };
}

void write_file_atomically(const std::string& path, const std::string& text) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) {
    std::error_code error;
    std::filesystem::create_directories(parent, error);
    if (error) {
      throw std::runtime_error("cannot write '" + path + "': cannot create folder '" +
                               parent.string() + "' (" + error.message() + ")");
    }
  }

  // The pid keeps concurrent writers (e.g. parallel study runs) off each other's temporary.
  const std::string temporary = path + ".tmp." + std::to_string(getpid());
  const auto fail = [&](const std::string& what, int error_number) {
    ::unlink(temporary.c_str());
    throw std::runtime_error("cannot write '" + path + "': " + what + " (" +
                             error_text(error_number) + ")");
  };

  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int error_number = errno;
    throw std::runtime_error("cannot write '" + path + "': cannot create '" + temporary + "' (" +
                             error_text(error_number) + ")");
  }
  std::size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error_number = errno;
      ::close(fd);
      fail("write failed", error_number);
    }
    written += static_cast<std::size_t>(n);
  }
  // close() is where some file systems (NFS) report a failed write-back.
  if (::close(fd) != 0) fail("close failed", errno);
  if (::rename(temporary.c_str(), path.c_str()) != 0) fail("rename failed", errno);
}

std::string read_file(const std::string& path) {
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

}  // namespace touchstone::studies
