// `lidartag detect CAPTURE [--config FILE] [--json] [--tag-size M ...] [--family NAME ...]`: runs
// the LiDARTag detector on every rotation of a pcap, or on one PCD file, and prints what it found:
// a table by default, one JSON object per rotation with --json.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lidartag/bag_clouds.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/mcap_output.hpp"
#include "lidartag/progress.hpp"
#ifdef LIDARTAG_HAVE_CONFIG
#include "lidartag/daemon/config.hpp"
#endif

namespace lidartag::cli {
namespace {

namespace det = lidartag::detector;

struct DetectArgs {
  CaptureArgs capture;
  OusterArgs ouster;
  std::string config;
  bool json = false;
  bool partial = false;
  bool clusters = false;    // explain every cluster with enough features to be a tag
  bool no_tracker = false;  // every rotation alone
  bool deskew = false;      // each cluster's points moved to its centre time (the tracker's motion)
  std::vector<double> tag_sizes;
  std::vector<std::string> families;
  int rings = 0;                // PCD without a ring field and no --model: beams to estimate
  double resolution_deg = 0.0;  // PCD or PointCloud2: width of a column (0: the cloud's own)
  McapArgs mcap;                // --mcap: every rotation's cloud and detections for Foxglove
};

det::DetectorOptions detector_options(const DetectArgs& args) {
  det::DetectorOptions options;
  if (!args.config.empty()) {
#ifdef LIDARTAG_HAVE_CONFIG
    options = daemon::load_detector_config(args.config);
#else
    throw std::runtime_error("--config needs the lidartag_config library (daemon/), not built");
#endif
  }
  // Always on: the summary names the sizes measured of clusters rejected as the wrong size (the
  // per-cluster JSON only with --clusters).
  options.cluster_diagnostics = true;
  if (!args.tag_sizes.empty()) options.tag_sizes_m = args.tag_sizes;
  if (!args.families.empty()) options.families = args.families;
  if (args.deskew) options.deskew.enabled = true;
  return options;
}

// The `tracker:` section of --config (defaults without one); --no-tracker turns it off.
det::TrackerOptions tracker_options(const DetectArgs& args) {
  det::TrackerOptions options;
  if (!args.config.empty()) {
#ifdef LIDARTAG_HAVE_CONFIG
    options = daemon::load_config(args.config).tracker;
#endif
  }
  if (args.no_tracker) options.enabled = false;
  return options;
}

nlohmann::json vec(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

// Each ring's elevation, degrees (the median of a sample of its returns; NaN without any): how
// far apart the rings are at a cluster's range.
std::vector<double> ring_elevations_deg(const Scan& scan) {
  std::vector<double> out(static_cast<size_t>(scan.rings), std::nan(""));
  std::vector<double> e;
  const int step = std::max(1, scan.columns / 256);
  for (int ring = 0; ring < scan.rings; ++ring) {
    e.clear();
    for (int col = 0; col < scan.columns; col += step) {
      const size_t i = scan.at(0, ring, col);
      if (scan.range[i] <= 0) continue;
      e.push_back(std::atan2(scan.z[i], std::hypot(scan.x[i], scan.y[i])) * 180.0 /
                  std::numbers::pi);
    }
    if (e.empty()) continue;
    std::nth_element(e.begin(), e.begin() + static_cast<long>(e.size() / 2), e.end());
    out[static_cast<size_t>(ring)] = e[e.size() / 2];
  }
  return out;
}

// What a cluster dropped for too few rings or points lacked, against the bound that dropped it;
// empty for the other reasons (their measurements say it).
std::string lacked(const det::ClusterDiagnostic& c, const det::Detector& detector,
                   const std::vector<double>& elevation_deg) {
  const auto& o = detector.options();
  if (c.rejection == det::Rejection::kTooFewPoints)
    return fmt::format(
        "{} points, eq. (3) asks {} for the configured families ({} as a track's evidence)",
        c.points, detector.limits().min_points, detector.limits().min_track_points);
  if (c.rejection != det::Rejection::kFewFeatures) return {};
  const int rings = c.max_ring - c.min_ring + 1;
  std::string s =
      fmt::format("{} ring{} crossed it, {} feature{}; a cluster needs {} rings and {} features",
                  rings, rings == 1 ? "" : "s", c.features, c.features == 1 ? "" : "s",
                  o.validation.min_rings, o.validation.min_features);
  // The rings' spacing where it is: the next ring up (or down) from its top ring.
  const double range = std::hypot(0.5 * (c.min_x + c.max_x), 0.5 * (c.min_y + c.max_y));
  const auto e = [&](int ring) {
    return ring >= 0 && ring < static_cast<int>(elevation_deg.size())
               ? elevation_deg[static_cast<size_t>(ring)]
               : std::nan("");
  };
  double gap = e(c.max_ring + 1) - e(c.max_ring);
  if (!std::isfinite(gap)) gap = e(c.min_ring) - e(c.min_ring - 1);
  if (std::isfinite(gap) && gap > 0)
    s += fmt::format(
        "; the rings are {:.2f} m apart at {:.1f} m (lidartag plan: where this sensor "
        "sees a tag)",
        range * std::tan(gap * std::numbers::pi / 180.0), range);
  return s;
}

nlohmann::json cluster_json(size_t index, const det::ClusterDiagnostic& c,
                            const std::string& lacks) {
  nlohmann::json o;
  o["index"] = index;  // what `lidartag render --cluster` takes
  o["result"] = std::string(det::rejection_name(c.rejection));
  o["stage"] = std::string(det::rejection_stage(c.rejection));
  o["box"] = nlohmann::json::array({c.min_x, c.max_x, c.min_y, c.max_y});
  o["rings"] = nlohmann::json::array({c.min_ring, c.max_ring});
  o["features"] = c.features;
  o["points"] = c.points;
  o["boundary_points"] = c.boundary_points;
  const std::pair<const char*, double> measured[] = {
      {"outlier_ratio", c.outlier_ratio}, {"side_m", c.side_m}, {"mean_cost_m", c.mean_cost_m},
      {"coverage", c.coverage},           {"score", c.score},   {"margin", c.margin}};
  for (const auto& [key, value] : measured)
    if (value >= 0) o[key] = value;
  if (!lacks.empty()) o["lacked"] = lacks;
  return o;
}

nlohmann::json quaternion(const Eigen::Quaterniond& q) {
  return nlohmann::json::array({q.w(), q.x(), q.y(), q.z()});
}

nlohmann::json track_json(const det::TrackInfo& t) {
  nlohmann::json o;
  o["id"] = t.track_id;
  o["rotations"] = t.rotations;
  o["confirmed"] = t.confirmed;
  o["margin"] = t.margin_cells;
  o["mean_score"] = t.mean_score;
  o["window"] = t.window_rotations;
  o["position"] = vec(t.position);
  o["orientation"] = quaternion(t.orientation);
  o["position_std"] = vec(t.position_std_m);
  o["angle_std_deg"] = t.angle_std_deg;
  o["moving"] = t.moving;
  o["velocity"] = vec(t.velocity_mps);
  o["turn_deg_s"] = vec(t.turn_deg_s);
  return o;
}

// What a rotation reports: its detections, with their tracks when the tracker runs.
struct Reported {
  const det::ScanResult* result = nullptr;
  const det::TrackerResult* tracked = nullptr;  // null: tracker off
};

// The deskew's counts of a rotation's validated clusters (ScanResult): moved by the odometry,
// by the tracker's model, and left as fired for want of a motion (all 0 with the deskew off).
nlohmann::json deskew_json(const det::ScanResult& r, bool enabled) {
  nlohmann::json o;
  o["enabled"] = enabled;
  o["ego"] = r.deskewed_ego;
  o["model"] = r.deskewed_model;
  o["without_motion"] = r.deskew_without_motion;
  return o;
}

nlohmann::json rotation_json(const Scan& scan, const Reported& rep, const det::Detector& detector,
                             bool clusters) {
  const det::ScanResult& r = *rep.result;
  nlohmann::json j;
  j["sequence"] = scan.sequence;  // the rotation's number, as the daemon and Python give it
  j["stamp"] = static_cast<double>(scan.stamp_ns) * 1e-9;
  j["points"] = scan.point_count();
  j["features"] = r.features;
  j["clusters"] = r.clusters;
  j["deskew"] = deskew_json(r, detector.options().deskew.enabled);
  nlohmann::json dets = nlohmann::json::array();
  auto add = [&](const det::Detection& d, const det::TrackedDetection* t) {
    nlohmann::json o;
    o["family"] = std::string(d.family);
    o["id"] = d.id;
    o["size_m"] = d.size_m;
    o["position"] = vec(d.position);
    const auto& q = d.orientation;
    o["orientation"] = quaternion(q);
    nlohmann::json corners = nlohmann::json::array();
    for (const auto& c : d.corners) corners.push_back(vec(c));
    o["corners"] = corners;
    o["score"] = d.score;
    o["margin"] = d.margin;
    o["points"] = d.points;
    // When the beams crossed the tag, seconds after the rotation's stamp.
    o["time_first_s"] = d.time_first_s;
    o["time_center_s"] = d.time_center_s;
    o["time_last_s"] = d.time_last_s;
    // The size check: what the points say the marker measures (null: they do not tell it).
    o["measured_size_m"] =
        d.measured_size_m > 0 ? nlohmann::json(d.measured_size_m) : nlohmann::json(nullptr);
    o["size_warning"] = d.size_warning;
    // What moved its points to time_center_s before the fits: "none" (as fired), "ego", "model".
    o["deskew"] = std::string(det::deskew_source_name(d.deskew));
    if (t != nullptr) {
      o["decoded"] = t->decoded;
      if (t->track.track_id >= 0) o["track"] = track_json(t->track);
    }
    dets.push_back(o);
  };
  if (rep.tracked != nullptr) {
    for (const auto& t : rep.tracked->tags) add(t.detection, &t);
    j["tracks"] = rep.tracked->tracks;
    j["confirmed_tracks"] = rep.tracked->confirmed_tracks;
    if (rep.tracked->truncated) j["tracker_truncated"] = true;  // out of memory: incomplete
  } else {
    for (const auto& d : r.detections) add(d, nullptr);
  }
  j["detections"] = dets;
  nlohmann::json timing, rejected;
  for (int s = 0; s < det::kStageCount; ++s) {
    const auto stage = static_cast<det::Stage>(s);
    timing[std::string(det::stage_name(stage))] = r.timing_ms[static_cast<size_t>(s)];
    if (stage != det::Stage::kFeatures)
      rejected[std::string(det::stage_name(stage))] = r.rejected_at(stage);
  }
  if (rep.tracked != nullptr) timing["tracker"] = rep.tracked->time_ms;
  j["timing_ms"] = timing;
  j["rejected"] = rejected;
  if (clusters) {
    nlohmann::json list = nlohmann::json::array();
    const std::vector<double> elevation = ring_elevations_deg(scan);
    for (size_t i = 0; i < r.diagnostics.size(); ++i)
      if (worth_explaining(r.diagnostics[i], detector.options().tag_sizes_m))
        list.push_back(
            cluster_json(i, r.diagnostics[i], lacked(r.diagnostics[i], detector, elevation)));
    j["cluster_diagnostics"] = list;
  }
  return j;
}

void print_detection(const det::Detection& d, const det::TrackedDetection* t) {
  const auto& q = d.orientation;
  fmt::print(
      "  {:<9} id {:3d}  size {:.3f} m  position [{:8.3f} {:8.3f} {:8.3f}] m  "
      "orientation [{:.4f} {:.4f} {:.4f} {:.4f}]  score {:.2f}  margin {:.1f}  "
      "{} points{}\n",
      d.family, d.id, d.size_m, d.position.x(), d.position.y(), d.position.z(), q.w(), q.x(), q.y(),
      q.z(), d.score, d.margin, d.points,
      t != nullptr && !t->decoded ? "  (by its track: not decoded alone)" : "");
  if (d.size_warning)
    fmt::print(
        "    SIZE: its points measure {:.3f} m, not the {:.3f} m given: the pose is biased\n",
        d.measured_size_m, d.size_m);
  if (t == nullptr || t->track.track_id < 0) return;
  const det::TrackInfo& k = t->track;
  fmt::print(
      "    track {}: {}, {} rotation{}, margin {:.2f} cells; {} of {}: [{:8.3f} {:8.3f} {:8.3f}] "
      "m, spread {:.1f} {:.1f} {:.1f} mm {:.2f} deg\n",
      k.track_id, k.confirmed ? "confirmed" : "unconfirmed", k.rotations,
      k.rotations == 1 ? "" : "s", k.margin_cells, k.moving ? "motion" : "mean", k.window_rotations,
      k.position.x(), k.position.y(), k.position.z(), 1e3 * k.position_std_m.x(),
      1e3 * k.position_std_m.y(), 1e3 * k.position_std_m.z(), k.angle_std_deg);
  if (k.moving)
    fmt::print("    moving at [{:.3f} {:.3f} {:.3f}] m/s, turning [{:.1f} {:.1f} {:.1f}] deg/s\n",
               k.velocity_mps.x(), k.velocity_mps.y(), k.velocity_mps.z(), k.turn_deg_s.x(),
               k.turn_deg_s.y(), k.turn_deg_s.z());
}

// With `clusters` (--clusters), every cluster with enough features to be a tag, explained.
void print_rotation(const Scan& scan, const Reported& rep, const det::Detector& detector,
                    bool clusters) {
  const det::ScanResult& r = *rep.result;
  const size_t count = rep.tracked ? rep.tracked->tags.size() : r.detections.size();
  fmt::print(
      "rotation {:4d}  stamp {:.6f}  {:6d} points  {:5d} features  {:4d} clusters  {:7.2f} ms"
      "  {} detection{}",
      scan.sequence, static_cast<double>(scan.stamp_ns) * 1e-9, scan.point_count(), r.features,
      r.clusters, r.total_ms() + (rep.tracked ? rep.tracked->time_ms : 0.0), count,
      count == 1 ? "" : "s");
  if (rep.tracked != nullptr)
    fmt::print("  {} track{} ({} confirmed){}", rep.tracked->tracks,
               rep.tracked->tracks == 1 ? "" : "s", rep.tracked->confirmed_tracks,
               rep.tracked->truncated ? "  TRACKER INCOMPLETE (out of memory)" : "");
  fmt::print("\n");
  if (rep.tracked != nullptr) {
    for (const auto& t : rep.tracked->tags) print_detection(t.detection, &t);
  } else {
    for (const auto& d : r.detections) print_detection(d, nullptr);
  }
  const std::vector<double> elevation =
      clusters ? ring_elevations_deg(scan) : std::vector<double>();
  for (size_t i = 0; clusters && i < r.diagnostics.size(); ++i) {
    const auto& c = r.diagnostics[i];
    if (!worth_explaining(c, detector.options().tag_sizes_m)) continue;
    fmt::print(
        "  cluster {} x [{:.2f}, {:.2f}] y [{:.2f}, {:.2f}] rings {}-{}: {} features, {} points, "
        "{} boundary",
        i, c.min_x, c.max_x, c.min_y, c.max_y, c.min_ring, c.max_ring, c.features, c.points,
        c.boundary_points);
    if (c.outlier_ratio >= 0) fmt::print(", outliers {:.2f}", c.outlier_ratio);
    if (c.side_m >= 0)
      fmt::print(", outline side {:.3f} m (marker and any board margin)", c.side_m);
    if (c.mean_cost_m >= 0) fmt::print(", cost {:.4f} m", c.mean_cost_m);
    if (c.coverage >= 0) fmt::print(", coverage {:.2f}", c.coverage);
    if (c.score >= 0) fmt::print(", score {:.2f} margin {:.2f}", c.score, c.margin);
    fmt::print(" -> {}/{}{}", det::rejection_stage(c.rejection), det::rejection_name(c.rejection),
               other_family_note(detector.other_family_of(r, c)));
    const std::string lacks = lacked(c, detector, elevation);
    fmt::print("{}\n", lacks.empty() ? "" : ": " + lacks);
  }
}

struct Totals {
  size_t rotations = 0;
  size_t skipped = 0;  // incomplete rotations left out (no --partial)
  std::map<std::pair<std::string, int>, size_t> found, tracked_only;
  std::array<double, det::kStageCount> ms{};
  std::array<uint64_t, det::kRejectionCount> rejected{};
  double worst_ms = 0.0;
  double tracker_ms = 0.0;
  bool deskew = false;  // --deskew: the summary says what moved the clusters
  uint64_t deskewed_ego = 0, deskewed_model = 0, deskew_without_motion = 0;
  size_t detections_deskewed = 0, detections = 0;
  bool tracker = false;
  std::map<long, size_t> wrong_size_cm;  // sides measured of clusters rejected for their size
  std::vector<double> sizes_m;           // the sizes asked for
  // The size check, per tag: detections warned about, and their measured sizes summed.
  struct SizeCheck {
    double size_m = 0.0, measured_sum = 0.0;
    size_t warned = 0;
  };
  std::map<std::pair<std::string, int>, SizeCheck> size_checks;

  void check_size(const det::Detection& d) {
    if (!d.size_warning) return;
    SizeCheck& c = size_checks[{std::string(d.family), d.id}];
    c.size_m = d.size_m;
    c.measured_sum += d.measured_size_m;
    ++c.warned;
  }

  void count_deskew(const det::Detection& d) {
    ++detections;
    detections_deskewed += d.deskew != det::DeskewSource::kNone ? 1 : 0;
  }

  // With --deskew: what moved the validated clusters' points, and how many detections were fitted
  // deskewed (on stderr with --json, as the size warnings).
  void print_deskew(std::FILE* out) const {
    if (!deskew) return;
    fmt::print(out,
               "deskew: {} clusters moved by the tracker's motion model, {} by odometry, {} "
               "fitted as fired (no motion known yet); {} of {} detections deskewed\n",
               deskewed_model, deskewed_ego, deskew_without_motion, detections_deskewed,
               detections);
  }

  void add(const Reported& rep) {
    const det::ScanResult& r = *rep.result;
    ++rotations;
    if (rep.tracked != nullptr) {
      tracker = true;
      tracker_ms += rep.tracked->time_ms;
      for (const auto& t : rep.tracked->tags) {
        check_size(t.detection);
        count_deskew(t.detection);
        ++found[{std::string(t.detection.family), t.detection.id}];
        if (!t.decoded) ++tracked_only[{std::string(t.detection.family), t.detection.id}];
      }
    } else {
      for (const auto& d : r.detections) {
        check_size(d);
        count_deskew(d);
        ++found[{std::string(d.family), d.id}];
      }
    }
    deskewed_ego += static_cast<uint64_t>(r.deskewed_ego);
    deskewed_model += static_cast<uint64_t>(r.deskewed_model);
    deskew_without_motion += static_cast<uint64_t>(r.deskew_without_motion);
    for (size_t s = 0; s < ms.size(); ++s) ms[s] += r.timing_ms[s];
    for (size_t k = 0; k < rejected.size(); ++k) rejected[k] += r.rejected[k];
    for (const auto& d : r.diagnostics)
      if (d.rejection == det::Rejection::kSize && d.side_m > 0)
        ++wrong_size_cm[std::lround(d.side_m * 100)];
    worst_ms = std::max(worst_ms, r.total_ms());
  }

  // The size check's verdict (after the summary; on stderr with --json): a tag whose points
  // measure another size than the one given, with the size to give.
  void print_size_warnings(std::FILE* out) const {
    for (const auto& [tag, c] : size_checks) {
      const size_t n = found.count(tag) ? found.at(tag) : c.warned;
      fmt::print(out,
                 "warning: {} id {} measures {:.3f} m, not the {:.3f} m given (in {} of the {} "
                 "rotations it was found in): its pose is biased; give --tag-size {:.3f} (the "
                 "printed marker's outer size)\n",
                 tag.first, tag.second, c.measured_sum / static_cast<double>(c.warned), c.size_m,
                 c.warned, n, c.measured_sum / static_cast<double>(c.warned));
    }
  }

  void print() const {
    fmt::print("\n{} rotation{}", rotations, rotations == 1 ? "" : "s");
    if (found.empty()) fmt::print(", no tags found\n");
    for (auto it = found.begin(); it != found.end(); ++it) {
      fmt::print("{} {} id {} in {}", it == found.begin() ? ":" : ",", it->first.first,
                 it->first.second, it->second);
      if (const auto t = tracked_only.find(it->first); t != tracked_only.end())
        fmt::print(" ({} confirmed by its track only)", t->second);
    }
    if (!found.empty()) fmt::print(" rotations\n");
    print_size_warnings(stdout);
    print_deskew(stdout);
    if (skipped > 0)
      fmt::print("skipped {} incomplete rotation{} (--partial detects in them)\n", skipped,
                 skipped == 1 ? "" : "s");
    if (rotations == 0) return;
    const auto n = static_cast<double>(rotations);
    double total = 0.0;
    fmt::print("{:<12}{:>10}\n", "stage", "mean ms");
    for (int s = 0; s < det::kStageCount; ++s) {
      fmt::print("{:<12}{:>10.3f}\n", det::stage_name(static_cast<det::Stage>(s)),
                 ms[static_cast<size_t>(s)] / n);
      total += ms[static_cast<size_t>(s)] / n;
    }
    if (tracker) {
      fmt::print("{:<12}{:>10.3f}\n", "tracker", tracker_ms / n);
      total += tracker_ms / n;
    }
    fmt::print("{:<12}{:>10.3f}   (worst rotation's detector {:.3f} ms)\n", "total", total,
               worst_ms);
    fmt::print("clusters rejected (mean per rotation):");
    for (int k = 1; k < det::kRejectionCount; ++k) {
      const auto reason = static_cast<det::Rejection>(k);
      if (rejected[static_cast<size_t>(k)] == 0) continue;
      fmt::print(" {}/{} {:.2f}", det::rejection_stage(reason), det::rejection_name(reason),
                 static_cast<double>(rejected[static_cast<size_t>(k)]) / n);
    }
    fmt::print("\n");
    if (!wrong_size_cm.empty()) {
      // What the wrong-size clusters measured, the commonest first: the size to ask for.
      std::vector<std::pair<size_t, long>> by_count;
      for (const auto& [cm, count] : wrong_size_cm) by_count.emplace_back(count, cm);
      std::sort(by_count.rbegin(), by_count.rend());
      std::string measured, sizes;
      for (size_t i = 0; i < std::min<size_t>(3, by_count.size()); ++i) {
        measured += fmt::format("{}{:.2f} m ({}x)", i == 0 ? "" : ", ",
                                static_cast<double>(by_count[i].second) / 100.0, by_count[i].first);
      }
      for (double s : sizes_m) sizes += fmt::format("{}{:.2f}", sizes.empty() ? "" : ", ", s);
      fmt::print(
          "clusters rejected as the wrong size for --tag-size {} m measured {} a side (a "
          "tag's outline, or the board it is mounted on: give the printed marker's size)\n",
          sizes, measured);
    }
  }
};

int run_detect(const DetectArgs& args) {
  det::Detector detector(detector_options(args));
  const det::TrackerOptions topt = tracker_options(args);
  std::optional<det::Tracker> tracker;
  if (topt.enabled) tracker.emplace(topt, detector.options());
  det::ScanResult result;
  det::TrackerResult tracked;
  Totals totals;
  totals.sizes_m = detector.options().tag_sizes_m;
  totals.deskew = detector.options().deskew.enabled;
  std::optional<McapOutput> mcap;
  if (!args.mcap.path.empty()) mcap.emplace(args.mcap, args.capture.capture);
  std::vector<det::Detection> reported;  // what the MCAP file shows: the printed detections
  auto report = [&](const Scan& scan) {
    // The deskew's motion: the tracker's model of how the world moves through the sensor's frame
    // (a capture carries no odometry).
    det::SensorMotion motion;
    if (tracker) motion.model = tracker->motion();
    detector.detect(scan, result, motion);
    Reported rep{&result, nullptr};
    if (tracker) {
      tracker->update(result, scan.stamp_ns, tracked);
      rep.tracked = &tracked;
    }
    totals.add(rep);
    std::string json;
    if (args.json || mcap) json = rotation_json(scan, rep, detector, args.clusters).dump();
    if (args.json) {
      fmt::print("{}\n", json);
      std::fflush(stdout);
    } else {
      print_rotation(scan, rep, detector, args.clusters);
    }
    if (mcap) {
      reported.clear();
      if (rep.tracked != nullptr) {
        for (const auto& t : rep.tracked->tags) reported.push_back(t.detection);
      } else {
        reported.assign(result.detections.begin(), result.detections.end());
      }
      mcap->rotation(scan, reported, json);
    }
  };

  if (is_pcd(args.capture.capture)) {
    Scan scan;
    load_pcd_scan(args.capture, args.rings, args.resolution_deg, scan);
    report(scan);
  } else if (is_point_cloud_bag(args.capture)) {
    if (for_each_bag_cloud(args.capture, args.rings, args.resolution_deg, [&](const Scan& s) {
          report(s);
          return true;
        }) == 0)
      throw std::runtime_error(args.capture.capture + ": no point cloud could be read");
  } else {
    // The rotations (Ouster: the frames, destaggered) of a Velodyne or an Ouster reader.
    auto detect_all = [&](auto& reader) {
      std::error_code ec;
      Progress progress(std::filesystem::file_size(args.capture.capture, ec));
      size_t n = 0;
      while (const Scan* scan = reader.next()) {
        if (scan->complete || args.partial) {
          report(*scan);
          ++n;
        } else {
          ++totals.skipped;
        }
        progress.update(capture_bytes_read(reader), fmt::format("{} rotations", n));
      }
      progress.done();
      warn_model_mismatch(reader, args.capture);
      if (mcap) mcap->close();
      if (!args.json) totals.print();
      if (args.json) {
        totals.print_size_warnings(stderr);
        totals.print_deskew(stderr);
      }
      require_rotations(reader, args.capture, n, totals.skipped, "detects in them");
    };
    open_capture(args.capture, args.ouster).visit(detect_all);
    return 0;
  }
  if (mcap) mcap->close();
  if (!args.json) totals.print();
  if (args.json) {
    totals.print_size_warnings(stderr);
    totals.print_deskew(stderr);
  }
  return 0;
}

const Registrar kDetect(
    "detect", "Detect LiDARTags in a capture (pcap) or a point cloud (PCD)",
    [](CLI::App& app) -> RunFunction {
      auto args = std::make_shared<DetectArgs>();
      add_capture_options(app, args->capture);
      app.get_option("capture")->description(
          "pcap or pcapng file, a PCD point cloud, or a ROS bag / MCAP file of VelodyneScan or "
          "Ouster packets or PointCloud2 clouds");
      add_ouster_options(app, args->ouster, true);
      app.add_option("--config", args->config,
                     "YAML file whose `detector:` and `tracker:` sections set the detector's and "
                     "the tracker's options (config/lidartagd.yaml)")
          ->check(CLI::ExistingFile);
      app.add_flag("--json", args->json, "One JSON object per rotation on stdout");
      app.add_option("--mcap", args->mcap.path,
                     "Also write every detected rotation to this MCAP file for Foxglove: its "
                     "cloud, its tags (scene entities and frames) and the --json object "
                     "(docs/foxglove.md)");
      add_mcap_options(app, args->mcap);
      app.add_option("--tag-size", args->tag_sizes,
                     "Tag size (full printed marker, white ring included): metres, or with a unit "
                     "(800mm, 80cm, 31.5in); repeat for "
                     "several sizes (default 1.2, or the config's)")
          ->transform(length_in_metres());
      app.add_option("--family", args->families,
                     "Tag family (tag16h5, tag25h9, tag36h10, tag36h11, tag16h6 or "
                     "FILE.json[:NAME]); repeat for several (default tag16h5, or the config's)")
          ->type_name("FAMILY");
      app.add_flag("--clusters", args->clusters,
                   "Explain every cluster with enough features to be a tag: what each stage "
                   "measured and why it was dropped");
      app.add_flag("--no-tracker", args->no_tracker,
                   "Every rotation alone: no evidence summed over rotations, no track fields "
                   "(the tracker is on by default)");
      app.add_flag("--deskew", args->deskew,
                   "Move each cluster's points to its centre's firing time with the motion the "
                   "tracker has fitted before the fits (a moving sensor; detector.deskew.enabled)")
          ->excludes("--no-tracker");
      app.add_flag("--partial", args->partial,
                   "Also detect in incomplete rotations (first, last, lossy)");
      app.add_option("--rings", args->rings,
                     "PCD or PointCloud2 without a ring field and no --model: number of beams to "
                     "regress")
          ->check(CLI::Range(1, 256));
      app.add_option("--resolution", args->resolution_deg, kResolutionHelp)
          ->check(CLI::Range(0.01, 5.0));
      return [args] { return run_detect(*args); };
    });

}  // namespace
}  // namespace lidartag::cli
