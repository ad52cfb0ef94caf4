// Stage 6 for one cluster: shift search along an unseen axis, arbitration between the hypotheses,
// and the check against the families that are not configured.
#include "lidartag/detector/decode_cluster.hpp"

#include <algorithm>
#include <cmath>

namespace lidartag::detector {
namespace {

// Index of the best hypothesis (the first of equal scores).
size_t best_of(const std::vector<DecodeHypothesis>& hypotheses) {
  size_t k = 0;
  for (size_t i = 1; i < hypotheses.size(); ++i)
    if (hypotheses[i].result.score > hypotheses[k].result.score) k = i;
  return k;
}

// The points pulled back into the tag frame, moved along `axis` to a given shift.
class ShiftedPoints {
 public:
  ShiftedPoints(ClusterDecodeWorkspace& ws, const Eigen::Vector3d& axis, const IntensityLevels& lv,
                double t)
      : ws_(ws), axis_(axis), levels_(lv), t_(t) {}

  double applied() const { return applied_; }

  // Moves the points by -(shift - applied) along the axis and prepares them for every family.
  void move_to(double shift) {
    const double d = shift - applied_;
    for (auto& q : ws_.pulled) {
      q.x -= static_cast<float>(d * axis_.x());
      q.y -= static_cast<float>(d * axis_.y());
      q.z -= static_cast<float>(d * axis_.z());
    }
    applied_ = shift;
    prepare_decode(ws_.pulled, levels_, t_, ws_.decode);
  }

