// The calibration benchmark of issue 30 (docs/calibration.md, "Benchmark"): for each row and seed,
// a calibration data set from the simulator (`lidartag sim` with a `camera:` section and a
// `series:` of 9 tag poses: the LiDAR's captures and the camera's rendered PNGs), a hidden random
// extrinsic per seed, then `lidartag calibrate` itself on those files: the image tags detected in
// the rendered images, the LiDAR tags by the detector and tracker over each capture's rotations.
// The true error of its answer against the hidden extrinsic, whether its reported 1-sigma covers
// that error, its held-out reprojection and its own run time, as a Markdown table of medians.
//
//   bench_calibration [--seeds N] [--first-seed N] [--rows vlp32c,vlp16,degenerate] [--supersample
//   S]
//                     [--rotations N] [--work DIR] [--keep]
//
// --keep leaves the data sets in --work DIR; a later run with the same DIR and options uses them
// again (only the calibration runs), e.g. after a change to the calibration.
// Rendering dominates (about 2 s per 1280 x 720 image at supersample 2 on one core): a full table
// (3 rows x 10 seeds x 9 images) takes 10-20 minutes. The figures are the command's, run as a
// user runs it; the benchmark adds nothing to the solver's inputs.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "bench_report.hpp"

namespace {

namespace fs = std::filesystem;
using lidartag::bench_report::fmt;
using lidartag::bench_report::median;

constexpr const char* kProgram = "bench_calibration";
constexpr double kDeg = std::numbers::pi / 180.0;

// The camera of the rows: 1280 x 720, fx 900, plumb-bob (k1 k2 p1 p2 k3).
constexpr int kWidth = 1280, kHeight = 720;
constexpr double kFx = 900.0, kCx = (kWidth - 1) / 2.0, kCy = (kHeight - 1) / 2.0;
constexpr std::array<double, 5> kDistortion{-0.12, 0.06, 0.0008, -0.0005, 0.0};
constexpr double kSensorHeight = 1.2;  // m, world z of the LiDAR
constexpr int kPoses = 9;

struct Row {
  std::string name;       // as in --rows
  std::string model;      // the simulator's sensor model
  double fov_lo, fov_hi;  // the sensor's vertical field of view, degrees
  bool degenerate;        // every pose at one spot
  double target_deg, target_mm, target_px;
};

const std::vector<Row> kRows = {
    {"vlp32c", "vlp32c", -25.0, 15.0, false, 0.1, 5.0, 1.0},
    {"vlp16", "vlp16", -15.0, 15.0, false, 0.2, 10.0, 1.5},
    {"degenerate", "vlp32c", -25.0, 15.0, true, 0.1, 5.0, 1.0},
};

// Uniform in [a, b) from the generator's bits (the std:: distributions differ between libraries).
double uniform(std::mt19937_64& rng, double a, double b) {
  return a + (b - a) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

struct Pose {
  Eigen::Vector3d center;  // world, m
  Eigen::Vector3d normal;  // world, out of the printed face
  int rotation_deg = 0;
};

struct DataSet {
  Eigen::Quaterniond rotation;  // lidar_to_camera (the hidden truth)
  Eigen::Vector3d translation;
  double tag_size = 1.0;
  std::vector<Pose> poses;
};

// A random unit vector perpendicular to n.
Eigen::Vector3d perpendicular(std::mt19937_64& rng, const Eigen::Vector3d& n) {
  const Eigen::Vector3d a = n.unitOrthogonal(), b = n.cross(a);
  const double phi = uniform(rng, 0.0, 2.0 * std::numbers::pi);
  return std::cos(phi) * a + std::sin(phi) * b;
}

// The hidden extrinsic: the camera looking along the LiDAR's +x (its optical frame's default),
// turned by up to 5 degrees about a random axis, and up to 0.2 m off along each axis; a tag size
// of 0.8-1.2 m; 9 poses, one per ninth of the image, at 2-8 m (a near, a middle and a far band
// spread over the rows and columns), each tilted up to 30 degrees from facing the camera and
// turned in its plane at random. A pose is kept only where the whole tag is in the image and in
// the LiDAR's vertical field of view and above the ground; a ninth where no such pose is found
// gives its pose to another row of the image, then another distance.
DataSet make_data_set(const Row& row, uint64_t seed) {
  std::mt19937_64 rng(seed * 7919 + (row.model == "vlp16" ? 1 : 0) + (row.degenerate ? 2 : 0));
  DataSet d;
  const Eigen::Vector3d axis =
      Eigen::Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)).normalized();
  d.rotation = Eigen::AngleAxisd(uniform(rng, 1.0, 5.0) * kDeg, axis) *
               Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5);
  d.rotation.normalize();
  d.translation = {uniform(rng, -0.2, 0.2), uniform(rng, -0.2, 0.2), uniform(rng, -0.2, 0.2)};
  d.tag_size = uniform(rng, 0.8, 1.2);
  const Eigen::Matrix3d lidar_from_camera = d.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d camera_in_lidar = -lidar_from_camera * d.translation;
  const double radius = d.tag_size * std::numbers::sqrt2 / 2;  // centre to a corner, any turn
  auto place = [&](double u, double v, double range) -> std::optional<Pose> {
    const Eigen::Vector3d ray = Eigen::Vector3d((u - kCx) / kFx, (v - kCy) / kFx, 1).normalized();
    const Eigen::Vector3d in_lidar = camera_in_lidar + range * (lidar_from_camera * ray);
    // In the image with a 15 px margin (the pinhole radius, plus a tenth for the lens).
    const double r_px = 1.1 * kFx * radius / range + 15;
    if (u - r_px < 0 || u + r_px > kWidth - 1 || v - r_px < 0 || v + r_px > kHeight - 1)
      return std::nullopt;
    // In the LiDAR's vertical field of view (a degree to spare) and above the ground.
    const double horizontal = in_lidar.head<2>().norm();
    const double top = std::atan2(in_lidar.z() + radius, horizontal) / kDeg;
    const double bottom = std::atan2(in_lidar.z() - radius, horizontal) / kDeg;
    if (top > row.fov_hi - 1 || bottom < row.fov_lo + 1) return std::nullopt;
    if (in_lidar.z() + kSensorHeight - radius < 0.2) return std::nullopt;
    Pose p;
    p.center = in_lidar + Eigen::Vector3d(0, 0, kSensorHeight);
    // Facing the camera, tilted by up to 30 degrees.
    const Eigen::Vector3d facing = -(lidar_from_camera * ray);
    p.normal = Eigen::AngleAxisd(uniform(rng, 0, 30) * kDeg, perpendicular(rng, facing)) * facing;
    p.rotation_deg = static_cast<int>(uniform(rng, 0, 90));
    return p;
  };
  if (row.degenerate) {
    // Every pose at one spot: 5 m, the image centre, facing the camera, turned 45 degrees.
    const std::optional<Pose> p = place(kCx, kCy, 5.0);
    if (!p) throw std::runtime_error("the degenerate pose does not fit");
    for (int i = 0; i < kPoses; ++i) {
      Pose q = *p;
      q.normal = -(lidar_from_camera * Eigen::Vector3d::UnitZ());
      q.rotation_deg = 45;  // a diamond: a square tag facing the sensor is not always found
      d.poses.push_back(q);
    }
    return d;
  }
  for (int i = 0; i < kPoses; ++i) {
    const int cell_row = i / 3, cell_col = i % 3, band = (cell_row + cell_col) % 3;
    std::optional<Pose> p;
    for (int attempt = 0; attempt < 4000 && !p; ++attempt) {
      // The top ninths are mostly above a Velodyne's field of view (+15 degrees; the image's
      // top edge is +22): after 1000 attempts the pose may take any row of the image, after
      // 2000 any distance too.
      const bool any_row = attempt >= 1000, any_range = attempt >= 2000;
      const double near = any_range ? 2.0 : 2.0 + 2.0 * band, far = any_range ? 8.0 : near + 2.0;
      const double v =
          any_row ? uniform(rng, 0, kHeight) : uniform(rng, cell_row, cell_row + 1) * kHeight / 3.0;
      p = place(uniform(rng, cell_col, cell_col + 1) * kWidth / 3.0, v, uniform(rng, near, far));
    }
    if (!p) throw std::runtime_error("no pose fits ninth " + std::to_string(i) + " of the image");
    d.poses.push_back(*p);
  }
  return d;
}

