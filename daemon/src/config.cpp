#include "lidartag/daemon/config.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <type_traits>
#include <utility>

#include "lidartag/detector/options.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/ouster/packet.hpp"
#include "lidartag/driver/sources/model_name.hpp"

namespace lidartag::daemon {

namespace {
// Lengths of the parts of a ConfigError's line: a value is shown up to ~80 characters, the key and
// the reason (which may quote a value) a little longer.
constexpr size_t kShownValue = 80, kShownKey = 120, kShownReason = 240;
}  // namespace

ConfigError::ConfigError(std::string key, std::string value, std::string reason)
    : std::runtime_error(fmt::format("{}: '{}': {}", clip_text(key, kShownKey),
                                     clip_text(value, kShownValue),
                                     clip_text(reason, kShownReason))),
      key_(std::move(key)),
      value_(std::move(value)),
      reason_(std::move(reason)) {}

ConfigError::ConfigError(std::string key, std::string reason)
    : std::runtime_error(
          fmt::format("{}: {}", clip_text(key, kShownKey), clip_text(reason, kShownReason))),
      key_(std::move(key)),
      reason_(std::move(reason)) {}

std::string clip_text(std::string_view text, size_t max) {
  std::string out;
  size_t shown = 0;  // characters of `out`
  size_t i = 0;
  for (; i < text.size() && shown < max; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7F) {
      out += fmt::format("\\x{:02x}", c);
    } else {
      out += static_cast<char>(c);
      // A UTF-8 sequence counts once and is never cut: its (at most 3) continuation bytes follow.
      for (int k = 0;
           k < 3 && i + 1 < text.size() && (static_cast<unsigned char>(text[i + 1]) & 0xC0) == 0x80;
           ++k) {
        out += text[++i];
      }
    }
    ++shown;
  }
  if (i < text.size()) out += fmt::format("... ({} bytes)", text.size());
  return out;
}

std::string_view source_kind_name(SourceKind kind) {
  switch (kind) {
    case SourceKind::kUdp:
      return "udp";
    case SourceKind::kInterface:
      return "interface";
    case SourceKind::kPcap:
      return "pcap";
    case SourceKind::kLcm:
      return "lcm";
  }
  return "?";
}

std::string channel_of(const SensorOptions& sensor, const std::string& channel) {
  return sensor.channel_prefix + channel;
}

const BodyMount& mount_of(const DaemonOptions& options, const SensorOptions& sensor) {
  return sensor.sensor_in_body ? *sensor.sensor_in_body : options.ego_motion.sensor_in_body;
}

