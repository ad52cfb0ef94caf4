// `lidartag render CAPTURE|PCD [--rotation N] [--cluster K] [-o PREFIX] ...`: pictures of what
// the detector made of one rotation: a bird's-eye view with the detections and the rejected
// clusters coloured by the stage that dropped them, and a close-up in its plane of each tag found
// and of each cluster that reached the plane fit but was rejected (or of the one asked for).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/bag_clouds.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/ring_regression.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/draw/birds_eye.hpp"
#include "lidartag/draw/cairo_util.hpp"
#include "lidartag/draw/close_up.hpp"
#include "lidartag/draw/units.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/exit_codes.hpp"
#include "lidartag/progress.hpp"
#ifdef LIDARTAG_HAVE_CONFIG
#include "lidartag/daemon/config.hpp"
#endif

namespace lidartag::cli {
namespace {

namespace det = lidartag::detector;
namespace fs = std::filesystem;

struct RenderArgs {
  CaptureArgs capture;
  OusterArgs ouster;
  std::string config;
  std::vector<double> tag_sizes;
  std::vector<std::string> families;
  int64_t rotation = -1;  // sequence number; -1: the first complete one (with --partial: the first)
  bool partial = false;
  double range_m = 0;
  int cluster = -1;
  std::string out;
  int size_px = 1000;
  int rings = 0;
  double resolution_deg = 0.0;  // PCD or PointCloud2: width of a column (0: the cloud's own)
};

det::DetectorOptions detector_options(const RenderArgs& args) {
  det::DetectorOptions options;
  if (!args.config.empty()) {
#ifdef LIDARTAG_HAVE_CONFIG
    options = daemon::load_detector_config(args.config);
#else
    throw UsageError("--config needs the lidartag_config library (daemon/), not built");
#endif
  }
  if (!args.tag_sizes.empty()) options.tag_sizes_m = args.tag_sizes;
  if (!args.families.empty()) options.families = args.families;
  options.cluster_diagnostics = true;
  options.keep_tag_points = true;
  options.keep_cluster_points = true;
  return options;
}

// The prefix of every file written: --out as given, a folder's capture-named prefix, or the
// capture's name in the current folder.
std::string output_prefix(const RenderArgs& args) {
  const std::string stem = fs::path(args.capture.capture).stem().string();
  if (args.out.empty()) return stem;
  std::error_code ec;
  if (args.out.back() == '/' || fs::is_directory(args.out, ec)) {
    fs::create_directories(args.out, ec);
    return (fs::path(args.out) / stem).string();
  }
  return args.out;
}

// The family of each configured name, loaded once (the detector resolved them too; they load
// again here to draw their codes).
class Families {
 public:
  explicit Families(const det::DetectorOptions& options) : options_(options) {}
  const tags::TagFamily& operator[](int index) {
    const std::string& name = options_.families[static_cast<size_t>(index)];
    auto it = loaded_.find(name);
    if (it == loaded_.end()) it = loaded_.emplace(name, tags::resolve_family(name)).first;
    return it->second;
  }

