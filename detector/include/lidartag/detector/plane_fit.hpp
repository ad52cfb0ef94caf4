// Stage 3, last check (paper Sec. IV-C): RANSAC plane fit and the outlier ratio kappa.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

struct PlaneOptions {
  // A point is an inlier within this distance of the plane, metres. Default 0.05 (as published);
  // must exceed about 3 sigma of the sensor's range noise.
  float inlier_m = 0.05f;
  // kappa: largest outlier fraction of a tag. Default 0.25 (the paper: 0.05 indoors; the
  // published outdoor setting 0.35): a clutter object whose features joined the tag's cluster
  // brings its own points (14 % in a rotation of pcaps/outdoor.pcap); the outline, fit-cost,
  // coverage and decoding checks reject non-tags that pass.
  float max_outlier_ratio = 0.25f;
  // Most RANSAC hypotheses. Default 40: with 90 % inliers, the chance to miss the plane is 1e-20.
  int iterations = 40;
  // Fewer when the plane is clear: the hypotheses stop once the chance that every one of them
  // drew an outlier, at the best inlier fraction found so far, is below this (the standard
  // adaptive RANSAC rule). Default 1e-9: 6 hypotheses at 99 % inliers, 16 at 90 %, all 40 below
  // 70 %. Tags and boards are 98-100 % inliers; the fit's least-squares passes on the inliers
  // make the plane the same from any all-inlier hypothesis.
  float miss_probability = 1e-9f;
  // RANSAC hypotheses are scored on at most this many evenly spaced points (the final inlier set
  // uses all). Default 256.
  int score_points = 256;
};

struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();   // unit, pointing toward the sensor
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // of the inliers
  double depth_sigma = 0.0;  // smallest principal standard deviation of the inliers, metres
  int inliers = 0;
  double outlier_ratio = 1.0;
  int hypotheses = 0;  // RANSAC hypotheses drawn (at most PlaneOptions::iterations)
};

// Fits a plane to `points` (deterministic for a given seed), refines it by PCA on the inliers and
// removes the outliers from `points`. Returns false when the outlier ratio exceeds kappa.
bool fit_plane(std::vector<ClusterPoint>& points, const PlaneOptions& opt, uint32_t seed,
               Plane& plane);

}  // namespace lidartag::detector
