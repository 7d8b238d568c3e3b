// The run-time LCM schema of thicket-replay against the generated C++ code: the same
// fingerprints, every type decoded and re-encoded byte for byte, fields read as the generated
// code wrote them, damaged messages and definitions refused with a reason; and the field-by-field
// diff built on it.
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli.h"
#include "diff.h"
#include "known_lcm_types.h"
#include "thicket/common/lcm_schema.h"
#include "temp_dir_test.h"
#include "thicket/common/lcm_log.h"

namespace thicket::replay {
namespace {

const LcmTypeSet& thicketTypes() {
  static const Expected<LcmTypeSet> types =
      LcmTypeSet::loadDirectory(std::string(THICKET_SOURCE_DIR) + "/lcmtypes");
  if (!types) throw std::runtime_error(types.error());
  return *types;
}

template <class Msg>
std::vector<uint8_t> encode(const Msg& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  EXPECT_EQ(msg.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  return bytes;
}

template <class Msg>
LcmValue decode(const Msg& msg) {
  const std::vector<uint8_t> bytes = encode(msg);
  auto value = thicketTypes().decode(bytes.data(), bytes.size());
  if (!value) throw std::runtime_error(value.error());
  return *value;
}

const LcmValue& at(const LcmValue& value, std::initializer_list<size_t> indices) {
  const LcmValue* v = &value;
  for (size_t i : indices) v = &v->items.at(i);
  return *v;
}

std::string shortest(double value) {
  char text[64];
  return std::string(text, std::to_chars(text, text + sizeof text, value).ptr);
}

TEST(LcmSchema, FingerprintsAreTheGeneratedCodesHashes) {
  const LcmTypeSet& types = thicketTypes();
  size_t generated = 0;
#define THICKET_CHECK_FINGERPRINT(Cpp, name)                                     \
  {                                                                              \
    const LcmStruct* type = types.find(name);                                    \
    ASSERT_NE(type, nullptr) << name;                                            \
    EXPECT_EQ(type->fingerprint, static_cast<uint64_t>(Cpp::getHash())) << name; \
    EXPECT_EQ(types.findByFingerprint(type->fingerprint), type) << name;         \
    ++generated;                                                                 \
  }
  THICKET_KNOWN_LCM_TYPES(THICKET_CHECK_FINGERPRINT)
#undef THICKET_CHECK_FINGERPRINT
  // Every parsed type is one the generated code has: nothing extra.
  EXPECT_EQ(types.types().size(), generated);
  EXPECT_GE(generated, 20u);
}

TEST(LcmSchema, TheFingerprintIgnoresTypeNamesAsLcmGenDoes) {
  // thicket.stereo_image_t's layout under other names: lcm-gen hashes member names, primitive
  // types and dimensions, not the struct names, so the fingerprint is the same.
  const auto renamed = LcmTypeSet::parse(
      {{"renamed.lcm",
        "package other;\n"
        "struct picture { int64_t utime; string camera_id; int32_t width; int32_t height;\n"
        "  int32_t row_stride; int8_t pixel_format; int8_t encoding; int32_t size;\n"
        "  byte data[size]; }\n"
        "struct pair { int64_t utime; string calibration_id; boolean rectified;\n"
        "  picture left; other.picture right; }\n"}});
  ASSERT_TRUE(renamed) << renamed.error();
  EXPECT_EQ(renamed->find("other.pair")->fingerprint,
            static_cast<uint64_t>(stereo_image_t::getHash()));
  EXPECT_EQ(renamed->find("other.picture")->fingerprint, static_cast<uint64_t>(image_t::getHash()));
}

class LcmSchemaSamples : public testing::TempDirTest {};

TEST_F(LcmSchemaSamples, DecodesEverySampleAndEncodesItBackByteForByte) {
  // tests/support/lcm_samples.cc: one fully populated sample of every type, as an LCM log.
  const std::string log = tempPath("samples.lcm");
  const auto written =
      testing::runCommand(std::string(THICKET_LCM_SAMPLES) + " " + tempPath("") + " --log " + log);
  ASSERT_EQ(written.status, 0) << written.output;
  LogReader reader(log);
  const std::vector<LogEvent> events = reader.readAll();
  ASSERT_TRUE(reader.error().empty()) << reader.error();
  EXPECT_EQ(events.size(), thicketTypes().types().size());
  for (const LogEvent& event : events) {
    const auto value = thicketTypes().decode(event.data.data(), event.data.size());
    ASSERT_TRUE(value) << event.channel << ": " << value.error();
    std::string channel = "SAMPLE_" + value->type->package + "_" + value->type->name;
    for (char& c : channel) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    EXPECT_EQ(event.channel, channel);
    const auto encoded = thicketTypes().encode(*value);
    ASSERT_TRUE(encoded) << event.channel << ": " << encoded.error();
    EXPECT_EQ(*encoded, event.data) << event.channel;
  }
}

TEST(LcmSchema, ReadsFieldsAsTheGeneratedCodeWritesThem) {
  polynomial_trajectory_t trajectory{};
  trajectory.utime = -5;
  trajectory.cycle = 7;
  trajectory.goal_id = -1;
  trajectory.yaw_policy = polynomial_trajectory_t::YAW_CONSTANT;
  trajectory.yaw = 0.1;
  trajectory.num_segments = 2;
  trajectory.num_coefficients = 3;
  trajectory.durations = {1.5, 2.5};
  trajectory.coefficients.assign(2, std::vector<std::vector<double>>(3));
  for (int s = 0; s < 2; ++s) {
    for (int a = 0; a < 3; ++a) {
      for (int k = 0; k < 3; ++k) {
        trajectory.coefficients[s][a].push_back(100.0 * s + 10.0 * a + k + 0.1);
      }
    }
  }
  const LcmValue t = decode(trajectory);
  EXPECT_EQ(t.type->fullName(), "thicket.polynomial_trajectory_t");
  EXPECT_EQ(t.field("utime")->integer(), -5);
  EXPECT_EQ(t.field("goal_id")->integer(), -1);
  EXPECT_EQ(t.field("yaw_policy")->integer(), 1);
  EXPECT_EQ(t.field("yaw")->real(), 0.1);
  EXPECT_EQ(at(*t.field("durations"), {1}).real(), 2.5);
  EXPECT_EQ(at(*t.field("coefficients"), {1, 2, 0}).real(), trajectory.coefficients[1][2][0]);
  EXPECT_EQ(t.field("coefficients")->items.size(), 2u);
  EXPECT_EQ(at(*t.field("coefficients"), {0}).items.size(), 3u);

  map_update_t update{};
  update.layer = map_update_t::LAYER_ESDF;
  update.full_snapshot = true;
  update.num_blocks = 2;
  update.blocks.resize(2);
  update.blocks[1].index[0] = 4;
  update.blocks[1].index[1] = -5;
  update.blocks[1].size = 3;
  update.blocks[1].data = {1, 2, 255};
  update.num_removed = 1;
  update.removed = {{7, -8, 9}};
  const LcmValue u = decode(update);
  EXPECT_EQ(u.field("full_snapshot")->integer(), 1);
  const LcmValue& block = at(*u.field("blocks"), {1});
  EXPECT_EQ(block.type->fullName(), "thicket.map_block_t");
  EXPECT_EQ(at(*block.field("index"), {1}).integer(), -5);
  EXPECT_EQ(block.field("data")->kind, LcmValue::Kind::kBytes);
  EXPECT_EQ(block.field("data")->bytes, (std::vector<uint8_t>{1, 2, 255}));
  EXPECT_EQ(at(*u.field("removed"), {0, 1}).integer(), -8);

  procman_lcm::output_t output{};
  output.deputy_id = "vehicle";
  output.num_commands = 2;
  output.command_ids = {"sim", ""};
  output.text = {"line\n", "x"};
  const LcmValue o = decode(output);
  EXPECT_EQ(o.field("deputy_id")->text, "vehicle");
  EXPECT_EQ(at(*o.field("command_ids"), {1}).text, "");
  EXPECT_EQ(at(*o.field("text"), {0}).text, "line\n");

  procman_lcm::cmd_status_t status{};
  status.cpu_usage = 0.3f;
  status.cmd.command_id = "mapper";
  status.cmd.stop_signal = -2;
  const LcmValue c = decode(status);
  EXPECT_EQ(c.field("cpu_usage")->primitive, Primitive::kFloat);
  EXPECT_EQ(static_cast<float>(c.field("cpu_usage")->real()), 0.3f);
  EXPECT_EQ(c.field("cmd")->field("command_id")->text, "mapper");
  EXPECT_EQ(c.field("cmd")->field("stop_signal")->integer(), -2);
}

TEST(LcmSchema, RefusesDamagedMessagesWithAReason) {
  goal_t goal{};
  goal.strategy = "random";
  goal.num_waypoints = 0;
  std::vector<uint8_t> bytes = encode(goal);
  // Every truncation, whatever field it cuts.
  for (size_t n = 0; n < bytes.size(); ++n) {
    const auto value = thicketTypes().decode(bytes.data(), n);
    ASSERT_FALSE(value) << n << " bytes";
    EXPECT_FALSE(value.error().empty());
    if (n >= 8) {
      EXPECT_NE(value.error().find("thicket.goal_t"), std::string::npos) << value.error();
    }
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_NE(thicketTypes().decode(longer.data(), longer.size()).error().find("1 bytes left over"),
            std::string::npos);

  // num_waypoints is the last field before the (empty) arrays.
  std::vector<uint8_t> negative = bytes;
  std::memset(negative.data() + negative.size() - 4, 0xff, 4);
  EXPECT_EQ(thicketTypes().decode(negative.data(), negative.size()).error(),
            "does not decode as thicket.goal_t: waypoints: size field num_waypoints is negative "
            "(-1)");
  std::vector<uint8_t> huge = bytes;
  huge[huge.size() - 4] = 0x7f;
  EXPECT_NE(thicketTypes().decode(huge.data(), huge.size()).error().find("exceeds"),
            std::string::npos);

  std::vector<uint8_t> unknown = bytes;
  unknown[0] ^= 0xff;
  EXPECT_NE(
      thicketTypes().decode(unknown.data(), unknown.size()).error().find("unknown fingerprint 0x"),
      std::string::npos);
}

TEST(LcmSchema, DefinitionErrorsNameTheFileAndLine) {
  auto error = [](const std::string& text) {
    const auto types = LcmTypeSet::parse({{"x.lcm", text}});
    return types ? std::string("parsed") : types.error();
  };
  EXPECT_EQ(error("package p;\nstruct s\n{\n  q.unknown_t x;\n}\n"),
            "x.lcm:4: p.s.x: unknown type q.unknown_t");
  EXPECT_EQ(error("package p;\nstruct s {\n  double v[n];\n  int32_t n;\n}\n"),
            "x.lcm:3: p.s.v: the size n is not an earlier field");
  EXPECT_EQ(error("package p;\nstruct s {\n  double d;\n  double v[d];\n}\n"),
            "x.lcm:4: p.s.v: the size d is not an integer field");
  EXPECT_EQ(error("package p;\nstruct s {\n  int32_t n\n}\n"), "x.lcm:4: expected ';', found '}'");
  EXPECT_EQ(error("package p;\nstruct s {\n  int32_t n;\n"), "x.lcm:3: missing '}' of struct s");
  EXPECT_EQ(error("struct s { int8_t a; }"), "x.lcm:1: a struct before the package line");
  EXPECT_EQ(error("package p;\nstruct s { int8_t a; int16_t a; }"), "x.lcm:2: 'a' declared twice");
  EXPECT_EQ(error("package p;\n/* never closed"), "x.lcm:2: unterminated comment");

  const auto types = LcmTypeSet::parse({{"y.lcm",
                                         "package p; // comment\nstruct s { int8_t a, b[2]; /* two "
                                         "*/ const int8_t X = 1, Y = -2; }"}});
  ASSERT_TRUE(types) << types.error();
  const LcmStruct& s = *types->find("p.s");
  ASSERT_EQ(s.fields.size(), 2u);
  EXPECT_EQ(s.fields[1].dimensions.at(0).size, 2);
  ASSERT_EQ(s.constants.size(), 2u);
  EXPECT_EQ(s.constants[1].name, "Y");
  EXPECT_EQ(s.constants[1].value, "-2");
}

// ---- the diff ----

polynomial_trajectory_t sampleTrajectory() {
  polynomial_trajectory_t t{};
  t.utime = 12'000'000;
  t.num_segments = 3;
  t.num_coefficients = 10;
  t.durations = {1.0, 1.0, 1.0};
  t.coefficients.assign(3, std::vector<std::vector<double>>(3, std::vector<double>(10, 0.5)));
  return t;
}

TEST(MessageDiff, NamesTheFieldWithBothValuesExactly) {
  polynomial_trajectory_t a = sampleTrajectory(), b = sampleTrajectory();
  b.coefficients[2][0][5] = std::nextafter(0.5, 1.0);  // one bit
  std::vector<FieldDifference> kept;
  EXPECT_EQ(diffMessages(decode(a), decode(b), 10, kept), 1u);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].path, "coefficients[2][0][5]");
  EXPECT_EQ(kept[0].recorded, "0.5");
  EXPECT_EQ(kept[0].replayed, shortest(std::nextafter(0.5, 1.0)));

  b.num_segments = 2;
  b.durations.pop_back();
  b.coefficients.pop_back();
  kept.clear();
  EXPECT_EQ(diffMessages(decode(a), decode(b), 10, kept), 3u);
  EXPECT_EQ(kept[0].path, "num_segments");
  EXPECT_EQ(kept[1].path, "durations");
  EXPECT_EQ(kept[1].recorded, "3 elements");
  EXPECT_EQ(kept[1].replayed, "2 elements");
  EXPECT_EQ(kept[2].path, "coefficients");
}

TEST(MessageDiff, SkipsWallClockFieldsAndNamesConstants) {
  planner_status_t a{}, b{};
  a.state = planner_status_t::STATE_STUCK;
  b.state = planner_status_t::STATE_PLANNED;
  a.solve_time_ms = 3.5;
  b.solve_time_ms = 4.25;
  a.reason = "no feasible trajectory";
  std::vector<FieldDifference> kept;
  EXPECT_EQ(diffMessages(decode(a), decode(b), 10, kept), 2u);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].path, "state");
  EXPECT_EQ(kept[0].recorded, "1 (STATE_STUCK)");
  EXPECT_EQ(kept[0].replayed, "0 (STATE_PLANNED)");
  EXPECT_EQ(kept[1].path, "reason");
  EXPECT_EQ(kept[1].recorded, "\"no feasible trajectory\"");
  EXPECT_EQ(kept[1].replayed, "\"\"");

