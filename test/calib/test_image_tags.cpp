// Image tag detection: corners in lidartag's pixel convention to 0.1 px on tags rendered with
// exactly known corners (a half-pixel convention error fails), AprilTag's corner order under
// quarter turns, families, options and the empty cases.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lidartag/calib/image_tags.hpp"
#include "lidartag/detector/tag_family.hpp"

namespace lidartag::calib {
namespace {

// A tag drawn into a grey image: its centre at `center` (our convention: pixel (u, v) covers
// [u - 0.5, u + 0.5)), `cell` pixels per cell, turned counter-clockwise as seen by `turn_deg`.
struct Placement {
  Eigen::Vector2d center{97.3, 101.7};
  double cell = 8.0;
  double turn_deg = 0.0;
  // The tag's right and up directions in the image (v grows downwards).
  Eigen::Vector2d right() const {
    const double t = turn_deg * std::numbers::pi / 180.0;
    return {std::cos(t), -std::sin(t)};
  }
  Eigen::Vector2d up() const {
    const double t = turn_deg * std::numbers::pi / 180.0;
    return {-std::sin(t), -std::cos(t)};
  }
  Eigen::Vector2d pixel(double a, double b) const {  // a right, b up, cells from the centre
    return center + cell * (a * right() + b * up());
  }
};

constexpr uint8_t kBlack = 30, kWhite = 225, kBackground = 160;

// Box-filtered rendering: 16 x 16 samples per pixel, the fraction of each cell colour, so edges
// sit exactly where the geometry puts them.
GrayImage render(const tags::TagFamily& family, int id, const Placement& pl, int w = 200,
                 int h = 200) {
  const std::vector<uint8_t> cells = family.render(family.codes[static_cast<size_t>(id)]);
  const int tw = family.total_width;
  GrayImage img(w, h);
  constexpr int kS = 16;
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double sum = 0;
      for (int j = 0; j < kS; ++j)
        for (int i = 0; i < kS; ++i) {
          const Eigen::Vector2d p(u - 0.5 + (i + 0.5) / kS, v - 0.5 + (j + 0.5) / kS);
          const Eigen::Vector2d d = (p - pl.center) / pl.cell;
          const double a = d.dot(pl.right()), b = d.dot(pl.up());
          const double col = std::floor(a + tw / 2.0), row = std::floor(tw / 2.0 - b);
          if (col < 0 || row < 0 || col >= tw || row >= tw) {
            sum += kBackground;
          } else {
            const size_t k =
                static_cast<size_t>(row) * static_cast<size_t>(tw) + static_cast<size_t>(col);
            sum += cells[k] ? kWhite : kBlack;
          }
        }
      img.at(u, v) = static_cast<uint8_t>(std::lround(sum / (kS * kS)));
    }
  return img;
}

// Black-square corners of the upright tag: bottom-left, bottom-right, top-right, top-left.
std::array<Eigen::Vector2d, 4> truth_corners(const tags::TagFamily& family, const Placement& pl) {
  const double s = family.width_at_border / 2.0;
  return {pl.pixel(-s, -s), pl.pixel(s, -s), pl.pixel(s, s), pl.pixel(-s, s)};
}

ImageTag detect_one(const GrayImage& img, ImageTagOptions o = {}) {
  ImageTagDetector detector(o);
  const std::vector<ImageTag> tags = detector.detect(img);
  EXPECT_EQ(tags.size(), 1u);
  return tags.empty() ? ImageTag{} : tags.front();
}

TEST(ImageTags, CornersMatchTruthToATenthOfAPixelInOurConvention) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  for (double turn : {0.0, 17.0, -31.0}) {
    for (const Eigen::Vector2d& c : {Eigen::Vector2d(97.3, 101.7), Eigen::Vector2d(100.0, 99.5)}) {
      Placement pl;
      pl.center = c;
      pl.turn_deg = turn;
      const ImageTag t = detect_one(render(fam, 7, pl));
      EXPECT_EQ(t.family, "tag36h11");
      EXPECT_EQ(t.id, 7);
      EXPECT_EQ(t.hamming, 0);
      const auto truth = truth_corners(fam, pl);
      for (size_t k = 0; k < 4; ++k)
        EXPECT_LT((t.corners[k] - truth[k]).norm(), 0.1)
            << "turn " << turn << " corner " << k << ": " << t.corners[k].transpose() << " vs "
            << truth[k].transpose();
      EXPECT_LT((t.center - c).norm(), 0.1);
    }
  }
}

