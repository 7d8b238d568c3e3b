#include "thicket/common/params.h"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>

namespace {

using thicket::loadParams;
using thicket::loadParamsFromString;
using thicket::ParamError;
using thicket::Params;
using thicket::Range;

struct WeightingOptions {
  double dropoff_voxels = 1.0;
  void declare(Params& p) {
    p("dropoff_voxels", dropoff_voxels, "weight falls off over this [voxels]", Range::atMost(10));
  }
};

struct TsdfOptions {
  int truncation_voxels = 4;
  double max_ray_length = 5.0;
  WeightingOptions weighting;
  void declare(Params& p) {
    p("truncation_voxels", truncation_voxels, "TSDF truncation distance [voxels]",
      Range::atLeast(1));
    p("max_ray_length", max_ray_length, "integrate returns up to this range [m]",
      Range::positive());
    p.group("weighting", weighting, "how measurements are weighted");
  }
};

struct MapperOptions {
  double voxel_size = 0.2;
  std::string integrator = "projective";
  bool publish_tsdf = true;
  std::int64_t max_blocks = 1000000;
  std::string name = "mapper";
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  std::vector<double> weights = {1.0, 2.0};
  TsdfOptions tsdf;
  void declare(Params& p) {
    p("voxel_size", voxel_size, "edge of a voxel [m]", Range::between(0.01, 1.0));
    p.choice("integrator", integrator, {"projective", "merged"}, "TSDF integrator");
    p("publish_tsdf", publish_tsdf, "publish the TSDF layer");
    p("max_blocks", max_blocks, "stop allocating blocks beyond this", Range::atLeast(1));
    p("name", name, "shown in logs");
    p("origin", origin, "map origin in the world frame [m]", Range::between(-100, 100));
    p("weights", weights, "per-sensor weights", Range::atLeast(0));
    p.group("tsdf", tsdf, "TSDF integration");
  }
};

void expectDefaults(const MapperOptions& o) {
  const MapperOptions d;
  EXPECT_EQ(o.voxel_size, d.voxel_size);
  EXPECT_EQ(o.integrator, d.integrator);
  EXPECT_EQ(o.publish_tsdf, d.publish_tsdf);
  EXPECT_EQ(o.max_blocks, d.max_blocks);
  EXPECT_EQ(o.name, d.name);
  EXPECT_EQ(o.origin, d.origin);
  EXPECT_EQ(o.weights, d.weights);
  EXPECT_EQ(o.tsdf.truncation_voxels, d.tsdf.truncation_voxels);
  EXPECT_EQ(o.tsdf.max_ray_length, d.tsdf.max_ray_length);
  EXPECT_EQ(o.tsdf.weighting.dropoff_voxels, d.tsdf.weighting.dropoff_voxels);
}

MapperOptions load(const std::string& yaml) {
  return loadParamsFromString<MapperOptions>(yaml, "inline.yaml");
}

// The ParamError message loading `yaml` gives; empty (and a test failure) if it loads.
std::string loadError(const std::string& yaml) {
  try {
    load(yaml);
  } catch (const ParamError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ParamError for:\n" << yaml;
  return "";
}

std::string fileLoadError(const std::string& path) {
  try {
    loadParams<MapperOptions>(path);
  } catch (const ParamError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ParamError for " << path;
  return "";
}

testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return testing::AssertionSuccess();
  return testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

const std::string kDataDir = std::string(THICKET_TEST_DATA_DIR) + "/params/";

TEST(Params, AbsentKeysKeepDefaults) {
  expectDefaults(load("{}"));
  const MapperOptions o = load("voxel_size: 0.5\ntsdf:\n  max_ray_length: 7.5\n");
  EXPECT_EQ(o.voxel_size, 0.5);
  EXPECT_EQ(o.tsdf.max_ray_length, 7.5);
  EXPECT_EQ(o.tsdf.truncation_voxels, 4);
  EXPECT_EQ(o.integrator, "projective");
}

TEST(Params, EmptyDocumentsGiveDefaults) {
  for (const char* yaml : {"", "\n\n", "# only a comment\n# and another\n", "~\n", "---\n"}) {
    SCOPED_TRACE(yaml);
    expectDefaults(load(yaml));
  }
}

TEST(Params, LoadsEveryType) {
  const MapperOptions o = load(R"(
voxel_size: 0.05
integrator: merged
publish_tsdf: false
max_blocks: 9223372036854775807
name: 42
origin: [1, -2.5, 3e1]
weights: []
tsdf:
  truncation_voxels: +7
)");
  EXPECT_EQ(o.voxel_size, 0.05);
  EXPECT_EQ(o.integrator, "merged");
  EXPECT_FALSE(o.publish_tsdf);
  EXPECT_EQ(o.max_blocks, INT64_MAX);
  EXPECT_EQ(o.name, "42");  // a plain scalar is a fine string
  EXPECT_EQ(o.origin, Eigen::Vector3d(1.0, -2.5, 30.0));
  EXPECT_TRUE(o.weights.empty());
  EXPECT_EQ(o.tsdf.truncation_voxels, 7);
}

TEST(Params, BoolAcceptsTrueFalseYesNo) {
  for (const char* t : {"true", "True", "TRUE", "yes", "Yes"}) {
    EXPECT_TRUE(load(std::string("publish_tsdf: ") + t).publish_tsdf) << t;
  }
  for (const char* f : {"false", "False", "no", "NO"}) {
    EXPECT_FALSE(load(std::string("publish_tsdf: ") + f).publish_tsdf) << f;
  }
}

TEST(Params, NestedGroups) {
  const MapperOptions o = load("tsdf:\n  weighting:\n    dropoff_voxels: 3.5\n");
  EXPECT_EQ(o.tsdf.weighting.dropoff_voxels, 3.5);
  EXPECT_EQ(o.tsdf.truncation_voxels, 4);
  // An empty group is a group with all defaults.
  expectDefaults(load("tsdf:\n"));
  expectDefaults(load("tsdf: {}\n"));
  expectDefaults(load("tsdf:\n  weighting: ~\n"));
}

TEST(Params, LoadsFixtureFile) {
  const MapperOptions o = loadParams<MapperOptions>(kDataDir + "mapper.yaml");
  EXPECT_EQ(o.voxel_size, 0.1);
  EXPECT_EQ(o.integrator, "merged");
  EXPECT_FALSE(o.publish_tsdf);
  EXPECT_EQ(o.max_blocks, 5000000000);
  EXPECT_EQ(o.name, "front mapper");
  EXPECT_EQ(o.origin, Eigen::Vector3d(1.0, -2.5, 3.0));
  EXPECT_EQ(o.weights, (std::vector<double>{0.5, 4.0, 1e-3}));
  EXPECT_EQ(o.tsdf.truncation_voxels, 6);
  EXPECT_EQ(o.tsdf.max_ray_length, 5.0);
  EXPECT_EQ(o.tsdf.weighting.dropoff_voxels, 2.5);
}

TEST(Params, MalformedFixtureNamesFileAndPosition) {
  const std::string path = kDataDir + "malformed.yaml";
  EXPECT_TRUE(contains(fileLoadError(path), path + ":4:5: invalid YAML"));
}

TEST(Params, MissingAndUnreadableFilesNameThePath) {
  const std::string missing = kDataDir + "no_such_file.yaml";
  EXPECT_TRUE(contains(fileLoadError(missing), missing + ": cannot open"));
  // A directory opens but cannot be read; a portable stand-in for a file without read
  // permission, which root (as in CI containers) could read anyway.
  EXPECT_TRUE(contains(fileLoadError(kDataDir), kDataDir + ": cannot read"));
}

TEST(Params, MalformedYamlGivesPosition) {
  EXPECT_TRUE(
      contains(loadError("voxel_size: 0.3\nweights: [1, 2\n"), "inline.yaml:3:1: invalid YAML"));
  EXPECT_TRUE(contains(loadError("voxel_size: 0.3\n  tsdf: 2\n"), "inline.yaml:2:7: invalid YAML"));
}

TEST(Params, TopLevelMustBeOneMap) {
  EXPECT_TRUE(contains(loadError("- 1\n- 2\n"),
                       "inline.yaml:1:1: expected a map of parameters, got a sequence"));
  EXPECT_TRUE(
      contains(loadError("hello\n"), "inline.yaml:1:1: expected a map of parameters, got 'hello'"));
  EXPECT_TRUE(contains(loadError("voxel_size: 0.3\n---\nvoxel_size: 0.4\n"),
                       "inline.yaml:3:1: expected one YAML document, got 2"));
}

TEST(Params, UnknownKeysAreRejectedWithSuggestion) {
  EXPECT_TRUE(contains(loadError("voxel_sise: 0.3\n"),
                       "inline.yaml:1:1: key 'voxel_sise': unknown parameter (did you mean "
                       "'voxel_size'?)"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxel: 3\n"),
                       "inline.yaml:2:3: key 'tsdf.truncation_voxel': unknown parameter (did you "
                       "mean 'tsdf.truncation_voxels'?)"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  weighting:\n    dropof_voxel: 3\n"),
                       "inline.yaml:3:5: key 'tsdf.weighting.dropof_voxel': unknown parameter "
                       "(did you mean 'tsdf.weighting.dropoff_voxels'?)"));
  // Nothing within edit distance 2: no suggestion. Several unknown keys: the first in the file.
  const std::string message = loadError("zebra: 1\nvoxel_size: 0.3\naardvark: 2\n");
  EXPECT_TRUE(contains(message, "inline.yaml:1:1: key 'zebra': unknown parameter"));
  EXPECT_FALSE(contains(message, "did you mean"));
}

TEST(Params, DuplicateKeysAreRejected) {
  EXPECT_TRUE(contains(loadError("voxel_size: 0.3\nname: a\nvoxel_size: 0.4\n"),
                       "inline.yaml:3:1: key 'voxel_size': duplicate key (first given on line 1)"));
  EXPECT_TRUE(contains(loadError("tsdf: {max_ray_length: 1, max_ray_length: 2}\n"),
                       "inline.yaml:1:27: key 'tsdf.max_ray_length': duplicate key"));
}

TEST(Params, IntTypeErrors) {
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxels: abc\n"),
                       "inline.yaml:2:22: key 'tsdf.truncation_voxels': expected an integer, got "
                       "'abc'"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxels: 1.5\n"),
                       "key 'tsdf.truncation_voxels': expected an integer, got '1.5'"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxels: {a: 1}\n"),
                       "key 'tsdf.truncation_voxels': expected an integer, got a map"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxels: \"5\"\n"),
                       "expected an integer, got the quoted string '5'"));
  // An empty value has no position of its own; the key's is used.
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxels:\nname: x\n"),
                       "inline.yaml:2:3: key 'tsdf.truncation_voxels': expected an integer, got "
                       "no value"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  truncation_voxels: 2147483648\n"),
                       "inline.yaml:2:22: key 'tsdf.truncation_voxels': 2147483648 is out of "
                       "range for a 32-bit integer"));
  EXPECT_EQ(load("tsdf:\n  truncation_voxels: 2147483647\n").tsdf.truncation_voxels, 2147483647);
  EXPECT_TRUE(contains(loadError("max_blocks: 9223372036854775808\n"),
                       "key 'max_blocks': 9223372036854775808 is out of range for a 64-bit"));
}