namespace {

// ---- Value checks: each returns the reason a value is bad, or an empty string. ----

using namespace ::lidartag::rules;  // the project's one vocabulary of rules

// Text that reaches log lines, channel names and systemd's STATUS=: printable ASCII only (a
// newline or an escape sequence in a sensor's name once went raw into the log).
auto printable(bool allow_empty) {
  return [allow_empty](const std::string& s) {
    if (s.empty() && !allow_empty) return std::string("must not be empty");
    for (const char c : s) {
      if (c < 0x20 || c > 0x7E) {
        return fmt::format("must be printable ASCII (holds byte 0x{:02x})",
                           static_cast<unsigned char>(c));
      }
    }
    return std::string();
  };
}
// A replay's speed factor: 0 (as fast as possible) or 1/1000 to 1000 times the recorded pace
// (1e-300 once overflowed the schedule and replayed at full speed).
auto replay_rate() {
  return [](double v) {
    return v == 0.0 || (v >= 1e-3 && v <= 1e3)
               ? std::string()
               : std::string("must be 0 (as fast as possible) or in [0.001, 1000]");
  };
}
auto ipv4_or_empty() {
  return [](const std::string& s) {
    uint32_t address = 0;
    return s.empty() || driver::parse_ipv4_address(s, address)
               ? std::string()
               : std::string("not an IPv4 address (dotted quad)");
  };
}
auto log_level() {
  return [](const std::string& s) {
    static const std::set<std::string> levels = {"trace", "debug",    "info", "warn",
                                                 "error", "critical", "off"};
    return levels.count(s)
               ? std::string()
               : std::string("expected trace, debug, info, warn, error, critical or off");
  };
}

// Named values of an enum field.
template <class E>
using Names = std::vector<std::pair<std::string, E>>;

template <class E>
std::string names_text(const Names<E>& names) {
  std::string text;
  for (size_t i = 0; i < names.size(); ++i) {
    text += (i == 0 ? "" : (i + 1 == names.size() ? " or " : ", ")) + names[i].first;
  }
  return text;
}

Names<SourceKind> source_kinds() {
  return {{"udp", SourceKind::kUdp},
          {"interface", SourceKind::kInterface},
          {"pcap", SourceKind::kPcap},
          {"lcm", SourceKind::kLcm}};
}
Names<JournalMode> journal_modes() {
  return {{"auto", JournalMode::kAuto},
          {"always", JournalMode::kAlways},
          {"never", JournalMode::kNever}};
}
// ---- Text form of values (the printer, and the value quoted in errors). ----

// A value as text (the printer, and the value quoted in errors): the rules' value_text, and a
// model by its name.
// The `model` key: a Velodyne model, an Ouster model name or auto (SensorOptions::model and
// ouster_model).
struct ModelKey {
  std::optional<velodyne::Model>* velodyne;
  std::string* ouster;
};

template <class T>
std::string to_text(const T& v) {
  if constexpr (std::is_same_v<T, ModelKey>) {
    return v.ouster->empty() ? to_text(*v.velodyne) : *v.ouster;
  } else if constexpr (std::is_same_v<T, std::optional<velodyne::Model>>) {
    return v ? std::string(velodyne::model_spec(*v).name) : "auto";
  } else {
    return value_text(v);
  }
}

std::string node_text(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "";
  if (node.IsScalar()) return node.Scalar();
  YAML::Emitter out;
  out << YAML::Flow << node;
  std::string text = out.c_str();
  for (char& c : text) {
    if (c == '\n') c = ' ';
  }
  return text;
}

// ---- Scalar parsing, strict: the whole text must be the value. ----

template <class T>
bool parse_number(const std::string& text, T& out) {
  if constexpr (std::is_floating_point_v<T>) {
    double v = 0;
    const char* end = text.data() + text.size();
    auto [p, ec] = std::from_chars(text.data(), end, v);
    if (ec != std::errc() || p != end || !std::isfinite(v)) return false;
    if (std::fabs(v) > static_cast<double>(std::numeric_limits<T>::max())) return false;
    out = static_cast<T>(v);
    return true;
  } else {
    long long v = 0;
    const char* end = text.data() + text.size();
    auto [p, ec] = std::from_chars(text.data(), end, v);
    if (ec != std::errc() || p != end) return false;
    if (!std::in_range<T>(v)) return false;
    out = static_cast<T>(v);
    return true;
  }
}

std::string join_key(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// ---- The visitors. Every option is listed once, in visit() below, for all three. ----

// Reads a YAML map into the options, checking every value and rejecting unknown keys.
class Reader {
 public:
  Reader(YAML::Node node, std::string path) : node_(std::move(node)), path_(std::move(path)) {
    if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
      throw ConfigError(path_.empty() ? "config" : path_, node_text(node_),
                        "expected a map of keys");
    }
  }

  template <class T, class Check = Any>
  void field(const char* key, T& value, Check check = {}, std::string_view /*unit*/ = {}) {
    const YAML::Node n = take(key);
    if (!n.IsDefined()) return;
    const std::string name = join_key(path_, key);
    T parsed = value;
    read(name, n, parsed);
    if constexpr (std::is_invocable_v<Check, const T&>) {
      if (std::string reason = check(parsed); !reason.empty()) {
        throw ConfigError(name, node_text(n), reason);
      }
    } else {
      // A check on each element of a list: the error names the element.
      for (size_t i = 0; i < parsed.size(); ++i) {
        if (std::string reason = check(parsed[i]); !reason.empty()) {
          throw ConfigError(fmt::format("{}[{}]", name, i), node_text(n[i]), reason);
        }
      }
    }
    value = std::move(parsed);
  }

  template <class E>
  void choice(const char* key, E& value, const Names<E>& names) {
    const YAML::Node n = take(key);
    if (!n.IsDefined()) return;
    const std::string name = join_key(path_, key);
    const std::string text = scalar(name, n);
    for (const auto& [label, v] : names) {
      if (label == text) {
        value = v;
        return;
      }
    }
    throw ConfigError(name, text, "expected " + names_text(names));
  }

  template <class F>
  void section(const char* key, F&& body) {
    Reader sub(take(key), join_key(path_, key));
    body(sub);
    sub.finish();
  }

  // A section that may be absent: given (even empty), `value` holds its settings, each from its
  // default; absent, `value` is left as it is.
  template <class T, class F>
  void optional_section(const char* key, std::optional<T>& value, F&& body) {
    const YAML::Node n = take(key);
    if (!n.IsDefined()) return;
    T parsed = value.value_or(T{});
    Reader sub(n, join_key(path_, key));
    body(sub, parsed);
    sub.finish();
    value = parsed;
  }

  // A list of maps; each element starts from `prototype`.
  template <class T, class F>
  void list(const char* key, std::vector<T>& values, const T& prototype, F&& body) {
    const YAML::Node n = take(key);
    if (!n.IsDefined()) return;
    const std::string name = join_key(path_, key);
    if (!n.IsSequence() || n.size() == 0) {
      throw ConfigError(name, node_text(n), "expected a non-empty list");
    }
    std::vector<T> parsed;
    for (size_t i = 0; i < n.size(); ++i) {
      T item = prototype;
      Reader sub(n[i], fmt::format("{}[{}]", name, i));
      body(sub, item);
      sub.finish();
      parsed.push_back(std::move(item));
    }
    values = std::move(parsed);
  }

  void finish() const {
    if (!node_.IsDefined() || node_.IsNull()) return;
    for (const auto& kv : node_) {
      const std::string key = kv.first.Scalar();
      if (!seen_.count(key)) {
        throw ConfigError(join_key(path_, key), node_text(kv.second), "unknown key");
      }
    }
  }

 private:
  YAML::Node take(const char* key) {
    seen_.insert(key);
    if (!node_.IsDefined() || node_.IsNull()) return YAML::Node(YAML::NodeType::Undefined);
    const YAML::Node n = node_[key];
    return n;
  }

  static std::string scalar(const std::string& name, const YAML::Node& n) {
    if (n.IsNull()) return "";
    if (!n.IsScalar()) throw ConfigError(name, node_text(n), "expected a single value");
    return n.Scalar();
  }

  static void read(const std::string& name, const YAML::Node& n, bool& out) {
    const std::string text = scalar(name, n);
    if (text == "true") {
      out = true;
    } else if (text == "false") {
      out = false;
    } else {
      throw ConfigError(name, text, "expected true or false");
    }
  }
  static void read(const std::string& name, const YAML::Node& n, std::string& out) {
    out = scalar(name, n);
  }
  template <class T>
  requires std::is_arithmetic_v<T>
  static void read(const std::string& name, const YAML::Node& n, T& out) {
    const std::string text = scalar(name, n);
    if (!parse_number(text, out)) {
      if constexpr (std::is_floating_point_v<T>) {
        throw ConfigError(name, text, "expected a number");
      } else {
        throw ConfigError(
            name, text,
            fmt::format("expected an integer in [{}, {}]", std::numeric_limits<T>::min(),
                        std::numeric_limits<T>::max()));
      }
    }
  }
  static void read(const std::string& name, const YAML::Node& n, ModelKey& out) {
    const std::string text = scalar(name, n);
    if (text == "auto") {
      out.velodyne->reset();
      out.ouster->clear();
      return;
    }
    // The names every front end takes (driver::model_from_name: any case, "VLP-32C", "OS1-128").
    const auto model = driver::model_from_name(text);
    if (!model) throw ConfigError(name, text, "expected auto or a model: " + driver::model_names());
    *out.velodyne = model->velodyne;
    *out.ouster = model->ouster;
  }
  template <class T>
  static void read(const std::string& name, const YAML::Node& n, std::vector<T>& out) {
    if (!n.IsSequence()) throw ConfigError(name, node_text(n), "expected a list");
    out.clear();
    for (size_t i = 0; i < n.size(); ++i) {
      T v{};
      read(fmt::format("{}[{}]", name, i), n[i], v);
      out.push_back(std::move(v));
    }
  }

  YAML::Node node_;
  std::string path_;
  std::set<std::string> seen_;
};

// Options built in code are checked with the same table and rules (rules::RuleChecker).
[[noreturn]] void config_error(const std::string& key, const std::string& value,
                               const std::string& reason) {
  throw ConfigError(key, value, reason);
}

// Emits the options as YAML.
class Printer {
 public:
  explicit Printer(YAML::Emitter& out) : out_(out) {}