  module_timing_t x{}, y{};
  x.module = y.module = "mapper";
  x.num_stages = y.num_stages = 1;
  x.stages = y.stages = {"tsdf_insert"};
  x.durations_ms = {1.0};
  y.durations_ms = {2.0};
  kept.clear();
  EXPECT_EQ(diffMessages(decode(x), decode(y), 10, kept), 0u);
}

TEST(MessageDiff, PayloadsDifferWhereTheyFirstDiffer) {
  map_update_t a{};
  a.num_blocks = 1;
  a.blocks.resize(1);
  a.blocks[0].size = 3;
  a.blocks[0].data = {1, 2, 3};
  map_update_t b = a;
  b.blocks[0].data[1] = 0xce;
  std::vector<FieldDifference> kept;
  EXPECT_EQ(diffMessages(decode(a), decode(b), 10, kept), 1u);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].path, "blocks[0].data");
  EXPECT_EQ(kept[0].recorded, "3 bytes (byte 1 = 0x02)");
  EXPECT_EQ(kept[0].replayed, "3 bytes (byte 1 = 0xce)");
}

TEST(MessageDiff, ComparesChannelsInOrderAndCountsWhatItDoesNotPrint) {
  polynomial_trajectory_t altered = sampleTrajectory();
  altered.coefficients[0][1][2] = 0.75;
  altered.coefficients[1][1][2] = 0.75;
  ChannelMessages recorded, replayed;
  recorded["PLANNER_TRAJECTORY"] = {encode(sampleTrajectory()), encode(sampleTrajectory()),
                                    encode(sampleTrajectory())};
  replayed["PLANNER_TRAJECTORY"] = {encode(sampleTrajectory()), encode(altered)};
  recorded["STATE_ESTIMATE"] = {encode(odometry_t{})};
  replayed["STATE_ESTIMATE"] = {encode(odometry_t{})};

  const Comparison all = compareChannels(thicketTypes(), recorded, replayed, 10);
  EXPECT_FALSE(all.equal());
  ASSERT_EQ(all.channels.size(), 2u);
  EXPECT_FALSE(all.channels[0].equal());
  EXPECT_EQ(all.channels[0].differing, 1u);
  EXPECT_TRUE(all.channels[1].equal());
  ASSERT_EQ(all.lines.size(), 3u);
  EXPECT_EQ(all.lines[0],
            "PLANNER_TRAJECTORY message 2 of 3 (utime 12000000): coefficients[0][1][2]: recorded "
            "0.5 replayed 0.75");
  EXPECT_EQ(all.lines[2],
            "PLANNER_TRAJECTORY message 3 of 3 (utime 12000000): recorded, not replayed");
  EXPECT_EQ(all.text().substr(0, all.text().find('\n')),
            "PLANNER_TRAJECTORY: recorded 3 messages, replayed 2, 1 differs");

  const Comparison one = compareChannels(thicketTypes(), recorded, replayed, 1);
  EXPECT_EQ(one.lines.size(), 1u);
  EXPECT_EQ(one.differences, 3u);
  EXPECT_NE(one.text().find("... and 2 more differences"), std::string::npos);

  // A recorded message that does not decode is a difference, not a crash.
  recorded["PLANNER_TRAJECTORY"][0].resize(20);
  const Comparison damaged = compareChannels(thicketTypes(), recorded, replayed, 10);
  EXPECT_NE(
      damaged.lines.at(0).find("PLANNER_TRAJECTORY message 1 of 3 (utime 12000000): the recorded "
                               "message does not decode as thicket.polynomial_trajectory_t"),
      std::string::npos)
      << damaged.lines[0];
}

}  // namespace
}  // namespace thicket::replay
