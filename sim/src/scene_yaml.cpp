// The one place where scene YAML becomes option structs. Every key is checked: unknown keys and
// bad values throw SceneError naming the key path (e.g. "tags[1].board.margin").
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <initializer_list>
#include <sstream>

#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

NoiseOptions NoiseOptions::ideal() {
  NoiseOptions n;
  n.range_sigma_m = 0.0;
  n.intensity_sigma = 0.0;
  n.divergence_h_mrad = 0.0;
  n.divergence_v_mrad = 0.0;
  n.footprint_samples = 1;
  n.depth_edge_missing = 0.0;
  n.depth_edge_mixed = 0.0;
  n.intensity_edge_missing = 0.0;
  n.dropout = 0.0;
  n.detect_reflectivity_10m = 0.0;
  return n;
}

NoiseOptions noise_defaults(velodyne::Model model) {
  NoiseOptions n;
  n.range_sigma_m = model == velodyne::Model::kHDL32E ? 0.02 : 0.015;
  return n;
}

std::string_view clutter_kind_name(ClutterKind kind) {
  switch (kind) {
    case ClutterKind::kLab:
      return "lab";
    case ClutterKind::kOutdoor:
      return "outdoor";
    case ClutterKind::kParking:
      return "parking";
  }
  return "unknown";
}

std::string_view board_kind_name(BoardKind kind) {
  switch (kind) {
    case BoardKind::kCheckerboard:
      return "checkerboard";
    case BoardKind::kHoles:
      return "holes";
    case BoardKind::kStrips:
      return "strips";
    case BoardKind::kSign:
      return "sign";
  }
  return "unknown";
}

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& why) {
  throw SceneError(path + ": " + why);
}

std::string join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

void check_map(const YAML::Node& node, const std::string& path,
               std::initializer_list<const char*> allowed) {
  if (!node.IsMap()) fail(path.empty() ? "scene" : path, "expected a mapping of keys");
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    bool ok = false;
    for (const char* a : allowed) ok = ok || key == a;
    if (ok) continue;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    fail(join(path, key), "unknown key (expected one of: " + list + ")");
  }
}

double as_double(const YAML::Node& n, const std::string& path) {
  if (!n.IsScalar()) fail(path, "expected a number");
  double v = 0.0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    fail(path, "expected a number, got '" + n.Scalar() + "'");
  }
  if (!std::isfinite(v)) fail(path, "must be finite");
  return v;
}

// Reads key `key` of `node` into `out` when present, checking lo <= value <= hi.
void read(const YAML::Node& node, const std::string& path, const char* key, double& out,
          double lo = -1e12, double hi = 1e12) {
  const YAML::Node n = node[key];
  if (!n) return;
  const std::string p = join(path, key);
  const double v = as_double(n, p);
  if (v < lo || v > hi) {
    std::ostringstream why;
    why << v << " is outside [" << lo << ", " << hi << "]";
    fail(p, why.str());
  }
  out = v;
}

void read(const YAML::Node& node, const std::string& path, const char* key, int& out, int lo,
          int hi) {
  double v = out;
  read(node, path, key, v, lo, hi);
  if (v != std::floor(v)) fail(join(path, key), "expected a whole number");
  out = static_cast<int>(v);
}

void read(const YAML::Node& node, const std::string& path, const char* key, bool& out) {
  const YAML::Node n = node[key];
  if (!n) return;
  try {
    if (!n.IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "");
    out = n.as<bool>();
  } catch (const YAML::Exception&) {
    fail(join(path, key), "expected true or false");
  }
}

void read(const YAML::Node& node, const std::string& path, const char* key, uint64_t& out) {
  const YAML::Node n = node[key];
  if (!n) return;
  const std::string p = join(path, key);
  const std::string s = n.IsScalar() ? n.Scalar() : std::string();
  if (s.empty() || s.size() > 19 || s.find_first_not_of("0123456789") != std::string::npos)
    fail(p, "expected a non-negative whole number");
  out = std::stoull(s);
}