  template <class T, class Check = Any>
  void field(const char* key, T& value, Check = {}, std::string_view /*unit*/ = {}) {
    out_ << YAML::Key << key << YAML::Value;
    if constexpr (std::is_same_v<T, std::string>) {
      out_ << YAML::DoubleQuoted << value;
    } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
      out_ << YAML::Flow << YAML::BeginSeq;
      for (const auto& v : value) out_ << YAML::DoubleQuoted << v;
      out_ << YAML::EndSeq;
    } else if constexpr (std::is_same_v<T, std::vector<double>>) {
      out_ << YAML::Flow << YAML::BeginSeq;
      for (const auto& v : value) out_ << to_text(v);
      out_ << YAML::EndSeq;
    } else {
      out_ << to_text(value);
    }
  }
  template <class E>
  void choice(const char* key, E& value, const Names<E>& names) {
    for (const auto& [label, v] : names) {
      if (v == value) out_ << YAML::Key << key << YAML::Value << label;
    }
  }
  template <class F>
  void section(const char* key, F&& body) {
    out_ << YAML::Key << key << YAML::Value << YAML::BeginMap;
    body(*this);
    out_ << YAML::EndMap;
  }
  template <class T, class F>
  void optional_section(const char* key, std::optional<T>& value, F&& body) {
    if (!value) return;
    out_ << YAML::Key << key << YAML::Value << YAML::BeginMap;
    body(*this, *value);
    out_ << YAML::EndMap;
  }
  template <class T, class F>
  void list(const char* key, std::vector<T>& values, const T&, F&& body) {
    out_ << YAML::Key << key << YAML::Value << YAML::BeginSeq;
    for (auto& v : values) {
      out_ << YAML::BeginMap;
      body(*this, v);
      out_ << YAML::EndMap;
    }
    out_ << YAML::EndSeq;
  }