TEST(Params, BoolAndStringTypeErrors) {
  EXPECT_TRUE(
      contains(loadError("publish_tsdf: maybe\n"),
               "inline.yaml:1:15: key 'publish_tsdf': expected true or false, got 'maybe'"));
  EXPECT_TRUE(contains(loadError("publish_tsdf: 1\n"), "expected true or false, got '1'"));
  EXPECT_TRUE(contains(loadError("publish_tsdf: on\n"), "expected true or false, got 'on'"));
  EXPECT_TRUE(contains(loadError("publish_tsdf: \"true\"\n"), "got the quoted string 'true'"));
  EXPECT_TRUE(contains(loadError("name: [a, b]\n"),
                       "inline.yaml:1:7: key 'name': expected a string, got a sequence"));
  EXPECT_TRUE(contains(loadError("name: ~\n"), "key 'name': expected a string, got no value"));
  EXPECT_EQ(load("name: \"\"\n").name, "");
}

TEST(Params, NonFiniteAndMalformedDoublesAreRejected) {
  for (const char* bad : {"nan", "NaN", ".nan", ".inf", "-.inf", "+.INF", "inf", "-infinity"}) {
    EXPECT_TRUE(contains(loadError(std::string("tsdf:\n  max_ray_length: ") + bad),
                         std::string("inline.yaml:2:19: key 'tsdf.max_ray_length': non-finite "
                                     "value '") +
                             bad + "'"));
  }
  EXPECT_TRUE(contains(loadError("voxel_size: 1e999\n"), "key 'voxel_size': 1e999 is out of the"));
  EXPECT_TRUE(contains(loadError("voxel_size: 0.1m\n"),
                       "inline.yaml:1:13: key 'voxel_size': expected a number, got '0.1m'"));
  EXPECT_TRUE(contains(loadError("voxel_size: \"0.1\"\n"), "got the quoted string '0.1'"));
}