template <size_t N>
void read(const YAML::Node& node, const std::string& path, const char* key,
          std::array<double, N>& out) {
  const YAML::Node n = node[key];
  if (!n) return;
  const std::string p = join(path, key);
  if (!n.IsSequence() || n.size() != N)
    fail(p, "expected a list of " + std::to_string(N) + " numbers");
  for (size_t i = 0; i < N; ++i) out[i] = as_double(n[i], p + "[" + std::to_string(i) + "]");
}

std::string read_string(const YAML::Node& node, const std::string& path, const char* key,
                        const std::string& fallback) {
  const YAML::Node n = node[key];
  if (!n) return fallback;
  if (!n.IsScalar()) fail(join(path, key), "expected a string");
  return n.Scalar();
}

void read_reflectivity(const YAML::Node& node, const std::string& path, const char* key,
                       double& out) {
  read(node, path, key, out, 0.0, 255.0);
}

void parse_noise(const YAML::Node& node, const std::string& path, NoiseOptions& n) {
  if (node.IsScalar()) {
    if (node.Scalar() == "none" || node.Scalar() == "ideal") {
      n = NoiseOptions::ideal();
      return;
    }
    fail(path, "expected a mapping or 'none'");
  }
  check_map(node, path,
            {"range_sigma_m", "intensity_sigma", "divergence_h_mrad", "divergence_v_mrad",
             "footprint_samples", "echo_separation_m", "depth_edge_m", "depth_edge_missing",
             "depth_edge_mixed", "intensity_edge", "intensity_edge_missing", "dropout",
             "detect_reflectivity_10m", "min_range_m", "max_range_m"});
  read(node, path, "range_sigma_m", n.range_sigma_m, 0.0, 1.0);
  read(node, path, "intensity_sigma", n.intensity_sigma, 0.0, 100.0);
  read(node, path, "divergence_h_mrad", n.divergence_h_mrad, 0.0, 50.0);
  read(node, path, "divergence_v_mrad", n.divergence_v_mrad, 0.0, 50.0);
  read(node, path, "footprint_samples", n.footprint_samples, 1, 9);
  if (n.footprint_samples != 1 && n.footprint_samples != 5 && n.footprint_samples != 9)
    fail(join(path, "footprint_samples"), "must be 1, 5 or 9");
  read(node, path, "echo_separation_m", n.echo_separation_m, 0.0, 100.0);
  read(node, path, "depth_edge_m", n.depth_edge_m, 0.0, 100.0);
  read(node, path, "depth_edge_missing", n.depth_edge_missing, 0.0, 1.0);
  read(node, path, "depth_edge_mixed", n.depth_edge_mixed, 0.0, 1.0);
  read(node, path, "intensity_edge", n.intensity_edge, 0.0, 255.0);
  read(node, path, "intensity_edge_missing", n.intensity_edge_missing, 0.0, 1.0);
  read(node, path, "dropout", n.dropout, 0.0, 1.0);
  read(node, path, "detect_reflectivity_10m", n.detect_reflectivity_10m, 0.0, 100.0);
  read(node, path, "min_range_m", n.min_range_m, 0.0, 1000.0);
  read(node, path, "max_range_m", n.max_range_m, 0.0, 1000.0);
  if (n.max_range_m > 0.0 && n.max_range_m <= n.min_range_m)
    fail(join(path, "max_range_m"), "must be larger than min_range_m");
}