 private:
  YAML::Emitter& out_;
};

// ---- The mapping: every key of config/lidartagd.yaml, with its rule. ----

// The detector's section is the detector library's own rule table (detector::visit_options): the
// same keys, units and rules for the daemon, `lidartag detect --config` and options built in code.

// The LiDAR's pose on the body (ego_motion.sensor_in_body, sensors[].sensor_in_body).
template <class V>
void visit_mount(V& m, BodyMount& b) {
  m.field("x", b.x, closed(-1000.0, 1000.0));
  m.field("y", b.y, closed(-1000.0, 1000.0));
  m.field("z", b.z, closed(-1000.0, 1000.0));
  m.field("roll_deg", b.roll_deg, closed(-360.0, 360.0));
  m.field("pitch_deg", b.pitch_deg, closed(-360.0, 360.0));
  m.field("yaw_deg", b.yaw_deg, closed(-360.0, 360.0));
}

template <class V>
void visit_sensor(V& v, SensorOptions& o) {
  v.field("name", o.name, printable(false));
  v.field("frame_id", o.frame_id, printable(false));
  v.field("channel_prefix", o.channel_prefix, printable(true));
  ModelKey model{&o.model, &o.ouster_model};
  v.field("model", model);
  v.field("calibration", o.calibration);
  v.field("metadata", o.metadata);
  if constexpr (std::is_same_v<V, Reader>) {
    // An Ouster sensor's ports are its own unless the entry names others (read next).
    if (!o.metadata.empty()) {
      o.source.data_port = driver::ouster::kLidarPort;
      o.source.position_port = driver::ouster::kImuPort;
    }
  }
  driver::visit_batcher_options(v, o.batcher);  // the driver's own tables, at this level
  velodyne::visit_decoder_options(v, o.decoder);
  v.section("source", [&](V& s) {
    SourceOptions& src = o.source;
    s.choice("kind", src.kind, source_kinds());
    s.field("data_port", src.data_port, at_least(uint16_t{1}));
    s.field("position_port", src.position_port, at_least(uint16_t{1}));
    s.field("sensor_address", src.sensor_address, ipv4_or_empty());
    s.field("bind_address", src.bind_address, ipv4_or_empty());
    s.field("share_port", src.share_port);
    s.field("receive_buffer_bytes", src.receive_buffer_bytes, at_least(4096));
    s.field("interface", src.interface);
    s.field("promiscuous", src.promiscuous);
    s.field("file", src.file);
    s.field("topic", src.topic, printable(true));
    s.field("rate", src.rate, replay_rate());
    s.field("loop", src.loop);
    s.field("start", src.start, at_least(0.0), "s");
    s.field("duration", src.duration, at_least(0.0), "s");
    s.field("channel", src.channel);
  });
  // Given: this LiDAR's own mount; absent (and not printed): ego_motion.sensor_in_body.
  v.optional_section("sensor_in_body", o.sensor_in_body,
                     [](V& m, BodyMount& b) { visit_mount(m, b); });
}

