// Stage 5 (paper Sec. V): Procrustes initial guess, eq. (10) [procrustes], solved by eqs.
// (11)-(16); the L1-inspired fitting cost, eqs. (7) [L1cost] and (8) [JKHcost], minimised with
// NLopt using its closed-form gradient, eq. (9) [Pose]; the coverage check (convex hull, surveyor's
// formula).
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

enum class PoseAlgorithm : uint8_t {
  kMMA,     // NLOPT_LD_MMA, gradient based (the paper's choice)
  kCCSAQ,   // NLOPT_LD_CCSAQ, gradient based
  kSLSQP,   // NLOPT_LD_SLSQP, gradient based
  kSBPLX,   // NLOPT_LN_SBPLX, derivative free (the Tier IV fork's choice)
  kBOBYQA,  // NLOPT_LN_BOBYQA, derivative free
};
std::string_view pose_algorithm_name(PoseAlgorithm a);
std::optional<PoseAlgorithm> pose_algorithm_from_name(std::string_view name);

struct PoseOptions {
  // NLopt algorithm for eq. (9). Default MMA: in the comparison printed by
  // test/detector/pose_fit_test.cpp (PoseFit.AlgorithmsCompared) it had the lowest mean
  // translation error with the fewest evaluations (about 56, against about 200 for LN_SBPLX).
  PoseAlgorithm algorithm = PoseAlgorithm::kMMA;
  // Search box around the initial guess: metres and radians. Defaults 0.2 m and 0.5 rad.
  double translation_bound_m = 0.2;
  double rotation_bound_rad = 0.5;
  // Stopping rules: relative parameter tolerance (default 1e-6), absolute parameter tolerance
  // (metres for the translation, radians for the rotation; default 1e-4, i.e. 0.1 mm and 0.006
  // degrees, far below the fit's error) and most cost evaluations (200). The parameters are the
  // offsets from the initial guess, near zero, so the relative rule alone kept MMA going for 50 to
  // 150 evaluations without changing the pose; with the absolute one a fit takes about 25. 0
  // disables the absolute rule.
  double xtol_rel = 1e-6;
  double xtol_abs = 1e-4;
  int max_evaluations = 200;
  // epsilon of eq. (8): the depth slack, the plane's smallest principal standard deviation
  // but at least this many metres. Default 0.01.
  double min_depth_epsilon_m = 0.01;
  // Fit-error gate: largest mean cost per point after the fit, metres. Default 0.05 (the paper
  // rejects above 10 % of the point count, i.e. 0.1 m per point).
  double max_mean_cost_m = 0.05;
  // Coverage: the convex hull of the pulled-back points must cover this fraction of t^2. Default
  // 0.75 (the paper's).
  double min_coverage = 0.75;
  // Most points in the fit: every ring's two end points (the outline, which sets the in-plane
  // pose) and evenly spaced interior points (the depth term) up to this count. Default 256: the
  // cost of a fit grows with points x evaluations; a tag at 4 m has about 1500 points.
  int max_points = 256;
  // Then this many evaluations on every point, from the subsample's optimum within 2 cm and
  // 0.02 rad (the subsample's depth term is noisier). Default 20; 0 skips it.
  int polish_evaluations = 20;
  // A cluster of more points than this is decoded on the subsample's fit and polished (on every
  // point) only when it scores as a tag: most clusters this large are no tag (a 1.2 m board at
  // 3-4 m of a VLP-32C returns 1,400-1,900 points; the polish's cost grows with the points), and
  // a tag this close decodes with a wide margin. Default 1024. 0: every cluster is polished
  // before decoding.
  int polish_max_points = 1024;
  // Place the tag in its plane on the black square's outline (square_fit.hpp) rather than on the
  // board's. Default true.
  bool border_refine = true;
  // The size check (with border_refine): a detection whose measured size (Detection::
  // measured_size_m) differs from the configured size by more than this fraction is flagged
  // (Detection::size_warning). Default 0.03: on the simulator the measured size of a tag given
  // its right size is within 0.1-0.8 % (median per cell) and 1.1 % (p95) of the truth, VLP-16 and
  // VLP-32C, 0.4-1.2 m tags at 2-10 m, face-on and at 45 degrees (docs/size-check.md); a size
  // 5 % off is warned about in every rotation there.
  double size_warning_ratio = 0.03;
  // A fit whose mean cost per point stays above this, metres, is done again from the initial
  // guess turned 45 degrees about the normal, and the better one kept: corners from few rings can
  // be a diamond-mounted tag's read as a square's (or the reverse), a local minimum the fit does
  // not leave. Default 0.005 (right fits of a VLP-16 at 6-10 m cost 2-3 mm; a VLP-16 at 7 m with
  // the tag 6-9 cm off its height was fitted turned 45 degrees at 13-17 mm, then 4-5 mm). 0: off.
  double retry_mean_cost_m = 0.005;
};