// An Ouster model's keys: `lidar_mode` (COLUMNSxRATE) and `profile`; the Velodyne-only keys
// are refused.
void parse_ouster(const YAML::Node& node, const std::string& path, driver::ouster::Model model,
                  SensorOptions& s) {
  for (const char* key :
       {"rpm", "return_mode", "cut_azimuth_deg", "position_packets", "position_rate_hz"})
    if (node[key]) fail(join(path, key), "not for an Ouster model (its lidar_mode sets the rate)");
  OusterSensorOptions o;
  o.model = model;
  const std::string mode = read_string(node, path, "lidar_mode", "1024x10");
  int columns = 0, rate = 0;
  char x = 0;
  std::istringstream in(mode);
  const bool parsed = (in >> columns >> x >> rate) && x == 'x' && in.eof();
  const bool known = ((columns == 512 || columns == 1024) && (rate == 10 || rate == 20)) ||
                     (columns == 2048 && rate == 10);
  if (!parsed || !known)
    fail(join(path, "lidar_mode"),
         "unknown lidar mode '" + mode + "' (512x10, 512x20, 1024x10, 1024x20, 2048x10)");
  o.columns = columns;
  o.rate_hz = rate;
  const std::string profile = read_string(node, path, "profile", "rng19");
  using driver::ouster::Profile;
  if (profile == "rng19" || profile == "RNG19_RFL8_SIG16_NIR16")
    o.profile = Profile::kRng19Rfl8Sig16Nir16;
  else if (profile == "legacy" || profile == "LEGACY")
    o.profile = Profile::kLegacy;
  else if (profile == "rng19_dual" || profile == "RNG19_RFL8_SIG16_NIR16_DUAL")
    o.profile = Profile::kRng19Rfl8Sig16Nir16Dual;
  else if (profile == "rng15" || profile == "RNG15_RFL8_NIR8")
    o.profile = Profile::kRng15Rfl8Nir8;
  else if (profile == "fusa_dual" || profile == "FUSA_RNG15_RFL8_NIR8_DUAL")
    o.profile = Profile::kFusaRng15Rfl8Nir8Dual;
  else
    fail(join(path, "profile"),
         "unknown profile '" + profile + "' (rng19, rng19_dual, legacy, rng15, fusa_dual)");
  s.ouster = o;
  s.noise = NoiseOptions{};
}

void parse_sensor(const YAML::Node& node, const std::string& path, SensorOptions& s) {
  check_map(node, path,
            {"model", "rpm", "return_mode", "position", "height", "roll_deg", "pitch_deg",
             "yaw_deg", "velocity", "angular_velocity", "start_time_s", "cut_azimuth_deg",
             "position_packets", "position_rate_hz", "noise", "lidar_mode", "profile"});
  const std::string model =
      read_string(node, path, "model", std::string(velodyne::model_spec(s.model).name));
  const auto m = velodyne::model_from_name(model);
  const auto ouster = driver::ouster::model_from_name(model);
  if (!m && !ouster)
    fail(join(path, "model"), "unknown model '" + model + "' (one of: " + velodyne::model_names() +
                                  ", " + driver::ouster::model_names() + ")");
  if (ouster) {
    parse_ouster(node, path, *ouster, s);
  } else {
    for (const char* key : {"lidar_mode", "profile"})
      if (node[key]) fail(join(path, key), "only for an Ouster model (" + model + " is not one)");
    s.model = *m;
    s.ouster.reset();
    s.noise = noise_defaults(s.model);
  }
  read(node, path, "rpm", s.rpm, 300.0, 1200.0);
  const std::string mode = read_string(node, path, "return_mode", "strongest");
  if (mode == "strongest")
    s.return_mode = velodyne::ReturnMode::kStrongest;
  else if (mode == "last")
    s.return_mode = velodyne::ReturnMode::kLast;
  else if (mode == "dual")
    s.return_mode = velodyne::ReturnMode::kDual;
  else
    fail(join(path, "return_mode"), "unknown return mode '" + mode + "' (strongest, last, dual)");
  read(node, path, "position", s.position);
  read(node, path, "height", s.height, -1000.0, 1000.0);
  read(node, path, "roll_deg", s.roll_deg, -180.0, 180.0);
  read(node, path, "pitch_deg", s.pitch_deg, -90.0, 90.0);
  read(node, path, "yaw_deg", s.yaw_deg, -360.0, 360.0);
  read(node, path, "velocity", s.velocity);
  read(node, path, "angular_velocity", s.angular_velocity);
  read(node, path, "start_time_s", s.start_time_s, 0.0, 4102444800.0);  // before 2100
  read(node, path, "cut_azimuth_deg", s.cut_azimuth_deg, 0.0, 359.99);
  read(node, path, "position_packets", s.position_packets);
  read(node, path, "position_rate_hz", s.position_rate_hz, 0.1, 10000.0);
  if (node["noise"]) parse_noise(node["noise"], join(path, "noise"), s.noise);
}