TEST(Params, SequenceErrorsNameTheElement) {
  EXPECT_TRUE(
      contains(loadError("weights: 1.0\n"),
               "inline.yaml:1:10: key 'weights': expected a sequence of numbers, got '1.0'"));
  EXPECT_TRUE(contains(loadError("weights: [1.0, x, 2]\n"),
                       "inline.yaml:1:16: key 'weights[1]': expected a number, got 'x'"));
  EXPECT_TRUE(contains(loadError("weights:\n  - 1\n  - -0.5\n"),
                       "inline.yaml:3:5: key 'weights[1]': -0.5 is out of range: must be >= 0"));
  EXPECT_TRUE(contains(loadError("origin: [1, 2]\n"),
                       "inline.yaml:1:9: key 'origin': expected 3 numbers [x, y, z], got 2"));
  EXPECT_TRUE(contains(loadError("origin: [1, 2, 3, 4]\n"), "expected 3 numbers [x, y, z], got 4"));
  EXPECT_TRUE(contains(loadError("origin: [1, .nan, 3]\n"), "key 'origin[1]': non-finite value"));
  EXPECT_TRUE(contains(loadError("origin: [0, 0, 100.5]\n"),
                       "key 'origin[2]': 100.5 is out of range: must be in [-100, 100]"));
}