// H_T^L: x_tag = R x_sensor + p (the paper's pull-back to the template at the origin).
struct RigidPose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return R * x + p; }
};

// Template corners of a tag of size t: (0, -t/2, -t/2), (0, t/2, -t/2), (0, t/2, t/2),
// (0, -t/2, t/2) (bottom-left, bottom-right, top-right, top-left seen from the front).
std::array<Eigen::Vector3d, 4> template_corners(double t);

// eq. (10): the rotation and translation taking `corners` (sensor frame, in template
// order) onto the template, with the corners' mean mapped to the origin.
RigidPose procrustes_initial_guess(const std::array<Eigen::Vector3d, 4>& corners, double t);

// eq. (8) of the points pulled back by `pose`, with eq. (7) per coordinate.
double fitting_cost(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                    double epsilon);

struct PoseFitResult {
  RigidPose pose;
  double initial_cost = 0.0;
  double cost = 0.0;
  int evaluations = 0;
  bool solver_ok = false;  // NLopt returned a success code
  // fit_tag_pose left the polish of a cluster of more than PoseOptions::polish_max_points points
  // to its caller (polish_tag_pose).
  bool polish_pending = false;
};

// Minimises eq. (8) over SE(3) near `initial` with NLopt. One instance per thread; the
// NLopt object and buffers are kept between calls.
class PoseSolver {
 public:
  explicit PoseSolver(PoseAlgorithm algorithm);
  ~PoseSolver();
  PoseSolver(const PoseSolver&) = delete;
  PoseSolver& operator=(const PoseSolver&) = delete;

  // `weights` (empty: all 1) scale each point's cost: a subsample stands for the points it
  // replaces. PoseFitResult::cost is the weighted sum.
  PoseFitResult fit(std::span<const ClusterPoint> points, double t, double epsilon,
                    const RigidPose& initial, const PoseOptions& opt,
                    std::span<const float> weights = {});

  // The objective in the solver's parameters (rotation vector, translation offset) around the
  // initial guess of the last fit(); public so that its closed-form gradient can be tested.
  double objective(const double* theta, double* grad) const;

 private:
  struct Impl;
  Impl* impl_;
};

// The points of a cluster's pose fit: every ring's two end points (`edge`: the outline, which
// sets the in-plane pose) and evenly spaced interior points (the depth term), at most max_points
// in all, into `subset`; `weights` gets 1 for an edge point and, for an interior point, the number
// of interior points each kept one stands for, so that the depth term keeps its weight against
// the outline (else the fit tilts the plane to pull edge points in).
void select_pose_points(std::span<const ClusterPoint> points, int max_points,
                        std::vector<ClusterPoint>& subset, std::vector<float>& weights);

// Work buffers of fit_tag_pose, kept by the caller between clusters.
struct TagPoseWorkspace {
  std::vector<ClusterPoint> subset;  // select_pose_points
  std::vector<float> weights;
};