void parse_world(const YAML::Node& node, const std::string& path, WorldOptions& w) {
  check_map(node, path,
            {"ground", "ground_reflectivity", "room", "walls", "boxes", "cylinders", "clutter"});
  read(node, path, "ground", w.ground);
  read_reflectivity(node, path, "ground_reflectivity", w.ground_reflectivity);
  if (const YAML::Node r = node["room"]) {
    const std::string p = join(path, "room");
    check_map(r, p, {"center", "size", "height", "yaw_deg", "reflectivity", "ceiling"});
    w.room.enabled = true;
    read(r, p, "center", w.room.center);
    read(r, p, "size", w.room.size);
    if (w.room.size[0] <= 0.0 || w.room.size[1] <= 0.0) fail(join(p, "size"), "must be positive");
    read(r, p, "height", w.room.height, 0.1, 1000.0);
    read(r, p, "yaw_deg", w.room.yaw_deg, -360.0, 360.0);
    read_reflectivity(r, p, "reflectivity", w.room.reflectivity);
    read(r, p, "ceiling", w.room.ceiling);
  }
  auto list = [&](const char* key) {
    const YAML::Node n = node[key];
    if (n && !n.IsSequence()) fail(join(path, key), "expected a list");
    return n;
  };
  if (const YAML::Node walls = list("walls")) {
    for (size_t i = 0; i < walls.size(); ++i) {
      const std::string p = join(path, "walls") + "[" + std::to_string(i) + "]";
      WallOptions wo;
      check_map(walls[i], p, {"from", "to", "height", "thickness", "reflectivity"});
      if (!walls[i]["from"] || !walls[i]["to"]) fail(p, "needs 'from' and 'to'");
      read(walls[i], p, "from", wo.from);
      read(walls[i], p, "to", wo.to);
      if (wo.from == wo.to) fail(join(p, "to"), "must differ from 'from'");
      read(walls[i], p, "height", wo.height, 0.01, 1000.0);
      read(walls[i], p, "thickness", wo.thickness, 0.001, 100.0);
      read_reflectivity(walls[i], p, "reflectivity", wo.reflectivity);
      w.walls.push_back(wo);
    }
  }
  if (const YAML::Node boxes = list("boxes")) {
    for (size_t i = 0; i < boxes.size(); ++i) {
      const std::string p = join(path, "boxes") + "[" + std::to_string(i) + "]";
      BoxOptions b;
      check_map(boxes[i], p, {"center", "size", "yaw_deg", "reflectivity"});
      read(boxes[i], p, "center", b.center);
      read(boxes[i], p, "size", b.size);
      for (double v : b.size)
        if (v <= 0.0) fail(join(p, "size"), "must be positive");
      read(boxes[i], p, "yaw_deg", b.yaw_deg, -360.0, 360.0);
      read_reflectivity(boxes[i], p, "reflectivity", b.reflectivity);
      w.boxes.push_back(b);
    }
  }
  if (const YAML::Node cyl = list("cylinders")) {
    for (size_t i = 0; i < cyl.size(); ++i) {
      const std::string p = join(path, "cylinders") + "[" + std::to_string(i) + "]";
      CylinderOptions c;
      check_map(cyl[i], p, {"base", "radius", "height", "reflectivity"});
      read(cyl[i], p, "base", c.base);
      read(cyl[i], p, "radius", c.radius, 0.001, 100.0);
      read(cyl[i], p, "height", c.height, 0.001, 1000.0);
      read_reflectivity(cyl[i], p, "reflectivity", c.reflectivity);
      w.cylinders.push_back(c);
    }
  }
  if (const YAML::Node c = node["clutter"]) {
    const std::string p = join(path, "clutter");
    check_map(c, p, {"kind", "seed", "count", "region", "clearance"});
    w.clutter.enabled = true;
    const std::string kind = read_string(c, p, "kind", "lab");
    if (kind == "lab")
      w.clutter.kind = ClutterKind::kLab;
    else if (kind == "outdoor")
      w.clutter.kind = ClutterKind::kOutdoor;
    else if (kind == "parking")
      w.clutter.kind = ClutterKind::kParking;
    else
      fail(join(p, "kind"), "unknown clutter kind '" + kind + "' (lab, outdoor, parking)");
    read(c, p, "seed", w.clutter.seed);
    read(c, p, "count", w.clutter.count, 0, 10000);
    read(c, p, "region", w.clutter.region);
    if (w.clutter.region[0] >= w.clutter.region[1] || w.clutter.region[2] >= w.clutter.region[3])
      fail(join(p, "region"), "expected [xmin, xmax, ymin, ymax] with min < max");
    read(c, p, "clearance", w.clutter.clearance, 0.0, 100.0);
  }
}

