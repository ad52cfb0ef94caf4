#include "lidartag/draw/calibration_view.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include "lidartag/draw/cairo_util.hpp"
#include "lidartag/draw/colors.hpp"

namespace lidartag::draw {
namespace {

constexpr uint32_t kImageCorner = 0x34d058;   // green: where the image found a corner
constexpr uint32_t kLidarCorner = 0xff4fd8;   // magenta: the LiDAR's corner, reprojected
constexpr double kNearM = 1.0, kFarM = 20.0;  // the range colour scale

Colour range_colour(double range_m) {
  return viridis(std::clamp((range_m - kNearM) / (kFarM - kNearM), 0.0, 1.0));
}

}  // namespace

CalibrationViewStats write_calibration_view(const CalibrationView& v, const std::string& path) {
  const calib::GrayImage& img = *v.image;
  const calib::CameraModel& cam = *v.camera;
  const int strip = 22 + 16 * static_cast<int>(v.title.size());
  Surface surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, img.width, img.height + strip));
  check(surface.get(), path);
  // The image, grey.
  cairo_surface_flush(surface.get());
  unsigned char* data = cairo_image_surface_get_data(surface.get());
  const int stride = cairo_image_surface_get_stride(surface.get());
  for (int y = 0; y < img.height; ++y) {
    auto* row = reinterpret_cast<uint32_t*>(data + static_cast<ptrdiff_t>(y) * stride);
    for (int x = 0; x < img.width; ++x) {
      const uint32_t g = img.at(x, y);
      row[x] = (g << 16) | (g << 8) | g;
    }
  }
  cairo_surface_mark_dirty(surface.get());
  Context cr(cairo_create(surface.get()));
  cairo_t* c = cr.get();
  // Pixel centres at integers (our convention) are Cairo's x + 0.5.
  auto at = [](const Eigen::Vector2d& p) { return Eigen::Vector2d(p.x() + 0.5, p.y() + 0.5); };

  CalibrationViewStats stats;
  for (const Eigen::Vector3f& p : v.points) {
    const Eigen::Vector3d q = v.camera_from_lidar * p.cast<double>();
    const auto px = cam.project(q);
    if (!px || !cam.in_image(*px)) continue;
    range_colour(q.norm()).use(c, 0.8);
    const Eigen::Vector2d d = at(*px);
    cairo_arc(c, d.x(), d.y(), 1.2, 0, 2 * std::numbers::pi);
    cairo_fill(c);
    ++stats.points_drawn;
  }
  for (const CalibrationViewTag& t : v.tags) {
    std::array<std::optional<Eigen::Vector2d>, 4> lidar;
    for (size_t k = 0; k < 4; ++k) lidar[k] = cam.project(v.camera_from_lidar * t.lidar[k]);
    // The image's outline and corners (crosses), then the LiDAR's (circles), corner 0 labelled.
    cairo_set_line_width(c, 1.5);
    from_hex(kImageCorner).use(c);
    for (size_t k = 0; k < 4; ++k) {
      const Eigen::Vector2d a = at(t.image[k]), b = at(t.image[(k + 1) % 4]);
      cairo_move_to(c, a.x(), a.y());
      cairo_line_to(c, b.x(), b.y());
    }
    cairo_stroke(c);
    for (size_t k = 0; k < 4; ++k) {
      const Eigen::Vector2d a = at(t.image[k]);
      cairo_move_to(c, a.x() - 5, a.y());
      cairo_line_to(c, a.x() + 5, a.y());
      cairo_move_to(c, a.x(), a.y() - 5);
      cairo_line_to(c, a.x(), a.y() + 5);
    }
    cairo_stroke(c);
    from_hex(kLidarCorner).use(c);
    if (!t.used) {
      const double dash[] = {4.0, 3.0};
      cairo_set_dash(c, dash, 2, 0);
    }
    for (size_t k = 0; k < 4; ++k) {
      if (!lidar[k] || !lidar[(k + 1) % 4]) continue;
      const Eigen::Vector2d a = at(*lidar[k]), b = at(*lidar[(k + 1) % 4]);
      cairo_move_to(c, a.x(), a.y());
      cairo_line_to(c, b.x(), b.y());
    }
    cairo_stroke(c);
    cairo_set_dash(c, nullptr, 0, 0);
    for (size_t k = 0; k < 4; ++k) {
      if (!lidar[k]) continue;
      const Eigen::Vector2d a = at(*lidar[k]);
      cairo_arc(c, a.x(), a.y(), 4.0, 0, 2 * std::numbers::pi);
      cairo_stroke(c);
      stats.max_corner_px = std::max(stats.max_corner_px, (*lidar[k] - t.image[k]).norm());
    }
    const Eigen::Vector2d label = at(t.image[0]);
    draw_text(c, t.label + (t.used ? "" : " (rejected)"), label.x() + 6, label.y() + 14, 12);
    if (lidar[0]) {
      const Eigen::Vector2d zero = at(*lidar[0]);
      draw_text(c, "0", zero.x() - 12, zero.y() - 6, 11);
    }
  }
  // The strip: title lines and the legend.
  cairo_set_source_rgb(c, 0.08, 0.09, 0.11);
  cairo_rectangle(c, 0, img.height, img.width, strip);
  cairo_fill(c);
  double y = img.height + 16;
  cairo_set_source_rgb(c, 0.91, 0.92, 0.93);
  for (const std::string& line : v.title) {
    draw_text(c, line, 8, y, 12);
    y += 16;
  }
  from_hex(kImageCorner).use(c);
  draw_text(c, "+ image corners", 8, y, 12);
  from_hex(kLidarCorner).use(c);
  draw_text(c, "o LiDAR corners reprojected", 130, y, 12);
  cairo_set_source_rgb(c, 0.91, 0.92, 0.93);
  draw_text(c, fmt::format("points by range {:g}-{:g} m (viridis)", kNearM, kFarM), 340, y, 12);
  check(c, path);
  write_png(surface.get(), path);
  return stats;
}

}  // namespace lidartag::draw
