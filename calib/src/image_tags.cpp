#include "lidartag/calib/image_tags.hpp"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <tuple>

namespace lidartag::calib {
namespace {

// Per family: its name (lidartag's and AprilTag's are the same), constructor and destructor.
struct FamilyEntry {
  const char* name;
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

constexpr FamilyEntry kFamilies[] = {
    {"tag16h5", tag16h5_create, tag16h5_destroy},
    {"tag25h9", tag25h9_create, tag25h9_destroy},
    {"tag36h10", tag36h10_create, tag36h10_destroy},
    {"tag36h11", tag36h11_create, tag36h11_destroy},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
    {"tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy},
    {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
    {"tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy},
    {"tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy},
};

const FamilyEntry& find_family(const std::string& name) {
  for (const FamilyEntry& f : kFamilies)
    if (name == f.name) return f;
  std::string known;
  for (const FamilyEntry& f : kFamilies) known += std::string(known.empty() ? "" : ", ") + f.name;
  throw ImageTagError("image tags: family '" + name +
                      "' has no AprilTag 3 detector (known: " + known + ")");
}

struct DetectorDeleter {
  void operator()(apriltag_detector_t* td) const { apriltag_detector_destroy(td); }
};
struct DetectionsDeleter {
  void operator()(zarray_t* detections) const { apriltag_detections_destroy(detections); }
};

// Bilinear grey level at (x, y) in our convention (pixel centres at integers), clamped to the
// image.
double sample(const GrayImage& im, double x, double y) {
  x = std::clamp(x, 0.0, im.width - 1.0);
  y = std::clamp(y, 0.0, im.height - 1.0);
  const int x0 = std::min(static_cast<int>(x), im.width - 2 < 0 ? 0 : im.width - 2);
  const int y0 = std::min(static_cast<int>(y), im.height - 2 < 0 ? 0 : im.height - 2);
  const int x1 = std::min(x0 + 1, im.width - 1), y1 = std::min(y0 + 1, im.height - 1);
  const double fx = x - x0, fy = y - y0;
  const double top = im.at(x0, y0) * (1 - fx) + im.at(x1, y0) * fx;
  const double bottom = im.at(x0, y1) * (1 - fx) + im.at(x1, y1) * fx;
  return top * (1 - fy) + bottom * fy;
}

// A line n . x = d with |n| = 1.
struct Line {
  Eigen::Vector2d n;
  double d;
};

// Points on one edge of the black square from a to b (the square's interior on the side of
// `inside`), each by the area under the intensity profile across the edge. False when too few
// profiles had contrast.
bool edge_points(const GrayImage& im, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                 const Eigen::Vector2d& inside, double half_window,
                 std::vector<Eigen::Vector2d>& points) {
  const Eigen::Vector2d along = (b - a).normalized();
  Eigen::Vector2d out(-along.y(), along.x());  // the normal pointing out of the square
  if (out.dot(inside - a) > 0) out = -out;
  constexpr int kProfiles = 24;
  // About 1/8 pixel along the normal, a whole number of steps across the window.
  const int steps = static_cast<int>(std::ceil(2 * half_window / 0.125));
  const double kStep = 2 * half_window / steps;
  points.clear();
  for (int i = 0; i < kProfiles; ++i) {
    // Stay clear of the corners, where the neighbouring edge enters the window.
    const double t = 0.12 + 0.76 * (i + 0.5) / kProfiles;
    const Eigen::Vector2d p = a + t * (b - a);
    // Levels: the ends of the window, black inside, white outside.
    double black = 0, white = 0;
    constexpr int kEnd = 4;
    for (int k = 0; k < kEnd; ++k) {
      const double s = half_window - k * kStep;
      black += sample(im, p.x() - s * out.x(), p.y() - s * out.y());
      white += sample(im, p.x() + s * out.x(), p.y() + s * out.y());
    }
    black /= kEnd;
    white /= kEnd;
    if (white - black < 10.0) continue;
    // Integral of the white fraction over [-w, w] (trapezoids) is w - e for a step at e.
    double area = 0;
    double prev = 0;
    for (int k = 0; k <= steps; ++k) {
      const double s = -half_window + k * kStep;
      const double g =
          (sample(im, p.x() + s * out.x(), p.y() + s * out.y()) - black) / (white - black);
      if (k > 0) area += 0.5 * (prev + g) * kStep;
      prev = g;
    }
    const double e = half_window - area;
    if (std::abs(e) > half_window) continue;
    points.push_back(p + e * out);
  }
  return points.size() >= kProfiles / 2;
}

// Total least-squares line through points.
Line fit_line(const std::vector<Eigen::Vector2d>& points) {
  Line line;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& q : points) mean += q;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& q : points) cov += (q - mean) * (q - mean).transpose();
  // The normal is the eigenvector of the smaller eigenvalue (closed form for 2x2).
  const double angle = 0.5 * std::atan2(2 * cov(0, 1), cov(0, 0) - cov(1, 1));
  const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
  line.n = Eigen::Vector2d(-dir.y(), dir.x());
  line.d = line.n.dot(mean);
  return line;
}

// With a lens model, edges are straight on the pinhole plane, not in the distorted image: the
// lines are fitted there (in pixel units, fx * x / z and fy * y / z) and the corners projected
// back. Without one, the image itself is taken as pinhole.
struct Plane {
  const CameraModel* lens = nullptr;
  std::optional<Eigen::Vector2d> to(const Eigen::Vector2d& px) const {
    if (!lens) return px;
    const Eigen::Vector3d r = lens->unproject(px);
    if (r.z() < 1e-6) return std::nullopt;
    return Eigen::Vector2d(lens->fx * r.x() / r.z(), lens->fy * r.y() / r.z());
  }
  std::optional<Eigen::Vector2d> from(const Eigen::Vector2d& q) const {
    if (!lens) return q;
    return lens->project(Eigen::Vector3d(q.x() / lens->fx, q.y() / lens->fy, 1.0));
  }
};

// Corners (our convention, AprilTag's order) refined edge by edge; unchanged where an edge or an
// intersection fails or a corner would move more than max_shift.
void refine_corners(const GrayImage& im, std::array<Eigen::Vector2d, 4>& corners, int cells,
                    double max_shift, const Plane& plane) {
  const Eigen::Vector2d centre = (corners[0] + corners[1] + corners[2] + corners[3]) / 4.0;
  double side = 0;
  for (size_t k = 0; k < 4; ++k) side += (corners[(k + 1) % 4] - corners[k]).norm() / 4.0;
  // The window across an edge: within the black border cell inside and the white cell outside.
  const double half_window = std::clamp(0.45 * side / cells, 1.0, 4.0);
  std::array<Line, 4> lines;
  std::vector<Eigen::Vector2d> points;
  for (size_t k = 0; k < 4; ++k) {
    if (!edge_points(im, corners[k], corners[(k + 1) % 4], centre, half_window, points)) return;
    for (Eigen::Vector2d& p : points) {
      const auto q = plane.to(p);
      if (!q) return;
      p = *q;
    }
    lines[k] = fit_line(points);
  }
  std::array<Eigen::Vector2d, 4> refined;
  for (size_t k = 0; k < 4; ++k) {
    // Corner k joins edge k - 1 (from corner k - 1) and edge k (to corner k + 1).
    const Line& l1 = lines[(k + 3) % 4];
    const Line& l2 = lines[k];
    Eigen::Matrix2d m;
    m << l1.n.transpose(), l2.n.transpose();
    if (std::abs(m.determinant()) < 1e-3) return;
    const auto px = plane.from(m.inverse() * Eigen::Vector2d(l1.d, l2.d));
    if (!px) return;
    refined[k] = *px;
    if ((refined[k] - corners[k]).norm() > max_shift) return;
  }
  corners = refined;
}

}  // namespace

struct ImageTagDetector::Impl {
  // A family AprilTag owns by pointer; destroyed with its own destructor after the detector.
  struct Family {
    const FamilyEntry* entry;
    apriltag_family_t* family;
  };
  std::vector<Family> families;
  std::unique_ptr<apriltag_detector_t, DetectorDeleter> detector;

  ~Impl() {
    detector.reset();  // the detector refers to the families: it goes first
    for (Family& f : families) f.entry->destroy(f.family);
  }
};

ImageTagDetector::ImageTagDetector(ImageTagOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  const ImageTagOptions& o = options_;
  if (o.families.empty()) throw ImageTagError("image tags: no family given");
  if (!(o.decimate >= 1.0 && o.decimate <= 16.0))
    throw ImageTagError("image tags: decimate must be in [1, 16]");
  if (!(o.blur_sigma >= 0.0 && o.blur_sigma <= 10.0))
    throw ImageTagError("image tags: blur_sigma must be in [0, 10] pixels");
  if (o.max_bits_corrected < 0 || o.max_bits_corrected > 2)
    throw ImageTagError("image tags: max_bits_corrected must be 0, 1 or 2");
  if (o.threads < 1 || o.threads > 256) throw ImageTagError("image tags: threads must be >= 1");
  if (!(o.decode_sharpening >= 0.0)) throw ImageTagError("image tags: decode_sharpening < 0");
  std::vector<const FamilyEntry*> entries;
  for (const std::string& name : o.families) {
    const FamilyEntry* e = &find_family(name);
    if (std::find(entries.begin(), entries.end(), e) == entries.end()) entries.push_back(e);
  }
  impl_->detector.reset(apriltag_detector_create());
  if (!impl_->detector) throw ImageTagError("image tags: cannot create the AprilTag detector");
  apriltag_detector_t* td = impl_->detector.get();
  td->quad_decimate = static_cast<float>(o.decimate);
  td->quad_sigma = static_cast<float>(o.blur_sigma);
  td->refine_edges = o.refine_edges;
  td->decode_sharpening = o.decode_sharpening;
  td->nthreads = o.threads;
  td->debug = false;
  for (const FamilyEntry* e : entries) {
    apriltag_family_t* f = e->create();
    if (!f) throw ImageTagError(std::string("image tags: cannot create family ") + e->name);
    impl_->families.push_back({e, f});
    apriltag_detector_add_family_bits(td, f, o.max_bits_corrected);
  }
}

ImageTagDetector::~ImageTagDetector() = default;
ImageTagDetector::ImageTagDetector(ImageTagDetector&&) noexcept = default;
ImageTagDetector& ImageTagDetector::operator=(ImageTagDetector&&) noexcept = default;

std::vector<ImageTag> ImageTagDetector::detect(const GrayImage& image) {
  return detect(image, nullptr);
}

std::vector<ImageTag> ImageTagDetector::detect(const GrayImage& image, const CameraModel& lens) {
  if (lens.width != image.width || lens.height != image.height)
    throw ImageTagError("image tags: the image is " + std::to_string(image.width) + "x" +
                        std::to_string(image.height) + " but the camera model is " +
                        std::to_string(lens.width) + "x" + std::to_string(lens.height));
  return detect(image, &lens);
}

std::vector<ImageTag> ImageTagDetector::detect(const GrayImage& image, const CameraModel* lens) {
  std::vector<ImageTag> tags;
  // AprilTag 3 hangs on images 1 pixel high and corrupts its heap on 2 (its 4-pixel threshold
  // tiles); no tag fits in fewer than kMinImageSide pixels anyway.
  if (image.width < kMinImageSide || image.height < kMinImageSide ||
      image.pixels.size() != static_cast<size_t>(image.width) * static_cast<size_t>(image.height))
    return tags;
  // AprilTag reads the caller's buffer through a non-const pointer but never writes it (it
  // copies before decimating or blurring).
  image_u8_t im{image.width, image.height, image.width, const_cast<uint8_t*>(image.pixels.data())};
  std::unique_ptr<zarray_t, DetectionsDeleter> detections(
      apriltag_detector_detect(impl_->detector.get(), &im));
  if (!detections) return tags;
  const int n = zarray_size(detections.get());
  for (int i = 0; i < n; ++i) {
    apriltag_detection_t* d = nullptr;
    zarray_get(detections.get(), i, &d);
    if (!d || d->decision_margin < options_.min_decision_margin) continue;
    ImageTag t;
    t.family = d->family->name;
    t.id = d->id;
    t.hamming = d->hamming;
    t.decision_margin = d->decision_margin;
    for (size_t k = 0; k < 4; ++k)
      t.corners[k] = Eigen::Vector2d(d->p[k][0], d->p[k][1]).array() + kAprilTagToLidartag;
    t.center = Eigen::Vector2d(d->c[0], d->c[1]).array() + kAprilTagToLidartag;
    if (options_.refine_corners) {
      refine_corners(image, t.corners, d->family->width_at_border, options_.max_corner_shift_px,
                     Plane{lens});
      // The centre: the diagonals' intersection (the homography's image of the tag centre).
      const Eigen::Vector2d p = t.corners[0], r = t.corners[2] - t.corners[0];
      const Eigen::Vector2d q = t.corners[1], s2 = t.corners[3] - t.corners[1];
      const double den = r.x() * s2.y() - r.y() * s2.x();
      if (std::abs(den) > 1e-9) {
        const Eigen::Vector2d qp = q - p;
        t.center = p + r * ((qp.x() * s2.y() - qp.y() * s2.x()) / den);
      }
    }
    tags.push_back(std::move(t));
  }
  std::sort(tags.begin(), tags.end(), [](const ImageTag& a, const ImageTag& b) {
    return std::tie(a.family, a.id, a.center.x()) < std::tie(b.family, b.id, b.center.x());
  });
  return tags;
}

std::vector<std::string> image_tag_families() {
  std::vector<std::string> names;
  for (const FamilyEntry& f : kFamilies) names.emplace_back(f.name);
  return names;
}

}  // namespace lidartag::calib
