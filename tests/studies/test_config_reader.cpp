#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <string>
#include <sys/stat.h>
#include <unistd.h>

namespace touchstone::studies {
namespace {

constexpr double pi = 3.14159265358979323846;

// Runs `action`, expects a ConfigError, and checks that its message holds every fragment.
void expect_config_error(const std::function<void()>& action,
                         std::initializer_list<std::string> fragments) {
  try {
    action();
  } catch (const ConfigError& error) {
    const std::string message = error.what();
    for (const std::string& fragment : fragments) {
      EXPECT_NE(message.find(fragment), std::string::npos)
          << "message: " << message << "\nlacks: " << fragment;
    }
    return;
  }
  ADD_FAILURE() << "no ConfigError thrown";
}

double parse(const std::string& text, Dimension dimension) {
  return parse_quantity(text, dimension, "test.toml: key");
}

TEST(ParseQuantity, Length) {
  EXPECT_DOUBLE_EQ(parse("2.5 mm", Dimension::length), 2.5e-3);
  EXPECT_DOUBLE_EQ(parse("2.5mm", Dimension::length), 2.5e-3);
  EXPECT_DOUBLE_EQ(parse("1e-3 m", Dimension::length), 1e-3);
  EXPECT_DOUBLE_EQ(parse("-3 mm", Dimension::length), -3e-3);
  EXPECT_DOUBLE_EQ(parse("+3 mm", Dimension::length), 3e-3);
  EXPECT_DOUBLE_EQ(parse("4 cm", Dimension::length), 0.04);
  EXPECT_DOUBLE_EQ(parse("7 um", Dimension::length), 7e-6);
  EXPECT_DOUBLE_EQ(parse("7 \xC2\xB5m", Dimension::length), 7e-6);  // micro sign
  EXPECT_DOUBLE_EQ(parse("7 \xCE\xBCm", Dimension::length), 7e-6);  // Greek mu
  EXPECT_DOUBLE_EQ(parse("  0.25  ", Dimension::length), 0.25);
  EXPECT_DOUBLE_EQ(parse(".5m", Dimension::length), 0.5);
}

TEST(ParseQuantity, Pressure) {
  EXPECT_DOUBLE_EQ(parse("12 Pa", Dimension::pressure), 12.0);
  EXPECT_DOUBLE_EQ(parse("10 kPa", Dimension::pressure), 1e4);
  EXPECT_DOUBLE_EQ(parse("10kPa", Dimension::pressure), 1e4);
  EXPECT_DOUBLE_EQ(parse("2.1 MPa", Dimension::pressure), 2.1e6);
  EXPECT_DOUBLE_EQ(parse("200 GPa", Dimension::pressure), 2e11);
  EXPECT_DOUBLE_EQ(parse("3000", Dimension::pressure), 3000.0);
}

TEST(ParseQuantity, Angle) {
  EXPECT_DOUBLE_EQ(parse("0.5 rad", Dimension::angle), 0.5);
  EXPECT_DOUBLE_EQ(parse("30 deg", Dimension::angle), pi / 6);
  EXPECT_DOUBLE_EQ(parse("180\xC2\xB0", Dimension::angle), pi);
  EXPECT_DOUBLE_EQ(parse("1", Dimension::angle), 1.0);
}

TEST(ParseQuantity, Time) {
  EXPECT_DOUBLE_EQ(parse("2 s", Dimension::time), 2.0);
  EXPECT_DOUBLE_EQ(parse("5 ms", Dimension::time), 5e-3);
  EXPECT_DOUBLE_EQ(parse("5us", Dimension::time), 5e-6);
  EXPECT_DOUBLE_EQ(parse("5 \xC2\xB5s", Dimension::time), 5e-6);
  EXPECT_DOUBLE_EQ(parse("40 ns", Dimension::time), 4e-8);
}

TEST(ParseQuantity, Force) {
  EXPECT_DOUBLE_EQ(parse("1.5 N", Dimension::force), 1.5);
  EXPECT_DOUBLE_EQ(parse("250 mN", Dimension::force), 0.25);
}

TEST(ParseQuantity, Stiffness) {
  EXPECT_DOUBLE_EQ(parse("200 N/m", Dimension::stiffness), 200.0);
  EXPECT_DOUBLE_EQ(parse("2 N/mm", Dimension::stiffness), 2000.0);
}

TEST(ParseQuantity, Dimensionless) {
  EXPECT_DOUBLE_EQ(parse("0.3", Dimension::dimensionless), 0.3);
  EXPECT_DOUBLE_EQ(parse("5 %", Dimension::dimensionless), 0.05);
  EXPECT_DOUBLE_EQ(parse("5%", Dimension::dimensionless), 0.05);
}

TEST(ParseQuantity, RejectsUnitsOfAnotherDimension) {
  expect_config_error([] { parse("2.5 parsecs", Dimension::length); },
                      {"test.toml: key: cannot read '2.5 parsecs' as a length",
                       "units: m, cm, mm, um"});
  expect_config_error([] { parse("10 kPa", Dimension::length); }, {"as a length"});
  expect_config_error([] { parse("3 mm", Dimension::pressure); }, {"as a pressure", "kPa"});
  expect_config_error([] { parse("3 mm", Dimension::dimensionless); }, {"as a number"});
  expect_config_error([] { parse("5 MM", Dimension::length); }, {"'5 MM'"});
  expect_config_error([] { parse("1 N/m", Dimension::force); }, {"as a force"});
  expect_config_error([] { parse("30 deg", Dimension::time); }, {"as a time"});
}

TEST(ParseQuantity, RejectsGarbage) {
  for (const char* text : {"", "   ", "mm", "abc", "2.5 mm extra", "2.5 m m", "1,5 mm", "--3 mm",
                           "+-3 mm", "0x10", "2..5 mm", "3 mm 4"}) {
    EXPECT_THROW(parse(text, Dimension::length), ConfigError) << "'" << text << "'";
  }
}

TEST(ParseQuantity, RejectsNonFinite) {
  expect_config_error([] { parse("nan", Dimension::length); }, {"'nan'", "not a finite number"});
  expect_config_error([] { parse("inf mm", Dimension::length); }, {"not a finite number"});
  expect_config_error([] { parse("-infinity", Dimension::pressure); }, {"not a finite number"});
  expect_config_error([] { parse("1e999", Dimension::length); }, {"'1e999'"});
  expect_config_error([] { parse("1e300 GPa", Dimension::pressure); }, {"'1e300 GPa'"});
}

TEST(ParseQuantity, EmptyWhereLeavesNoDanglingPrefix) {
  try {
    parse_quantity("x", Dimension::length, "");
    FAIL() << "no ConfigError thrown";
  } catch (const ConfigError& error) {
    EXPECT_EQ(std::string(error.what()).rfind("cannot read 'x'", 0), 0u) << error.what();
  }
}

TEST(ConfigTable, ReadsEveryKind) {
  ConfigTable config = ConfigTable::from_string(R"(
name = "sphere"
model = "mfs"
seed = 42
verbose = true
scale = 1
ratio = 0.5
[problem]
depth = "2.5 mm"
radius = 0.01
modulus = 3
poisson = "49 %"
direction = [0, 0, "-1 m"]
depths = ["1 mm", 2e-3, 3]
single = "4 mm"
nodes = [100, 200, 400]
)",
                                                "inline.toml");
  EXPECT_EQ(config.string("name"), "sphere");
  EXPECT_EQ(config.choice("model", {"mfs", "fem", "analytic"}, "fem"), "mfs");
  EXPECT_EQ(config.integer("seed", 0), 42);
  EXPECT_TRUE(config.boolean("verbose", false));
  EXPECT_DOUBLE_EQ(config.number("scale", 0.0), 1.0);  // TOML integer where a number is expected
  EXPECT_DOUBLE_EQ(config.number("ratio", 0.0), 0.5);

