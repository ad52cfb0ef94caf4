#include "lidartag/daemon/config.hpp"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <type_traits>
#include <utility>

#include "lidartag/detector/options.hpp"
#include "lidartag/driver/io/udp_frame.hpp"

namespace lidartag::daemon {

ConfigError::ConfigError(std::string key, std::string value, std::string reason)
    : std::runtime_error(fmt::format("{}: '{}': {}", key, value, reason)),
      key_(std::move(key)),
      value_(std::move(value)),
      reason_(std::move(reason)) {}

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

namespace {

// ---- Value checks: each returns the reason a value is bad, or an empty string. ----

struct Any {
  template <class T>
  std::string operator()(const T&) const {
    return {};
  }
};

template <class T>
auto at_least(T lo) {
  return [lo](auto v) { return v >= lo ? std::string() : fmt::format("must be >= {}", lo); };
}
template <class T>
auto above(T lo) {
  return [lo](auto v) { return v > lo ? std::string() : fmt::format("must be > {}", lo); };
}
template <class T>
auto closed(T lo, T hi) {
  return [lo, hi](auto v) {
    return v >= lo && v <= hi ? std::string() : fmt::format("must be in [{}, {}]", lo, hi);
  };
}
template <class T>
auto half_open(T lo, T hi) {
  return [lo, hi](auto v) {
    return v >= lo && v < hi ? std::string() : fmt::format("must be in [{}, {})", lo, hi);
  };
}
template <class T>
auto open_closed(T lo, T hi) {
  return [lo, hi](auto v) {
    return v > lo && v <= hi ? std::string() : fmt::format("must be in ({}, {}]", lo, hi);
  };
}
auto non_empty() {
  return [](const std::string& s) { return s.empty() ? std::string("must not be empty") : ""; };
}
auto ipv4_or_empty() {
  return [](const std::string& s) {
    uint32_t address = 0;
    return s.empty() || velodyne::parse_ipv4_address(s, address)
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

template <class T>
std::string to_text(const T& v) {
  if constexpr (std::is_same_v<T, bool>) {
    return v ? "true" : "false";
  } else if constexpr (std::is_same_v<T, std::string>) {
    return v;
  } else if constexpr (std::is_arithmetic_v<T>) {
    return fmt::format("{}", v);
  } else if constexpr (std::is_same_v<T, std::optional<velodyne::Model>>) {
    return v ? std::string(velodyne::model_spec(*v).name) : "auto";
  } else {
    std::string text = "[";
    for (size_t i = 0; i < v.size(); ++i) text += (i ? ", " : "") + to_text(v[i]);
    return text + "]";
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
  static void read(const std::string& name, const YAML::Node& n,
                   std::optional<velodyne::Model>& out) {
    const std::string text = scalar(name, n);
    if (text == "auto") {
      out.reset();
      return;
    }
    out = velodyne::model_from_name(text);
    if (!out) throw ConfigError(name, text, "expected auto or " + velodyne::model_names());
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

// Checks options built in code with the same rules.
class Checker {
 public:
  explicit Checker(std::string path) : path_(std::move(path)) {}

  template <class T, class Check = Any>
  void field(const char* key, T& value, Check check = {}, std::string_view /*unit*/ = {}) {
    const std::string name = join_key(path_, key);
    if constexpr (std::is_invocable_v<Check, const T&>) {
      if (std::string reason = check(value); !reason.empty()) {
        throw ConfigError(name, to_text(value), reason);
      }
    } else {
      for (size_t i = 0; i < value.size(); ++i) {
        if (std::string reason = check(value[i]); !reason.empty()) {
          throw ConfigError(fmt::format("{}[{}]", name, i), to_text(value[i]), reason);
        }
      }
    }
  }
  template <class E>
  void choice(const char*, E&, const Names<E>&) {}
  template <class F>
  void section(const char* key, F&& body) {
    Checker sub(join_key(path_, key));
    body(sub);
  }
  template <class T, class F>
  void list(const char* key, std::vector<T>& values, const T&, F&& body) {
    const std::string name = join_key(path_, key);
    if (values.empty()) throw ConfigError(name, "[]", "expected a non-empty list");
    for (size_t i = 0; i < values.size(); ++i) {
      Checker sub(fmt::format("{}[{}]", name, i));
      body(sub, values[i]);
    }
  }

 private:
  std::string path_;
};

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

template <class V>
void visit_sensor(V& v, SensorOptions& o) {
  v.field("name", o.name, non_empty());
  v.field("frame_id", o.frame_id, non_empty());
  v.field("channel_prefix", o.channel_prefix);
  v.field("model", o.model);
  v.field("calibration", o.calibration);
  v.field("cut_azimuth_deg", o.batcher.cut_azimuth_deg, half_open(0.0, 360.0));
  v.field("flush_timeout_s", o.batcher.flush_timeout_s, above(0.0));
  v.field("max_column_step_deg", o.batcher.max_column_step_deg, above(0.0));
  v.field("min_range_m", o.decoder.min_range_m, at_least(0.0));
  v.field("max_range_m", o.decoder.max_range_m, at_least(0.0));
  v.section("source", [&](V& s) {
    SourceOptions& src = o.source;
    s.choice("kind", src.kind, source_kinds());
    s.field("data_port", src.data_port, at_least(uint16_t{1}));
    s.field("position_port", src.position_port, at_least(uint16_t{1}));
    s.field("sensor_address", src.sensor_address, ipv4_or_empty());
    s.field("bind_address", src.bind_address, ipv4_or_empty());
    s.field("receive_buffer_bytes", src.receive_buffer_bytes, at_least(4096));
    s.field("interface", src.interface);
    s.field("promiscuous", src.promiscuous);
    s.field("file", src.file);
    s.field("rate", src.rate, at_least(0.0));
    s.field("loop", src.loop);
    s.field("channel", src.channel);
  });
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
      c.field("detections", o.lcm.channels.detections, non_empty());
      c.field("status", o.lcm.channels.status, non_empty());
      c.field("raw", o.lcm.channels.raw, non_empty());
      c.field("tag_points", o.lcm.channels.tag_points, non_empty());
      c.field("cloud", o.lcm.channels.cloud, non_empty());
    });
  });
  v.section("pipeline", [&](V& s) {
    s.field("worker_threads", o.pipeline.worker_threads, closed(0, 256));
    s.field("queue_depth", o.pipeline.queue_depth, closed(1, 1024));
    s.field("publish_queue", o.pipeline.publish_queue, closed(1, 1024));
    s.field("lossless_replay", o.pipeline.lossless_replay);
  });
  v.section("status", [&](V& s) { s.field("period_s", o.status.period_s, closed(0.01, 3600.0)); });
  v.section("watchdog", [&](V& s) {
    s.field("stall_timeout_s", o.watchdog.stall_timeout_s, closed(0.1, 3600.0));
  });
  v.section("logging", [&](V& s) {
    s.field("level", o.logging.level, log_level());
    s.field("file", o.logging.file);
    s.choice("journald", o.logging.journald, journal_modes());
  });
  v.field("record_pcap", o.record_pcap);
  v.section("detector", [&](V& s) { detector::visit_options(s, o.detector); });
  v.section("tracker", [&](V& s) { detector::visit_tracker_options(s, o.tracker); });
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
  check_detector(o.detector);
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
    value = YAML::Load(text);
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

YAML::Node load_yaml(std::string_view text, const std::string& origin) {
  try {
    return YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, "",
                      fmt::format("not valid YAML (line {}, column {}): {}", e.mark.line + 1,
                                  e.mark.column + 1, e.msg));
  }
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError("config", path, "cannot read the file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
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
  const YAML::Node root = load_yaml(read_file(path), "config " + path);
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
  Checker checker("");
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
