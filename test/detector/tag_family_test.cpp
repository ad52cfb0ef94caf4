// Tag families as data: the built-in tables against the shared reference file, a user's own family
// from a JSON file (loaded, then decoded on the demo capture), and one clear error per bad file.
#include "lidartag/detector/tag_family.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::tags {
namespace {

namespace fs = std::filesystem;

const std::string kReference = LIDARTAG_SHARED_DIR "/reference/apriltag_families.json";

// A file in the test's temporary directory, removed at the end of the test.
class TempJson {
 public:
  TempJson(const std::string& name, const std::string& text)
      : path_(::testing::TempDir() + "/" + std::to_string(::getpid()) + "_" + name + ".json") {
    std::ofstream(path_) << text;
  }
  ~TempJson() { fs::remove(path_); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// tag16h5's layout as a JSON family object, with the given code words.
nlohmann::json tag16h5_with(const std::vector<uint64_t>& codes) {
  const TagFamily& f = builtin_family("tag16h5");
  nlohmann::json o;
  o["nbits"] = f.nbits;
  o["total_width"] = f.total_width;
  o["width_at_border"] = f.width_at_border;
  o["reversed_border"] = false;
  o["bit_x"] = f.bit_x;
  o["bit_y"] = f.bit_y;
  o["codes"] = nlohmann::json::array();
  for (uint64_t c : codes) {
    char hex[32];
    std::snprintf(hex, sizeof hex, "0x%llx", static_cast<unsigned long long>(c));
    o["codes"].push_back(hex);
  }
  return o;
}

TEST(TagFamily, TheSharedReferenceFileGivesTheBuiltInTables) {
  if (!fs::exists(kReference)) GTEST_SKIP() << "no " << kReference;
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"tag16h5", "tag16h5"},
      {"tag25h9", "tag25h9"},
      {"tag36h10", "tag36h10"},
      {"tag36h11", "tag36h11"},
      {"tag16h6_lidartag_paper", "tag16h6"}};
  for (const auto& [key, builtin] : pairs) {
    const TagFamily file = load_family_file(kReference, key);
    const TagFamily& table = builtin_family(builtin);
    EXPECT_EQ(file.nbits, table.nbits) << key;
    EXPECT_EQ(file.total_width, table.total_width) << key;
    EXPECT_EQ(file.width_at_border, table.width_at_border) << key;
    EXPECT_EQ(file.bit_x, table.bit_x) << key;
    EXPECT_EQ(file.bit_y, table.bit_y) << key;
    EXPECT_EQ(file.codes, table.codes) << key;
  }
  // Through the name a user gives on the command line or in the configuration.
  EXPECT_EQ(resolve_family(kReference + ":tag36h11").codes, builtin_family("tag36h11").codes);
}

// A user's own family: tag16h5's layout with its first two code words swapped, so that the demo's
// tag 0 is "mine" id 1 and its tag 1 is "mine" id 0. The built-in tag16h5 (decoded too, as a family
// that is not configured) has the same patterns: ties stay with the configured family.
TEST(TagFamily, AUserFamilyFromAJsonFileDecodesTheDemoTags) {
  const std::string demo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";
  if (!fs::exists(demo)) GTEST_SKIP() << "no " << demo;
  const TagFamily& t16 = builtin_family("tag16h5");
  nlohmann::json file;
  file["mine"] = tag16h5_with({t16.codes[1], t16.codes[0]});
  const TempJson json("mine", file.dump());
  const TagFamily mine = resolve_family(json.path());  // the only family: no ":NAME" needed
  EXPECT_EQ(mine.name, "mine");
  EXPECT_EQ(mine.codes, (std::vector<uint64_t>{t16.codes[1], t16.codes[0]}));

  detector::DetectorOptions o;
  o.tag_sizes_m = {0.8, 0.6};
  o.families = {json.path()};
  detector::Detector det(o);
  detector::ScanResult result;
  velodyne::CaptureReader reader(demo, {});
  int rotations = 0;
  while (const Scan* scan = reader.next()) {
    if (!scan->complete) continue;
    det.detect(*scan, result);
    ++rotations;
    ASSERT_EQ(result.detections.size(), 2u) << "rotation " << rotations;
    for (const auto& d : result.detections) {
      EXPECT_EQ(d.family, "mine");
      // pcaps/demo.truth.json: tag 0 at (4.0, 0.9), tag 1 at (3.2, -1.6).
      const bool at_tag0 =
          std::abs(d.position.x() - 4.0) < 0.1 && std::abs(d.position.y() - 0.9) < 0.1;
      const bool at_tag1 =
          std::abs(d.position.x() - 3.2) < 0.1 && std::abs(d.position.y() + 1.6) < 0.1;
      ASSERT_TRUE(at_tag0 || at_tag1) << d.position.transpose();
      EXPECT_EQ(d.id, at_tag0 ? 1 : 0);
    }
  }
  EXPECT_EQ(rotations, 10);
}

TEST(TagFamily, EachBadFileGivesOneErrorNamingTheProblem) {
  const nlohmann::json good = tag16h5_with(builtin_family("tag16h5").codes);
  auto with = [&](const char* key, const nlohmann::json& value) {
    nlohmann::json o = good;
    o[key] = value;
    return nlohmann::json{{"bad", o}}.dump();
  };
  auto without = [&](const char* key) {
    nlohmann::json o = good;
    o.erase(key);
    return nlohmann::json{{"bad", o}}.dump();
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{\"bad\": {", "tag family file"},  // not JSON
      {"[]", "no family"},
      {nlohmann::json{{"a", good}, {"b", good}}.dump(), "several families"},
      {with("nbits", 1e30), "nbits"},
      {with("nbits", 2.5), "nbits"},
      {with("nbits", -16), "nbits"},
      {with("nbits", std::numeric_limits<int64_t>::min()), "nbits"},
      {with("nbits", 17), "square payload"},
      {with("total_width", 99999999999LL), "total_width"},
      {with("bit_x", nlohmann::json::array({1, 2, 3})), "bit_x and bit_y"},
      {with("bit_x", "1,2,3"), "bit_x"},
      {with("codes", nlohmann::json::array({"0xZZ"})), "code word"},
      {with("codes", nlohmann::json::array({-3})), "code word"},
      {with("codes", nlohmann::json::array({1.5})), "code word"},
      {with("codes", nlohmann::json::array({"0x1ffff"})), "more than nbits bits"},
      {with("codes", nlohmann::json::array()), "no codes"},
      {with("codes", 7), "codes"},
      {without("codes"), "codes"},
      {without("nbits"), "nbits"},
  };
  for (const auto& [text, expected] : cases) {
    const TempJson json("bad", text);
    try {
      load_family_file(json.path());
      ADD_FAILURE() << "accepted: " << text;
    } catch (const FamilyError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << "for " << text << ": " << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(resolve_family("/nonexistent/families.json:tag16h5"), FamilyError);
  EXPECT_THROW(load_family_file(kReference, "tag99h99"), FamilyError);
}

}  // namespace
}  // namespace lidartag::tags