std::string vec(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s.precision(9);
  s << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return s.str();
}

void write_scene(const fs::path& path, const Row& row, const DataSet& d, int supersample,
                 int rotations, uint64_t seed) {
  std::ofstream f(path);
  f.precision(9);
  f << "sensor: {model: " << row.model << ", height: " << kSensorHeight << "}\n"
    << "world: {room: {center: [5, 0], size: [20, 16], height: 4.0}}\n"
    << "camera: {width: " << kWidth << ", height: " << kHeight << ", fx: " << kFx
    << ", distortion_model: plumb_bob,\n  distortion_coefficients: [" << kDistortion[0] << ", "
    << kDistortion[1] << ", " << kDistortion[2] << ", " << kDistortion[3] << ", " << kDistortion[4]
    << "],\n  rotation_wxyz: [" << d.rotation.w() << ", " << d.rotation.x() << ", "
    << d.rotation.y() << ", " << d.rotation.z() << "],\n  translation_m: " << vec(d.translation)
    << ", supersample: " << supersample << "}\n"
    << "rotations: " << rotations << "\nseed: " << seed << "\n"
    << "tags:\n  - {family: tag36h11, id: 5, size: " << d.tag_size
    << ", center: " << vec(d.poses[0].center) << "}\nseries:\n";
  for (const Pose& p : d.poses)
    f << "  - {center: " << vec(p.center) << ", normal: " << vec(p.normal)
      << ", rotation: " << p.rotation_deg << "}\n";
  if (!f) throw std::runtime_error(path.string() + ": cannot write");
}

