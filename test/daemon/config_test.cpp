// The configuration mapping: defaults, the shipped file, overrides, and one error per bad input.
#include "lidartag/daemon/config.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

#include "config_cases.hpp"
#include "field_count.hpp"

namespace lidartag::daemon {
namespace {

const std::string kShippedConfig = LIDARTAG_SOURCE_DIR "/config/lidartagd.yaml";

// Every leaf key of a YAML document, as dotted paths (list elements as [i]).
void leaf_keys(const YAML::Node& node, const std::string& path, std::set<std::string>& out) {
  if (node.IsMap()) {
    for (const auto& kv : node) {
      leaf_keys(kv.second, path.empty() ? kv.first.Scalar() : path + "." + kv.first.Scalar(), out);
    }
  } else if (node.IsSequence() && node.size() > 0 && node[0].IsMap()) {
    for (size_t i = 0; i < node.size(); ++i) {
      leaf_keys(node[i], path + "[" + std::to_string(i) + "]", out);
    }
  } else {
    out.insert(path);
  }
}

TEST(Config, ShippedFileHoldsEveryKeyWithItsDefault) {
  const DaemonOptions defaults;
  const DaemonOptions shipped = load_config(kShippedConfig);
  EXPECT_EQ(print_config(shipped), print_config(defaults));
  std::set<std::string> shipped_keys, all_keys;
  leaf_keys(YAML::LoadFile(kShippedConfig), "", shipped_keys);
  leaf_keys(YAML::Load(print_config(defaults)), "", all_keys);
  EXPECT_EQ(shipped_keys, all_keys);
}

using lidartag::test::field_count;

// Counts what a rule table lists: per section (a section is one field of its parent), and the
// settings (fields and choices) in all.
struct TableCounter {
  std::map<std::string, size_t>& fields;
  size_t& settings;
  std::string path;
  template <class T, class Rule = rules::Any>
  void field(const char*, T&, Rule = {}, std::string_view = {}) {
    ++fields[path];
    ++settings;
  }
  template <class E>
  void choice(const char*, E&, const std::vector<std::pair<std::string, E>>&) {
    ++fields[path];
    ++settings;
  }
  template <class F>
  void section(const char* key, F&& body) {
    ++fields[path];
    TableCounter sub{fields, settings, path + key + "."};
    body(sub);
  }
};

// What a rule table lists for default options: `visit(counter, options)` calls the table.
struct TableCount {
  std::map<std::string, size_t> fields;  // per section ("": the top level)
  size_t settings = 0;
};
template <class Options, class Visit>
TableCount count_table(Visit visit) {
  TableCount c;
  Options options;
  TableCounter counter{c.fields, c.settings, ""};
  visit(counter, options);
  return c;
}

size_t printed_keys(const std::string& prefix) {
  std::set<std::string> keys;
  leaf_keys(YAML::Load(print_config(DaemonOptions{})), "", keys);
  size_t n = 0;
  for (const auto& k : keys) n += k.rfind(prefix, 0) == 0 ? 1u : 0u;
  return n;
}

// Every field of every option struct is in its rule table (the counts come from the structs and
// the tables, nothing kept by hand): a field added to a struct but not to its table fails here,
// and the configuration prints one key per setting of the table.
TEST(Config, EveryDetectorOptionIsMapped) {
  auto [fields, settings] = count_table<detector::DetectorOptions>(
      [](auto& v, auto& o) { detector::visit_options(v, o); });
  // keep_tag_points is lcm.publish_tag_points (outside the detector section); keep_cluster_points
  // is for tools that draw clusters.
  EXPECT_EQ(field_count<detector::DetectorOptions>(), fields[""] + 2);
  EXPECT_EQ(field_count<detector::FeatureOptions>(), fields["features."]);
  EXPECT_EQ(field_count<detector::ClusterOptions>(), fields["cluster."]);
  EXPECT_EQ(field_count<detector::ValidationOptions>(), fields["validation."]);
  EXPECT_EQ(field_count<detector::PlaneOptions>(), fields["plane."]);
  EXPECT_EQ(field_count<detector::CornerOptions>(), fields["corners."]);
  EXPECT_EQ(field_count<detector::PoseOptions>(), fields["pose."]);
  EXPECT_EQ(field_count<detector::DecodeOptions>(), fields["decode."]);
  EXPECT_EQ(field_count<detector::DeskewOptions>(), fields["deskew."]);
  EXPECT_EQ(fields.size(), 9u);  // the detector's table and its eight sections
  EXPECT_EQ(printed_keys("detector."), settings);
}

TEST(Config, EveryDriverOptionIsMappedByItsRuleTable) {
  EXPECT_EQ(field_count<driver::BatcherOptions>(),
            count_table<driver::BatcherOptions>([](auto& v, auto& o) {
              driver::visit_batcher_options(v, o);
            }).settings);
  EXPECT_EQ(field_count<velodyne::DecoderOptions>(),
            count_table<velodyne::DecoderOptions>([](auto& v, auto& o) {
              velodyne::visit_decoder_options(v, o);
            }).settings);
  // The driver's keys sit in each sensor's entry, checked with the driver's rules.
  const DaemonOptions parsed = parse_config(
      "sensors: [{name: a, cut_azimuth_deg: 90, flush_timeout_s: 0.5, max_column_step_deg: 3, "
      "min_range_m: 1, max_range_m: 50}]");
  EXPECT_EQ(parsed.sensors[0].batcher.cut_azimuth_deg, 90.0);
  EXPECT_EQ(parsed.sensors[0].batcher.flush_timeout_s, 0.5);
  EXPECT_EQ(parsed.sensors[0].batcher.max_column_step_deg, 3.0);
  EXPECT_EQ(parsed.sensors[0].decoder.min_range_m, 1.0);
  EXPECT_EQ(parsed.sensors[0].decoder.max_range_m, 50.0);
  try {
    (void)parse_config("sensors: [{name: a, cut_azimuth_deg: 360}]");
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "sensors[0].cut_azimuth_deg");
    EXPECT_EQ(e.reason(), "must be in [0, 360)");
  }
  DaemonOptions built;
  built.sensors[0].batcher.flush_timeout_s = 0.001;
  try {
    validate(built);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "sensors[0].flush_timeout_s");
    EXPECT_EQ(e.value(), "0.001");
    EXPECT_EQ(e.reason(), "must be in [0.01, 3600]");
  }
}