TEST(Params, RangeBoundsAreInclusiveExceptPositive) {
  EXPECT_EQ(load("voxel_size: 0.01").voxel_size, 0.01);
  EXPECT_EQ(load("voxel_size: 1.0").voxel_size, 1.0);
  EXPECT_TRUE(contains(loadError("voxel_size: 1.0000001\n"),
                       "inline.yaml:1:13: key 'voxel_size': 1.0000001 is out of range: must be in "
                       "[0.01, 1]"));
  EXPECT_TRUE(contains(loadError("voxel_size: 0.00999\n"), "must be in [0.01, 1]"));

  EXPECT_EQ(load("tsdf: {truncation_voxels: 1}").tsdf.truncation_voxels, 1);
  EXPECT_TRUE(contains(loadError("tsdf: {truncation_voxels: 0}"),
                       "key 'tsdf.truncation_voxels': 0 is out of range: must be >= 1"));

  EXPECT_EQ(load("tsdf: {max_ray_length: 1e-300}").tsdf.max_ray_length, 1e-300);
  EXPECT_TRUE(contains(loadError("tsdf: {max_ray_length: 0}"),
                       "key 'tsdf.max_ray_length': 0 is out of range: must be > 0"));
  EXPECT_TRUE(contains(loadError("tsdf: {max_ray_length: -0.0}"), "must be > 0"));

  EXPECT_EQ(load("tsdf: {weighting: {dropoff_voxels: 10}}").tsdf.weighting.dropoff_voxels, 10.0);
  EXPECT_TRUE(contains(loadError("tsdf: {weighting: {dropoff_voxels: 10.5}}"),
                       "key 'tsdf.weighting.dropoff_voxels': 10.5 is out of range: must be <= 10"));

  EXPECT_TRUE(contains(loadError("max_blocks: 0\n"), "key 'max_blocks': 0 is out of range"));
  EXPECT_THROW(Range::between(2.0, 1.0), std::logic_error);
}

