// The configuration of Ouster sensors: `model` takes Ouster model names, `metadata` makes the
// sensor an Ouster on its own ports unless the entry names others, the rules between them, and
// `source.topic` for bags; the printed configuration reads back the same.
#include <gtest/gtest.h>

#include "config_cases.hpp"
#include "lidartag/daemon/config.hpp"

namespace lidartag::daemon {
namespace {

TEST(ConfigOuster, ModelNamesMetadataAndTheSensorsPorts) {
  const DaemonOptions o = parse_config(
      "sensors:\n"
      "  - {name: a, model: os1-128, metadata: /etc/os.json}\n"
      "  - {name: b, channel_prefix: B_, metadata: /etc/os.json, source: {data_port: 7600}}\n"
      "  - {name: c, channel_prefix: C_, model: vlp16, source: {kind: pcap, file: x.bag, "
      "topic: /velodyne_packets}}\n");
  EXPECT_EQ(o.sensors[0].ouster_model, "os1-128");
  EXPECT_FALSE(o.sensors[0].model);
  EXPECT_EQ(o.sensors[0].metadata, "/etc/os.json");
  EXPECT_EQ(o.sensors[0].source.data_port, 7502);  // the sensor's own ports
  EXPECT_EQ(o.sensors[0].source.position_port, 7503);
  EXPECT_EQ(o.sensors[1].source.data_port, 7600);  // named: kept
  EXPECT_EQ(o.sensors[1].source.position_port, 7503);
  EXPECT_EQ(o.sensors[2].model, velodyne::Model::kVLP16);
  EXPECT_EQ(o.sensors[2].ouster_model, "");
  EXPECT_EQ(o.sensors[2].source.data_port, 2368);
  EXPECT_EQ(o.sensors[2].source.topic, "/velodyne_packets");
  // Printed and read back: the same.
  const DaemonOptions again = parse_config(print_config(o));
  for (size_t i = 0; i < o.sensors.size(); ++i) {
    EXPECT_EQ(again.sensors[i].ouster_model, o.sensors[i].ouster_model);
    EXPECT_EQ(again.sensors[i].model, o.sensors[i].model);
    EXPECT_EQ(again.sensors[i].metadata, o.sensors[i].metadata);
    EXPECT_EQ(again.sensors[i].source.data_port, o.sensors[i].source.data_port);
    EXPECT_EQ(again.sensors[i].source.position_port, o.sensors[i].source.position_port);
    EXPECT_EQ(again.sensors[i].source.topic, o.sensors[i].source.topic);
  }
  // The names the tools' --model takes, in any case (driver::model_from_name).
  const DaemonOptions cased = parse_config(
      "sensors:\n"
      "  - {name: a, model: OS1-128, metadata: /etc/os.json}\n"
      "  - {name: b, channel_prefix: B_, model: VLP-32C}\n");
  EXPECT_EQ(cased.sensors[0].ouster_model, "os1-128");
  EXPECT_FALSE(cased.sensors[0].model);
  EXPECT_EQ(cased.sensors[1].model, velodyne::Model::kVLP32C);
  EXPECT_EQ(cased.sensors[1].ouster_model, "");
  EXPECT_EQ(print_config(cased), print_config(parse_config(print_config(cased))));
  // --set overrides the same way.
  const DaemonOptions set = parse_config("", {"sensors[0].metadata=os.json"});
  EXPECT_EQ(set.sensors[0].source.data_port, 7502);
}

TEST(ConfigOuster, RulesBetweenModelMetadataAndCalibration) {
  test::expect_refused({
      {"sensors: [{model: os1-128}]", "sensors[0].metadata", "", "required for the Ouster model"},
      {"sensors: [{model: vlp32c, metadata: os.json}]", "sensors[0].model", "vlp32c",
       "is Velodyne's"},
      {"sensors: [{calibration: c.yaml, metadata: os.json}]", "sensors[0].calibration", "c.yaml",
       "is Velodyne's"},
      {"sensors: [{model: os3-64}]", "sensors[0].model", "os3-64", "Ouster: os0, os1, os2"},
      {"sensors: [{model: os1-96}]", "sensors[0].model", "os1-96", "with -16, -32, -64 or -128"},
      {"sensors: [{model: vlp64}]", "sensors[0].model", "vlp64", "expected auto or a model"},
  });
  // Options built in code obey the same rules.
  DaemonOptions built;
  built.sensors[0].ouster_model = "os0-32";
  EXPECT_THROW(validate(built), ConfigError);
  built.sensors[0].metadata = "os.json";
  EXPECT_NO_THROW(validate(built));
  built.sensors[0].ouster_model = "os3-32";  // not a model
  EXPECT_THROW(validate(built), ConfigError);
}

}  // namespace
}  // namespace lidartag::daemon