  ConfigTable problem = config.table("problem", true);
  EXPECT_DOUBLE_EQ(problem.quantity("depth", Dimension::length), 2.5e-3);
  EXPECT_DOUBLE_EQ(problem.quantity("radius", Dimension::length, 1.0), 0.01);
  EXPECT_DOUBLE_EQ(problem.quantity("modulus", Dimension::pressure), 3.0);
  EXPECT_DOUBLE_EQ(problem.quantity("poisson", Dimension::dimensionless), 0.49);
  const auto direction = problem.vector3("direction", Dimension::length, {{0, 0, 0}});
  EXPECT_DOUBLE_EQ(direction[0], 0.0);
  EXPECT_DOUBLE_EQ(direction[1], 0.0);
  EXPECT_DOUBLE_EQ(direction[2], -1.0);
  EXPECT_EQ(problem.quantity_list("depths", Dimension::length, {}),
            (std::vector<double>{1e-3, 2e-3, 3.0}));
  EXPECT_EQ(problem.quantity_list("single", Dimension::length, {}), (std::vector<double>{4e-3}));
  EXPECT_EQ(problem.integer_list("nodes", {}), (std::vector<std::int64_t>{100, 200, 400}));
  EXPECT_NO_THROW(config.finish());
}

TEST(ConfigTable, DefaultsWhenAbsent) {
  ConfigTable config = ConfigTable::from_string("", "empty.toml");
  EXPECT_FALSE(config.has("anything"));
  EXPECT_DOUBLE_EQ(config.quantity("depth", Dimension::length, 0.002), 0.002);
  EXPECT_DOUBLE_EQ(config.number("x", 1.5), 1.5);
  EXPECT_EQ(config.integer("n", 7), 7);
  EXPECT_FALSE(config.boolean("b", false));
  EXPECT_EQ(config.string("s", "d"), "d");
  EXPECT_EQ(config.choice("c", {"a", "b"}, "b"), "b");
  EXPECT_EQ(config.vector3("v", Dimension::length, {{1, 2, 3}}), (std::array<double, 3>{{1, 2, 3}}));
  EXPECT_EQ(config.quantity_list("l", Dimension::time, {1.0}), (std::vector<double>{1.0}));
  EXPECT_EQ(config.integer_list("i", {4}), (std::vector<std::int64_t>{4}));
  ConfigTable absent = config.table("solver");
  EXPECT_DOUBLE_EQ(absent.number("tolerance", 1e-9), 1e-9);
  EXPECT_EQ(absent.where("tolerance"), "empty.toml: solver.tolerance");
  EXPECT_NO_THROW(config.finish());
}

TEST(ConfigTable, HasDoesNotCountAsReading) {
  ConfigTable config = ConfigTable::from_string("a = 1", "has.toml");
  EXPECT_TRUE(config.has("a"));
  expect_config_error([&] { config.finish(); }, {"has.toml: unknown key 'a'"});
}

TEST(ConfigTable, UnknownTopLevelKey) {
  ConfigTable config = ConfigTable::from_string("depth = 1\ndepht = 2", "typo.toml");
  config.number("depth", 0.0);
  expect_config_error([&] { config.finish(); }, {"typo.toml: unknown key 'depht'"});
}

TEST(ConfigTable, UnknownNestedKeyNamesItsPath) {
  ConfigTable config = ConfigTable::from_string(R"(
[problem]
depth = "1 mm"
tool_radus = "2 mm"
[problem.tool]
shape = "sphere"
colour = "red"
)",
                                                "study.toml");
  ConfigTable problem = config.table("problem");
  problem.quantity("depth", Dimension::length);
  problem.quantity("tool_radius", Dimension::length, 1e-3);
  ConfigTable tool = problem.table("tool");
  tool.string("shape");
  expect_config_error([&] { config.finish(); },
                      {"study.toml: unknown keys 'problem.tool_radus'",
                       "did you mean 'problem.tool_radius'?", "'problem.tool.colour'"});
  // finish() on a sub-table looks at that sub-table only.
  expect_config_error([&] { tool.finish(); }, {"'problem.tool.colour'"});
}

