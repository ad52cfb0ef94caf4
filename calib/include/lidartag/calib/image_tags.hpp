// Tags in camera images: AprilTag 3 (Debian's libapriltag 3.3) with its sub-pixel edge
// refinement, behind a plain options struct, results in lidartag's pixel convention.
//
// Pixel convention. AprilTag 3 puts the centre of the top-left pixel at (0.5, 0.5): its quad
// corners found on a decimated image are mapped back as (p - 0.5) * decimate + 0.5 (apriltag.c,
// apriltag_detector_detect), which is the rule for pixel i spanning [i, i + 1). lidartag (ROS
// camera_info, OpenCV, camera_model.hpp) puts that centre at (0, 0), so every corner and centre is
// shifted by -0.5 in u and v here: kAprilTagToLidartag. test_image_tags renders tags with exactly
// known corners and checks the result to 0.1 px (a half-pixel shift fails it).
//
// Corner order. corners[0..3] are AprilTag 3's p[0..3], which are attached to the tag, not to the
// image: for the tag seen upright (its top edge up) they are its bottom-left, bottom-right,
// top-right and top-left corners of the black square (counter-clockwise as seen in the image);
// they turn with the tag (test_image_tags turns it by 0/90/180/270 degrees). This is the order of
// the simulator's truth corners (sim::TagTruth::corners) and of the image corners it writes.
#pragma once

#include <Eigen/Core>
#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/image_io.hpp"

namespace lidartag::calib {

// Added to AprilTag 3's coordinates to get lidartag's (both axes).
inline constexpr double kAprilTagToLidartag = -0.5;

// The smallest image side searched, pixels: the whole marker of the smallest family (tag16h5, 8
// modules) at one pixel per module.
inline constexpr int kMinImageSide = 8;

// A family AprilTag 3 does not have, or options out of range.
class ImageTagError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ImageTagOptions {
  // Families to look for, by lidartag's names (tag_family.hpp): tag16h5, tag25h9, tag36h10,
  // tag36h11; AprilTag 3's own tagStandard41h12, tagStandard52h13, tagCircle21h7,
  // tagCircle49h12 and tagCustom48h12 too. Each family costs decoding time per quad.
  std::vector<std::string> families{"tag36h11"};
  // Quads are searched on the image shrunk by this factor (AprilTag's quad_decimate); 1: full
  // resolution, the most accurate corners. 2 is about 3x faster on large images; the edge
  // refinement then recovers most of the accuracy. >= 1.
  double decimate = 1.0;
  // Gaussian blur (pixels, sigma) before the quad search (quad_sigma); 0: none. 0.8 helps on
  // very noisy images.
  double blur_sigma = 0.0;
  // Snap the quad's edges to the image gradient (refine_edges): the sub-pixel corners that the
  // calibration needs. Keep on.
  bool refine_edges = true;
  // lidartag's own corner refinement after AprilTag's: each edge of the black square located
  // along its normal by the area under its intensity profile (exact for an edge blurred by the
  // pixel's box filter), a line fitted per edge, the corners intersected. AprilTag 3's corners
  // carry up to 0.2 px of bias on ideal images (its refine_edges samples the nearest pixel);
  // these come within 0.05 px (test_image_tags). Corners that would move more than
  // max_corner_shift_px keep AprilTag's.
  bool refine_corners = true;
  double max_corner_shift_px = 1.5;
  // Sharpening of the decoded payload (decode_sharpening); AprilTag's default.
  double decode_sharpening = 0.25;
  // Bit errors corrected (0..2). 2 (AprilTag's default) finds damaged tags but raises false
  // positives on small families (tag16h5) and takes tens of MB for the larger ones.
  int max_bits_corrected = 1;
  // Detections with a smaller decision margin (mean payload contrast over the threshold, grey
  // levels) are dropped; 0 keeps all. Small families want ~30 against false positives.
  double min_decision_margin = 0.0;
  int threads = 1;  // AprilTag's worker threads for one image
};

struct ImageTag {
  std::string family;  // lidartag's name of the family
  int id = 0;
  int hamming = 0;                                   // bits corrected
  double decision_margin = 0.0;                      // grey levels
  std::array<Eigen::Vector2d, 4> corners{};          // pixels (our convention), order as above
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // the homography's image of the tag centre
};

// Owns an AprilTag 3 detector and its families. Not thread-safe: one detect() at a time per
// object (AprilTag keeps per-call state in its detector); separate objects are independent and
// may run in parallel.
class ImageTagDetector {
 public:
  // Throws ImageTagError for an unknown family or an option out of range.
  explicit ImageTagDetector(ImageTagOptions options = {});
  ~ImageTagDetector();
  ImageTagDetector(ImageTagDetector&&) noexcept;
  ImageTagDetector& operator=(ImageTagDetector&&) noexcept;
  ImageTagDetector(const ImageTagDetector&) = delete;
  ImageTagDetector& operator=(const ImageTagDetector&) = delete;

  // Tags in a grey image, sorted by family and id. An image narrower or lower than kMinImageSide
  // gives none.
  std::vector<ImageTag> detect(const GrayImage& image);
  // The same with the camera's lens model: the corner refinement fits each edge as a straight
  // line on the undistorted (pinhole) plane, where it is straight, instead of in the image, where
  // distortion bends it (k1 = -0.12 bends a 270 px edge by ~0.6 px at 1280x720, fx 900).
  // Throws ImageTagError when the image's size is not the model's (intrinsics of another
  // camera or resolution).
  std::vector<ImageTag> detect(const GrayImage& image, const CameraModel& lens);

  const ImageTagOptions& options() const { return options_; }

 private:
  std::vector<ImageTag> detect(const GrayImage& image, const CameraModel* lens);
  struct Impl;
  ImageTagOptions options_;
  std::unique_ptr<Impl> impl_;
};

// AprilTag 3 family names this build can detect.
std::vector<std::string> image_tag_families();

}  // namespace lidartag::calib
