#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <regex>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace touchstone::studies {
namespace {

// Known-answer digests from FIPS 180-2.
TEST(Sha256Hex, KnownDigests) {
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256Hex, HashesEmbeddedNulBytes) {
  const std::string with_nul("a\0b", 3);
  EXPECT_NE(sha256_hex(with_nul), sha256_hex("a"));
  EXPECT_EQ(sha256_hex(with_nul).size(), 64u);
}

TEST(Provenance, HasAllKeys) {
  const nlohmann::json record = provenance("depth = 1\n");
  for (const char* key : {"git", "build_type", "compiler", "machine", "blas", "config_sha256", "time_utc",
                          "touchstone_version"}) {
    ASSERT_TRUE(record.contains(key)) << key;
    ASSERT_TRUE(record[key].is_string()) << key;
    EXPECT_FALSE(record[key].get<std::string>().empty()) << key;
  }
  EXPECT_EQ(record["config_sha256"], sha256_hex("depth = 1\n"));
  EXPECT_TRUE(std::regex_match(record["time_utc"].get<std::string>(),
                               std::regex(R"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}Z)")))
      << record["time_utc"];
  EXPECT_NE(record["machine"].get<std::string>().find(" cores"), std::string::npos)
      << record["machine"];
}

class AtomicWrite : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = std::filesystem::temp_directory_path() /
              ("touchstone_test_provenance_" + std::to_string(::getpid()));
    std::filesystem::remove_all(folder_);
  }
  void TearDown() override { std::filesystem::remove_all(folder_); }

  std::filesystem::path folder_;
};

TEST_F(AtomicWrite, CreatesFoldersAndReplacesContent) {
  const std::string path = (folder_ / "a" / "b" / "results.json").string();
  write_file_atomically(path, "first version, longer than the second");
  EXPECT_EQ(read_file(path), "first version, longer than the second");
  write_file_atomically(path, "second");
  EXPECT_EQ(read_file(path), "second");

  // No temporary is left behind next to the file.
  int entries = 0;
  for ([[maybe_unused]] const auto& entry :
       std::filesystem::directory_iterator(folder_ / "a" / "b")) {
    ++entries;
  }
  EXPECT_EQ(entries, 1);
}

TEST_F(AtomicWrite, KeepsBinaryContent) {
  const std::string path = (folder_ / "binary.bin").string();
  std::string bytes(300000, '\0');
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(i * 7);
  write_file_atomically(path, bytes);
  EXPECT_EQ(read_file(path), bytes);
}

TEST_F(AtomicWrite, UnwritablePathThrowsNamingIt) {
  for (const std::string path : {"/proc/touchstone_no_such_dir/results.json",
                                 "/proc/touchstone_results.json"}) {
    try {
      write_file_atomically(path, "x");
      ADD_FAILURE() << "no exception for " << path;
    } catch (const std::runtime_error& error) {
      EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
    }
  }
}

TEST_F(AtomicWrite, ReadMissingFileThrowsNamingIt) {
  const std::string path = (folder_ / "absent.txt").string();
  try {
    read_file(path);
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace touchstone::studies
