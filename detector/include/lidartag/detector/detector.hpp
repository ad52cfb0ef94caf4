// The LiDARTag detector (paper Secs. IV-VI) as a pure library: a rotation in, detections,
// candidates and per-stage statistics out. No I/O, no global state. One Detector is used by one
// thread at a time.
#pragma once

#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "lidartag/detector/cluster_validation.hpp"
#include "lidartag/detector/clustering.hpp"
#include "lidartag/detector/corners.hpp"
#include "lidartag/detector/decode_cluster.hpp"
#include "lidartag/detector/edge_features.hpp"
#include "lidartag/detector/options.hpp"
#include "lidartag/detector/plane_fit.hpp"
#include "lidartag/detector/pose_fit.hpp"
#include "lidartag/detector/result.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/types.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

// What the detector derives from its options once; passed to the stages as arguments.
struct DetectorLimits {
  double t_max = 0.0;             // the largest tag size, metres
  double board_max = 0.0;         // t_max + 2 corners.board_margin_m: the largest board
  float tau_m = 0.0f;             // eq. (2): linkage_scale * t_max * sqrt(2) / 4
  float max_pair_chord_m = 0.0f;  // ring runs paired as one object: 1.1 x board_max's diagonal
  float max_extent_m = 0.0f;      // clusters split above 1.25 x board_max's diagonal
  int min_points = 0;             // eq. (3) with min_returns_per_cell, smallest over the families
  int min_track_points = 0;       // the same with track_returns_per_cell (at most the above)
  int psi = 0;                    // eq. (6)'s 2 (d + 2), smallest over the families
  int min_boundary_points = 0;    // eq. (6) with boundary_scale, smallest over the families
  int min_track_boundary_points = 0;  // the same with track_boundary_scale (at most the above)
  float min_ring_width_m = 0.0f;      // validation.min_ring_width x the smallest tag size
};
DetectorLimits derive_limits(const DetectorOptions& options,
                             std::span<const RkhsDictionary> dictionaries);

class Detector {
 public:
  // Validates the options (validate_options) and builds the RKHS function dictionaries. Throws
  // OptionsError.
  explicit Detector(DetectorOptions options);
  ~Detector();
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  const DetectorOptions& options() const { return opt_; }
  const DetectorLimits& limits() const { return limits_; }
  // One per configured family, in DetectorOptions::families order.
  const std::vector<RkhsDictionary>& dictionaries() const { return dicts_; }
  // For a cluster rejected as another family's tag, the built-in family that fits it better
  // (its candidate's Candidate::other_family); empty otherwise.
  std::string_view other_family_of(const ScanResult& result, const ClusterDiagnostic& c) const;

  // Detects the tags of one rotation into `out` (cleared first). Never throws; reuses the
  // detector's buffers, so it does not allocate once they have grown to the scene. A scan whose
  // sizes disagree with its storage is refused (ScanResult::refused); if memory runs out part-way,
  // what was found so far is kept and ScanResult::truncated is set.
  void detect(const Scan& scan, ScanResult& out) noexcept;
  // The same with what is known of the sensor's motion during the scan: with
  // DeskewOptions::enabled, each cluster's points are moved to its centre time with it before
  // the fits (deskew.hpp); `motion.ego` is read during the call only. Without deskew, the same as
  // detect(scan, out).
  void detect(const Scan& scan, ScanResult& out, const SensorMotion& motion) noexcept;

 private:
  struct Buffers;
  void detect_clusters(const Scan& scan, ScanResult& out, const SensorMotion& motion);
  void process_cluster(const Scan& scan, int cluster, double horizontal_res_rad,
                       const SensorMotion& motion, ScanResult& out);
  int add_candidate(const ClusterDecode& decoded, const Eigen::Vector3d& center,
                    const Eigen::Matrix3d& undecoded, double t, int points, double fit_cost,
                    double coverage, ScanResult& out);

  DetectorOptions opt_;
  std::vector<RkhsDictionary> dicts_;
  // The built-in families not configured (decode.reject_other_families): a cluster that one of
  // them fits better is a tag of another family.
  std::vector<RkhsDictionary> decoys_;
  DetectorLimits limits_;
  std::unique_ptr<Buffers> buf_;
};

}  // namespace lidartag::detector
