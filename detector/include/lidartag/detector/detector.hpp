// The LiDARTag detector (paper Secs. IV-VI) as a pure library: a rotation in, detections and
// per-stage statistics out. No I/O, no global state. One Detector is used by one thread at a time.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/detector/cluster_validation.hpp"
#include "lidartag/detector/clustering.hpp"
#include "lidartag/detector/corners.hpp"
#include "lidartag/detector/edge_features.hpp"
#include "lidartag/detector/plane_fit.hpp"
#include "lidartag/detector/pose_fit.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/types.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

// Setup error: options that cannot work (no tag size, unknown family, a threshold out of range).
class OptionsError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// Every threshold of the pipeline, nested per stage; the defaults work on the bundled scenes.
struct DetectorOptions {
  // Sizes of the tags to find, metres: the full outer size of the printed marker (white ring
  // included; for 16-bit families 8 cells). Default {1.2}. The side length measured from the
  // points selects the nearest one; sizes closer than ~25 % are hard to tell apart.
  std::vector<double> tag_sizes_m = {1.2};
  // Families to decode: built-in names (tag16h5, tag25h9, tag36h10, tag36h11, tag16h6) or
  // "FILE.json[:NAME]". Default {"tag16h5"}. Each adds its dictionary to every decode.
  std::vector<std::string> families = {"tag16h5"};
  FeatureOptions features;       // stage 1, eq. (GD)
  ClusterOptions cluster;        // stage 2, eq. (linkage)
  ValidationOptions validation;  // stage 3, fill-in, point counts, eq. (GI)
  PlaneOptions plane;            // stage 3, plane fit, kappa
  CornerOptions corners;         // stage 4
  PoseOptions pose;              // stage 5, eqs. (L1cost), (JKHcost), (Pose)
  DecodeOptions decode;          // stage 6, eqs. (InnerProduct), (kernel), (kernel_intensity)
  // Record one ClusterDiagnostic per cluster in ScanResult. Default true.
  bool cluster_diagnostics = true;
  // Also return the points of each detection's cluster (ScanResult::tag_points), e.g. to show
  // what the tag was found from. Default false: a copy of each detection's points (about 1,300
  // for a 0.8 m tag at 4 m on a VLP-32C).
  bool keep_tag_points = false;
};

enum class Stage : uint8_t {
  kFeatures,    // eq. (GD)
  kClustering,  // eq. (linkage)
  kValidation,  // fill-in, point counts, eq. (GI)
  kPlane,       // RANSAC plane, kappa
  kCorners,     // edge lines and intersections
  kPose,        // Procrustes, eq. (Pose), coverage
  kDecode,      // RKHS decoding
  kCount
};
inline constexpr int kStageCount = static_cast<int>(Stage::kCount);
std::string_view stage_name(Stage s);

struct Detection {
  int family_index = 0;                                // into DetectorOptions::families
  std::string_view family;                             // the family's name (owned by the Detector)
  int id = 0;                                          // index of the code in the family
  double size_m = 0.0;                                 // the tag size t that matched
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // tag centre, sensor frame, metres
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // tag frame -> sensor frame
  // Corners of the black square in the sensor frame: bottom-left, bottom-right, top-right,
  // top-left, as seen from the front.
  std::array<Eigen::Vector3d, 4> corners;
  double score = 0.0;     // RKHS decoding score, <= 1
  double margin = 0.0;    // over the second best function, in cells' worth of evidence
  int points = 0;         // points of the cluster used for the pose
  double fit_cost = 0.0;  // eq. (JKHcost) at the optimum, metres summed over the points
  // Its `points` points in ScanResult::tag_points start here; -1 without keep_tag_points.
  int first_point = -1;
};

// What happened to one cluster.
struct ClusterDiagnostic {
  int features = 0;
  int points = 0;  // after fill-in
  int boundary_points = 0;
  Rejection rejection = Rejection::kNone;
  float min_x = 0, max_x = 0, min_y = 0, max_y = 0;
  int min_ring = 0, max_ring = 0;
  // What the later stages measured, -1 when the cluster did not get that far.
  double outlier_ratio = -1;  // plane fit
  double side_m = -1;         // corners: measured side length
  double mean_cost_m = -1;    // pose: eq. (JKHcost) per point after the fit
  double coverage = -1;       // pose: convex hull / t^2
  double score = -1;          // decode: best normalised score
  double margin = -1;         // decode: best minus second best, payload cells
};

struct ScanResult {
  std::vector<Detection> detections;
  std::array<double, kStageCount> timing_ms{};       // wall time per stage in this rotation
  std::array<uint32_t, kRejectionCount> rejected{};  // clusters dropped, by reason
  int features = 0;
  int clusters = 0;
  std::vector<ClusterDiagnostic> diagnostics;  // when DetectorOptions::cluster_diagnostics
  // When DetectorOptions::keep_tag_points: the points each detection's pose was fitted to (sensor
  // frame), one detection after the other; one vector for all, so that it is reused.
  std::vector<ClusterPoint> tag_points;
  double total_ms() const;
  // The points of `d` in tag_points (empty without keep_tag_points).
  std::span<const ClusterPoint> points_of(const Detection& d) const;
  // Clusters rejected at a stage (sum over that stage's reasons).
  uint32_t rejected_at(Stage s) const;
};

// The stage a rejection reason belongs to.
Stage stage_of(Rejection r);

class Detector {
 public:
  // Validates the options and builds the RKHS function dictionaries. Throws OptionsError.
  explicit Detector(DetectorOptions options);
  ~Detector();
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  const DetectorOptions& options() const { return opt_; }
  const std::vector<RkhsDictionary>& dictionaries() const { return dicts_; }

  // Detects the tags of one rotation into `out` (cleared first). Never throws; reuses the
  // detector's buffers, so it does not allocate once they have grown to the scene.
  void detect(const Scan& scan, ScanResult& out) noexcept;

 private:
  struct Buffers;
  void process_cluster(const Scan& scan, int cluster, double horizontal_res_rad, ScanResult& out);

  DetectorOptions opt_;
  std::vector<RkhsDictionary> dicts_;
  // The built-in families not configured (decode.reject_other_families): a cluster that one of
  // them fits better is a tag of another family.
  std::vector<RkhsDictionary> decoys_;
  double t_max_ = 0.0;
  int min_points_ = 0;
  int min_boundary_ = 0;
  float min_ring_width_m_ = 0.0f;
  std::unique_ptr<Buffers> buf_;
};

// Validates options without building a detector (what the Detector constructor checks).
void validate_options(const DetectorOptions& options);

}  // namespace lidartag::detector