TEST(Config, PrintedConfigParsesBackToTheSameOptions) {
  DaemonOptions o;
  o.sensors[0].model = velodyne::Model::kVLP32C;
  o.sensors[0].source.kind = SourceKind::kPcap;
  o.sensors[0].source.file = "/tmp/a b.pcap";
  o.sensors.push_back(o.sensors[0]);
  o.sensors[1].name = "rear";
  o.sensors[1].channel_prefix = "REAR_";
  o.detector.tag_sizes_m = {0.8, 0.6};
  o.detector.pose.algorithm = detector::PoseAlgorithm::kSBPLX;
  o.lcm.url = "udpm://239.255.76.67:7667?ttl=1";
  o.logging.journald = JournalMode::kNever;
  const std::string text = print_config(o);
  EXPECT_EQ(print_config(parse_config(text)), text);
  const DaemonOptions back = parse_config(text);
  ASSERT_EQ(back.sensors.size(), 2u);
  EXPECT_EQ(back.sensors[1].channel_prefix, "REAR_");
  EXPECT_EQ(back.sensors[0].source.file, "/tmp/a b.pcap");
  EXPECT_EQ(back.detector.tag_sizes_m, (std::vector<double>{0.8, 0.6}));
  EXPECT_EQ(back.detector.pose.algorithm, detector::PoseAlgorithm::kSBPLX);
}

