// thicket-map and thicket-mapper as a user runs them: a map built from simulator views answers
// queries like the library, exports and describes itself; bad arguments fail with a message.
#include <unistd.h>

#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "cli.h"
#include "mapper_node.h"
#include "thicket/common/esdf_query.h"
#include "thicket/mapper/map_io.h"

namespace thicket::mapper {
namespace {

using thicket::testing::CliResult;

CliResult map(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_MAP) + " " + args);
}

std::string temp(const std::string& name) {
  return ::testing::TempDir() + "/mapper_cli_" + std::to_string(::getpid()) + "_" + name;
}

TEST(MapTool, BuildsQueriesExportsAndDescribesAMap) {
  const std::string path = temp("forest.map");
  CliResult result =
      map("build --scenario forest50 --density 0.2 --seed 1 --views 8 --out " + path);
  ASSERT_EQ(result.status, 0) << result.output;
  // View 3 stands inside a tree's robot radius on this world (see the world's JSON).
  EXPECT_NE(result.output.find("view 3 at"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("skipped"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("integrated 7 of 8 views"), std::string::npos) << result.output;
  auto loaded = loadMap(path);
  ASSERT_TRUE(loaded) << loaded.error();
  EXPECT_EQ(loaded->revision, 7);

  result = map("query " + path + " 3,3,1.5 40,40,1");
  ASSERT_EQ(result.status, 0) << result.output;
  const EsdfSample near = sampleEsdf(loaded->esdf, {3, 3, 1.5});
  ASSERT_TRUE(near.known);
  char expected[128];
  std::snprintf(expected, sizeof(expected), "3,3,1.5: distance %.3f m, observed", near.distance);
  EXPECT_NE(result.output.find(expected), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("40,40,1: unknown"), std::string::npos) << result.output;

  result = map("info " + path);
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("revision 7"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("voxel size 0.200 m"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("TSDF " + std::to_string(loaded->tsdf.numBlocks()) + " blocks"),
            std::string::npos)
      << result.output;

  const std::string ply = temp("mesh.ply"), pcd = temp("occupied.pcd");
  result = map("export " + path + " --ply " + ply + " --pcd " + pcd);
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("triangles -> " + ply), std::string::npos) << result.output;
  std::ifstream mesh(ply);
  std::string first_line;
  std::getline(mesh, first_line);
  EXPECT_EQ(first_line, "ply");
}

TEST(MapTool, BadArgumentsFailWithAMessage) {
  const auto fails = [](const std::string& args, const std::string& message) {
    const CliResult result = map(args);
    EXPECT_EQ(result.status, 2) << args;
    EXPECT_NE(result.output.find(message), std::string::npos) << args << ": " << result.output;
  };
  fails("", "A subcommand is required");
  fails("fly", "unexpected argument 'fly'");
  fails("build --scenario forest50 --density 0.2 --seed 1 --views 2", "--out is required");
  fails("build --scenario nowhere --density 0.2 --seed 1 --views 2 --out x", "nowhere");
  fails("build --scenario paper --density 0.2 --seed 1 --views -2 --out x",
        "--views: must be an integer");
  fails("build --scenario paper --density abc --seed 1 --views 2 --out x",
        "--density: must be a number >= 0, not 'abc'");
  fails("build --scenario paper --density 0.2 --seed 1 --views 2 --voxel 0 --out x", "voxel");
  fails("query /nonexistent.map 1,2,3", "cannot read");
  fails("info " + std::string(THICKET_SOURCE_DIR) + "/README.md", "not a thicket map");
  const std::string path = temp("small.map");
  ASSERT_EQ(map("build --scenario paper --density 0.2 --seed 1 --views 1 --out " + path).status, 0);
  fails("query " + path + " 1,2", "is not x,y,z");
  fails("query " + path + " 1,2,z", "must be a number, not 'z'");
  fails("export " + path, "needs --ply");
  fails("export " + path + " --obj x.obj", "--obj");
}

// config/params/mapper.yaml documents every option; it must load and must not fall behind.
TEST(MapperCli, TheShippedParameterFileIsCurrent) {
  thicket::testing::expectParamsFileCurrent<MapperNodeOptions>(
      THICKET_MAPPER, "thicket-mapper",
      std::string(THICKET_SOURCE_DIR) + "/config/params/mapper.yaml");
  const CliResult bad =
      thicket::testing::runCommand(std::string(THICKET_MAPPER) + " --config /nonexistent.yaml");
  EXPECT_EQ(bad.status, 2);
}

// A map to continue from that cannot be read stops the mapper at start, saying why.
TEST(MapperCli, RefusesAMapItCannotLoad) {
  const std::string config = temp("load.yaml");
  std::ofstream(config) << "load_map: " << temp("missing.map") << "\n";
  const CliResult result = thicket::testing::runCommand(std::string(THICKET_MAPPER) +
                                                        " --lcm-url memq:// --config " + config);
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("cannot read"), std::string::npos) << result.output;
  std::remove(config.c_str());
}

}  // namespace
}  // namespace thicket::mapper