TEST(ConfigTable, UnreadSubTableIsUnknown) {
  ConfigTable config = ConfigTable::from_string("[solver]\ntolerance = 1e-6", "sub.toml");
  expect_config_error([&] { config.finish(); }, {"sub.toml: unknown key 'solver'"});
}

TEST(ConfigTable, SubTableTakenTwiceSharesUsedKeys) {
  ConfigTable config = ConfigTable::from_string("[a]\nx = 1\ny = 2", "twice.toml");
  config.table("a").number("x", 0.0);
  config.table("a").number("y", 0.0);
  EXPECT_NO_THROW(config.finish());
}

TEST(ConfigTable, MissingRequiredKey) {
  ConfigTable config = ConfigTable::from_string("[problem]\nradius = 1", "req.toml");
  ConfigTable problem = config.table("problem");
  expect_config_error([&] { problem.quantity("depth", Dimension::length); },
                      {"req.toml: missing key 'problem.depth'"});
  expect_config_error([&] { problem.string("name"); }, {"req.toml: missing key 'problem.name'"});
  expect_config_error([&] { config.table("solver", true); },
                      {"req.toml: missing key 'solver'"});
}

TEST(ConfigTable, TypeErrorsNameKeyAndExpectedType) {
  ConfigTable config = ConfigTable::from_string(R"(
[problem]
depth = true
seed = 1.5
flag = "yes"
name = 3
scale = "2"
direction = [1, 2]
nodes = [1, 2.5]
depths = [1, false]
sub = 4
)",
                                                "types.toml");
  ConfigTable problem = config.table("problem");
  expect_config_error([&] { problem.quantity("depth", Dimension::length); },
                      {"types.toml: problem.depth: expected a length such as \"2.5 mm\" or a "
                       "number in m",
                       "got a boolean"});
  expect_config_error([&] { problem.integer("seed", 0); },
                      {"types.toml: problem.seed: expected an integer"});
  expect_config_error([&] { problem.boolean("flag", false); },
                      {"types.toml: problem.flag: expected true or false", "got a string"});
  expect_config_error([&] { problem.string("name", ""); },
                      {"types.toml: problem.name: expected a string", "got an integer"});
  expect_config_error([&] { problem.number("scale", 0.0); },
                      {"types.toml: problem.scale: expected a number"});
  expect_config_error([&] { problem.vector3("direction", Dimension::length, {{0, 0, 0}}); },
                      {"types.toml: problem.direction", "3 elements", "got 2"});
  expect_config_error([&] { problem.integer_list("nodes", {}); },
                      {"types.toml: problem.nodes[1]: expected an integer"});
  expect_config_error([&] { problem.quantity_list("depths", Dimension::length, {}); },
                      {"types.toml: problem.depths[1]: expected a length"});
  expect_config_error([&] { problem.table("sub"); },
                      {"types.toml: problem.sub: expected a table"});
}