TEST(Config, VisualisationOutputsAreOffByDefaultAndMappedOntoTheOptions) {
  const DaemonOptions defaults;
  EXPECT_FALSE(defaults.detector.keep_tag_points);
  EXPECT_EQ(defaults.lcm.cloud_decimation, 0);
  EXPECT_EQ(defaults.lcm.channels.tag_points, "LIDARTAG_TAG_POINTS");
  EXPECT_EQ(defaults.lcm.channels.cloud, "LIDARTAG_CLOUD");
  const std::string printed = print_config(defaults);
  for (const char* key : {"publish_tag_points: false", "cloud_decimation: 0",
                          "tag_points: \"LIDARTAG_TAG_POINTS\"", "cloud: \"LIDARTAG_CLOUD\""}) {
    EXPECT_NE(printed.find(key), std::string::npos) << key << " in\n" << printed;
  }
  const DaemonOptions o = parse_config(R"(
lcm:
  publish_tag_points: true
  cloud_decimation: 4
  channels: {tag_points: PTS, cloud: CLOUD}
)");
  EXPECT_TRUE(o.detector.keep_tag_points);
  EXPECT_EQ(o.lcm.cloud_decimation, 4);
  EXPECT_EQ(o.lcm.channels.tag_points, "PTS");
  EXPECT_EQ(o.lcm.channels.cloud, "CLOUD");
  const DaemonOptions back = parse_config(print_config(o));
  EXPECT_TRUE(back.detector.keep_tag_points);
  EXPECT_EQ(back.lcm.cloud_decimation, 4);
  EXPECT_EQ(back.lcm.channels.cloud, "CLOUD");
  const DaemonOptions set =
      parse_config("", {"lcm.publish_tag_points=true", "lcm.cloud_decimation=1"});
  EXPECT_TRUE(set.detector.keep_tag_points);
  EXPECT_EQ(set.lcm.cloud_decimation, 1);
}

TEST(Config, PartialFileKeepsDefaultsAndSensorEntriesStartFromDefaults) {
  const DaemonOptions o = parse_config(R"(
sensors:
  - name: front
    model: vls128
  - name: rear
    channel_prefix: REAR_
    source: {data_port: 2369, position_port: 8309}
detector:
  plane: {iterations: 7}
)");
  ASSERT_EQ(o.sensors.size(), 2u);
  EXPECT_EQ(o.sensors[0].model, velodyne::Model::kVLS128);
  EXPECT_EQ(o.sensors[1].model, std::nullopt);
  EXPECT_EQ(o.sensors[1].frame_id, "velodyne");
  EXPECT_EQ(o.sensors[1].source.data_port, 2369);
  EXPECT_EQ(o.detector.plane.iterations, 7);
  EXPECT_EQ(o.detector.plane.inlier_m, detector::PlaneOptions{}.inlier_m);
  EXPECT_EQ(o.lcm.channels.detections, "LIDARTAG_DETECTIONS");
}

TEST(Config, OverridesApplyBeforeChecking) {
  const DaemonOptions o =
      parse_config("sensors: [{name: a}]\n", {"sensors[0].source.data_port=3000", "lcm.url=memq://",
                                              "detector.tag_sizes_m=[0.5, 0.7]",
                                              "sensors[1].name=b", "sensors[1].channel_prefix=B_"});
  EXPECT_EQ(o.sensors[0].source.data_port, 3000);
  EXPECT_EQ(o.lcm.url, "memq://");
  EXPECT_EQ(o.detector.tag_sizes_m, (std::vector<double>{0.5, 0.7}));
  ASSERT_EQ(o.sensors.size(), 2u);
  EXPECT_EQ(o.sensors[1].name, "b");
}

using test::BadCase;
using test::expect_refused;