// eq. (9) for one cluster from the initial guess `initial` (eq. (10)): minimises eq. (8) with a
// template of size t_fit and depth slack epsilon on the points of select_pose_points
// (ws.subset). A fit whose cost over every point stays above opt.retry_mean_cost_m per point is
// done again from `initial` turned 45 degrees about the normal, and the cheaper kept. When the
// subset was a subsample, only that fit is then polished, with opt.polish_evaluations
// evaluations on every point within 2 cm and 0.02 rad (the subsample's depth term is noisier),
// unless there are more than opt.polish_max_points points: then the polish is left to the caller
// (PoseFitResult::polish_pending). The cost returned is eq. (8) over every point.
PoseFitResult fit_tag_pose(PoseSolver& solver, std::span<const ClusterPoint> points,
                           const RigidPose& initial, double t_fit, double epsilon,
                           const PoseOptions& opt, TagPoseWorkspace& ws);

// The polish on every point from `start`: opt.polish_evaluations evaluations within 2 cm and
// 0.02 rad.
PoseFitResult polish_tag_pose(PoseSolver& solver, std::span<const ClusterPoint> points,
                              const RigidPose& start, double t_fit, double epsilon,
                              const PoseOptions& opt);

// Fraction of t^2 covered by the convex hull of the pulled-back points in the tag's y-z plane
// (surveyor's formula).
double coverage_ratio(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                      std::vector<Eigen::Vector2d>& buffer, std::vector<Eigen::Vector2d>& hull);

// The coverage_ratio a whole tag of side t shows when sampled as `points` (ring by ring, by
// column, as fill_cluster emits them) sample it. A hull of sparse rings misses up to a column step
// at each ring's ends and up to a ring spacing at the top and bottom: at a VLP-32C's 28 m and 45
// degrees a whole 1.2 m tag covers about 0.65 of t^2. Measured in the tag's y-z plane: the rings'
// direction (the longest ring's ends), their spacing (the median gap between neighbouring rings
// across it) and the column step (the median gap between neighbouring points of a ring); the
// tag's square is then sampled on that grid, half a spacing and half a step in from its edges,
// and that sample's hull area is divided by t^2. 1 when the points show no sampling (fewer than
// two rings of two points). `buffer` and `hull` are scratch space.
double sampled_coverage(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                        std::vector<Eigen::Vector2d>& buffer, std::vector<Eigen::Vector2d>& hull);

// The share of t^2 that a cluster for a track alone (issue 33's far edge) is held to, before
// pose.min_coverage: what a whole tag shows at the cluster's sampling (sampled_coverage), times
// n / (n + 1) for a cluster of n rings. One ring that crosses the tag may be missing from one
// rotation's cluster (an edge ring's few returns, lost at clustering); the track's evidence over
// rotations makes up for what that rotation lacks. `buffer` and `hull` are scratch space.
double track_coverage_share(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                            std::vector<Eigen::Vector2d>& buffer,
                            std::vector<Eigen::Vector2d>& hull);

// An upper bound of coverage_ratio before the pose fit, from the hull of the ring ends in the
// cluster's own plane (CornerWorkspace::hull): its area over t^2, divided by kCoverageBoundSlack.
// A rigid pull-back projects the points onto the tag's y-z plane, which cannot enlarge the hull
// of a planar set, and the fit uses a subset of the cluster's points. The slack covers what is not
// quite planar: a ring curves a little between its ends (a cone cut by the plane) and the plane
// fit's normal may be tilted against the pose fit's by a degree or two. A cluster whose bound is
// below pose.min_coverage is rejected without the fit (boards of a configured size but not square,
// half-seen walls).
inline constexpr double kCoverageBoundSlack = 0.98;
double coverage_bound(const std::vector<Eigen::Vector2d>& plane_hull, double t);

}  // namespace lidartag::detector