template <class V>
void visit(V& v, DaemonOptions& o) {
  v.list("sensors", o.sensors, SensorOptions{},
         [](V& s, SensorOptions& sensor) { visit_sensor(s, sensor); });
  v.section("lcm", [&](V& s) {
    s.field("url", o.lcm.url);
    s.field("publish_raw", o.lcm.publish_raw);
    s.field("publish_tag_points", o.detector.keep_tag_points);
    s.field("cloud_decimation", o.lcm.cloud_decimation, at_least(0));
    s.section("channels", [&](V& c) {
      c.field("detections", o.lcm.channels.detections, printable(false));
      c.field("status", o.lcm.channels.status, printable(false));
      c.field("raw", o.lcm.channels.raw, printable(false));
      c.field("tag_points", o.lcm.channels.tag_points, printable(false));
      c.field("cloud", o.lcm.channels.cloud, printable(false));
    });
  });
  v.section("pipeline", [&](V& s) {
    // Each worker and queue slot holds a rotation (and each worker a detector): on a VLS-128 the
    // former maxima (256, 1024, 1024) took 6 GB and 19 s before the first publication.
    s.field("worker_threads", o.pipeline.worker_threads, closed(0, 128));
    s.field("queue_depth", o.pipeline.queue_depth, closed(1, 64));
    s.field("publish_queue", o.pipeline.publish_queue, closed(1, 64));
    s.field("lossless_replay", o.pipeline.lossless_replay);
  });
  v.section("status", [&](V& s) { s.field("period_s", o.status.period_s, closed(0.01, 3600.0)); });
  v.section("watchdog", [&](V& s) {
    s.field("stall_timeout_s", o.watchdog.stall_timeout_s, closed(0.1, 3600.0));
    s.field("while_silent", o.watchdog.while_silent);
  });
  v.section("health", [&](V& s) {
    s.field("startup_grace_s", o.health.startup_grace_s, closed(0.0, 86400.0));
    s.field("silence_s", o.health.silence_s, closed(0.01, 3600.0));
    s.field("window_s", o.health.window_s, closed(0.1, 3600.0));
    s.field("max_loss", o.health.max_loss, closed(0.0, 1.0));
    s.field("min_rpm", o.health.min_rpm, closed(0.0, 10000.0));
    s.field("max_rpm", o.health.max_rpm, closed(0.0, 10000.0));
    s.field("max_rotation_ratio", o.health.max_rotation_ratio, closed(1.0, 1000.0));
  });
  v.section("logging", [&](V& s) {
    s.field("level", o.logging.level, log_level());
    s.field("file", o.logging.file);
    s.choice("journald", o.logging.journald, journal_modes());
  });
  v.field("record_pcap", o.record_pcap);
  v.section("detector", [&](V& s) { detector::visit_options(s, o.detector); });
  v.section("tracker", [&](V& s) { detector::visit_tracker_options(s, o.tracker); });
  v.section("ego_motion", [&](V& s) {
    EgoMotionConfig& e = o.ego_motion;
    s.field("channel", e.channel, printable(true));
    s.field("url", e.url);
    detector::visit_ego_motion_options(s, e.buffer);
    s.field("stale_s", e.stale_s, closed(0.001, 3600.0));
    s.section("sensor_in_body", [&](V& m) { visit_mount(m, e.sensor_in_body); });
  });
}

// The detector's rules (each field's, also on options built in code, and those between fields),
// as a ConfigError naming the key under `detector.`.
void check_detector(const detector::DetectorOptions& o) {
  try {
    detector::validate_options(o);
  } catch (const detector::OptionsError& e) {
    throw ConfigError(e.key().empty() ? std::string("detector") : "detector." + e.key(), e.value(),
                      e.reason());
  }
}