TEST(Config, EachBadKeyOrValueNamesKeyValueAndReason) {
  const std::vector<BadCase> cases = {
      {"bogus: 1", "bogus", "1", "unknown key"},
      {"lcm: {urll: x}", "lcm.urll", "x", "unknown key"},
      {"sensors: [{name: a, sauce: {}}]", "sensors[0].sauce", "{}", "unknown key"},
      {"sensors: [{source: {kind: serial}}]", "sensors[0].source.kind", "serial", "expected udp"},
      {"sensors: [{source: {data_port: 70000}}]", "sensors[0].source.data_port", "70000",
       "integer"},
      {"sensors: [{source: {data_port: 0}}]", "sensors[0].source.data_port", "0", ">= 1"},
      {"sensors: [{source: {data_port: two}}]", "sensors[0].source.data_port", "two", "integer"},
      {"sensors: [{model: vlp64}]", "sensors[0].model", "vlp64", "expected auto"},
      {"sensors: [{cut_azimuth_deg: 360}]", "sensors[0].cut_azimuth_deg", "360", "[0, 360)"},
      {"sensors: [{source: {sensor_address: 10.0.0}}]", "sensors[0].source.sensor_address",
       "10.0.0", "IPv4"},
      {"sensors: [{source: {loop: maybe}}]", "sensors[0].source.loop", "maybe", "true or false"},
      {"sensors: [{source: {kind: pcap}}]", "sensors[0].source.file", "", "required"},
      {"sensors: [{source: {kind: interface}}]", "sensors[0].source.interface", "", "required"},
      {"sensors: [{name: a}, {name: a}]", "sensors[1].name", "a", "another sensor"},
      {"sensors: [{name: a}, {name: b}]", "sensors[1].channel_prefix", "", "collide"},
      {"sensors: []", "sensors", "[]", "non-empty list"},
      {"sensors: [{name: \"\"}]", "sensors[0].name", "", "must not be empty"},
      {"pipeline: {queue_depth: 0}", "pipeline.queue_depth", "0", "[1, 64]"},
      {"pipeline: {queue_depth: 1024}", "pipeline.queue_depth", "1024", "[1, 64]"},
      {"pipeline: {publish_queue: 1024}", "pipeline.publish_queue", "1024", "[1, 64]"},
      {"pipeline: {worker_threads: -1}", "pipeline.worker_threads", "-1", "[0, 128]"},
      {"pipeline: {worker_threads: 256}", "pipeline.worker_threads", "256", "[0, 128]"},
      // Attack round 2: nonsense once accepted.
      {"sensors: [{min_range_m: 1e308}]", "sensors[0].min_range_m", "1e+308",
       "below the model's maximum range"},
      {"sensors: [{model: vlp16, min_range_m: 150}]", "sensors[0].min_range_m", "150", "(100 m)"},
      {"sensors: [{flush_timeout_s: 1e-4}]", "sensors[0].flush_timeout_s", "1e-4", "[0.01, 3600]"},
      {"sensors: [{source: {rate: 1e-300}}]", "sensors[0].source.rate", "1e-300", "[0.001, 1000]"},
      {"sensors: [{name: \"a\\nb\"}]", "sensors[0].name", "a\nb",
       "printable ASCII (holds byte 0x0a)"},
      {"sensors: [{name: \"a\\x1b[31mb\"}]", "sensors[0].name", "a\x1b[31mb", "0x1b"},
      {"sensors: [{frame_id: \"v\\r\"}]", "sensors[0].frame_id", "v\r", "printable"},
      {"sensors: [{name: a, channel_prefix: A}, {name: b, channel_prefix: \"\"}]\n"
       "lcm: {channels: {detections: X, status: AX}}",
       "sensors[1].channel_prefix", "", "which is sensors[0]'s detections channel"},
      {"status: {period_s: fast}", "status.period_s", "fast", "number"},
      {"logging: {level: loud}", "logging.level", "loud", "expected trace"},
      {"logging: {journald: sometimes}", "logging.journald", "sometimes", "expected auto"},
      {"lcm: {channels: {status: \"\"}}", "lcm.channels.status", "", "must not be empty"},
      {"lcm: {channels: {tag_points: \"\"}}", "lcm.channels.tag_points", "", "must not be empty"},
      {"lcm: {channels: {cloud: LIDARTAG_STATUS}}", "lcm.channels.cloud", "LIDARTAG_STATUS",
       "same as lcm.channels.status"},
      {"lcm: {channels: {raw: X, tag_points: X}}", "lcm.channels.tag_points", "X",
       "same as lcm.channels.raw"},
      {"lcm: {cloud_decimation: -1}", "lcm.cloud_decimation", "-1", "must be >= 0"},
      {"lcm: {cloud_decimation: 2.5}", "lcm.cloud_decimation", "2.5", "integer"},
      {"lcm: {publish_tag_points: 1}", "lcm.publish_tag_points", "1", "true or false"},
      {"detector: {tag_sizes_m: [1.2, -1]}", "detector.tag_sizes_m[1]", "-1", "(0, 20)"},
      {"detector: {tag_sizes_m: 1.2}", "detector.tag_sizes_m", "1.2", "expected a list"},
      {"detector: {families: [tag99h1]}", "detector.families[0]", "tag99h1", "unknown tag family"},
      {"detector: {plane: {max_outlier_ratio: 1.0}}", "detector.plane.max_outlier_ratio", "1.0",
       "[0, 1)"},
      {"detector: {pose: {algorithm: newton}}", "detector.pose.algorithm", "newton",
       "expected mma"},
      {"detector: {decode: {samples_per_cell: 9}}", "detector.decode.samples_per_cell", "9",
       "[1, 8]"},
      {"detector: {features: {min_range_m: 50}}", "detector.features.max_range_m", "40",
       "above features.min_range_m"},
      {"detector: {features: [1, 2]}", "detector.features", "[1, 2]", "expected a map"},
      {"[1, 2]", "config", "[1, 2]", "expected a map"},
  };
  expect_refused(cases);
}