// "diamond", "square" or degrees, into `out`.
void read_rotation(const YAML::Node& node, const std::string& path, double& out) {
  const YAML::Node r = node["rotation"];
  if (!r) return;
  const std::string p = join(path, "rotation");
  if (r.IsScalar() && r.Scalar() == "diamond") {
    out = 45.0;
  } else if (r.IsScalar() && r.Scalar() == "square") {
    out = 0.0;
  } else {
    out = as_double(r, p);
    if (std::abs(out) > 360.0) fail(p, "expected diamond, square or degrees");
  }
}

void parse_stand(const YAML::Node& node, const std::string& path, StandOptions& stand) {
  const YAML::Node s = node["stand"];
  if (!s) return;
  const std::string p = join(path, "stand");
  if (s.IsScalar()) {
    read(node, path, "stand", stand.enabled);
  } else {
    check_map(s, p, {"width", "reflectivity"});
    stand.enabled = true;
    read(s, p, "width", stand.width, 0.005, 10.0);
    read_reflectivity(s, p, "reflectivity", stand.reflectivity);
  }
}

void parse_tag(const YAML::Node& node, const std::string& path, TagOptions& t) {
  check_map(node, path,
            {"family", "id", "size", "center", "normal", "rotation", "board", "stand",
             "white_reflectivity", "black_reflectivity", "retro_reflective"});
  t.family = read_string(node, path, "family", t.family);
  read(node, path, "id", t.id, 0, 1 << 30);
  if (!node["size"]) fail(path, "needs 'size' (full outer size of the marker, metres)");
  read(node, path, "size", t.size, 0.01, 100.0);
  if (!node["center"]) fail(path, "needs 'center' ([x, y, z], metres)");
  read(node, path, "center", t.center);
  read(node, path, "normal", t.normal);
  read_rotation(node, path, t.rotation_deg);
  if (const YAML::Node b = node["board"]) {
    const std::string p = join(path, "board");
    check_map(b, p, {"thickness", "margin", "reflectivity"});
    read(b, p, "thickness", t.board.thickness, 0.001, 10.0);
    read(b, p, "margin", t.board.margin, 0.0, 10.0);
    read_reflectivity(b, p, "reflectivity", t.board.reflectivity);
  }
  parse_stand(node, path, t.stand);
  bool retro = false;
  read(node, path, "retro_reflective", retro);
  if (retro) t.white_reflectivity = 200.0;  // retro-reflective sheet: 101..255 on the wire
  read_reflectivity(node, path, "white_reflectivity", t.white_reflectivity);
  read_reflectivity(node, path, "black_reflectivity", t.black_reflectivity);
}