// Rules between fields, after each field passed its own.
void check_relations(const DaemonOptions& o) {
  std::set<std::string> names, prefixes;
  for (size_t i = 0; i < o.sensors.size(); ++i) {
    const SensorOptions& s = o.sensors[i];
    const std::string key = fmt::format("sensors[{}]", i);
    if (!names.insert(s.name).second) {
      throw ConfigError(key + ".name", s.name, "another sensor has this name");
    }
    if (!prefixes.insert(s.channel_prefix).second) {
      throw ConfigError(key + ".channel_prefix", s.channel_prefix,
                        "another sensor has this prefix (their channels would collide)");
    }
    if (s.decoder.max_range_m > 0 && s.decoder.max_range_m <= s.decoder.min_range_m) {
      throw ConfigError(key + ".max_range_m", to_text(s.decoder.max_range_m),
                        "must be 0 (the model's limit) or above min_range_m");
    }
    if (s.decoder.max_range_m == 0) {
      // Against the model's own limit (with model auto, the farthest-seeing model's): above it,
      // every return would be dropped without a word.
      double limit = 0;
      for (const velodyne::Model m : velodyne::all_models()) {
        if (!s.model || *s.model == m) limit = std::max(limit, velodyne::model_spec(m).max_range_m);
      }
      if (s.decoder.min_range_m >= limit) {
        throw ConfigError(key + ".min_range_m", to_text(s.decoder.min_range_m),
                          fmt::format("must be below the model's maximum range ({} m)", limit));
      }
    }
    if (!s.ouster_model.empty() && !driver::ouster::is_model_name(s.ouster_model)) {
      throw ConfigError(key + ".model", s.ouster_model,
                        "expected a lower-case Ouster model name (os1-128; the configuration "
                        "file takes any case)");
    }
    if (!s.ouster_model.empty() && s.metadata.empty()) {
      throw ConfigError(key + ".metadata", s.metadata,
                        fmt::format("required for the Ouster model {} (the sensor's metadata "
                                    "JSON describes its beams, mode and packets)",
                                    s.ouster_model));
    }
    if (!s.metadata.empty() && (s.model || !s.calibration.empty())) {
      throw ConfigError(key + (s.model ? ".model" : ".calibration"),
                        s.model ? to_text(s.model) : s.calibration,
                        "is Velodyne's, but the sensor has Ouster metadata (sensors[].metadata)");
    }
    const SourceOptions& src = s.source;
    const std::string kind(source_kind_name(src.kind));
    if (src.data_port == src.position_port) {
      throw ConfigError(key + ".source.position_port", to_text(src.position_port),
                        "must differ from data_port");
    }
    if ((src.kind == SourceKind::kPcap || src.kind == SourceKind::kLcm) && src.file.empty()) {
      throw ConfigError(key + ".source.file", src.file, "required for source kind " + kind);
    }
    if (src.kind == SourceKind::kInterface && src.interface.empty()) {
      throw ConfigError(key + ".source.interface", src.interface,
                        "required for source kind interface");
    }
  }
  // Each channel carries one type (a subscriber decodes by channel).
  const auto& ch = o.lcm.channels;
  const std::array<std::pair<const char*, const std::string*>, 5> channels = {
      {{"detections", &ch.detections},
       {"status", &ch.status},
       {"raw", &ch.raw},
       {"tag_points", &ch.tag_points},
       {"cloud", &ch.cloud}}};
  for (size_t i = 1; i < channels.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (*channels[i].second == *channels[j].second) {
        throw ConfigError(fmt::format("lcm.channels.{}", channels[i].first), *channels[i].second,
                          fmt::format("same as lcm.channels.{}", channels[j].first));
      }
    }
  }
  // Across sensors too: a prefix and another sensor's channel name can meet (prefix "A" with
  // channel "X" is "AX", another sensor's channel "AX" with no prefix).
  std::map<std::string, std::string> used;
  for (size_t i = 0; i < o.sensors.size(); ++i) {
    for (const auto& [what, base] : channels) {
      const std::string full = channel_of(o.sensors[i], *base);
      const std::string who = fmt::format("sensors[{}]'s {} channel", i, what);
      const auto [it, inserted] = used.emplace(full, who);
      if (!inserted) {
        throw ConfigError(fmt::format("sensors[{}].channel_prefix", i), o.sensors[i].channel_prefix,
                          fmt::format("makes its {} channel '{}', which is {} (each channel "
                                      "carries one message type of one sensor)",
                                      what, full, it->second));
      }
    }
  }
  if (o.health.max_rpm <= o.health.min_rpm) {
    throw ConfigError("health.max_rpm", to_text(o.health.max_rpm), "must be above health.min_rpm");
  }
  check_detector(o.detector);
}