TEST(Config, BadYamlAndBadOverridesAreConfigErrors) {
  EXPECT_THROW((void)parse_config("a: [1, 2"), ConfigError);
  EXPECT_THROW((void)parse_config("", {"no_equals_sign"}), ConfigError);
  EXPECT_THROW((void)parse_config("", {"sensors[3].name=x"}), ConfigError);
  EXPECT_THROW((void)load_config("/nonexistent/lidartagd.yaml"), ConfigError);
}

TEST(Config, RandomlyDamagedConfigsLoadOrFailWithOneConfigError) {
  std::ifstream in(kShippedConfig);
  std::stringstream text;
  text << in.rdbuf();
  const std::string shipped = text.str();
  std::mt19937 rng(31);
  int loaded = 0, refused = 0;
  for (int k = 0; k < 200; ++k) {
    std::string yaml = shipped;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits; ++e) {
      // Into the values and structure past the comments' start, not only the comments.
      const size_t at = rng() % yaml.size();
      switch (rng() % 5) {
        case 0:
          yaml[at] = static_cast<char>('0' + rng() % 10);
          break;
        case 1:
          yaml[at] = "-.e:,{}[]& *!|>'\"\n\t9"[rng() % 20];
          break;
        case 2:
          yaml.insert(at, "1e" + std::to_string(rng() % 400));
          break;
        case 3:
          yaml.insert(at, std::to_string(rng()) + std::to_string(rng()));  // 20 digits
          break;
        default:
          yaml.resize(at);
      }
    }
    try {
      const DaemonOptions o = parse_config(yaml);
      ++loaded;
      EXPECT_NO_THROW(validate(o)) << "mutant " << k;
      // What loaded prints and parses back to the same options.
      EXPECT_EQ(print_config(parse_config(print_config(o))), print_config(o)) << "mutant " << k;
    } catch (const ConfigError& e) {
      ++refused;
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
  EXPECT_GT(loaded, 10);
  EXPECT_GT(refused, 10);
}

TEST(Config, ValidateChecksOptionsBuiltInCode) {
  DaemonOptions o;
  EXPECT_NO_THROW(validate(o));
  o.pipeline.queue_depth = 0;
  try {
    validate(o);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "pipeline.queue_depth");
  }
  o = DaemonOptions{};
  o.sensors[0].source.kind = SourceKind::kLcm;
  EXPECT_THROW(validate(o), ConfigError);
  o = DaemonOptions{};
  o.lcm.cloud_decimation = -2;
  try {
    validate(o);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "lcm.cloud_decimation");
  }
  o = DaemonOptions{};
  o.lcm.channels.cloud = o.lcm.channels.detections;
  EXPECT_THROW(validate(o), ConfigError);
}