void parse_board(const YAML::Node& node, const std::string& path, CalibrationBoardOptions& b) {
  check_map(node, path,
            {"kind", "center", "normal", "rotation", "size", "thickness", "reflectivity",
             "dark_reflectivity", "stand", "inner_corners", "square_m", "holes", "strips",
             "strip_width_m", "vertical_strips", "strip_reflectivity", "border_m", "text_lines",
             "text_seed"});
  const std::string kind = read_string(node, path, "kind", "checkerboard");
  if (kind == "checkerboard")
    b.kind = BoardKind::kCheckerboard;
  else if (kind == "holes")
    b.kind = BoardKind::kHoles;
  else if (kind == "strips")
    b.kind = BoardKind::kStrips;
  else if (kind == "sign")
    b.kind = BoardKind::kSign;
  else
    fail(join(path, "kind"),
         "unknown board kind '" + kind + "' (checkerboard, holes, strips, sign)");
  if (!node["center"]) fail(path, "needs 'center' ([x, y, z], metres)");
  read(node, path, "center", b.center);
  read(node, path, "normal", b.normal);
  read_rotation(node, path, b.rotation_deg);
  read(node, path, "size", b.size);
  for (double v : b.size)
    if (!(v >= 0.01 && v <= 100.0)) fail(join(path, "size"), "each side must be in [0.01, 100] m");
  read(node, path, "thickness", b.thickness, 0.001, 10.0);
  read_reflectivity(node, path, "reflectivity", b.reflectivity);
  read_reflectivity(node, path, "dark_reflectivity", b.dark_reflectivity);
  parse_stand(node, path, b.stand);
  if (const YAML::Node ic = node["inner_corners"]) {
    std::array<double, 2> v{};
    read(node, path, "inner_corners", v);
    for (size_t i = 0; i < 2; ++i) {
      if (v[i] != std::floor(v[i]) || v[i] < 1 || v[i] > 100)
        fail(join(path, "inner_corners"), "expected two whole numbers in [1, 100]");
      b.inner_corners[i] = static_cast<int>(v[i]);
    }
  }
  read(node, path, "square_m", b.square_m, 0.001, 10.0);
  if (b.kind == BoardKind::kCheckerboard &&
      ((b.inner_corners[0] + 1) * b.square_m > b.size[0] + 1e-9 ||
       (b.inner_corners[1] + 1) * b.square_m > b.size[1] + 1e-9))
    fail(join(path, "square_m"), "the squares do not fit on the board ('size')");
  if (const YAML::Node h = node["holes"]) {
    const std::string p = join(path, "holes");
    if (!h.IsSequence()) fail(p, "expected a list of [y, z, radius]");
    for (size_t i = 0; i < h.size(); ++i) {
      const std::string pi = p + "[" + std::to_string(i) + "]";
      if (!h[i].IsSequence() || h[i].size() != 3) fail(pi, "expected [y, z, radius]");
      std::array<double, 3> c{};
      for (size_t k = 0; k < 3; ++k) c[k] = as_double(h[i][k], pi);
      if (!(c[2] > 0.0) || std::abs(c[0]) + c[2] > b.size[0] / 2 ||
          std::abs(c[1]) + c[2] > b.size[1] / 2)
        fail(pi, "a hole must have a positive radius and lie on the board");
      b.holes.push_back(c);
    }
  }
  if (b.kind == BoardKind::kHoles && b.holes.empty())
    fail(path, "kind 'holes' needs 'holes' ([[y, z, radius], ...], metres)");
  read(node, path, "strips", b.strips, 1, 100);
  read(node, path, "strip_width_m", b.strip_width_m, 0.001, 10.0);
  read(node, path, "vertical_strips", b.vertical_strips);
  read_reflectivity(node, path, "strip_reflectivity", b.strip_reflectivity);
  if (b.kind == BoardKind::kStrips &&
      b.strips * b.strip_width_m > (b.vertical_strips ? b.size[0] : b.size[1]))
    fail(join(path, "strips"), "the strips do not fit on the board ('size')");
  read(node, path, "border_m", b.border_m, 0.0, 10.0);
  if (b.kind == BoardKind::kSign && 2 * b.border_m >= std::min(b.size[0], b.size[1]))
    fail(join(path, "border_m"), "the border leaves no face");
  read(node, path, "text_lines", b.text_lines, 0, 20);
  read(node, path, "text_seed", b.text_seed);
}