// Walks the parse events of a document (before yaml-cpp builds nodes, which keep the first of two
// equal keys and drop the second silently) to reject a key given twice in one mapping and a second
// document. Events, not nodes: aliases stay single events, so shared subtrees are visited once.
class KeyChecker final : public YAML::EventHandler {
 public:
  // `origin` names the text in messages; `base` is the key path of its top level ("" for a file).
  KeyChecker(std::string origin, std::string base)
      : origin_(std::move(origin)), base_(std::move(base)) {}

  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents_ > 1) {
      throw ConfigError(origin_, fmt::format("a second YAML document (line {}): one document "
                                             "holds the whole configuration",
                                             mark.line + 1));
    }
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { node(mark, "~"); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { node(mark, nullptr); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                const std::string& value) override {
    node(mark, value.c_str());
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    push(node(mark, nullptr), false);
  }
  void OnSequenceEnd() override { frames_.pop_back(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    push(node(mark, nullptr), true);
  }
  void OnMapEnd() override { frames_.pop_back(); }

 private:
  struct Frame {
    std::string path;
    bool map = false;
    bool want_key = true;
    size_t index = 0;                 // sequences: the next element's index
    std::string key;                  // maps: the key whose value comes next
    std::map<std::string, int> keys;  // maps: each key and its line
  };

  void push(std::string path, bool map) {
    Frame& f = frames_.emplace_back();
    f.path = std::move(path);
    f.map = map;
  }

  // Places a node in its parent (a key or a value of a map, an element of a sequence) and returns
  // its path. `scalar`: the text of a scalar node, null for collections and aliases.
  std::string node(const YAML::Mark& mark, const char* scalar) {
    if (frames_.empty()) return base_;
    Frame& f = frames_.back();
    if (!f.map) return fmt::format("{}[{}]", f.path, f.index++);
    if (!f.want_key) {
      f.want_key = true;
      return join_key(f.path, f.key);
    }
    f.want_key = false;
    f.key = scalar != nullptr ? scalar : "?";  // a collection or alias as a key: no name
    const std::string path = join_key(f.path, f.key);
    if (scalar != nullptr) {
      const int line = mark.line + 1;
      const auto [it, inserted] = f.keys.emplace(f.key, line);
      if (!inserted) {
        throw ConfigError(
            path, fmt::format("duplicate key (lines {} and {} of {})", it->second, line, origin_));
      }
    }
    return path;
  }

  std::string origin_, base_;
  int documents_ = 0;
  std::vector<Frame> frames_;
};

// Parses one YAML document after the KeyChecker's pass. Throws YAML::Exception or ConfigError.
YAML::Node parse_yaml(std::string_view text, const std::string& origin, const std::string& base) {
  const std::string copy(text);
  std::istringstream in(copy);
  YAML::Parser parser(in);
  KeyChecker checker(origin, base);
  while (parser.HandleNextDocument(checker)) {
  }
  return YAML::Load(copy);
}

YAML::Node load_yaml(std::string_view text, const std::string& origin) {
  try {
    return parse_yaml(text, origin, "");
  } catch (const YAML::DeepRecursion& e) {
    throw ConfigError(origin,
                      fmt::format("not valid YAML (line {}): nested too deeply", e.mark.line + 1));
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, fmt::format("not valid YAML (line {}, column {}): {}",
                                          e.mark.line + 1, e.mark.column + 1, e.msg));
  }
}

// "a.b[2].c" -> the node, created when missing (a list index may be one past the end: append).
YAML::Node locate(YAML::Node root, const std::string& path, const std::string& text) {
  YAML::Node node;
  node.reset(root);
  std::stringstream parts(path);
  std::string part;
  while (std::getline(parts, part, '.')) {
    std::optional<size_t> index;
    if (const auto open = part.find('['); open != std::string::npos) {
      size_t i = 0;
      const std::string digits = part.substr(open + 1, part.size() - open - 2);
      if (part.back() != ']' || !parse_number(digits, i)) {
        throw ConfigError(path, text, "bad index in key (expected NAME[N])");
      }
      index = i;
      part = part.substr(0, open);
    }
    if (part.empty()) throw ConfigError(path, text, "empty key");
    if (node.IsDefined() && !node.IsNull() && !node.IsMap()) {
      throw ConfigError(path, text, "'" + part + "' is inside a value that is not a map");
    }
    YAML::Node child = node[part];
    node.reset(child);
    if (index) {
      if (!node.IsDefined() || node.IsNull()) node = YAML::Node(YAML::NodeType::Sequence);
      if (!node.IsSequence() || *index > node.size()) {
        throw ConfigError(path, text, "no such list element");
      }
      if (*index == node.size()) node.push_back(YAML::Node(YAML::NodeType::Map));
      YAML::Node element = node[*index];
      node.reset(element);
    }
  }
  return node;
}

