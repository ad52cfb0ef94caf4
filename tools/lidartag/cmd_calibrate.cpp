// `lidartag calibrate --camera CAMERA.yaml --pair IMAGE CAPTURE [--pair ...] -o RESULT.json`:
// where a camera sits relative to the LiDAR, from LiDARTags seen by both (docs/calibration.md).
// Each pair is one static scene: the image's tags (AprilTag 3, sub-pixel corners) and the
// capture's (the detector and the tracker over all its rotations: the track's mean pose, its
// spread as the corners' uncertainty) pair by family, ID and size; the solver refines the
// camera-from-LiDAR transform over every pair's corners and says how sure it is. A pair that
// cannot be used (a corrupt image, an image of another size, no tag, IDs that differ) is reported
// and the rest is still used.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "lidartag/calib/calibration_report.hpp"
#include "lidartag/calib/correspondence.hpp"
#include "lidartag/calib/extrinsic_solver.hpp"
#include "lidartag/calib/image_io.hpp"
#include "lidartag/calib/image_tags.hpp"
#include "lidartag/calib/intrinsics_file.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/draw/cairo_util.hpp"
#include "lidartag/draw/calibration_view.hpp"
#include "lidartag/exit_codes.hpp"

namespace lidartag::cli {
namespace {

namespace det = detector;
namespace fs = std::filesystem;

struct CalibrateArgs {
  std::string camera;
  std::vector<std::pair<std::string, std::string>> pairs;  // image, capture
  std::vector<std::string> pairs_dirs;                     // folders of matching names
  std::vector<std::string> families;
  std::vector<double> tag_sizes;
  std::string out;
  bool json = false;
  double pixel_sigma = 0.3;
  std::string lidar_frame = "lidar";
  std::string camera_frame = "camera_optical_frame";
  std::string model;     // of the captures, when their packets do not say
  std::string pictures;  // PREFIX: PREFIX-pairN.png per pair
};

// The pairs of a folder (--pairs-dir): each image (.png, .jpg, .jpeg) with the capture (.pcap,
// .pcapng, .pcd) of the same base name, any case of the extension, in the order of the names.
// Other files (truth files, intrinsics, pictures of another kind) are not inputs and are left
// alone; sub-folders are not searched. A file of either kind without its partner, or a base name
// with two images or two captures, is returned in `unmatched` with the reason.
struct FolderPairs {
  std::vector<std::pair<std::string, std::string>> pairs;      // image, capture
  std::vector<std::pair<std::string, std::string>> unmatched;  // file, why
};

std::string lower_extension(const fs::path& f) {
  std::string e = f.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

bool is_image_name(const fs::path& f) {
  const std::string e = lower_extension(f);
  return e == ".png" || e == ".jpg" || e == ".jpeg";
}

bool is_capture_name(const fs::path& f) {
  const std::string e = lower_extension(f);
  return e == ".pcap" || e == ".pcapng" || e == ".pcd";
}

FolderPairs pairs_in_folder(const std::string& dir) {
  std::map<std::string, std::pair<std::vector<std::string>, std::vector<std::string>>> by_name;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const bool image = is_image_name(e.path()), capture = is_capture_name(e.path());
    if (!image && !capture) continue;
    auto& [images, captures] = by_name[e.path().stem().string()];
    (image ? images : captures).push_back(e.path().string());
  }
  FolderPairs out;
  for (auto& [name, files] : by_name) {
    auto& [images, captures] = files;
    std::sort(images.begin(), images.end());
    std::sort(captures.begin(), captures.end());
    if (images.size() == 1 && captures.size() == 1) {
      out.pairs.emplace_back(images[0], captures[0]);
    } else if (images.size() > 1 || captures.size() > 1) {
      // Which image goes with which capture is anybody's guess: none of the name's files is used.
      auto count = [](size_t n, const char* what) {
        return fmt::format("{} {}{}", n, what, n == 1 ? "" : "s");
      };
      const std::string why =
          fmt::format("the base name '{}' has {} and {} in {}: one of each pairs", name,
                      count(images.size(), "image"), count(captures.size(), "capture"), dir);
      for (const auto& f : images) out.unmatched.emplace_back(f, why);
      for (const auto& f : captures) out.unmatched.emplace_back(f, why);
    } else if (images.size() == 1) {
      out.unmatched.emplace_back(
          images[0],
          fmt::format("no capture {0}.pcap, {0}.pcapng or {0}.pcd beside the image in {1}", name,
                      dir));
    } else if (captures.size() == 1) {
      out.unmatched.emplace_back(
          captures[0],
          fmt::format("no image {0}.png, {0}.jpg or {0}.jpeg beside the capture in {1}", name,
                      dir));
    }
  }
  return out;
}

// One pair's inputs as found, and why it could not be used when it could not.
struct PairInput {
  std::string image, capture;
  std::vector<calib::ImageTagCorners> image_tags;
  std::vector<calib::LidarTag> lidar_tags;
  calib::GrayImage image_pixels;        // kept for the picture
  std::vector<Eigen::Vector3f> points;  // the capture's last rotation, for the picture
  int rotations = 0;                    // complete rotations of the capture read
  std::string error;                    // the pair was dropped whole (unreadable, wrong size)
  calib::Pairing pairing;
};

// The capture's tags: each confirmed track's window over the whole capture (the evidence of
// every rotation; its spread is the corners' uncertainty); a single rotation (a PCD) gives its
// detections.
std::vector<calib::LidarTag> lidar_tags_of(const std::string& path, const CalibrateArgs& args,
                                           const det::DetectorOptions& options, int& rotations,
                                           std::vector<Eigen::Vector3f>& points) {
  det::Detector detector(options);
  det::Tracker tracker(det::TrackerOptions{}, options);
  det::ScanResult result;
  det::TrackerResult tracked;
  std::vector<det::Detection> last_detections;
  // Each track's latest report that was confirmed or decoded by the detector alone (a tag missed
  // in the last rotations keeps its window). A square-mounted tag's track is never confirmed (its
  // candidates carry no cell votes: Tracker::add_evidence), so a decoded one counts too.
  std::map<int, det::TrackedDetection> latest;
  std::vector<double> ring_elevations;  // of the last rotation's rings with returns, radians
  rotations = 0;
  auto take = [&](const Scan& scan) {
    detector.detect(scan, result);
    tracker.update(result, scan.stamp_ns, tracked);
    last_detections = result.detections;
    points.clear();
    for (int ring = 0; ring < scan.rings; ++ring)
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(0, ring, col);
        if (scan.range[i] > 0) points.emplace_back(scan.x[i], scan.y[i], scan.z[i]);
      }
    ring_elevations = calib::ring_elevations_rad(scan);
    for (const det::TrackedDetection& t : tracked.tags)
      if (t.track.confirmed || t.decoded) latest[t.track.track_id] = t;
    ++rotations;
  };
  CaptureArgs capture;
  capture.capture = path;
  capture.model = args.model;
  if (is_pcd(path)) {
    Scan scan;
    load_pcd_scan(capture, 0, 0.0, scan);
    take(scan);
  } else {
    open_capture(capture, OusterArgs{}).visit([&](auto& reader) {
      while (const Scan* scan = reader.next())
        if (scan->complete) take(*scan);
      warn_model_mismatch(reader, capture);
    });
  }
  std::vector<calib::LidarTag> out;
  if (rotations > 1) {
    for (auto& [id, t] : latest) {
      det::TrackInfo info = t.track;
      if (!info.confirmed) {
        // The detector's ID, and the window's mean orientation turned by the quarter turns it
        // decoded (an unconfirmed track's leading function is no evidence).
        info.id = t.detection.id;
        Eigen::Quaterniond best = info.orientation;
        for (int k = 1; k < 4; ++k) {
          const Eigen::Quaterniond q =
              info.orientation *
              Eigen::AngleAxisd(k * std::numbers::pi / 2, Eigen::Vector3d::UnitX());
          if (q.angularDistance(t.detection.orientation) <
              best.angularDistance(t.detection.orientation))
            best = q;
        }
        info.orientation = best;
      }
      const auto& family = tags::builtin_family(t.detection.family);
      out.push_back(calib::lidar_tag_from_track(info, family, t.detection.size_m));
    }
  } else {
    for (const det::Detection& d : last_detections)
      out.push_back(calib::lidar_tag_from_detection(d, tags::builtin_family(d.family)));
  }
  // What the rings' spacing leaves unknown, which the spread over rotations does not show.
  for (calib::LidarTag& t : out)
    calib::add_ring_spacing_uncertainty(t, tags::builtin_family(t.family), ring_elevations);
  return out;
}

std::vector<calib::ImageTagCorners> image_tags_of(const std::string& path,
                                                  const calib::CameraModel& camera,
                                                  calib::ImageTagDetector& detector,
                                                  const CalibrateArgs& args,
                                                  calib::GrayImage& image) {
  image = calib::read_gray(path);
  if (image.width != camera.width || image.height != camera.height)
    throw calib::ImageError(fmt::format(
        "{}: the image is {} x {} px but the camera's intrinsics ({}) are for {} x {}: another "
        "camera or resolution",
        path, image.width, image.height, args.camera, camera.width, camera.height));
  std::vector<calib::ImageTagCorners> out;
  for (const calib::ImageTag& t : detector.detect(image, camera)) {
    calib::ImageTagCorners c;
    c.family = t.family;
    c.id = t.id;
    c.apriltag_p = t.corners;
    c.sigma_px = args.pixel_sigma;
    // One configured size is the image's too; with several, the LiDAR side says which matched.
    if (args.tag_sizes.size() == 1) c.size_m = args.tag_sizes.front();
    out.push_back(c);
  }
  return out;
}

// "family:id, ..." of a pair's tags (image or LiDAR side), "none" when there are none.
template <typename Tag>
std::string tag_list(const std::vector<Tag>& tags) {
  std::string s;
  for (const auto& t : tags) s += fmt::format("{}{}:{}", s.empty() ? "" : ", ", t.family, t.id);
  return s.empty() ? "none" : s;
}

nlohmann::json pair_json(const PairInput& p) {
  nlohmann::json j;
  j["image"] = p.image;
  j["capture"] = p.capture;
  if (!p.error.empty()) {
    j["error"] = p.error;
    return j;
  }
  j["rotations"] = p.rotations;
  for (const auto& t : p.image_tags)
    j["image_tags"].push_back(fmt::format("{}:{}", t.family, t.id));
  for (const auto& t : p.lidar_tags)
    j["lidar_tags"].push_back(fmt::format("{}:{}", t.family, t.id));
  j["paired"] = p.pairing.poses.size();
  for (const auto& u : p.pairing.unpaired)
    j["unpaired"].push_back({{"tag", u.label}, {"reason", u.reason}});
  return j;
}

std::string fmt_vec(const Eigen::Vector3d& v, const char* f) {
  return fmt::format("[{}, {}, {}]", fmt::format(fmt::runtime(f), v.x()),
                     fmt::format(fmt::runtime(f), v.y()), fmt::format(fmt::runtime(f), v.z()));
}

void print_text(const calib::CalibrationResult& r, const std::vector<PairInput>& inputs,
                const calib::FrameNames& frames, const CalibrateArgs& args) {
  for (const auto& p : inputs) {
    if (!p.error.empty()) {
      fmt::print("pair {} + {}: not used: {}\n", p.image.empty() ? "(no image)" : p.image,
                 p.capture.empty() ? "(no capture)" : p.capture, p.error);
      continue;
    }
    fmt::print("pair {} + {}: image tags {}; LiDAR tags {} ({} rotations); {} paired\n", p.image,
               p.capture, tag_list(p.image_tags), tag_list(p.lidar_tags), p.rotations,
               p.pairing.poses.size());
    for (const auto& u : p.pairing.unpaired)
      fmt::print("  not paired: {}: {}\n", u.label, u.reason);
  }
  Eigen::Quaterniond q(r.camera_from_lidar.rotation());
  if (q.w() < 0) q.coeffs() *= -1.0;  // q and -q are the same rotation; print w >= 0
  const Eigen::Vector3d t = r.camera_from_lidar.translation();
  fmt::print("\nlidar_to_camera (maps LiDAR-frame points into the camera's optical frame):\n");
  fmt::print("  rotation_wxyz [{:.6f}, {:.6f}, {:.6f}, {:.6f}]  translation_m {}\n", q.w(), q.x(),
             q.y(), q.z(), fmt_vec(t, "{:.4f}"));
  fmt::print("  1 sigma: rotation {:.3f} deg (about camera x y z {}), translation {} mm\n",
             r.rotation_sigma_total_deg, fmt_vec(r.rotation_sigma_deg, "{:.3f}"),
             fmt_vec(r.translation_sigma_mm, "{:.1f}"));
  fmt::print("  reprojection: {:.2f} px RMS over {} pose{}", r.rms_px, r.used_poses,
             r.used_poses == 1 ? "" : "s");
  if (r.held_out_median_px >= 0)
    fmt::print(", held out (each pose left out): median {:.2f} px, worst {:.2f} px",
               r.held_out_median_px, r.held_out_max_px);
  fmt::print("\n");
  for (const auto& p : r.poses) {
    fmt::print("  {}: {}", p.label,
               p.used ? fmt::format("{:.2f} px RMS at {:.1f} m", p.rms_px, p.range_m)
                      : "rejected: " + p.reason);
    if (p.used && p.held_out_px >= 0) fmt::print(", held out {:.2f} px", p.held_out_px);
    fmt::print("\n");
  }
  for (const auto& w : r.warnings) fmt::print("warning: {}\n", w);
  if (!r.suggestion.empty()) fmt::print("next pose: {}\n", r.suggestion);
  fmt::print("\nURDF:\n{}\n", calib::urdf_joint(r.camera_from_lidar.inverse(), frames));
  fmt::print("ROS 2: {}\n", calib::ros2_static_transform(r.camera_from_lidar.inverse(), frames));
  if (!args.out.empty()) fmt::print("wrote {}\n", args.out);
}

// One picture per usable pair: its image, the capture's points through the extrinsic, and its
// tags' corners from both sensors.
void write_pictures(const calib::CalibrationResult& r, const calib::CameraModel& camera,
                    const std::vector<PairInput>& inputs, const std::string& prefix) {
  const draw::FontCacheRelease release_fonts;  // after every surface below
  std::map<std::string, const calib::PoseReport*> reports;
  for (const auto& p : r.poses) reports[p.label] = &p;
  for (size_t i = 0; i < inputs.size(); ++i) {
    const PairInput& p = inputs[i];
    if (!p.error.empty()) continue;
    draw::CalibrationView v;
    v.image = &p.image_pixels;
    v.camera = &camera;
    v.camera_from_lidar = r.camera_from_lidar;
    v.points = p.points;
    std::string errors;
    for (const calib::TagPose& pose : p.pairing.poses) {
      draw::CalibrationViewTag t;
      t.label = fmt::format("{}:{}", pose.lidar.family, pose.lidar.id);
      t.image = pose.pixels;
      t.lidar = pose.lidar.corners;
      const auto it = reports.find(pose.label);
      t.used = it != reports.end() && it->second->used;
      if (it != reports.end())
        errors += fmt::format("{}{} {}", errors.empty() ? "" : "; ", t.label,
                              t.used ? fmt::format("{:.2f} px RMS", it->second->rms_px)
                                     : "rejected: " + it->second->reason);
      v.tags.push_back(t);
    }
    v.title = {fmt::format("pair {}: {} + {}", i, p.image, p.capture),
               errors.empty() ? std::string("no tag paired") : errors};
    const std::string path = fmt::format("{}-pair{}.png", prefix, i);
    draw::write_calibration_view(v, path);
    fmt::print(stderr, "wrote {}\n", path);
  }
}

int run_calibrate(const CalibrateArgs& args) {
  const calib::CameraModel camera = calib::load_intrinsics(args.camera);
  det::DetectorOptions options;
  if (!args.families.empty()) options.families = args.families;
  if (!args.tag_sizes.empty()) options.tag_sizes_m = args.tag_sizes;
  det::validate_options(options);
  calib::ImageTagOptions io;
  io.families = options.families;
  calib::ImageTagDetector image_detector(io);

  std::vector<PairInput> inputs;
  std::vector<calib::TagPose> poses;
  std::vector<std::pair<std::string, std::string>> pairs = args.pairs;
  std::vector<PairInput> unmatched;  // reported after the pairs, which keep their numbers
  for (const std::string& dir : args.pairs_dirs) {
    FolderPairs found = pairs_in_folder(dir);
    if (found.pairs.empty() && found.unmatched.empty())
      spdlog::warn("{}: no image or capture in the folder", dir);
    pairs.insert(pairs.end(), found.pairs.begin(), found.pairs.end());
    // A file without its partner is reported as a pair that cannot be used.
    for (const auto& [file, why] : found.unmatched) {
      PairInput p;
      (is_image_name(file) ? p.image : p.capture) = file;
      p.error = why;
      spdlog::warn("{}: not used: {}", file, why);
      unmatched.push_back(std::move(p));
    }
  }
  if (pairs.empty() && unmatched.empty())
    throw UsageError("no pair to calibrate from: give --pair IMAGE CAPTURE or --pairs-dir DIR");
  for (size_t i = 0; i < pairs.size(); ++i) {
    PairInput p;
    p.image = pairs[i].first;
    p.capture = pairs[i].second;
    try {
      p.image_tags = image_tags_of(p.image, camera, image_detector, args, p.image_pixels);
      p.lidar_tags = lidar_tags_of(p.capture, args, options, p.rotations, p.points);
    } catch (const std::exception& e) {
      // One bad pair is reported; the others still calibrate.
      p.error = e.what();
      spdlog::warn("pair {}: {}", i, p.error);
      inputs.push_back(std::move(p));
      continue;
    }
    p.pairing = calib::pair_tags(p.lidar_tags, p.image_tags, fmt::format("pair {}", i));
    if (p.image_tags.empty()) spdlog::warn("pair {}: no tag in {}", i, p.image);
    if (p.lidar_tags.empty()) spdlog::warn("pair {}: no tag in {}", i, p.capture);
    for (const auto& u : p.pairing.unpaired)
      spdlog::warn("pair {}: {} not paired: {}", i, u.label, u.reason);
    poses.insert(poses.end(), p.pairing.poses.begin(), p.pairing.poses.end());
    inputs.push_back(std::move(p));
  }
  for (PairInput& p : unmatched) inputs.push_back(std::move(p));
  if (poses.empty())
    throw calib::CalibrationError(
        "no tag was seen by both the camera and the LiDAR in any pair (see the warnings above)");
  const calib::CalibrationResult r = calib::solve_extrinsic(camera, poses);
  const calib::FrameNames frames{args.lidar_frame, args.camera_frame};
  nlohmann::json j = calib::calibration_json(r, frames);
  j["camera_file"] = args.camera;
  for (const auto& p : inputs) j["pairs"].push_back(pair_json(p));
  if (!args.out.empty()) {
    std::ofstream f(args.out);
    f << j.dump(2) << "\n";
    if (!f) throw std::runtime_error(fmt::format("{}: cannot write the result", args.out));
  }
  if (!args.pictures.empty()) write_pictures(r, camera, inputs, args.pictures);
  if (args.json) {
    fmt::print("{}\n", j.dump());
  } else {
    print_text(r, inputs, frames, args);
  }
  return 0;
}

const Registrar kCalibrate(
    "calibrate", "Camera-LiDAR extrinsic from LiDARTags seen by both (images and captures)",
    [](CLI::App& app) {
      auto args = std::make_shared<CalibrateArgs>();
      app.add_option("--camera", args->camera,
                     "the camera's intrinsics: ROS camera_info YAML or OpenCV FileStorage YAML")
          ->required()
          ->check(CLI::ExistingFile);
      app.add_option("--pair", args->pairs,
                     "IMAGE CAPTURE: a PNG or JPEG and a pcap or PCD of the same static scene "
                     "(repeat for each pose)");
      app.add_option("--pairs-dir", args->pairs_dirs,
                     "DIR: every image (.png .jpg .jpeg) in it with the capture (.pcap .pcapng "
                     ".pcd) of the same base name (repeat for several folders)")
          ->check(CLI::ExistingDirectory);
      app.add_option("--family", args->families,
                     "tag family (repeat for several; default tag16h5)");
      app.add_option("--tag-size", args->tag_sizes,
                     "full marker size t, white ring included, metres (repeat for several)")
          ->transform(length_in_metres());
      app.add_option("-o,--out", args->out, "result file (JSON) to write");
      app.add_flag("--json", args->json, "print the result as one JSON object");
      app.add_option("--pixel-sigma", args->pixel_sigma,
                     "the image corners' 1-sigma, pixels (AprilTag 3 with refinement)")
          ->capture_default_str()
          ->check(CLI::Range(0.01, 10.0));
      app.add_option("--lidar-frame", args->lidar_frame, "the LiDAR's frame name (URDF, ROS)")
          ->capture_default_str();
      app.add_option("--camera-frame", args->camera_frame, "the camera's optical frame name")
          ->capture_default_str();
      app.add_option("--model", args->model, "the captures' model, when their packets do not say")
          ->check(model_validator());
      app.add_option("--pictures", args->pictures,
                     "PREFIX: write PREFIX-pairN.png per pair: the image with the LiDAR's points "
                     "and both sensors' tag corners");
      return [args] { return run_calibrate(*args); };
    });

}  // namespace
}  // namespace lidartag::cli