 private:
  ClusterDecodeWorkspace& ws_;
  Eigen::Vector3d axis_;
  IntensityLevels levels_;
  double t_;
  double applied_ = 0.0;
};

}  // namespace

IntensityLevels board_levels(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                             std::vector<ClusterPoint>& inside, DecodeWorkspace& ws) {
  inside.clear();
  for (const ClusterPoint& p : points) {
    const Eigen::Vector3d q = pose.apply(Eigen::Vector3d(p.x, p.y, p.z));
    if (std::abs(q.y()) <= t / 2 && std::abs(q.z()) <= t / 2) inside.push_back(p);
  }
  return inside.size() >= 16 ? intensity_levels(inside, ws) : intensity_levels(points, ws);
}

ClusterDecode decode_cluster(std::span<const ClusterPoint> points, const RigidPose& pose,
                             const Eigen::Vector3d& unseen_axis, double t,
                             std::span<const RkhsDictionary> dictionaries,
                             std::span<const RkhsDictionary> decoys, const DecodeOptions& opt,
                             ClusterDecodeWorkspace& ws, bool on_board, double board_slack_m) {
  ClusterDecode out;
  ws.hypotheses.clear();
  ws.shifts.clear();
  ws.votes.clear();
  ws.vote_counts.clear();
  if (ws.families.size() < dictionaries.size()) ws.families.resize(dictionaries.size());
  for (auto& f : ws.families) f.scored = false;
  if (dictionaries.empty()) return out;

  // The points pulled back into the template frame (eq. (9)'s H_T^L), at most max_points of them
  // evenly spaced, and their extent along the unseen axis (in the tag frame).
  const Eigen::Vector3d axis = pose.R * unseen_axis;
  double lo = 0.0, hi = 0.0;
  const auto cap = static_cast<size_t>(std::max(opt.max_points, 16));
  const size_t stride = std::max<size_t>(1, (points.size() + cap - 1) / cap);
  ws.pulled.clear();
  for (size_t i = 0; i < points.size(); i += stride) {
    const auto& p = points[i];
    const Eigen::Vector3d q = pose.apply(Eigen::Vector3d(p.x, p.y, p.z));
    ClusterPoint c = p;
    c.x = static_cast<float>(q.x());
    c.y = static_cast<float>(q.y());
    c.z = static_cast<float>(q.z());
    ws.pulled.push_back(c);
    const double a = q.dot(axis);
    lo = i == 0 ? a : std::min(lo, a);
    hi = i == 0 ? a : std::max(hi, a);
  }
  // When a pair of sides was not seen (square mount), the tag may sit anywhere along that axis
  // where the points stay inside it: shifts in [s0, s1].
  const double cell = t / dictionaries.front().width();
  const bool search = !unseen_axis.isZero();
  out.shift_searched = search;
  // On a board the points reach past the tag: it may sit anywhere the board holds it, up to
  // board_slack_m either way.
  const double s0 = !search ? 0.0 : on_board ? -board_slack_m : std::min(0.0, hi - t / 2);
  const double s1 = !search ? 0.0 : on_board ? board_slack_m : std::max(0.0, lo + t / 2);
  ShiftedPoints shifted(ws, axis,
                        on_board ? board_levels(ws.pulled, RigidPose{}, t, ws.inside, ws.decode)
                                 : intensity_levels(ws.pulled, ws.decode),
                        t);

  // Every (shift, family) is a hypothesis; each family's best one keeps its evidence.
  auto try_shift = [&](double shift) {
    // The refinement's steps are clamped to [s0, s1]: a shift tried before would only add the
    // same hypotheses again.
    for (double s : ws.shifts)
      if (std::abs(s - shift) < 1e-9 * t) return;
    ws.shifts.push_back(shift);
    shifted.move_to(shift);
    for (size_t f = 0; f < dictionaries.size(); ++f) {
      const DecodeResult d = decode_prepared(dictionaries[f], opt, ws.decode);
      if (d.function < 0) continue;
      ws.hypotheses.push_back({d, static_cast<int>(f), shift});
      FamilyDecode& fd = ws.families[f];
      if (!fd.scored || d.score > fd.result.score) {
        fd.scored = true;
        fd.result = d;
        fd.shift = shift;
        normalised_scores(ws.decode, fd.scores);
        fd.cells.assign(ws.decode.evidence.begin(), ws.decode.evidence.end());
      }
    }
  };
  if (!search) {
    try_shift(0.0);
  } else {
    // Half-cell steps, then halved twice around the best one.
    for (double shift = s0; shift <= s1 + 1e-9; shift += cell / 2) try_shift(shift);
    for (double step = cell / 4; step > cell / 10 && !ws.hypotheses.empty(); step /= 2) {
      const double centre = ws.hypotheses[best_of(ws.hypotheses)].shift;
      try_shift(std::max(s0, centre - step));
      try_shift(std::min(s1, centre + step));
    }
  }
  if (ws.hypotheses.empty()) return out;  // kLowContrast: nothing could be scored

  // Arbitration: the best hypothesis must beat the best *other* function of its family at any
  // shift (another code or rotation) by the margin, so that searching more shifts does not make a
  // wrong ID more likely. Families are chosen between by score alone (normalised scores of two
  // families do not compare otherwise).
  const DecodeHypothesis& h = ws.hypotheses[best_of(ws.hypotheses)];
  double rival = -1e30;
  for (const auto& o : ws.hypotheses) {
    if (o.family != h.family) continue;
    if (o.result.function != h.result.function) rival = std::max(rival, o.result.score);
    if (o.result.second_function >= 0 && o.result.second_function != h.result.function)
      rival = std::max(rival, o.result.second_score);
  }
  out.best = h.result;
  out.family = h.family;
  out.shift = h.shift;
  out.best.margin_bits = rival > -1e29 ? (h.result.score - rival) * h.result.cells_per_score : 1e9;
  const double min_margin = search && square_mount_axis(unseen_axis, axis)
                                ? opt.min_margin_bits_searched
                                : opt.min_margin_bits;
  out.best.rejection = out.best.score < opt.min_score      ? Rejection::kLowScore
                       : out.best.margin_bits < min_margin ? Rejection::kAmbiguous
                                                           : Rejection::kNone;

  // A tag of a family that is not configured still has a best code in the configured ones (the
  // margin only compares codes of one family): the built-in families left out are decoded at the
  // same shifts, and one that fits strictly better makes it another family's tag. Identical
  // patterns tie and stay with the configured family. Clusters rejected at the decode stage are
  // checked too (below min_score only at the best shift, and not below other_family_min_score,
  // where the cluster is no tag of any family), so that evidence added up over rotations can be
  // checked the same way.
  const bool low = out.best.rejection == Rejection::kLowScore;
  const bool check = !low || out.best.score >= opt.other_family_min_score;
  for (size_t si = 0; check && !decoys.empty() && si < ws.shifts.size(); ++si) {
    const double shift = ws.shifts[si];
    if (low && shift != out.shift) continue;
    if (shifted.applied() != shift) shifted.move_to(shift);
    for (size_t k = 0; k < decoys.size(); ++k) {
      const DecodeResult d = decode_prepared(decoys[k], opt, ws.decode);
      if (d.function >= 0 && d.score > out.other_family_score) {
        out.other_family_score = d.score;
        out.other_family = static_cast<int>(k);
      }
    }
  }
  if (out.best.rejection == Rejection::kNone && out.other_family_score > out.best.score)
    out.best.rejection = Rejection::kOtherFamily;

  // The margin counts every cell's evidence, also the kernel tails that cells no ring crosses get
  // from their neighbours. When the cells actually seen do not lead on their own returns, the
  // decision rests on those tails: with 1 point per cell (VLP-32C at 24 m, 45 degrees) they once
  // made a wrong ID with a margin of 1.7 cells, with the rings at an unlucky height a VLP-16 at
  // 7 m one with 1.46, and a VLP-32C at 20 m one with 1.90 whose only seen deciding cell held one
  // grey return. The cell votes at the best shift serve this check and evidence over rotations.
  const int w = dictionaries[static_cast<size_t>(out.family)].width();
  if (shifted.applied() != out.shift) shifted.move_to(out.shift);
  cell_votes(ws.decode.prepared, w, opt.vote_inset_cells, ws.votes, ws.vote_counts);
  if (out.best.rejection == Rejection::kNone &&
      seen_cells_lead(dictionaries[static_cast<size_t>(out.family)], out.best.function, ws.votes,
                      ws.vote_counts, opt, ws.decode) < opt.min_seen_margin_cells)
    out.best.rejection = Rejection::kAmbiguous;

  // Too few returns per cell for one rotation's decision to be trusted (the margin and the score
  // of a wrong code look like a right one's there): evidence for a tracker only.
  if (out.best.rejection == Rejection::kNone &&
      static_cast<double>(points.size()) < opt.min_returns_per_cell * w * w)
    out.best.rejection = Rejection::kSparse;
  return out;
}

}  // namespace lidartag::detector