TEST(ConfigTable, QuantityStringErrorNamesKey) {
  ConfigTable config = ConfigTable::from_string("depth = \"2.5 parsecs\"", "q.toml");
  expect_config_error([&] { config.quantity("depth", Dimension::length); },
                      {"q.toml: depth: cannot read '2.5 parsecs' as a length (units: m, cm, mm"});
}

TEST(ConfigTable, RejectsNonFiniteTomlFloats) {
  ConfigTable config = ConfigTable::from_string("a = nan\nb = inf\nc = [1, -inf, 2]", "nan.toml");
  expect_config_error([&] { config.quantity("a", Dimension::length); },
                      {"nan.toml: a", "not a finite number"});
  expect_config_error([&] { config.number("b", 0.0); }, {"nan.toml: b", "not a finite number"});
  expect_config_error([&] { config.vector3("c", Dimension::length, {}); },
                      {"nan.toml: c[1]", "not a finite number"});
}

TEST(ConfigTable, ChoiceErrorListsChoices) {
  ConfigTable config = ConfigTable::from_string("model = \"mfx\"", "choice.toml");
  expect_config_error([&] { config.choice("model", {"mfs", "fem", "analytic"}, "mfs"); },
                      {"choice.toml: model", "'mfx'", "'mfs', 'fem', 'analytic'"});
}

