// libFuzzer harness of the TOML study and scene readers: the bytes as the study file of the
// `touchstone` subcommands fem (and mesh), mfs, collision, study and sim, read and validated
// only, never run. (The atlas reader shares its file with the atlas's FEM runs, which need MPI
// and deal.II, kept out of the fuzz build.) ConfigError (naming the file and the key) is the readers'
// documented answer to a bad file; another exception escaping, a sanitizer report or a hang is
// a finding. The shipped studies/configs/*.toml are copied next to the input first, so that the
// comparison study's references to other study files resolve as in the repository.
#include "touchstone/studies/collision_study.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/sim_scene.hpp"
#include "touchstone/studies/study_runner.hpp"

#include "fuzz_input_file.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <typeinfo>

namespace {

namespace studies = touchstone::studies;

/// Runs one reader; ConfigError is the expected outcome of a bad file, anything else aborts.
template <class Reader>
void read_expecting_config_errors(const char* reader_name, Reader&& reader) {
  try {
    reader();
  } catch (const studies::ConfigError&) {
  } catch (const std::exception& error) {
    std::fprintf(stderr, "%s: %s escaped instead of a ConfigError: %s\n", reader_name, typeid(error).name(),
                 error.what());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  namespace fs = std::filesystem;
  for (const fs::directory_entry& entry : fs::directory_iterator(fs::path(TOUCHSTONE_SOURCE_DIR) / "studies/configs"))
    if (entry.is_regular_file() && entry.path().extension() == ".toml")
      fs::copy_file(entry.path(), touchstone::fuzz::scratch_directory() / entry.path().filename(),
                    fs::copy_options::overwrite_existing);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = touchstone::fuzz::write_input_file("fuzz_input.toml", data, size);
  const std::string directory = touchstone::fuzz::scratch_directory().string();
  const std::string text(reinterpret_cast<const char*>(data), size);
  read_expecting_config_errors("read_reference_study", [&] {
    studies::ConfigTable config = studies::ConfigTable::from_string(text, path);
    (void)studies::read_reference_study(config);
  });
  read_expecting_config_errors("read_mfs_study", [&] {
    studies::ConfigTable config = studies::ConfigTable::from_string(text, path);
    (void)studies::read_mfs_study(config, directory);
  });
  read_expecting_config_errors("read_collision_study", [&] {
    studies::ConfigTable config = studies::ConfigTable::from_string(text, path);
    (void)studies::read_collision_study(config);
  });
  read_expecting_config_errors("read_comparison_study", [&] { (void)studies::read_comparison_study(path); });
  read_expecting_config_errors("read_sim_scene", [&] { (void)studies::read_sim_scene(path); });
  return 0;
}