TEST(Config, DetectorSectionAloneForTheCli) {
  const std::string path =
      ::testing::TempDir() + "/" + std::to_string(::getpid()) + "_detector_only.yaml";
  {
    std::ofstream out(path);
    out << "sensors: [{name: ignored}]\ndetector:\n  tag_sizes_m: [0.8]\n  corners: "
           "{size_tolerance: 0.3}\n";
  }
  const detector::DetectorOptions d = load_detector_config(path);
  EXPECT_EQ(d.tag_sizes_m, (std::vector<double>{0.8}));
  EXPECT_FLOAT_EQ(d.corners.size_tolerance, 0.3f);
  {
    std::ofstream out(path);
    out << "detector:\n  corners: {size_tol: 0.3}\n";
  }
  try {
    (void)load_detector_config(path);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "detector.corners.size_tol");
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace lidartag::daemon

namespace lidartag::daemon {
namespace {

// The tracker's keys come from its rule table (detector::visit_tracker_options): every field of
// TrackerOptions is a key of the `tracker:` section.
TEST(Config, EveryTrackerOptionIsMappedByItsRuleTable) {
  const size_t settings = count_table<detector::TrackerOptions>([](auto& v, auto& o) {
                            detector::visit_tracker_options(v, o);
                          }).settings;
  EXPECT_EQ(field_count<detector::TrackerOptions>(), settings);
  EXPECT_EQ(printed_keys("tracker."), settings);
  const DaemonOptions o = parse_config("tracker: {enabled: false, window: 20, max_angle_deg: 5}");
  EXPECT_FALSE(o.tracker.enabled);
  EXPECT_EQ(o.tracker.window, 20);
  EXPECT_EQ(o.tracker.max_angle_deg, 5.0);
  EXPECT_EQ(print_config(parse_config(print_config(o))), print_config(o));
}

TEST(Config, TrackerBadValuesNameKeyValueAndRule) {
  const std::vector<BadCase> cases = {
      {"tracker: {max_angle_deg: 50}", "tracker.max_angle_deg", "50", "must be in (0, 45)"},
      {"tracker: {max_distance_m: 0}", "tracker.max_distance_m", "0", "must be > 0"},
      {"tracker: {window: 0}", "tracker.window", "0", "must be in [1, 1000]"},
      {"tracker: {min_rotations: 2.5}", "tracker.min_rotations", "2.5", "integer"},
      {"tracker: {enabled: maybe}", "tracker.enabled", "maybe", "true or false"},
      {"tracker: {max_tracks: 0}", "tracker.max_tracks", "0", "must be in [1, 4096]"},
      {"tracker: {gate: 1}", "tracker.gate", "1", "unknown key"},
  };
  expect_refused(cases);
  // Options built in code: the same table.
  DaemonOptions o;
  o.tracker.full_cell_votes = 0.5;
  try {
    validate(o);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "tracker.full_cell_votes");
    EXPECT_EQ(e.reason(), "must be >= 1");
  }
  EXPECT_THROW(detector::validate_tracker_options(o.tracker), detector::OptionsError);
}

}  // namespace
}  // namespace lidartag::daemon