// The intrinsics as ROS writes them.
void write_camera(const fs::path& path) {
  std::ofstream f(path);
  f.precision(9);
  f << "image_width: " << kWidth << "\nimage_height: " << kHeight << "\ncamera_name: sim\n"
    << "camera_matrix: {rows: 3, cols: 3, data: [" << kFx << ", 0, " << kCx << ", 0, " << kFx
    << ", " << kCy << ", 0, 0, 1]}\ndistortion_model: plumb_bob\n"
    << "distortion_coefficients: {rows: 1, cols: 5, data: [" << kDistortion[0] << ", "
    << kDistortion[1] << ", " << kDistortion[2] << ", " << kDistortion[3] << ", " << kDistortion[4]
    << "]}\n";
  if (!f) throw std::runtime_error(path.string() + ": cannot write");
}

std::string read_file(const fs::path& path) {
  std::ifstream f(path);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

struct Run {
  std::string out;
  int status = 0;
  double wall_s = 0, cpu_s = 0;  // the child's wall time and its user + system CPU time
};

double children_cpu_s() {
  rusage u{};
  ::getrusage(RUSAGE_CHILDREN, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// `command`'s stdout, exit status and times (stderr goes to `err`).
Run run(const std::string& command, const fs::path& err) {
  Run r;
  const double cpu0 = children_cpu_s();
  const auto t0 = std::chrono::steady_clock::now();
  FILE* pipe = ::popen((command + " 2>" + err.string()).c_str(), "r");
  if (!pipe) throw std::runtime_error("cannot run " + command);
  std::array<char, 4096> buf{};
  size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.out.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpu_s = children_cpu_s() - cpu0;
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

struct Outcome {
  bool solved = false;
  double rot_err_deg = NAN, trans_err_mm = NAN, rot_sigma_deg = NAN, trans_sigma_mm = NAN;
  double held_out_px = NAN, wall_s = NAN, cpu_s = NAN;
  int poses_used = 0;
  std::string weak;  // the weakest direction named, "" when none
  std::string lost;  // the poses not used and why
  std::string error;
};

Outcome evaluate(const Run& r, const DataSet& d) {
  Outcome o;
  o.wall_s = r.wall_s;
  o.cpu_s = r.cpu_s;
  if (r.status != 0) {
    o.error = "exit status " + std::to_string(r.status);
    return o;
  }
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const auto& q = j["lidar_to_camera"]["rotation_wxyz"];
  const Eigen::Quaterniond rot(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(),
                               q[3].get<double>());
  const auto& t = j["lidar_to_camera"]["translation_m"];
  const Eigen::Vector3d tr(t[0].get<double>(), t[1].get<double>(), t[2].get<double>());
  const auto& sigma = j["lidar_to_camera"]["sigma"];
  o.solved = true;
  o.rot_err_deg = rot.angularDistance(d.rotation) / kDeg;
  o.trans_err_mm = 1000.0 * (tr - d.translation).norm();
  o.rot_sigma_deg = sigma["rotation_total_deg"].get<double>();
  const auto& ts = sigma["translation_mm"];
  o.trans_sigma_mm = std::hypot(ts[0].get<double>(), ts[1].get<double>(), ts[2].get<double>());
  o.held_out_px = j["errors"]["held_out_median_px"].get<double>();
  o.poses_used = j["poses_used"].get<int>();
  for (const auto& p : j["pairs"]) {
    if (p.value("paired", 0) > 0) continue;
    o.lost += "; " + fs::path(p["image"].get<std::string>()).stem().string() + " not paired (" +
              (p.contains("error")
                   ? p["error"].get<std::string>()
                   : "image tags " + p.value("image_tags", nlohmann::json::array()).dump() +
                         ", LiDAR tags " + p.value("lidar_tags", nlohmann::json::array()).dump()) +
              ")";
  }
  for (const auto& p : j["poses_rejected"])
    o.lost += "; " + p["label"].get<std::string>() + " rejected: " + p["reason"].get<std::string>();
  const auto& weak = j["degeneracy"]["weak"];
  if (weak.is_array() && !weak.empty()) o.weak = weak[0]["name"].get<std::string>();
  return o;
}

int run_benchmark(int argc, char** argv) {
  int seeds = 10, first_seed = 1, supersample = 2, rotations = 10;
  std::string rows = "vlp32c,vlp16,degenerate", work, cli = LIDARTAG_CLI;
  bool keep = false;
  std::string command = kProgram;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seeds") {
      seeds = lidartag::bench_args::count(kProgram, argc, argv, i, "--seeds", 1, command);
    } else if (a == "--first-seed") {
      first_seed = lidartag::bench_args::count(kProgram, argc, argv, i, "--first-seed", 1, command);
    } else if (a == "--supersample") {
      supersample =
          lidartag::bench_args::count(kProgram, argc, argv, i, "--supersample", 1, command);
    } else if (a == "--rotations") {
      rotations = lidartag::bench_args::count(kProgram, argc, argv, i, "--rotations", 1, command);
    } else if (a == "--rows") {
      rows = lidartag::bench_args::value(kProgram, argc, argv, i, "--rows");
      command += " --rows " + rows;
    } else if (a == "--work") {
      work = lidartag::bench_args::value(kProgram, argc, argv, i, "--work");
    } else if (a == "--cli") {
      cli = lidartag::bench_args::value(kProgram, argc, argv, i, "--cli");
    } else if (a == "--keep") {
      keep = true;
    } else {
      std::fprintf(stderr,
                   "usage: %s [--seeds N] [--first-seed N] [--rows vlp32c,vlp16,degenerate] "
                   "[--supersample S] "
                   "[--rotations N] [--work DIR] [--keep] [--cli PATH]\n",
                   kProgram);
      return 2;
    }
  }
  const fs::path root =
      work.empty() ? fs::temp_directory_path() / ("bench_calibration_" + std::to_string(::getpid()))
                   : fs::path(work);
  fs::create_directories(root);
  write_camera(root / "camera.yaml");

  std::printf(
      "| row | seeds solved | poses used (median) | rotation error, deg | translation error, mm "
      "| held-out px | rotation within 2 sigma | translation within 2 sigma | calibrate wall s "
      "(CPU s) | weak direction named | target |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|\n");
  std::fflush(stdout);
  for (const Row& row : kRows) {
    if (("," + rows + ",").find("," + row.name + ",") == std::string::npos) continue;
    std::vector<Outcome> outcomes;
    for (int s = first_seed; s < first_seed + seeds; ++s) {
      const DataSet d = make_data_set(row, static_cast<uint64_t>(s));
      const fs::path dir = root / (row.name + "_" + std::to_string(s));
      fs::create_directories(dir);
      // A data set kept by an earlier run (--keep) of the same scene is used again.
      const std::string kept = read_file(dir / "scene.yaml");
      write_scene(dir / "scene.yaml", row, d, supersample, rotations, static_cast<uint64_t>(s));
      Run sim;
      if (kept.empty() || kept != read_file(dir / "scene.yaml") ||
          !fs::exists(dir / ("cal_0" + std::to_string(kPoses - 1) + ".png"))) {
        sim = run(
            cli + " sim " + (dir / "scene.yaml").string() + " --out " + (dir / "cal.pcap").string(),
            dir / "sim.err");
        if (sim.status != 0) throw std::runtime_error("lidartag sim failed in " + dir.string());
      }
      std::string pairs;
      for (int i = 0; i < kPoses; ++i) {
        const std::string n = (dir / ("cal_0" + std::to_string(i))).string();
        pairs += " --pair " + n + ".png " + n + ".pcap";
      }
      std::ostringstream size;
      size.precision(9);
      size << d.tag_size;
      const Run cal = run(cli + " calibrate --camera " + (root / "camera.yaml").string() + pairs +
                              " --family tag36h11 --tag-size " + size.str() + " --json",
                          dir / "calibrate.err");
      Outcome o = evaluate(cal, d);
      std::fprintf(stderr,
                   "%s seed %d: sim %.0f s; calibrate %.2f s wall, %.2f s CPU; %s rotation %.4f "
                   "deg (1 sigma %.4f), translation %.2f mm (1 sigma %.2f), held out %.2f px, "
                   "%d poses%s%s%s\n",
                   row.name.c_str(), s, sim.wall_s, o.wall_s, o.cpu_s,
                   o.solved ? "" : o.error.c_str(), o.rot_err_deg, o.rot_sigma_deg, o.trans_err_mm,
                   o.trans_sigma_mm, o.held_out_px, o.poses_used,
                   o.weak.empty() ? "" : "; weak: ", o.weak.c_str(), o.lost.c_str());
      outcomes.push_back(o);
      if (!keep) fs::remove_all(dir);
    }
    std::vector<double> rot, trans, held, wall, cpu, used;
    int solved = 0, rot_in = 0, trans_in = 0, weak = 0;
    std::string weak_name;
    for (const Outcome& o : outcomes) {
      wall.push_back(o.wall_s);
      cpu.push_back(o.cpu_s);
      if (!o.solved) continue;
      ++solved;
      rot.push_back(o.rot_err_deg);
      trans.push_back(o.trans_err_mm);
      held.push_back(o.held_out_px);
      used.push_back(o.poses_used);
      rot_in += o.rot_err_deg <= 2 * o.rot_sigma_deg;
      trans_in += o.trans_err_mm <= 2 * o.trans_sigma_mm;
      if (!o.weak.empty()) {
        ++weak;
        if (weak_name.empty()) weak_name = o.weak;
      }
    }
    const int n = static_cast<int>(outcomes.size());
    std::string target;
    if (row.degenerate) {
      target = "weak direction named in every seed: " + std::string(weak == n ? "met" : "missed");
    } else {
      const bool met = solved == n && median(rot) <= row.target_deg &&
                       median(trans) <= row.target_mm && median(held) <= row.target_px &&
                       rot_in * 10 >= 9 * n && trans_in * 10 >= 9 * n && median(wall) <= 10.0;
      target = fmt(row.target_deg, 1) + " deg, " + fmt(row.target_mm, 0) + " mm, " +
               fmt(row.target_px, 1) + " px, 90 %, 10 s: " + (met ? "met" : "missed");
    }
    std::printf(
        "| %s | %d/%d | %s | %s | %s | %s | %d/%d | %d/%d | %s (%s) | %d/%d%s | %s |\n",
        row.name.c_str(), solved, n, fmt(median(used), 0).c_str(), fmt(median(rot), 3).c_str(),
        fmt(median(trans), 1).c_str(), fmt(median(held), 2).c_str(), rot_in, solved, trans_in,
        solved, fmt(median(wall), 2).c_str(), fmt(median(cpu), 2).c_str(), weak, n,
        (weak_name.empty() ? std::string() : " (e.g. " + weak_name + ")").c_str(), target.c_str());
    std::fflush(stdout);
  }
  std::printf("\nrun with: %s (supersample %d); %s\n", command.c_str(), supersample,
              lidartag::bench_report::machine().c_str());
  if (!keep && work.empty()) fs::remove_all(root);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return lidartag::bench_args::run_reporting_errors(kProgram,
                                                    [&] { return run_benchmark(argc, argv); });
}