calib::Distortion parse_distortion(const std::string& name, const std::string& path) {
  if (name == "none" || name == "pinhole") return calib::Distortion::kNone;
  if (name == "plumb_bob" || name == "radtan") return calib::Distortion::kPlumbBob;
  if (name == "equidistant" || name == "fisheye") return calib::Distortion::kEquidistant;
  fail(path, "unknown distortion model '" + name + "' (expected none, plumb_bob, equidistant)");
}

void parse_camera(const YAML::Node& node, const std::string& path, CameraOptions& c) {
  check_map(node, path,
            {"width", "height", "fx", "fy", "cx", "cy", "skew", "distortion_model",
             "distortion_coefficients", "rotation_wxyz", "translation_m", "noise_sigma",
             "blur_sigma", "supersample", "gain", "background"});
  calib::CameraModel& m = c.model;
  read(node, path, "width", m.width, 1, 16384);
  read(node, path, "height", m.height, 1, 16384);
  // Principal point: the image centre unless given.
  m.cx = (m.width - 1) / 2.0;
  m.cy = (m.height - 1) / 2.0;
  read(node, path, "fx", m.fx, 1e-3, 1e6);
  m.fy = m.fx;
  read(node, path, "fy", m.fy, 1e-3, 1e6);
  read(node, path, "cx", m.cx, -1e6, 1e6);
  read(node, path, "cy", m.cy, -1e6, 1e6);
  read(node, path, "skew", m.skew, -1e6, 1e6);
  m.distortion = parse_distortion(read_string(node, path, "distortion_model", "none"),
                                  join(path, "distortion_model"));
  if (const YAML::Node d = node["distortion_coefficients"]) {
    const std::string p = join(path, "distortion_coefficients");
    if (!d.IsSequence() || d.size() > 5) fail(p, "expected a list of at most 5 numbers");
    m.d = {};
    for (size_t i = 0; i < d.size(); ++i)
      m.d[i] = as_double(d[i], p + "[" + std::to_string(i) + "]");
  }
  try {
    m.check();
  } catch (const calib::CameraModelError& e) {
    fail(path, e.what());
  }
  read(node, path, "rotation_wxyz", c.rotation_wxyz);
  const double qn =
      std::sqrt(c.rotation_wxyz[0] * c.rotation_wxyz[0] + c.rotation_wxyz[1] * c.rotation_wxyz[1] +
                c.rotation_wxyz[2] * c.rotation_wxyz[2] + c.rotation_wxyz[3] * c.rotation_wxyz[3]);
  if (qn < 1e-9) fail(join(path, "rotation_wxyz"), "must not be zero");
  for (double& q : c.rotation_wxyz) q /= qn;
  read(node, path, "translation_m", c.translation_m);
  read(node, path, "noise_sigma", c.noise_sigma, 0.0, 100.0);
  read(node, path, "blur_sigma", c.blur_sigma, 0.0, 20.0);
  read(node, path, "supersample", c.supersample, 1, 8);
  read(node, path, "gain", c.gain, 0.0, 100.0);
  read(node, path, "background", c.background, 0.0, 255.0);
}

}  // namespace

