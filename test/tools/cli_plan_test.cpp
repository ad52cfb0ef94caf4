// `lidartag plan`: the simulator's answer to "where will this sensor see this tag?".
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "run_tool.hpp"

namespace lidartag::testing {
namespace {

nlohmann::json plan_json(const std::string& args) {
  const ToolResult r = run_tool("plan " + args + " --json", false);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return nlohmann::json::parse(r.out);
}

const nlohmann::json& cell(const nlohmann::json& j, double distance, int angle) {
  for (const auto& c : j["cells"])
    if (c["distance_m"].get<double>() == distance && c["angle_deg"].get<int>() == angle) return c;
  ADD_FAILURE() << "no cell " << distance << " m " << angle << " deg";
  return j;
}

TEST(CliPlan, NearTagIsFoundFarTagIsNotAndTheMissSaysWhatItLacked) {
  // A VLP-16's beams are 2 degrees apart: at 4 m about 7 rings cross a 1.2 m tag, at 16 m two.
  const auto j = plan_json(
      "--model vlp16 --tag-size 1.2 --distances 4,16 --angles 0 --runs 2 "
      "--rotations 5");
  EXPECT_EQ(j["model"], "vlp16");
  const auto& near = cell(j, 4, 0);
  const auto& far = cell(j, 16, 0);
  EXPECT_EQ(near["rotations"], 10);
  EXPECT_GE(near["detected"].get<int>(), 9);
  EXPECT_GE(near["tracked"].get<int>(), near["tracked_scored"].get<int>() - 1);
  EXPECT_EQ(far["detected"], 0);
  EXPECT_EQ(far["tracked"], 0);
  // Every missed rotation has a reason; what the misses had at the tag.
  int misses = 0;
  for (const auto& [why, n] : far["misses"].items()) {
    EXPECT_NE(why.find('/'), std::string::npos) << why;  // stage/reason
    misses += n.get<int>();
  }
  EXPECT_EQ(misses, 10);
  // The misses' clusters at 16 m: two or three rings, far fewer points than the 64 of eq. (3).
  EXPECT_GE(far["missed_rings"][0].get<int>(), 1);
  EXPECT_LE(far["missed_rings"][1].get<int>(), 3);
  EXPECT_LT(far["missed_points"][1].get<int>(), 64);
  EXPECT_EQ(near["wrong_id_rotations"], 0);
  EXPECT_EQ(far["wrong_id_rotations"], 0);
}

TEST(CliPlan, ABiggerTagReachesFarther) {
  // A VLP-32C: a 0.4 m tag is lost by 12 m (too few points for eq. (3); the few rotations with
  // enough for a track's evidence, validation.track_returns_per_cell, then too few boundary
  // points), a 1.2 m one is not.
  const auto small = plan_json(
      "--model vlp32c --tag-size 0.4 --distances 12 --angles 0 --runs 2 "
      "--rotations 3");
  const auto big = plan_json(
      "--model vlp32c --tag-size 1.2 --distances 12 --angles 0 --runs 2 "
      "--rotations 3");
  EXPECT_EQ(cell(small, 12, 0)["detected"], 0);
  const auto& misses = cell(small, 12, 0)["misses"];
  EXPECT_EQ(misses.value("validation/too_few_points", 0) +
                misses.value("validation/few_boundary_points", 0),
            6);
  EXPECT_GE(misses.value("validation/too_few_points", 0), 4);
  EXPECT_EQ(cell(big, 12, 0)["detected"], 6);
}

TEST(CliPlan, AnOusterIsPlannedWithItsOwnBeams) {
  // An OS1-64's beams are 0.71 degrees apart, an OS1-128's 0.35: at 20 m about 6 and 12 rings
  // cross a 1.2 m tag; the OS1-128 sees it in most rotations, the OS1-64 in none by itself.
  const auto os64 =
      plan_json("--model OS1-64 --tag-size 1.2 --distances 5,20 --angles 0 --runs 2 --rotations 4");
  const auto os128 = plan_json(
      "--model os1-128 --tag-size 1.2 --distances 5,20 --angles 0 --runs 2 --rotations 4");
  EXPECT_EQ(os64["model"], "os1-64");
  EXPECT_EQ(os128["model"], "os1-128");
  EXPECT_EQ(cell(os64, 5, 0)["detected"], 8);
  EXPECT_EQ(cell(os128, 5, 0)["detected"], 8);
  EXPECT_EQ(cell(os64, 20, 0)["detected"], 0);
  // The misses' clusters at 20 m: the OS1-64's fewer rings than the OS1-128's.
  EXPECT_LE(cell(os64, 20, 0)["missed_rings"][1].get<int>(), 6);
  const auto& far128 = cell(os128, 20, 0);
  EXPECT_GT(far128["tracked"].get<int>() + far128["detected"].get<int>(), 0);
  EXPECT_EQ(far128["wrong_id_rotations"], 0);
  // A model name without a beam table to simulate, and a rate an Ouster lacks: usage errors.
  for (const char* args :
       {"--model os1-32 --tag-size 1.2", "--model os1-64 --tag-size 1.2 --rpm 900"}) {
    const ToolResult r = run_tool(std::string("plan ") + args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.out;
    EXPECT_NE(
        r.out.find(std::string(args).find("rpm") != std::string::npos ? "--rpm" : "no beam table"),
        std::string::npos)
        << r.out;
  }
}

TEST(CliPlan, TextNamesTheReachAndTheReason) {
  const ToolResult r = run_tool(
      "plan --model vlp16 --tag-size 1.2 --distances 4,16 --angles 0 --runs 1 --rotations 5");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("95 % of rotations or more to 4 m"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("        at 16 m: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("wrong IDs: 0 rotations"), std::string::npos) << r.out;
}

TEST(CliPlan, BadValuesAreUsageErrorsNamingTheOption) {
  struct Case {
    const char* args;
    const char* named;
  } cases[] = {
      {"--model vlp16 --tag-size 1.2 --distances 8:2:1", "--distances"},
      {"--model vlp16 --tag-size 1.2 --distances 2:8", "--distances"},
      {"--model vlp16 --tag-size 1.2 --distances x,3", "--distances"},
      {"--model vlp16 --tag-size 1.2 --angles 0,95", "--angles"},
      {"--model vlp99 --tag-size 1.2", "--model"},
      {"--model vlp16 --tag-size 1.2 --mount sideways", "--mount"},
      {"--model vlp16 --tag-size 1.2 --family tag99h1", "tag99h1"},
  };
  for (const auto& c : cases) {
    const ToolResult r = run_tool(std::string("plan ") + c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.named), std::string::npos) << c.args << "\n" << r.out;
  }
}

}  // namespace
}  // namespace lidartag::testing
