// The check every reader of a user's file makes first: a folder, a device or a named pipe is
// named, a regular file or a missing path is left to the opening.
#include "touchstone/geometry/regular_file.hpp"

#include "support/temporary_directory.hpp"

#include <gtest/gtest.h>

#include <string>

#include <sys/stat.h>

namespace {

using touchstone::geometry::non_regular_file_reason;

TEST(RegularFile, FoldersDevicesAndPipesAreNamedFilesAndMissingPathsAreNot) {
  const touchstone::testing::TemporaryDirectory directory("regular_file");
  EXPECT_EQ(non_regular_file_reason(directory.file("plain.toml", "a = 1\n")), "");
  EXPECT_EQ(non_regular_file_reason(directory.path("missing.toml")), "");
  EXPECT_EQ(non_regular_file_reason(directory.path("")), "it is a folder");
  const std::string pipe = directory.path("pipe.toml");
  ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0);
  EXPECT_EQ(non_regular_file_reason(pipe), "it is a device, pipe or socket, not a regular file");
  EXPECT_EQ(non_regular_file_reason("/dev/zero"), "it is a device, pipe or socket, not a regular file");
}

}  // namespace