TEST(Params, ChoiceListsAllowedValues) {
  EXPECT_TRUE(contains(loadError("integrator: raycast\n"),
                       "inline.yaml:1:13: key 'integrator': 'raycast' is not one of: projective, "
                       "merged"));
  EXPECT_TRUE(contains(loadError("integrator: Merged\n"), "'Merged' is not one of"));
}

TEST(Params, GroupMustBeAMap) {
  EXPECT_TRUE(contains(loadError("tsdf: 3\n"),
                       "inline.yaml:1:7: key 'tsdf': expected a map of parameters, got '3'"));
  EXPECT_TRUE(contains(loadError("tsdf:\n  weighting: [1]\n"),
                       "inline.yaml:2:14: key 'tsdf.weighting': expected a map of parameters, got "
                       "a sequence"));
}

TEST(Params, NonStringKeysAreRejected) {
  EXPECT_TRUE(
      contains(loadError("? [a, b]\n: 1\n"), "inline.yaml:1:3: parameter names must be strings"));
}

TEST(Params, ErrorsLeaveNoPartiallyLoadedResult) {
  // Every field before the error is valid; the unknown key is only found after all fields of
  // the top level were read, so a loader that returned early would hand back a loaded struct.
  const std::string valid_then_bad =
      "voxel_size: 0.5\nintegrator: merged\ntsdf:\n  truncation_voxels: 9\nbogus: 1\n";
  EXPECT_THROW(load(valid_then_bad), ParamError);
  const std::string valid_then_wrong_type =
      "voxel_size: 0.5\ntsdf:\n  truncation_voxels: 9\nweights: [1, x]\n";
  EXPECT_THROW(load(valid_then_wrong_type), ParamError);
  // Nothing leaks into later loads either.
  expectDefaults(load(""));
}

struct DuplicateDeclaration {
  int a = 1;
  int b = 2;
  void declare(Params& p) {
    p("a", a, "");
    p("a", b, "");
  }
};

struct DefaultOutOfRange {
  double gain = 0.0;
  void declare(Params& p) { p("gain", gain, "", Range::positive()); }
};

struct DefaultNotAChoice {
  std::string mode = "fast";
  void declare(Params& p) { p.choice("mode", mode, {"slow", "careful"}, ""); }
};

struct BadKeyName {
  int a = 1;
  void declare(Params& p) { p("a.b", a, ""); }
};

TEST(Params, DeclarationMistakesAreLogicErrors) {
  EXPECT_THROW(loadParamsFromString<DuplicateDeclaration>("", "x"), std::logic_error);
  EXPECT_THROW(thicket::describeParams<DuplicateDeclaration>(), std::logic_error);
  EXPECT_THROW(loadParamsFromString<DefaultOutOfRange>("gain: 1.0", "x"), std::logic_error);
  EXPECT_THROW(loadParamsFromString<DefaultNotAChoice>("", "x"), std::logic_error);
  EXPECT_THROW(loadParamsFromString<BadKeyName>("", "x"), std::logic_error);
  try {
    thicket::describeParams<DefaultOutOfRange>();
    FAIL() << "out-of-range default accepted";
  } catch (const std::logic_error& e) {
    EXPECT_TRUE(contains(e.what(), "invalid value: key 'gain': 0 is out of range: must be > 0"));
  }
  // ParamError is also a runtime_error, never a logic_error: the two must stay apart.
  EXPECT_FALSE((std::is_base_of_v<std::logic_error, ParamError>));
}

