// The corner order checked against the AprilTag 3 library itself: a marker drawn from the
// family's code (TagFamily::render, upright as printed), turned by quarter turns in the image,
// detected by libapriltag; calibration corner k (bottom-left, bottom-right, top-right, top-left
// of the upright marker) must be AprilTag's p[apriltag_corner_of(k)] at every turn.
#include <apriltag.h>
#include <gtest/gtest.h>
#include <tag36h11.h>

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "lidartag/calib/correspondence.hpp"
#include "lidartag/detector/tag_family.hpp"

namespace lidartag::calib {
namespace {

constexpr int kCell = 12;    // pixels per cell
constexpr int kMargin = 40;  // white pixels around the marker

TEST(AprilTagCornerOrder, LibraryCornersAreTheCalibrationOrderAtEveryQuarterTurn) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  const int id = 17;
  const std::vector<uint8_t> cells = fam.render(fam.codes[static_cast<std::size_t>(id)]);
  const int w = fam.total_width;
  const int side = w * kCell + 2 * kMargin;
  // Corner k of the upright marker's black square, in cell-edge units from its top-left:
  // bottom-left, bottom-right, top-right, top-left (row 0 at the top).
  const int b0 = fam.border_start(), b1 = fam.border_start() + fam.width_at_border;
  const Eigen::Vector2d upright[4] = {{b0, b1}, {b1, b1}, {b1, b0}, {b0, b0}};

  std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> family(tag36h11_create(),
                                                                          tag36h11_destroy);
  std::unique_ptr<apriltag_detector_t, void (*)(apriltag_detector_t*)> det(
      apriltag_detector_create(), apriltag_detector_destroy);
  apriltag_detector_add_family(det.get(), family.get());
  det->quad_decimate = 1.0f;
  det->nthreads = 1;

  for (int q = 0; q < 4; ++q) {
    // The image turned q quarter turns clockwise: pixel (x, y) of the upright image goes to
    // (side - 1 - y, x) per turn.
    std::vector<uint8_t> img(static_cast<std::size_t>(side * side), 255);
    auto turn = [&](Eigen::Vector2d p, double extent) {  // a point in edge units [0, extent]
      for (int t = 0; t < q; ++t) p = Eigen::Vector2d(extent - p.y(), p.x());
      return p;
    };
    for (int y = 0; y < w * kCell; ++y)
      for (int x = 0; x < w * kCell; ++x) {
        const uint8_t v = cells[static_cast<std::size_t>((y / kCell) * w + x / kCell)] ? 255 : 0;
        // The pixel's centre turned (edge units of the whole image), back to its index.
        const Eigen::Vector2d c = turn(Eigen::Vector2d(kMargin + x + 0.5, kMargin + y + 0.5), side);
        img[static_cast<std::size_t>(static_cast<int>(c.y()) * side + static_cast<int>(c.x()))] = v;
      }
    image_u8_t im{side, side, side, img.data()};
    zarray_t* found = apriltag_detector_detect(det.get(), &im);
    ASSERT_EQ(zarray_size(found), 1) << "turn " << q;
    apriltag_detection_t* d = nullptr;
    zarray_get(found, 0, &d);
    EXPECT_EQ(d->id, id);
    for (int k = 0; k < 4; ++k) {
      // Expected: the upright corner k, turned with the image (pixel-edge units, to within the
      // libraries' half-pixel conventions).
      const Eigen::Vector2d e = turn(Eigen::Vector2d(kMargin, kMargin) + upright[k] * kCell, side);
      const int i = apriltag_corner_of(k);
      const Eigen::Vector2d p(d->p[i][0], d->p[i][1]);
      EXPECT_LT((p - e).norm(), 1.5) << "turn " << q << " corner " << k << ": AprilTag p[" << i
                                     << "] = " << p.transpose() << ", expected " << e.transpose();
    }
    apriltag_detections_destroy(found);
  }
}

}  // namespace
}  // namespace lidartag::calib
