// The detector's options: one plain struct nested per stage (each stage's struct, with the default,
// unit and reason of every field, is in that stage's header), and the one table of their rules,
// visit_options(), which the Detector (validate_options) and the daemon's YAML mapping both use.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lidartag/detector/cluster_validation.hpp"
#include "lidartag/detector/clustering.hpp"
#include "lidartag/detector/corners.hpp"
#include "lidartag/detector/deskew.hpp"
#include "lidartag/detector/edge_features.hpp"
#include "lidartag/detector/plane_fit.hpp"
#include "lidartag/detector/pose_fit.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/options/rules.hpp"

namespace lidartag::detector {

// Setup error: options that cannot work (no tag size, unknown family, a value out of range).
// key() is the dotted option name ("pose.xtol_rel"; empty for a family file that cannot be read),
// value() its value as text, reason() what is wrong.
class OptionsError : public std::invalid_argument {
 public:
  OptionsError(std::string key, std::string value, std::string reason);
  const std::string& key() const { return key_; }
  const std::string& value() const { return value_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string key_, value_, reason_;
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
  FeatureOptions features;       // Sec. IV-A, eq. (1)
  ClusterOptions cluster;        // Sec. IV-B, eq. (2)
  ValidationOptions validation;  // Sec. IV-C: fill-in, eqs. (3)-(6)
  PlaneOptions plane;            // Sec. IV-C: plane fit, kappa
  CornerOptions corners;         // Sec. V-B remark: the outline's corners
  PoseOptions pose;              // Sec. V: eqs. (7)-(10)
  DecodeOptions decode;          // Sec. VI: eqs. (18), (19), (21), (22)
  DeskewOptions deskew;          // before the fits: the points moved to one time (deskew.hpp)
  // Record one ClusterDiagnostic per cluster in ScanResult. Default true.
  bool cluster_diagnostics = true;
  // Output selections (not thresholds: visit_options leaves them to the caller; the daemon maps
  // keep_tag_points to lcm.publish_tag_points).
  // Also return the points of each detection's cluster (ScanResult::tag_points), e.g. to show
  // what the tag was found from. Default false: a copy of each detection's points (about 1,300
  // for a 0.8 m tag at 4 m on a VLP-32C).
  bool keep_tag_points = false;
  // Also return the points of every cluster, as they were when the cluster was accepted or
  // dropped (ScanResult::cluster_points; ClusterDiagnostic and Candidate say where each cluster's
  // are), e.g. to draw why a cluster was rejected; a cluster dropped at clustering, before the
  // fill-in, has its edge features. Default false: a copy of every cluster's points (tens of
  // thousands in a cluttered rotation).
  bool keep_cluster_points = false;
};

// ---- The rules: the project's one vocabulary (lidartag/options/rules.hpp), and the detector's
// own.
namespace rules {
using namespace ::lidartag::rules;

// A family name the detector can load: built in, or FILE.json[:NAME] that reads.
struct KnownFamily {
  using value_type = std::string;
  std::string operator()(const std::string& name) const;
};

}  // namespace rules

// Names of the pose algorithms, for a visitor's choice().
std::vector<std::pair<std::string, PoseAlgorithm>> pose_algorithm_names();

// The rule table: every setting of DetectorOptions with its key, its unit and its rule, nested by
// stage (a visitor as lidartag/options/rules.hpp describes). The daemon's YAML reader, checker and
// printer are such visitors (daemon/src/config.cpp), and so is validate_options. A rule on a list
// (rules::Each) is called per element. Rules between fields are in check_option_relations.
template <class V>
void visit_options(V& v, DetectorOptions& o) {
  using namespace rules;
  v.field("tag_sizes_m", o.tag_sizes_m, each(open(0.0, 20.0)), "m");
  v.field("families", o.families, each(KnownFamily{}), "");
  v.field("cluster_diagnostics", o.cluster_diagnostics, Any{}, "");
  v.section("features", [&](V& s) {
    s.field("ell", o.features.ell, at_least(1), "columns");
    s.field("zeta_m", o.features.zeta_m, above(0.0f), "m");
    s.field("n", o.features.n, at_least(0), "points");
    s.field("max_gap", o.features.max_gap, at_least(0), "columns");
    s.field("min_range_m", o.features.min_range_m, at_least(0.0f), "m");
    s.field("max_range_m", o.features.max_range_m, above(0.0f), "m");
  });
  v.section("cluster", [&](V& s) {
    s.field("linkage_scale", o.cluster.linkage_scale, above(0.0f), "");
    s.field("ring_gap", o.cluster.ring_gap, at_least(1), "rings");
  });
  v.section("validation", [&](V& s) {
    s.field("min_features", o.validation.min_features, at_least(1), "features");
    s.field("min_rings", o.validation.min_rings, at_least(1), "rings");
    s.field("min_returns_per_cell", o.validation.min_returns_per_cell, at_least(0.0f), "points");
    s.field("max_points_scale", o.validation.max_points_scale, above(0.0f), "");
    s.field("fill_margin_m", o.validation.fill_margin_m, at_least(0.0f), "m");
    s.field("gi_ell", o.validation.gi_ell, at_least(1), "columns");
    s.field("boundary_ratio", o.validation.boundary_ratio, at_least(0.0f), "");
    s.field("min_intensity_step", o.validation.min_intensity_step, at_least(0.0f), "intensity");
    s.field("boundary_scale", o.validation.boundary_scale, at_least(0.0f), "");
    s.field("track_boundary_scale", o.validation.track_boundary_scale, at_least(0.0f), "");
    s.field("track_returns_per_cell", o.validation.track_returns_per_cell, at_least(0.0f),
            "points");
    s.field("track_testable_per_transition", o.validation.track_testable_per_transition,
            above(0.0f), "points");
    s.field("track_transitions_per_ring", o.validation.track_transitions_per_ring, at_least(0.0f),
            "boundary points");
    s.field("min_ring_width", o.validation.min_ring_width, half_open(0.0f, 1.0f), "tag sizes");
  });
  v.section("plane", [&](V& s) {
    s.field("inlier_m", o.plane.inlier_m, above(0.0f), "m");
    s.field("max_outlier_ratio", o.plane.max_outlier_ratio, half_open(0.0f, 1.0f), "");
    s.field("iterations", o.plane.iterations, at_least(1), "hypotheses");
    s.field("miss_probability", o.plane.miss_probability, open(0.0f, 1.0f), "");
    s.field("score_points", o.plane.score_points, at_least(0), "points");
  });
  v.section("corners", [&](V& s) {
    s.field("line_inlier_m", o.corners.line_inlier_m, above(0.0f), "m");
    s.field("line_iterations", o.corners.line_iterations, at_least(1), "hypotheses");
    s.field("min_line_points", o.corners.min_line_points, at_least(2), "points");
    s.field("corner_exclusion", o.corners.corner_exclusion, half_open(0.0f, 0.5f), "sides");
    s.field("size_tolerance", o.corners.size_tolerance, above(0.0f), "");
    s.field("board_margin_m", o.corners.board_margin_m, at_least(0.0f), "m");
    s.field("max_side_angle_deg", o.corners.max_side_angle_deg, open_closed(0.0f, 90.0f), "deg");
    s.field("square_fit", o.corners.square_fit, Any{}, "");
    s.field("square_fit_max_rms", o.corners.square_fit_max_rms, open(0.0f, 1.0f), "sides");
  });
  v.section("pose", [&](V& s) {
    s.choice("algorithm", o.pose.algorithm, pose_algorithm_names());
    s.field("translation_bound_m", o.pose.translation_bound_m, above(0.0), "m");
    s.field("rotation_bound_rad", o.pose.rotation_bound_rad, above(0.0), "rad");
    s.field("xtol_rel", o.pose.xtol_rel, at_least(0.0), "");
    s.field("xtol_abs", o.pose.xtol_abs, at_least(0.0), "m, rad");
    s.field("max_evaluations", o.pose.max_evaluations, at_least(1), "evaluations");
    s.field("min_depth_epsilon_m", o.pose.min_depth_epsilon_m, above(0.0), "m");
    s.field("max_mean_cost_m", o.pose.max_mean_cost_m, above(0.0), "m");
    s.field("min_coverage", o.pose.min_coverage, closed(0.0, 1.0), "t^2");
    s.field("max_points", o.pose.max_points, at_least(8), "points");
    s.field("polish_evaluations", o.pose.polish_evaluations, at_least(0), "evaluations");
    s.field("polish_max_points", o.pose.polish_max_points, at_least(0), "points");
    s.field("border_refine", o.pose.border_refine, Any{}, "");
    s.field("size_warning_ratio", o.pose.size_warning_ratio, open(0.0, 1.0), "");
    s.field("retry_mean_cost_m", o.pose.retry_mean_cost_m, at_least(0.0), "m");
  });
  v.section("decode", [&](V& s) {
    s.field("samples_per_cell", o.decode.samples_per_cell, closed(1, 8), "samples");
    s.field("length_scale_cells", o.decode.length_scale_cells, above(0.0), "cells");
    s.field("intensity_length_scale", o.decode.intensity_length_scale, above(0.0), "");
    s.field("lift_cells", o.decode.lift_cells, at_least(0.0), "cells");
    s.field("min_contrast", o.decode.min_contrast, at_least(0.0), "intensity");
    s.field("min_score", o.decode.min_score, closed(0.0, 1.0), "");
    s.field("min_margin_bits", o.decode.min_margin_bits, at_least(0.0), "cells");
    s.field("min_margin_bits_searched", o.decode.min_margin_bits_searched, at_least(0.0), "cells");
    s.field("parallel_min_functions", o.decode.parallel_min_functions, at_least(1), "functions");
    s.field("max_points", o.decode.max_points, at_least(16), "points");
    s.field("reject_other_families", o.decode.reject_other_families, Any{}, "");
    s.field("other_family_min_score", o.decode.other_family_min_score, closed(0.0, 1.0), "");
    s.field("vote_inset_cells", o.decode.vote_inset_cells, half_open(0.0, 0.5), "cells");
    s.field("min_seen_margin_cells", o.decode.min_seen_margin_cells, at_least(0.0), "cells");
    s.field("min_returns_per_cell", o.decode.min_returns_per_cell, at_least(0.0), "points");
  });
  v.section("deskew", [&](V& s) { s.field("enabled", o.deskew.enabled, Any{}, ""); });
}

// Rules between fields (features.max_range_m above features.min_range_m). Throws OptionsError.
void check_option_relations(const DetectorOptions& options);

// Every rule of visit_options and check_option_relations: what the Detector constructor checks.
// Throws OptionsError naming the first bad option.
void validate_options(const DetectorOptions& options);

}  // namespace lidartag::detector