// AprilTag 3's own corners (refine_corners off) carry a bias of up to 0.2 px that depends on
// where the edges fall within their pixels; over the sub-pixel phases of the tag's position it
// averages out, and that average is ours to 0.1 px, while AprilTag's raw coordinates are half a
// pixel away in both axes: the shift this wrapper applies.
TEST(ImageTags, AprilTagsOwnConventionIsHalfAPixelAway) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  Eigen::Vector2d mean_error = Eigen::Vector2d::Zero();
  constexpr int kPhases = 8;
  for (int i = 0; i < kPhases; ++i) {
    Placement pl;
    pl.center = Eigen::Vector2d(97.0 + i / double(kPhases), 101.0 + ((3 * i) % kPhases) / 8.0);
    pl.turn_deg = 11.0;
    ImageTagOptions o;
    o.refine_corners = false;
    const ImageTag t = detect_one(render(fam, 3, pl), o);
    const auto truth = truth_corners(fam, pl);
    for (size_t k = 0; k < 4; ++k) mean_error += (t.corners[k] - truth[k]) / (4.0 * kPhases);
  }
  EXPECT_LT(mean_error.norm(), 0.1);
  const Eigen::Vector2d raw_error = mean_error.array() - kAprilTagToLidartag;
  EXPECT_NEAR(raw_error.x(), 0.5, 0.1);
  EXPECT_NEAR(raw_error.y(), 0.5, 0.1);
}

TEST(ImageTags, OwnCornerRefinementBeatsAprilTags) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  double worst_refined = 0, worst_apriltag = 0;
  for (double turn : {0.0, 17.0, -31.0, 63.0}) {
    Placement pl;
    pl.turn_deg = turn;
    const GrayImage img = render(fam, 21, pl);
    const auto truth = truth_corners(fam, pl);
    ImageTagOptions o;
    const ImageTag refined = detect_one(img, o);
    o.refine_corners = false;
    const ImageTag plain = detect_one(img, o);
    for (size_t k = 0; k < 4; ++k) {
      worst_refined = std::max(worst_refined, (refined.corners[k] - truth[k]).norm());
      worst_apriltag = std::max(worst_apriltag, (plain.corners[k] - truth[k]).norm());
    }
  }
  EXPECT_LT(worst_refined, 0.06);
  EXPECT_LT(worst_refined, worst_apriltag);
  std::printf("worst corner error: refined %.3f px, AprilTag 3 alone %.3f px\n", worst_refined,
              worst_apriltag);
}

// p[k] is attached to the tag: turning it by quarter turns turns which image corner each p[k]
// is, never which tag corner.
TEST(ImageTags, CornerOrderIsBottomLeftBottomRightTopRightTopLeftOfTheTag) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  for (int quarter = 0; quarter < 4; ++quarter) {
    Placement pl;
    pl.turn_deg = 90.0 * quarter;
    const ImageTag t = detect_one(render(fam, 12, pl));
    EXPECT_EQ(t.id, 12);
    const auto truth = truth_corners(fam, pl);
    for (size_t k = 0; k < 4; ++k)
      EXPECT_LT((t.corners[k] - truth[k]).norm(), 0.1)
          << quarter << " quarter turns, p[" << k << "]";
  }
  // Upright, p[0] is the bottom-left corner in the image: smallest u, largest v.
  Placement pl;
  const ImageTag t = detect_one(render(fam, 12, pl));
  EXPECT_LT(t.corners[0].x(), t.corners[1].x());
  EXPECT_GT(t.corners[0].y(), t.corners[3].y());
}

TEST(ImageTags, DecimatedSearchStillGivesSubPixelCorners) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  Placement pl;
  pl.turn_deg = 23.0;
  ImageTagOptions o;
  o.decimate = 2.0;
  const ImageTag t = detect_one(render(fam, 5, pl), o);
  const auto truth = truth_corners(fam, pl);
  for (size_t k = 0; k < 4; ++k) EXPECT_LT((t.corners[k] - truth[k]).norm(), 0.15) << k;
}