calib::CameraModel CameraOptions::default_model() {
  calib::CameraModel m;
  m.width = 1280;
  m.height = 720;
  m.fx = m.fy = 900.0;
  m.cx = 639.5;
  m.cy = 359.5;
  return m;
}

std::array<double, 4> CameraOptions::forward_wxyz() {
  // Rows of R: x_c = -y_l, y_c = -z_l, z_c = x_l; its quaternion (w, x, y, z).
  return {0.5, 0.5, -0.5, 0.5};
}

Scene parse_scene(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw SceneError(source + ": invalid YAML: " + e.what());
  }
  Scene scene;
  try {
    if (!root || root.IsNull()) fail("scene", "empty");
    check_map(root, "",
              {"sensor", "camera", "world", "tags", "boards", "series", "seed", "rotations"});
    scene.sensor.noise = noise_defaults(scene.sensor.model);
    if (root["sensor"]) parse_sensor(root["sensor"], "sensor", scene.sensor);
    if (root["world"]) parse_world(root["world"], "world", scene.world);
    if (root["camera"]) parse_camera(root["camera"], "camera", scene.camera.emplace());
    if (const YAML::Node tags = root["tags"]) {
      if (!tags.IsSequence()) fail("tags", "expected a list");
      if (tags.size() > 100) fail("tags", "at most 100 tags");
      for (size_t i = 0; i < tags.size(); ++i) {
        TagOptions t;
        parse_tag(tags[i], "tags[" + std::to_string(i) + "]", t);
        scene.tags.push_back(t);
      }
    }
    if (const YAML::Node boards = root["boards"]) {
      if (!boards.IsSequence()) fail("boards", "expected a list");
      if (boards.size() > 100) fail("boards", "at most 100 boards");
      for (size_t i = 0; i < boards.size(); ++i) {
        CalibrationBoardOptions b;
        parse_board(boards[i], "boards[" + std::to_string(i) + "]", b);
        scene.boards.push_back(b);
      }
    }
    if (const YAML::Node series = root["series"]) {
      if (!series.IsSequence()) fail("series", "expected a list of tag poses");
      if (series.size() > 1000) fail("series", "at most 1000 poses");
      if (scene.tags.empty()) fail("series", "moves the first tag: give 'tags'");
      for (size_t i = 0; i < series.size(); ++i) {
        const std::string p = "series[" + std::to_string(i) + "]";
        check_map(series[i], p, {"center", "normal", "rotation"});
        if (!series[i]["center"]) fail(p, "needs 'center' ([x, y, z], metres)");
        TagPose pose;
        pose.normal = scene.tags[0].normal;
        pose.rotation_deg = scene.tags[0].rotation_deg;
        read(series[i], p, "center", pose.center);
        read(series[i], p, "normal", pose.normal);
        read_rotation(series[i], p, pose.rotation_deg);
        scene.series.push_back(pose);
      }
    }
    read(root, "", "seed", scene.seed);
    read(root, "", "rotations", scene.rotations, 1, 100000);
  } catch (const SceneError& e) {
    throw SceneError(source + ": " + e.what());
  } catch (const YAML::Exception& e) {
    throw SceneError(source + ": " + e.what());
  }
  return scene;
}

Scene series_scene(const Scene& scene, size_t index) {
  Scene out = scene;
  out.series.clear();
  const TagPose& pose = scene.series.at(index);
  TagOptions& tag = out.tags.at(0);
  tag.center = pose.center;
  tag.normal = pose.normal;
  tag.rotation_deg = pose.rotation_deg;
  return out;
}

Scene load_scene(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw SceneError("cannot open scene file '" + path + "'");
  std::stringstream text;
  text << in.rdbuf();
  return parse_scene(text.str(), path);
}

}  // namespace lidartag::sim
