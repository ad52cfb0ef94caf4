// The one vocabulary of point-cloud field names: which field of another driver's cloud gives each
// column the detector reads (x y z intensity ring time, and lidartag's own azimuth and
// return_type), and the rule that turns a cloud's point times, in whatever unit, into seconds. Used
// alike by the sensor_msgs/PointCloud2 reader (driver/bag/messages.hpp) and the PCD reader
// (driver/velodyne/io/pcd.hpp), so that a cloud reads the same from a bag and from a PCD file.
// Header only, bytes-free: a reader lists its fields (name, integer or floating) and reads a field
// as a column of doubles on request. docs/bags.md "Point clouds of other drivers" is the table.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lidartag::driver {

// Names of the ring field, the first present wins: lidartag, Velodyne, Hesai, RoboSense and
// Ouster write `ring`, Autoware's nebula `channel`, Luminar `laser_id`, Livox `line` (its laser
// line; the detector checks that a ring field's rings are level, see detector/cloud_scan.hpp).
inline constexpr std::array<std::string_view, 4> kRingFieldNames = {"ring", "channel", "laser_id",
                                                                    "line"};
// Names of a per-point time field, the first present wins: lidartag and Velodyne `time`, Ouster
// `t`, `time_offset`, Hesai and RoboSense `timestamp`, nebula `time_stamp`, Livox's custom
// point `offset_time`. (A pair `time_sec` + `time_nsec` comes before all of them.)
inline constexpr std::array<std::string_view, 6> kTimeFieldNames = {
    "time", "t", "time_offset", "timestamp", "time_stamp", "offset_time"};
// Fields read by their own name only.
inline constexpr std::array<std::string_view, 6> kPlainFieldNames = {
    "x", "y", "z", "intensity", "azimuth", "return_type"};

// No LiDAR sweep lasts this long (seconds): a floating time field spanning more in one cloud counts
// nanoseconds, and times beyond it are absolute.
inline constexpr double kLongestSweepS = 1000.0;

// A field of a cloud as its reader describes it.
struct CloudSourceField {
  std::string_view name;
  bool integer = false;  // an integer type (its times count ns)
};

// A cloud's points as columns named as the detector's clouds name them (detector/cloud_scan.hpp's
// kCloudFieldNames): x, y, z, intensity, azimuth, return_type by those names; `ring` from the
// first of kRingFieldNames present; `time` (seconds, time_to_seconds's rule) from the pair
// time_sec + time_nsec or the first of kTimeFieldNames present. Fields the cloud lacks are left
// out. `source` names, for each column, the cloud field it came from.
struct CloudColumns {
  std::vector<std::string> names;
  std::vector<std::string> source;
  std::vector<std::vector<double>> columns;
  size_t width = 0, height = 1;
};

// Point times into seconds, in place; `integer`: the field is of an integer type. The rule:
//  - units: integer times count nanoseconds (Ouster's `t`, Livox's `offset_time`); floating ones
//    are seconds, unless their span in this one cloud is beyond any sweep's (kLongestSweepS: Livox
//    writes ns since the epoch in a double), then nanoseconds;
//  - origin: times already offsets within a sweep (every finite time in [0, kLongestSweepS)) are
//    kept, as the cloud's stamp is their origin; absolute times (seconds since the epoch, Hesai
//    and RoboSense) and negative ones (Velodyne's ROS driver: relative to the last packet) become
//    seconds from the cloud's earliest point. `absolute`: the times are absolute by construction
//    (time_sec + time_nsec): always made relative to the earliest.
// Non-finite times stay as they are.
inline void time_to_seconds(std::vector<double>& time, bool integer, bool absolute = false) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const double v : time)
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  if (!(lo <= hi)) return;  // no finite time
  if (integer || hi - lo > kLongestSweepS) {
    for (double& v : time) v *= 1e-9;
    lo *= 1e-9;
    hi *= 1e-9;
  }
  if (absolute || lo < 0.0 || hi >= kLongestSweepS)
    for (double& v : time) v -= lo;
}

// The columns of a cloud whose fields are `fields`; `read(k, column)` fills `column` with field
// k's values, one per point (the reader's own bytes: PointCloud2 or PCD). `out` is cleared first;
// its width and height are the caller's to set.
template <class Read>
void cloud_columns_of(std::span<const CloudSourceField> fields, Read&& read, CloudColumns& out) {
  out.names.clear();
  out.source.clear();
  out.columns.clear();
  const auto find = [&](std::string_view name) -> const CloudSourceField* {
    for (const CloudSourceField& f : fields)
      if (f.name == name) return &f;
    return nullptr;
  };
  const auto index = [&](const CloudSourceField* f) { return static_cast<size_t>(f - &fields[0]); };
  const auto add = [&](std::string_view name, const CloudSourceField& f) {
    out.names.emplace_back(name);
    out.source.emplace_back(f.name);
    out.columns.emplace_back();
    read(index(&f), out.columns.back());
  };
  for (const std::string_view name : kPlainFieldNames)
    if (const CloudSourceField* f = find(name)) add(name, *f);
  for (const std::string_view name : kRingFieldNames) {
    if (const CloudSourceField* f = find(name)) {
      add("ring", *f);
      break;
    }
  }
  const CloudSourceField* sec = find("time_sec");
  const CloudSourceField* nsec = find("time_nsec");
  if (sec && nsec) {
    std::vector<double> s, ns;
    read(index(sec), s);
    read(index(nsec), ns);
    // Seconds from the earliest whole second first: a double of ns since the epoch loses them.
    double s0 = std::numeric_limits<double>::infinity();
    for (const double v : s)
      if (std::isfinite(v)) s0 = std::min(s0, v);
    if (!std::isfinite(s0)) s0 = 0.0;
    for (size_t i = 0; i < s.size() && i < ns.size(); ++i) s[i] = (s[i] - s0) + ns[i] * 1e-9;
    time_to_seconds(s, false, true);
    out.names.emplace_back("time");
    out.source.emplace_back("time_sec+time_nsec");
    out.columns.push_back(std::move(s));
    return;
  }
  for (const std::string_view name : kTimeFieldNames) {
    if (const CloudSourceField* f = find(name)) {
      add("time", *f);
      time_to_seconds(out.columns.back(), f->integer);
      return;
    }
  }
}

}  // namespace lidartag::driver