namespace lidartag::daemon {
namespace {

// One mount per sensor (issue 33): a sensors[] entry may give its own sensor_in_body, else the
// global ego_motion.sensor_in_body is its; checked by the same rules, printed only when given.
TEST(Config, EachSensorMayGiveItsOwnMountOrTakesTheGlobalOne) {
  const DaemonOptions o = parse_config(
      "sensors: [{name: front, sensor_in_body: {x: 1.5, z: 0.8}}, {name: rear, channel_prefix: "
      "REAR_}]\n"
      "ego_motion: {channel: ODOM, sensor_in_body: {x: -0.5, yaw_deg: 180}}");
  ASSERT_TRUE(o.sensors[0].sensor_in_body.has_value());
  EXPECT_FALSE(o.sensors[1].sensor_in_body.has_value());
  EXPECT_EQ(mount_of(o, o.sensors[0]).x, 1.5);
  EXPECT_EQ(mount_of(o, o.sensors[0]).z, 0.8);
  EXPECT_EQ(mount_of(o, o.sensors[0]).yaw_deg, 0.0);  // its own: unset fields are 0, not global
  EXPECT_EQ(mount_of(o, o.sensors[1]).x, -0.5);
  EXPECT_EQ(mount_of(o, o.sensors[1]).yaw_deg, 180.0);
  // Printed back only where given; the round trip keeps both.
  const std::string printed = print_config(o);
  const DaemonOptions back = parse_config(printed);
  ASSERT_TRUE(back.sensors[0].sensor_in_body.has_value());
  EXPECT_EQ(back.sensors[0].sensor_in_body->x, 1.5);
  EXPECT_FALSE(back.sensors[1].sensor_in_body.has_value());
  EXPECT_EQ(print_config(back), printed);
  EXPECT_EQ(print_config(DaemonOptions{}).find("sensors:\n  - name: lidar\n    sensor_in_body"),
            std::string::npos);
  // The same rules as the global mount, on files and on options built in code.
  try {
    (void)parse_config("sensors: [{name: a, sensor_in_body: {pitch_deg: 400}}]");
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "sensors[0].sensor_in_body.pitch_deg");
    EXPECT_EQ(e.reason(), "must be in [-360, 360]");
  }
  try {
    (void)parse_config("sensors: [{name: a, sensor_in_body: {w: 1}}]");
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "sensors[0].sensor_in_body.w");
    EXPECT_EQ(e.reason(), "unknown key");
  }
  DaemonOptions built;
  built.sensors[0].sensor_in_body = BodyMount{};
  built.sensors[0].sensor_in_body->z = 2000.0;
  try {
    validate(built);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "sensors[0].sensor_in_body.z");
  }
}

// The ego-motion input (issue 33): off by default; its keys come from EgoMotionConfig and the
// detector's rule table of EgoMotionOptions.
TEST(Config, EgoMotionIsOffByDefaultAndMappedWithItsRules) {
  const size_t settings = count_table<detector::EgoMotionOptions>([](auto& v, auto& o) {
                            detector::visit_ego_motion_options(v, o);
                          }).settings;
  EXPECT_EQ(field_count<detector::EgoMotionOptions>(), settings);
  // The buffer's keys, the channel, URL, stale_s and the six of the mount.
  EXPECT_EQ(printed_keys("ego_motion."), settings + 3 + 6);
  EXPECT_TRUE(DaemonOptions{}.ego_motion.channel.empty());
  const DaemonOptions o = parse_config(
      "ego_motion: {channel: ROBOT_ODOM, max_gap_s: 0.5, stale_s: 2, sensor_in_body: {z: 1.2, "
      "yaw_deg: 90}}");
  EXPECT_EQ(o.ego_motion.channel, "ROBOT_ODOM");
  EXPECT_EQ(o.ego_motion.buffer.max_gap_s, 0.5);
  EXPECT_EQ(o.ego_motion.stale_s, 2.0);
  EXPECT_EQ(o.ego_motion.sensor_in_body.z, 1.2);
  EXPECT_EQ(o.ego_motion.sensor_in_body.yaw_deg, 90.0);
  EXPECT_EQ(print_config(parse_config(print_config(o))), print_config(o));
  const std::vector<BadCase> cases = {
      {"ego_motion: {capacity: 1}", "ego_motion.capacity", "1", "must be in [2, 1000000]"},
      {"ego_motion: {max_gap_s: 0}", "ego_motion.max_gap_s", "0", "must be in (0, 60]"},
      {"ego_motion: {stale_s: 0}", "ego_motion.stale_s", "0", "must be in [0.001, 3600]"},
      {"ego_motion: {sensor_in_body: {roll_deg: 400}}", "ego_motion.sensor_in_body.roll_deg", "400",
       "must be in [-360, 360]"},
      {"ego_motion: {channel: \"A\\tB\"}", "ego_motion.channel", "A\tB", "printable ASCII"},
  };
  expect_refused(cases);
}

}  // namespace
}  // namespace lidartag::daemon