TEST(ConfigTable, WhereNamesFileAndDottedPath) {
  ConfigTable config = ConfigTable::from_string("[a.b]\nc = 1", "w.toml");
  ConfigTable b = config.table("a").table("b");
  EXPECT_EQ(b.where("c"), "w.toml: a.b.c");
  EXPECT_EQ(config.where("top"), "w.toml: top");
}

TEST(ConfigTable, ParseErrorNamesFileLineAndColumn) {
  expect_config_error(
      [] { ConfigTable::from_string("a = 1\nb = 2\nc = = 3\n", "broken.toml"); },
      {"broken.toml:3:"});
}

class ConfigTableFile : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = std::filesystem::temp_directory_path() /
              ("touchstone_test_config_reader_" + std::to_string(::getpid()));
    std::filesystem::create_directories(folder_);
  }
  void TearDown() override { std::filesystem::remove_all(folder_); }

  std::string write(const std::string& name, const std::string& text) {
    const std::filesystem::path path = folder_ / name;
    std::ofstream(path) << text;
    return path.string();
  }

  std::filesystem::path folder_;
};

TEST_F(ConfigTableFile, ReadsFileAndNamesItInErrors) {
  const std::string path = write("study.toml", "[problem]\ndepth = \"1 mm\"\nextra = 1\n");
  ConfigTable config = ConfigTable::from_file(path);
  EXPECT_DOUBLE_EQ(config.table("problem").quantity("depth", Dimension::length), 1e-3);
  expect_config_error([&] { config.finish(); }, {path + ": unknown key 'problem.extra'"});
}

// The text a file was parsed from stays with it, sub-tables included: a run records what it
// read without reading the file again.
TEST_F(ConfigTableFile, KeepsTheTextItWasParsedFrom) {
  const std::string text = "study = \"s\"\n[problem]\ndepth = \"1 mm\"\n";
  const std::string path = write("kept.toml", text);
  ConfigTable config = ConfigTable::from_file(path);
  std::ofstream(path) << "changed";
  EXPECT_EQ(config.source_text(), text);
  EXPECT_EQ(config.table("problem").source_text(), text);
  EXPECT_EQ(ConfigTable::from_string("a = 1\n", "inline").source_text(), "a = 1\n");
}

TEST_F(ConfigTableFile, ParseErrorNamesFileAndLine) {
  const std::string path = write("broken.toml", "# comment\n[problem]\ndepth = \"1 mm\n");
  expect_config_error([&] { ConfigTable::from_file(path); }, {path + ":3:"});
}

TEST_F(ConfigTableFile, MissingFileNamesIt) {
  const std::string path = (folder_ / "absent.toml").string();
  expect_config_error([&] { ConfigTable::from_file(path); }, {path, "cannot open"});
  expect_config_error([&] { ConfigTable::from_file(folder_.string()); },
                      {folder_.string(), "folder"});
  // A named pipe or a device would block the read or never end it.
  const std::string pipe = (folder_ / "pipe.toml").string();
  ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0);
  expect_config_error([&] { ConfigTable::from_file(pipe); }, {pipe, "not a regular file"});
  expect_config_error([&] { ConfigTable::from_file("/dev/zero"); }, {"/dev/zero", "not a regular file"});
}

}  // namespace
}  // namespace touchstone::studies