TEST(ImageTags, SmallerFamiliesAndSeveralAtOnce) {
  for (const char* name : {"tag16h5", "tag25h9", "tag36h10"}) {
    const tags::TagFamily& fam = tags::builtin_family(name);
    Placement pl;
    pl.turn_deg = 8.0;
    pl.cell = 12.0;
    ImageTagOptions o;
    o.families = {"tag36h11", name};
    const ImageTag t = detect_one(render(fam, 4, pl), o);
    EXPECT_EQ(t.family, name);
    EXPECT_EQ(t.id, 4);
    const auto truth = truth_corners(fam, pl);
    for (size_t k = 0; k < 4; ++k) EXPECT_LT((t.corners[k] - truth[k]).norm(), 0.1) << name;
  }
}

TEST(ImageTags, PlainImagesGiveNothing) {
  ImageTagDetector detector;
  EXPECT_TRUE(detector.detect(GrayImage(120, 80, 128)).empty());
  EXPECT_TRUE(detector.detect(GrayImage()).empty());
  GrayImage broken(10, 10);
  broken.pixels.resize(5);
  EXPECT_TRUE(detector.detect(broken).empty());
  // Rows or columns of one or two pixels: AprilTag 3 itself hangs or aborts on them; refused
  // before it (no tag fits in fewer than kMinImageSide pixels).
  for (const auto& [w, h] : {std::pair{1, 1}, std::pair{200, 1}, std::pair{200, 2},
                             std::pair{2, 200}, std::pair{kMinImageSide - 1, 300}})
    EXPECT_TRUE(detector.detect(GrayImage(w, h, 200)).empty()) << w << " x " << h;
}

TEST(ImageTags, WrongFamilyFindsNothing) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  ImageTagOptions o;
  o.families = {"tag25h9"};
  ImageTagDetector detector(o);
  EXPECT_TRUE(detector.detect(render(fam, 7, Placement{})).empty());
}

TEST(ImageTags, UnknownFamiliesAndBadOptionsAreRefused) {
  ImageTagOptions o;
  o.families = {"tag16h6"};  // the LiDARTag paper's markers: no AprilTag 3 decoder
  try {
    ImageTagDetector d(o);
    FAIL();
  } catch (const ImageTagError& e) {
    EXPECT_NE(std::string(e.what()).find("tag16h6"), std::string::npos);
  }
  o.families = {};
  EXPECT_THROW(ImageTagDetector{o}, ImageTagError);
  o = {};
  o.decimate = 0.5;
  EXPECT_THROW(ImageTagDetector{o}, ImageTagError);
  o = {};
  o.max_bits_corrected = 3;
  EXPECT_THROW(ImageTagDetector{o}, ImageTagError);
}

TEST(ImageTags, DetectorsMoveAndDetectAgain) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  ImageTagDetector a;
  ImageTagDetector b(std::move(a));
  const GrayImage img = render(fam, 9, Placement{});
  EXPECT_EQ(b.detect(img).size(), 1u);
  EXPECT_EQ(b.detect(img).size(), 1u);
  a = std::move(b);
  EXPECT_EQ(a.detect(img).size(), 1u);
}

// With the lens given, edges are fitted on the pinhole plane; a distortion-free model changes
// nothing, and a model of another size is refused.
TEST(ImageTags, LensModelMustMatchTheImage) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  Placement pl;
  pl.turn_deg = 17.0;
  const GrayImage img = render(fam, 7, pl);
  CameraModel lens;
  lens.width = 200;
  lens.height = 200;
  lens.fx = lens.fy = 300;
  lens.cx = 99.5;
  lens.cy = 99.5;
  ImageTagDetector detector;
  const auto with = detector.detect(img, lens);
  const auto without = detector.detect(img);
  ASSERT_EQ(with.size(), 1u);
  ASSERT_EQ(without.size(), 1u);
  for (size_t k = 0; k < 4; ++k)
    EXPECT_LT((with[0].corners[k] - without[0].corners[k]).norm(), 1e-6);
  lens.width = 640;
  try {
    (void)detector.detect(img, lens);
    FAIL();
  } catch (const ImageTagError& e) {
    EXPECT_NE(std::string(e.what()).find("200x200 but the camera model is 640x200"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace lidartag::calib
