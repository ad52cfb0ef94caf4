// The rule table of the detector's options: every setting named once with a rule, the same rules
// for options built in code as for the daemon's YAML (which uses the same table).
#include "lidartag/detector/options.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>

#include "field_count.hpp"
#include "lidartag/detector/detector.hpp"

namespace lidartag::detector {
namespace {

using lidartag::test::field_count;

// Records every key the table visits, per section, with its unit.
class KeyLister {
 public:
  explicit KeyLister(std::string path, std::map<std::string, std::string>& keys)
      : path_(std::move(path)), keys_(keys) {}
  template <class T, class Rule>
  void field(const char* key, T&, Rule, std::string_view unit) {
    EXPECT_TRUE(keys_.emplace(path_ + key, std::string(unit)).second) << path_ + key;
  }
  template <class E>
  void choice(const char* key, E&, const std::vector<std::pair<std::string, E>>& names) {
    EXPECT_FALSE(names.empty());
    EXPECT_TRUE(keys_.emplace(path_ + key, "").second) << path_ + key;
  }
  template <class F>
  void section(const char* key, F&& body) {
    KeyLister sub(path_ + key + ".", keys_);
    body(sub);
  }

 private:
  std::string path_;
  std::map<std::string, std::string>& keys_;
};

size_t keys_under(const std::map<std::string, std::string>& keys, const std::string& prefix) {
  size_t n = 0;
  for (const auto& [k, unit] : keys) n += k.rfind(prefix, 0) == 0 ? 1u : 0u;
  return n;
}

TEST(Options, TheTableNamesEverySettingOnce) {
  std::map<std::string, std::string> keys;
  KeyLister lister("", keys);
  DetectorOptions o;
  visit_options(lister, o);
  // Every field of every stage's struct; of the top level all but the two output selections
  // (keep_tag_points, keep_cluster_points) and the seven stage sections.
  EXPECT_EQ(keys_under(keys, "features."), field_count<FeatureOptions>());
  EXPECT_EQ(keys_under(keys, "cluster."), field_count<ClusterOptions>());
  EXPECT_EQ(keys_under(keys, "validation."), field_count<ValidationOptions>());
  EXPECT_EQ(keys_under(keys, "plane."), field_count<PlaneOptions>());
  EXPECT_EQ(keys_under(keys, "corners."), field_count<CornerOptions>());
  EXPECT_EQ(keys_under(keys, "pose."), field_count<PoseOptions>());
  EXPECT_EQ(keys_under(keys, "decode."), field_count<DecodeOptions>());
  size_t top = 0;
  for (const auto& [k, unit] : keys) top += k.find('.') == std::string::npos ? 1u : 0u;
  EXPECT_EQ(top, field_count<DetectorOptions>() - 2 - 7);
  // Lengths carry their unit.
  for (const auto& [k, unit] : keys)
    if (k.size() > 2 && k.compare(k.size() - 2, 2, "_m") == 0) {
      EXPECT_EQ(unit, "m") << k;
    }
}

// A copy of the defaults with one change.
template <class F>
DetectorOptions with(F&& change) {
  DetectorOptions o;
  change(o);
  return o;
}

void expect_rejected(const DetectorOptions& o, const std::string& key, const std::string& value) {
  try {
    validate_options(o);
    ADD_FAILURE() << key << " accepted";
  } catch (const OptionsError& e) {
    EXPECT_EQ(e.key(), key);
    EXPECT_EQ(e.value(), value);
    EXPECT_FALSE(e.reason().empty());
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
  }
  EXPECT_THROW(Detector{o}, OptionsError) << key;
}

TEST(Options, CodeBuiltOptionsGetEveryRule) {
  EXPECT_NO_THROW(validate_options(DetectorOptions{}));
  // Rules that only the YAML path had before the table: now the Detector checks them too.
  expect_rejected(with([](auto& o) { o.corners.corner_exclusion = 0.5f; }),
                  "corners.corner_exclusion", "0.5");
  expect_rejected(with([](auto& o) { o.decode.min_score = 1.5; }), "decode.min_score", "1.5");
  expect_rejected(with([](auto& o) { o.validation.min_rings = 0; }), "validation.min_rings", "0");
  expect_rejected(with([](auto& o) { o.pose.min_depth_epsilon_m = 0.0; }),
                  "pose.min_depth_epsilon_m", "0");
  expect_rejected(with([](auto& o) { o.decode.parallel_min_functions = 0; }),
                  "decode.parallel_min_functions", "0");
  // Lists: the element is named; an empty list is refused.
  expect_rejected(with([](auto& o) { o.tag_sizes_m = {1.2, -1.0}; }), "tag_sizes_m[1]", "-1");
  expect_rejected(with([](auto& o) { o.tag_sizes_m.clear(); }), "tag_sizes_m", "[]");
  expect_rejected(with([](auto& o) {
                    o.families = {"tag16h5", "tag99h1"};
                  }),
                  "families[1]", "tag99h1");
  expect_rejected(with([](auto& o) { o.families.clear(); }), "families", "[]");
  // Between fields.
  expect_rejected(with([](auto& o) { o.features.min_range_m = 50.0f; }), "features.max_range_m",
                  "40");
}

TEST(Options, BoundsAreInclusiveOrExclusiveAsDocumented) {
  // xtol_rel >= 0 (0 disables it, as 0 disables xtol_abs): the YAML path said > 0 before.
  EXPECT_NO_THROW(validate_options(with([](auto& o) { o.pose.xtol_rel = 0.0; })));
  expect_rejected(with([](auto& o) { o.pose.xtol_rel = -1e-6; }), "pose.xtol_rel", "-1e-06");
  EXPECT_NO_THROW(validate_options(with([](auto& o) { o.pose.min_coverage = 1.0; })));
  EXPECT_NO_THROW(validate_options(with([](auto& o) { o.plane.max_outlier_ratio = 0.0f; })));
  expect_rejected(with([](auto& o) { o.plane.max_outlier_ratio = 1.0f; }),
                  "plane.max_outlier_ratio", "1");
  EXPECT_NO_THROW(validate_options(with([](auto& o) { o.corners.max_side_angle_deg = 90.0f; })));
  expect_rejected(with([](auto& o) { o.corners.max_side_angle_deg = 0.0f; }),
                  "corners.max_side_angle_deg", "0");
  EXPECT_NO_THROW(validate_options(with([](auto& o) { o.decode.samples_per_cell = 8; })));
  expect_rejected(with([](auto& o) { o.decode.samples_per_cell = 9; }), "decode.samples_per_cell",
                  "9");
  expect_rejected(with([](auto& o) { o.tag_sizes_m = {20.0}; }), "tag_sizes_m[0]", "20");
}

TEST(Options, RulesSayWhatIsExpected) {
  EXPECT_EQ(rules::at_least(1)(0), "must be >= 1");
  EXPECT_EQ(rules::above(0.0)(0.0), "must be > 0");
  EXPECT_EQ(rules::half_open(0.0f, 1.0f)(1.0f), "must be in [0, 1)");
  EXPECT_EQ(rules::open(0.0, 20.0)(0.0), "must be in (0, 20)");
  EXPECT_EQ(rules::closed(1, 8)(4), "");
  EXPECT_EQ(rules::number_text(1e-6), "1e-06");
  EXPECT_EQ(rules::number_text(0.25), "0.25");
  EXPECT_EQ(rules::KnownFamily{}("tag36h11"), "");
  EXPECT_NE(rules::KnownFamily{}("/nonexistent.json").find("nonexistent"), std::string::npos);
}

TEST(Options, DerivedLimitsAreArgumentsNotOptions) {
  DetectorOptions o;
  o.tag_sizes_m = {0.6, 1.2};
  const Detector det(o);
  // The options come back as given: nothing derived is written into them.
  EXPECT_EQ(det.options().tag_sizes_m, o.tag_sizes_m);
  const DetectorLimits& l = det.limits();
  EXPECT_DOUBLE_EQ(l.t_max, 1.2);
  EXPECT_NEAR(l.tau_m, 1.2 * std::sqrt(2.0) / 4, 1e-6);
  // The largest object a tag can be is its board: 1.2 m and a 0.2 m margin on each side.
  EXPECT_NEAR(l.board_max, 1.6, 1e-6);
  EXPECT_NEAR(l.max_pair_chord_m, 1.1 * 1.6 * std::sqrt(2.0), 1e-5);
  EXPECT_NEAR(l.max_extent_m, 1.25 * 1.6 * std::sqrt(2.0), 1e-5);
  EXPECT_EQ(l.min_points, 64);           // 1 return x 8 x 8 cells of tag16h5
  EXPECT_EQ(l.min_boundary_points, 12);  // eq. (6): 2 (4 + 2)
  EXPECT_NEAR(l.min_ring_width_m, 0.25 * 0.6, 1e-6);
}

}  // namespace
}  // namespace lidartag::detector