TEST(Params, DescribeListsDefaultsWithDocs) {
  const std::string text = thicket::describeParams<MapperOptions>();
  EXPECT_TRUE(contains(text, "voxel_size: 0.2  # edge of a voxel [m] (in [0.01, 1])\n"));
  EXPECT_TRUE(contains(text,
                       "integrator: projective  # TSDF integrator (one of: projective, "
                       "merged)\n"));
  EXPECT_TRUE(contains(text, "publish_tsdf: true  # publish the TSDF layer\n"));
  EXPECT_TRUE(contains(text, "origin: [0.0, 0.0, 0.0]  # map origin"));
  EXPECT_TRUE(contains(text, "weights: [1.0, 2.0]  # per-sensor weights (>= 0)\n"));
  EXPECT_TRUE(contains(text,
                       "tsdf:  # TSDF integration\n"
                       "  truncation_voxels: 4  # TSDF truncation distance [voxels] (>= 1)\n"
                       "  max_ray_length: 5.0  # integrate returns up to this range [m] (> 0)\n"
                       "  weighting:  # how measurements are weighted\n"
                       "    dropoff_voxels: 1.0  # weight falls off over this [voxels] (<= 10)\n"));
}

TEST(Params, DescribeOutputLoadsBackToDefaults) {
  expectDefaults(load(thicket::describeParams<MapperOptions>()));
}

// Defaults chosen to be awkward to print: binary fractions that need care to round-trip,
// strings YAML would read as something else, empty containers.
struct AwkwardOptions {
  double tenth = 0.1;
  double tiny = 1e-7;
  double third = 1.0 / 3.0;
  double big = 6.02214076e23;
  double negative_zero = -0.0;
  std::int64_t large = 9007199254740993;  // not representable as a double
  std::string empty;
  std::string looks_like_bool = "true";
  std::string looks_like_null = "null";
  std::string looks_like_number = "1.5";
  std::string has_comment = "a: b # c";
  std::string multi_line = "line one\nline two";
  std::vector<double> none;
  Eigen::Vector3d point{0.1, -1e-7, 1e300};
  void declare(Params& p) {
    p("tenth", tenth, "");
    p("tiny", tiny, "doc with\na newline");
    p("third", third, "");
    p("big", big, "");
    p("negative_zero", negative_zero, "");
    p("large", large, "");
    p("empty", empty, "");
    p("looks_like_bool", looks_like_bool, "");
    p("looks_like_null", looks_like_null, "");
    p("looks_like_number", looks_like_number, "");
    p("has_comment", has_comment, "");
    p("multi_line", multi_line, "");
    p("none", none, "");
    p("point", point, "");
  }
};

TEST(Params, DescribeRoundTripsAwkwardValuesExactly) {
  const std::string text = thicket::describeParams<AwkwardOptions>();
  EXPECT_TRUE(contains(text, "tenth: 0.1\n"));
  EXPECT_TRUE(contains(text, "tiny: 1e-07  # doc with a newline\n"));
  EXPECT_TRUE(contains(text, "looks_like_bool: \"true\"\n"));
  EXPECT_TRUE(contains(text, "looks_like_number: \"1.5\"\n"));
  const AwkwardOptions d;
  const AwkwardOptions o = loadParamsFromString<AwkwardOptions>(text, "describe");
  EXPECT_EQ(o.tenth, d.tenth);
  EXPECT_EQ(o.tiny, d.tiny);
  EXPECT_EQ(o.third, d.third);
  EXPECT_EQ(o.big, d.big);
  EXPECT_TRUE(std::signbit(o.negative_zero));
  EXPECT_EQ(o.large, d.large);
  EXPECT_EQ(o.empty, d.empty);
  EXPECT_EQ(o.looks_like_bool, d.looks_like_bool);
  EXPECT_EQ(o.looks_like_null, d.looks_like_null);
  EXPECT_EQ(o.looks_like_number, d.looks_like_number);
  EXPECT_EQ(o.has_comment, d.has_comment);
  EXPECT_EQ(o.multi_line, d.multi_line);
  EXPECT_EQ(o.none, d.none);
  EXPECT_EQ(o.point, d.point);
}

}  // namespace