void apply_override(YAML::Node& root, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ConfigError("--set", assignment, "expected KEY=VALUE (e.g. lcm.url=memq://)");
  }
  const std::string key = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  YAML::Node value;
  try {
    value = parse_yaml(text, "--set " + key, key);
  } catch (const YAML::Exception& e) {
    throw ConfigError(key, text, "not a YAML value: " + e.msg);
  }
  if (!root.IsDefined() || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  YAML::Node target = locate(root, key, text);
  target = value;
}

DaemonOptions map_document(YAML::Node root) {
  DaemonOptions options;
  Reader reader(root, "");
  visit(reader, options);
  reader.finish();
  check_relations(options);
  return options;
}

// What a path that is not a regular file is, for the message.
std::string file_kind(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

// A regular file of at most kMaxConfigBytes, read with bounded memory. Opened without blocking (a
// FIFO would wait for a writer) and checked on the open descriptor (no race with a rename).
std::string read_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    throw ConfigError("config", path, std::string("cannot read the file: ") + std::strerror(errno));
  }
  const std::unique_ptr<int, void (*)(int*)> closer(new int(fd), [](int* f) {
    ::close(*f);
    delete f;
  });
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    throw ConfigError("config", path, std::string("cannot read the file: ") + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode)) {
    throw ConfigError("config", path, "not a regular file (" + file_kind(st.st_mode) + ")");
  }
  const std::string limit =
      fmt::format("larger than the limit of {} bytes (1 MiB)", kMaxConfigBytes);
  if (static_cast<uint64_t>(st.st_size) > kMaxConfigBytes) {
    throw ConfigError("config", path, fmt::format("{} bytes: {}", st.st_size, limit));
  }
  // The size may be wrong (a file still growing, /proc): read at most one byte past the limit.
  std::string text(kMaxConfigBytes + 1, '\0');
  size_t got = 0;
  while (got < text.size()) {
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      throw ConfigError("config", path,
                        std::string("cannot read the file: ") + std::strerror(errno));
    }
    if (n == 0) break;
    got += static_cast<size_t>(n);
  }
  if (got > kMaxConfigBytes) throw ConfigError("config", path, "grew while read: " + limit);
  text.resize(got);
  return text;
}

}  // namespace

DaemonOptions parse_config(std::string_view yaml, const std::vector<std::string>& overrides) {
  YAML::Node root = load_yaml(yaml, "config");
  for (const auto& o : overrides) apply_override(root, o);
  return map_document(root);
}

DaemonOptions load_config(const std::string& path, const std::vector<std::string>& overrides) {
  YAML::Node root = load_yaml(read_file(path), "config " + path);
  for (const auto& o : overrides) apply_override(root, o);
  return map_document(root);
}

detector::DetectorOptions load_detector_config(const std::string& path) {
  return parse_detector_config(read_file(path), "config " + path);
}

detector::DetectorOptions parse_detector_config(std::string_view yaml, const std::string& origin) {
  const YAML::Node root = load_yaml(yaml, origin);
  if (root.IsDefined() && !root.IsNull() && !root.IsMap()) {
    throw ConfigError("config", node_text(root), "expected a map of keys");
  }
  DaemonOptions options;
  Reader reader(root.IsMap() ? root["detector"] : YAML::Node(), "detector");
  detector::visit_options(reader, options.detector);
  reader.finish();
  check_detector(options.detector);
  return options.detector;
}

void validate(const DaemonOptions& options) {
  DaemonOptions copy = options;
  RuleChecker checker("", config_error);
  visit(checker, copy);
  check_relations(copy);
}

std::string print_config(const DaemonOptions& options) {
  DaemonOptions copy = options;
  YAML::Emitter out;
  out << YAML::BeginMap;
  Printer printer(out);
  visit(printer, copy);
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace lidartag::daemon