 private:
  const det::DetectorOptions& options_;
  std::map<std::string, tags::TagFamily> loaded_;
};

// The black square's corners of a marker of size t in a tag frame (sensor frame): bottom-left,
// bottom-right, top-right, top-left seen from the front (the detector's order).
std::array<Eigen::Vector3d, 4> square_corners(const Eigen::Vector3d& centre,
                                              const Eigen::Matrix3d& rotation, double t,
                                              const tags::TagFamily& f) {
  const double s = t / 2 * f.width_at_border / f.total_width;
  const double yz[4][2] = {{-s, -s}, {s, -s}, {s, s}, {-s, s}};
  std::array<Eigen::Vector3d, 4> corners;
  for (size_t k = 0; k < 4; ++k)
    corners[k] = centre + rotation * Eigen::Vector3d(0, yz[k][0], yz[k][1]);
  return corners;
}

// What a candidate's points read, turned upright in its decoded frame.
void add_cells_read(const det::ScanResult& result, const det::Candidate& c, draw::CloseUp& v) {
  if (c.grid_width <= 0) return;
  v.cells_read = draw::turn_counter_clockwise(result.cells_of(c), c.grid_width, c.quarter_turns);
  v.cells_width = c.grid_width;
}

const det::Candidate* candidate_of_detection(const det::ScanResult& result, int detection) {
  for (const auto& c : result.candidates)
    if (c.detection == detection) return &c;
  return nullptr;
}

draw::CloseUp detection_view(const det::ScanResult& result, int k, Families& families) {
  const det::Detection& d = result.detections[static_cast<size_t>(k)];
  const tags::TagFamily& family = families[d.family_index];
  draw::CloseUp v;
  v.points = result.points_of(d);
  v.centre = d.position;
  v.rotation = d.orientation.toRotationMatrix();
  v.size_m = d.size_m;
  v.family = &family;
  v.code = family.codes[static_cast<size_t>(d.id)];
  v.fitted = true;
  v.corners = d.corners;
  if (const det::Candidate* c = candidate_of_detection(result, k)) add_cells_read(result, *c, v);
  v.title = {
      fmt::format("{} id {}: {} m marker ({} m black square)", d.family, d.id,
                  draw::format_number(d.size_m, 3),
                  draw::format_number(d.size_m * family.width_at_border / family.total_width, 3)),
      fmt::format("{:.2f} m away, score {:.2f}, margin {:.1f} cells, {} points", d.position.norm(),
                  d.score, d.margin, d.points)};
  return v;
}

// What the stages measured of a cluster, as `detect --clusters` says it.
std::string measured(const det::ClusterDiagnostic& c) {
  std::string s = fmt::format("{} points, {} boundary", c.points, c.boundary_points);
  if (c.outlier_ratio >= 0) s += fmt::format(", outliers {:.2f}", c.outlier_ratio);
  if (c.side_m >= 0)
    s += fmt::format(", outline side {:.3f} m (marker and any board margin)", c.side_m);
  if (c.mean_cost_m >= 0) s += fmt::format(", cost {:.4f} m", c.mean_cost_m);
  if (c.coverage >= 0) s += fmt::format(", coverage {:.2f}", c.coverage);
  if (c.score >= 0) s += fmt::format(", score {:.2f} margin {:.2f}", c.score, c.margin);
  return s;
}

// A cluster: in its decoded frame with the best code when it reached decoding, else in the plane
// of its points with a marker of the configured size nearest to what was measured, for scale.
// `other_family`: for a cluster rejected as another family's tag, the family that fits better
// (Detector::other_family_of).
draw::CloseUp cluster_view(const det::ScanResult& result, int index,
                           const det::DetectorOptions& options, Families& families,
                           std::string_view other_family) {
  const det::ClusterDiagnostic& c = result.diagnostics[static_cast<size_t>(index)];
  draw::CloseUp v;
  v.points = result.points_of(c);
  const std::string verdict =
      c.rejection == det::Rejection::kNone
          ? "accepted"
          : fmt::format("rejected at {}: {}{}", det::rejection_stage(c.rejection),
                        det::rejection_name(c.rejection), other_family_note(other_family));
  v.title = {fmt::format("cluster {}: {}", index, verdict), measured(c)};
  if (c.candidate >= 0) {
    const det::Candidate& k = result.candidates[static_cast<size_t>(c.candidate)];
    v.centre = k.position;
    v.rotation = k.orientation.toRotationMatrix();
    v.size_m = k.size_m;
    if (k.family_index >= 0 && k.id >= 0) {
      const tags::TagFamily& family = families[k.family_index];
      v.family = &family;
      v.code = family.codes[static_cast<size_t>(k.id)];
      v.fitted = true;
      v.corners = square_corners(v.centre, v.rotation, v.size_m, family);
      v.title.push_back(fmt::format("best: {} id {} at {} m, {:.2f} m away", family.name, k.id,
                                    draw::format_number(k.size_m, 3), k.position.norm()));
    }
    add_cells_read(result, k, v);
    return v;
  }
  draw::plane_frame(v.points, v.centre, v.rotation);
  v.measured_side_m = c.side_m;
  // The configured size nearest to the measured side, else the largest.
  const auto& sizes = options.tag_sizes_m;
  v.size_m = *std::max_element(sizes.begin(), sizes.end());
  if (c.side_m > 0)
    v.size_m = *std::min_element(sizes.begin(), sizes.end(), [&](double a, double b) {
      return std::fabs(a - c.side_m) < std::fabs(b - c.side_m);
    });
  v.title.push_back(fmt::format("{:.2f} m away; dashed: a {} m marker{}", v.centre.norm(),
                                draw::format_number(v.size_m, 3),
                                c.side_m > 0 ? ", the side measured" : ""));
  return v;
}

int run_render(const RenderArgs& args) {
  const draw::FontCacheRelease release_fonts;  // after every surface below
  const det::DetectorOptions options = detector_options(args);
  det::Detector detector(options);
  if (args.size_px < 200 || args.size_px > 8000)
    throw UsageError("--size must be 200 to 8000 pixels");

  // The rotation by its sequence number, as detect, dump, the daemon and Python number them.
  Scan pcd_scan;
  const Scan* scan = nullptr;
  std::optional<OpenedCapture> capture;  // `scan` is one of its reader's
  if (is_pcd(args.capture.capture)) {
    load_pcd_scan(args.capture, args.rings, args.resolution_deg, pcd_scan);
    if (args.rotation >= 0 && static_cast<uint64_t>(args.rotation) != pcd_scan.sequence) {
      throw UsageError(fmt::format("--rotation {}: a PCD file holds one rotation (rotation {})",
                                   args.rotation, pcd_scan.sequence));
    }
    scan = &pcd_scan;
  } else if (is_point_cloud_bag(args.capture)) {  // a bag's PointCloud2 topic: cloud --rotation
    bag_cloud_scan(args.capture, args.rings, args.resolution_deg, args.rotation, pcd_scan);
    scan = &pcd_scan;
  } else {
    // The rotations (Ouster: the frames, destaggered) of a Velodyne or an Ouster reader.
    auto find = [&](auto& rd) {
      size_t complete = 0, skipped = 0;
      std::optional<uint64_t> first, last;
      std::error_code ec;
      Progress progress(fs::file_size(args.capture.capture, ec));  // a late rotation of a long one
      while (const Scan* s = rd.next()) {
        progress.update(capture_bytes_read(rd), fmt::format("rotation {}", s->sequence));
        if (!first) first = s->sequence;
        last = s->sequence;
        complete += s->complete ? 1 : 0;
        skipped += s->complete ? 0 : 1;
        const bool wanted = args.rotation < 0 ? s->complete || args.partial
                                              : s->sequence == static_cast<uint64_t>(args.rotation);
        if (!wanted) continue;
        if (!s->complete && !args.partial) {
          throw UsageError(fmt::format(
              "--rotation {}: rotation {} of {} is incomplete (a capture's first and last, or "
              "lossy); --partial draws it",
              args.rotation, s->sequence, args.capture.capture));
        }
        scan = s;
        break;
      }
      progress.done();
      warn_model_mismatch(rd, args.capture);
      if (scan == nullptr) {
        require_rotations(rd, args.capture, complete, skipped, "renders them");
        throw UsageError(fmt::format("--rotation {}: {} has rotations {}-{}", args.rotation,
                                     args.capture.capture, first.value_or(0), last.value_or(0)));
      }
    };
    capture.emplace(open_capture(args.capture, args.ouster));
    capture->visit(find);
  }
  const uint64_t number = scan->sequence;

  det::ScanResult result;
  detector.detect(*scan, result);
  if (args.cluster >= 0 && args.cluster >= static_cast<int>(result.diagnostics.size()))
    throw UsageError(
        fmt::format("--cluster {}: rotation {} has clusters 0-{} (detect --clusters "
                    "lists them)",
                    args.cluster, number, static_cast<int>(result.diagnostics.size()) - 1));

  std::vector<draw::ViewCluster> clusters;
  for (size_t i = 0; i < result.diagnostics.size(); ++i)
    if (worth_explaining(result.diagnostics[i], options.tag_sizes_m) ||
        static_cast<int>(i) == args.cluster)
      clusters.push_back(
          {static_cast<int>(i), &result.diagnostics[i], result.points_of(result.diagnostics[i])});

  const std::string prefix = fmt::format("{}-rotation{}", output_prefix(args), number);
  const std::string name = fs::path(args.capture.capture).filename().string();

  draw::BirdsEyeOptions bo;
  bo.size_px = args.size_px;
  bo.range_m = args.range_m;
  bo.highlight = args.cluster;
  bo.title = {
      fmt::format("{}, rotation {} (stamp {:.6f} s)", name, number,
                  static_cast<double>(scan->stamp_ns) * 1e-9),
      fmt::format("{} points, {} clusters, {} detection{}", scan->point_count(), result.clusters,
                  result.detections.size(), result.detections.size() == 1 ? "" : "s")};
  const std::string top = prefix + ".png";
  const auto m = draw::write_birds_eye(*scan, result, clusters, bo, top);
  fmt::print(
      "wrote {}: bird's-eye view, {} x {} px, {} px per metre, sensor at pixel {},{} (x forward "
      "up, y left left)\n",
      top, args.size_px, args.size_px, draw::format_number(m.px_per_m, 4),
      draw::format_number(m.centre_x, 2), draw::format_number(m.centre_y, 2));

  const int close_px = std::max(200, args.size_px * 4 / 5);
  Families families(options);
  auto write = [&](const draw::CloseUp& v, const std::string& path, const std::string& what) {
    const auto cm = draw::write_close_up(v, close_px, path);
    fmt::print("wrote {}: {} in its plane, {} x {} px, {} px per metre, centre at pixel {},{}\n",
               path, what, close_px, close_px, draw::format_number(cm.px_per_m, 4),
               draw::format_number(cm.centre_x, 2), draw::format_number(cm.centre_y, 2));
  };
  if (args.cluster < 0) {
    for (size_t k = 0; k < result.detections.size(); ++k) {
      const det::Detection& d = result.detections[k];
      draw::CloseUp v = detection_view(result, static_cast<int>(k), families);
      v.title.push_back(fmt::format("{}, rotation {}", name, number));
      write(v, fmt::format("{}-{}-{}.png", prefix, d.family, d.id),
            fmt::format("{} id {}", d.family, d.id));
    }
  }
  // Clusters: the one asked for, or every one rejected at the plane fit or later (what could
  // have been a tag).
  for (size_t i = 0; i < result.diagnostics.size(); ++i) {
    const det::ClusterDiagnostic& c = result.diagnostics[i];
    const bool asked = static_cast<int>(i) == args.cluster;
    const bool candidate =
        c.rejection != det::Rejection::kNone &&
        static_cast<int>(det::stage_of(c.rejection)) >= static_cast<int>(det::Stage::kPlane);
    if (!(asked || (args.cluster < 0 && candidate))) continue;
    draw::CloseUp v = cluster_view(result, static_cast<int>(i), options, families,
                                   detector.other_family_of(result, c));
    v.title.push_back(fmt::format("{}, rotation {}", name, number));
    std::string what = fmt::format("cluster {} (", i);
    what += c.rejection == det::Rejection::kNone
                ? std::string("accepted")
                : fmt::format("{}/{}", det::rejection_stage(c.rejection),
                              det::rejection_name(c.rejection));
    if (v.family != nullptr)
      what += fmt::format(", best {} id {}", v.family->name,
                          result.candidates[static_cast<size_t>(c.candidate)].id);
    write(v, fmt::format("{}-cluster{}.png", prefix, i), what + ")");
  }
  return 0;
}

const Registrar kRender(
    "render",
    "Draw what the detector made of a rotation: a bird's-eye view and close-ups of tags and "
    "rejected clusters (PNG)",
    [](CLI::App& app) -> RunFunction {
      auto a = std::make_shared<RenderArgs>();
      add_capture_options(app, a->capture);
      app.get_option("capture")->description("pcap or pcapng file, or a PCD point cloud");
      add_ouster_options(app, a->ouster, true);
      app.add_option("--rotation", a->rotation,
                     "Rotation to draw, by its number (as detect, dump and the daemon number "
                     "them; default: the first complete one)")
          ->check(CLI::NonNegativeNumber);
      app.add_flag("--partial", a->partial,
                   "Draw an incomplete rotation too (first, last, lossy): by default the first "
                   "rotation, complete or not");
      app.add_option("--cluster", a->cluster,
                     "Draw this cluster (its index in detect --clusters) highlighted, and its "
                     "close-up instead of the others'")
          ->check(CLI::NonNegativeNumber);
      app.add_option("--range", a->range_m,
                     "Bird's-eye view: distance from the sensor to the picture's edge, metres "
                     "or with a unit (8, 800cm; default: the detections and candidates with room "
                     "around them)")
          ->transform(length_in_metres())
          ->check(CLI::PositiveNumber);
      app.add_option("-o,--out", a->out,
                     "Prefix of the files (PREFIX-rotationN.png, PREFIX-rotationN-FAMILY-ID.png, "
                     "PREFIX-rotationN-clusterK.png); a folder puts them there under the "
                     "capture's name (default: the capture's name, here)");
      app.add_option("--size", a->size_px, "Bird's-eye picture side, pixels (close-ups: 4/5)")
          ->check(CLI::Range(200, 8000))
          ->capture_default_str();
      app.add_option("--config", a->config,
                     "YAML file whose `detector:` section sets the detector's options")
          ->check(CLI::ExistingFile);
      app.add_option("--tag-size", a->tag_sizes,
                     "Tag size (full printed marker, white ring included): metres, or with a unit "
                     "(800mm, 80cm, 31.5in); repeat for "
                     "several sizes (default 1.2, or the config's)")
          ->transform(length_in_metres());
      app.add_option("--family", a->families,
                     "Tag family (tag16h5, tag25h9, tag36h10, tag36h11, tag16h6 or "
                     "FILE.json[:NAME]); repeat for several (default tag16h5, or the config's)")
          ->type_name("FAMILY");
      app.add_option("--rings", a->rings,
                     "PCD without a ring field and no --model: number of beams to regress")
          ->check(CLI::Range(1, 256));
      app.add_option("--resolution", a->resolution_deg, kResolutionHelp)
          ->check(CLI::Range(0.01, 5.0));
      return [a] { return run_render(*a); };
    });

}  // namespace
}  // namespace lidartag::cli
