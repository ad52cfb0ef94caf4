// Echo formation, the Fig. 2 artefacts, detection limit, return-mode choice and noise.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "lidartag/sim/beam_model.hpp"

namespace lidartag::sim {
namespace {

using velodyne::ReturnMode;

NoiseOptions edges_only() {
  NoiseOptions n = NoiseOptions::ideal();
  n.footprint_samples = 5;
  return n;
}

std::vector<SubReturn> footprint(std::initializer_list<SubReturn> s) {
  return s;
}

TEST(BeamModel, FootprintPatterns) {
  NoiseOptions n;
  std::array<std::array<double, 2>, 9> off{};
  n.footprint_samples = 1;
  EXPECT_EQ(footprint_offsets(n, off), 1);
  n.footprint_samples = 5;
  n.divergence_h_mrad = 4.0;
  EXPECT_EQ(footprint_offsets(n, off), 5);
  EXPECT_DOUBLE_EQ(off[2][0], 0.002);  // half the full divergence
  n.footprint_samples = 9;
  EXPECT_EQ(footprint_offsets(n, off), 9);
}

TEST(BeamModel, OneSurfaceGivesOneExactEcho) {
  Rng rng(1);
  const SubReturn s{true, 7.5, 60.0, 2};
  const auto subs = footprint({s, s, s, s, s});
  const BeamEchoes e = form_echoes(subs, edges_only(), rng);
  ASSERT_EQ(e.count, 1);
  EXPECT_DOUBLE_EQ(e.echo[0].range, 7.5);
  EXPECT_DOUBLE_EQ(e.echo[0].reflectivity, 60.0);
  EXPECT_EQ(e.echo[0].tag, 2);
}

TEST(BeamModel, SeparatedSurfacesGiveTwoEchoesSharingTheEnergy) {
  Rng rng(1);
  const SubReturn near{true, 5.0, 80.0, 0}, far{true, 9.0, 40.0, -1};
  const BeamEchoes e = form_echoes(footprint({near, near, far, far, far}), edges_only(), rng);
  ASSERT_EQ(e.count, 2);
  EXPECT_DOUBLE_EQ(e.echo[0].range, 5.0);
  EXPECT_DOUBLE_EQ(e.echo[0].reflectivity, 80.0 * 2 / 5);
  EXPECT_EQ(e.echo[0].tag, 0);
  EXPECT_DOUBLE_EQ(e.echo[1].range, 9.0);
  EXPECT_DOUBLE_EQ(e.echo[1].reflectivity, 40.0 * 3 / 5);
  EXPECT_EQ(e.echo[1].tag, -1);
}

TEST(BeamModel, CloseSurfacesMergeIntoAMixedReturnBetweenThem) {
  Rng rng(1);
  const SubReturn a{true, 5.0, 80.0, -1}, b{true, 5.3, 20.0, -1};
  const BeamEchoes e = form_echoes(footprint({a, a, b, b, b}), edges_only(), rng);
  ASSERT_EQ(e.count, 1);
  const double expect = (2 * 80.0 * 5.0 + 3 * 20.0 * 5.3) / (2 * 80.0 + 3 * 20.0);
  EXPECT_DOUBLE_EQ(e.echo[0].range, expect);
  EXPECT_GT(e.echo[0].range, 5.0);
  EXPECT_LT(e.echo[0].range, 5.3);
}

TEST(BeamModel, ForcedMixingOnDepthEdges) {
  NoiseOptions n = edges_only();
  n.depth_edge_mixed = 1.0;
  Rng rng(1);
  const SubReturn a{true, 5.0, 50.0, -1}, b{true, 9.0, 50.0, -1};
  const BeamEchoes e = form_echoes(footprint({a, a, b, b, b}), n, rng);
  ASSERT_EQ(e.count, 1);
  EXPECT_NEAR(e.echo[0].range, (2 * 5.0 + 3 * 9.0) / 5.0, 1e-12);
}

double missing_fraction(const NoiseOptions& n, const std::vector<SubReturn>& subs) {
  Rng rng(3);
  int missing = 0;
  const int trials = 20000;
  for (int i = 0; i < trials; ++i) missing += form_echoes(subs, n, rng).count == 0 ? 1 : 0;
  return static_cast<double>(missing) / trials;
}

TEST(BeamModel, MissingReturnsOnEdgesFollowTheirProbabilities) {
  NoiseOptions n = edges_only();
  n.depth_edge_missing = 0.3;
  n.intensity_edge_missing = 0.15;
  n.dropout = 0.05;
  const SubReturn white{true, 5.0, 80.0, 0}, black{true, 5.0, 8.0, 0}, wall{true, 7.0, 50.0, -1};
  const SubReturn sky{};
  // Dropout alone on a plain surface.
  EXPECT_NEAR(missing_fraction(n, footprint({white, white, white, white, white})), 0.05, 0.01);
  // Black/white transition: dropout, then the edge probability.
  EXPECT_NEAR(missing_fraction(n, footprint({white, white, black, black, black})),
              0.05 + 0.95 * 0.15, 0.015);
  // Depth discontinuity, and a silhouette against the sky.
  EXPECT_NEAR(missing_fraction(n, footprint({white, white, wall, wall, wall})), 0.05 + 0.95 * 0.3,
              0.015);
  EXPECT_NEAR(missing_fraction(n, footprint({white, white, sky, sky, sky})), 0.05 + 0.95 * 0.3,
              0.015);
}

TEST(BeamModel, DetectionFallsOffWithTheSquareOfRange) {
  NoiseOptions n = NoiseOptions::ideal();
  n.detect_reflectivity_10m = 0.05;
  Rng rng(1);
  const auto at = [&](double range, double refl) {
    return form_echoes(footprint({{true, range, refl, -1}}), n, rng).count;
  };
  EXPECT_EQ(at(50.0, 5.0), 1);   // needs 1.25
  EXPECT_EQ(at(120.0, 5.0), 0);  // needs 7.2
  EXPECT_EQ(at(120.0, 8.0), 1);
}

TEST(BeamModel, ReturnModesPickStrongestLastAndDualPairs) {
  BeamEchoes e;
  e.count = 3;
  e.echo[0] = {4.0, 10.0, -1};   // strength 0.625
  e.echo[1] = {6.0, 80.0, 1};    // strength 2.22: strongest
  e.echo[2] = {12.0, 30.0, -1};  // last
  std::array<Echo, 2> out{};
  EXPECT_EQ(select_returns(e, ReturnMode::kStrongest, out), 1);
  EXPECT_EQ(out[0].range, 6.0);
  EXPECT_EQ(select_returns(e, ReturnMode::kLast, out), 1);
  EXPECT_EQ(out[0].range, 12.0);
  EXPECT_EQ(select_returns(e, ReturnMode::kDual, out), 2);
  EXPECT_EQ(out[0].range, 12.0);
  EXPECT_EQ(out[1].range, 6.0);
  // The last echo is also the strongest: dual reports the second strongest.
  e.echo[2] = {12.0, 900.0, -1};
  EXPECT_EQ(select_returns(e, ReturnMode::kDual, out), 2);
  EXPECT_EQ(out[0].range, 12.0);
  EXPECT_EQ(out[1].range, 6.0);
  // One echo: dual repeats it.
  e.count = 1;
  EXPECT_EQ(select_returns(e, ReturnMode::kDual, out), 1);
  EXPECT_EQ(out[1].range, out[0].range);
  e.count = 0;
  EXPECT_EQ(select_returns(e, ReturnMode::kStrongest, out), 0);
}

TEST(BeamModel, NoiseHasTheConfiguredSigma) {
  NoiseOptions n;
  n.range_sigma_m = 0.02;
  n.intensity_sigma = 3.0;
  Rng rng(9);
  double s = 0, s2 = 0, i2 = 0;
  const int trials = 50000;
  for (int k = 0; k < trials; ++k) {
    const Echo e = add_noise({10.0, 50.0, -1}, n, rng);
    s += e.range - 10.0;
    s2 += (e.range - 10.0) * (e.range - 10.0);
    i2 += (e.reflectivity - 50.0) * (e.reflectivity - 50.0);
  }
  EXPECT_NEAR(s / trials, 0.0, 0.0005);
  EXPECT_NEAR(std::sqrt(s2 / trials), 0.02, 0.0005);
  EXPECT_NEAR(std::sqrt(i2 / trials), 3.0, 0.06);
}

}  // namespace
}  // namespace lidartag::sim
