#include "touchstone/studies/provenance.hpp"

#include "touchstone/fem/blas_kernels.hpp"
#include "touchstone/realtime/runtime/loop_timing.hpp"

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
  const std::string blas_kernels = fem::loaded_openblas_core();
  return {
      {"git", version::git_hash},
      {"build_type", version::build_type},
      {"compiler", version::compiler},
      {"machine", host_name() + ", " + cpu_model() + ", " +
                      (cores == 0 ? std::string("unknown number of") : std::to_string(cores)) +
                      " cores"},
      // The direct solver's speed depends on it: OpenBLAS's kernel set for this CPU.
      {"blas", blas_kernels.empty() ? std::string("not OpenBLAS") : "OpenBLAS, " + blas_kernels + " kernels"},
      // So do mesh generation and the factorisation: whether the heap is on transparent huge pages.
      {"heap_huge_pages", realtime::runtime::heap_huge_pages_description()},
      {"config_sha256", sha256_hex(config_text)},
      {"time_utc", utc_now_iso8601()},
      {"touchstone_version", touchstone::version::project_version},
  };
}

}  // namespace touchstone::studies
