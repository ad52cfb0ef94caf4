#include "lidartag/draw/close_up.hpp"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "lidartag/draw/cairo_util.hpp"
#include "lidartag/draw/colors.hpp"
#include "lidartag/draw/units.hpp"

namespace lidartag::draw {
namespace {

// The marker takes this share of the picture's width; the rest is the frame around it.
constexpr double kMarkerShare = 0.625;

double nice_length(double target) {
  const double p = std::pow(10.0, std::floor(std::log10(target)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= target) return m * p;
  return 10 * p;
}

void square_path(cairo_t* cr, double cx, double cy, double half) {
  cairo_rectangle(cr, cx - half, cy - half, 2 * half, 2 * half);
}

// The inset: what the points read, one square per cell, its side growing with the evidence.
void cells_inset(cairo_t* cr, const CloseUp& v, double x0, double y0, double side, double u) {
  const int w = v.cells_width;
  float strongest = 0;
  for (const float e : v.cells_read) strongest = std::max(strongest, std::fabs(e));
  from_hex(0xffffff).use(cr);
  cairo_rectangle(cr, x0, y0, side, side);
  cairo_fill_preserve(cr);
  cairo_set_source_rgb(cr, 0.6, 0.6, 0.6);
  cairo_set_line_width(cr, 1.0 * u);
  cairo_stroke(cr);
  const double cell = side / w;
  for (int r = 0; r < w; ++r)
    for (int c = 0; c < w; ++c) {
      const float e = v.cells_read[static_cast<size_t>(r * w + c)];
      if (e == 0 || strongest == 0) continue;
      const double s = cell * (0.35 + 0.6 * std::sqrt(std::fabs(e) / strongest));
      from_hex(e > 0 ? kReadWhite : kReadBlack).use(cr);
      cairo_rectangle(cr, x0 + (c + 0.5) * cell - s / 2, y0 + (r + 0.5) * cell - s / 2, s, s);
      cairo_fill(cr);
    }
  cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
  draw_text(cr, "cells read", x0 + side / 2, y0 + side + 15 * u, 12 * u, Align::kCentre);
}

}  // namespace

std::vector<float> turn_counter_clockwise(std::span<const float> cells, int width,
                                          int quarter_turns) {
  std::vector<float> out(cells.begin(), cells.end());
  const auto w = static_cast<size_t>(width);
  for (int q = 0; q < ((quarter_turns % 4) + 4) % 4; ++q) {
    std::vector<float> turned(out.size());
    // Counter-clockwise: the cell at (row, col) moves to (W-1-col, row).
    for (size_t r = 0; r < w; ++r)
      for (size_t c = 0; c < w; ++c) turned[(w - 1 - c) * w + r] = out[r * w + c];
    out.swap(turned);
  }
  return out;
}

void plane_frame(std::span<const detector::ClusterPoint> points, Eigen::Vector3d& centre,
                 Eigen::Matrix3d& rotation) {
  centre.setZero();
  rotation.setIdentity();
  if (points.size() < 3) return;
  for (const auto& p : points) centre += Eigen::Vector3d(p.x, p.y, p.z);
  centre /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector3d d = Eigen::Vector3d(p.x, p.y, p.z) - centre;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d x = eig.eigenvectors().col(0);  // least variance: the normal
  if (x.dot(centre) > 0) x = -x;                  // toward the sensor
  Eigen::Vector3d z = Eigen::Vector3d::UnitZ() - x.z() * x;
  if (z.norm() < 1e-6) z = eig.eigenvectors().col(2);  // a horizontal plane
  z.normalize();
  Eigen::Vector3d y = z.cross(x);
  // Turned within the plane to the smallest square around the points (a board mounted at 45
  // degrees is shown along its sides), the turn nearest to upright on a tie; centred on it.
  std::vector<Eigen::Vector2d> in_plane;
  for (const auto& p : points) {
    const Eigen::Vector3d d = Eigen::Vector3d(p.x, p.y, p.z) - centre;
    in_plane.emplace_back(d.dot(y), d.dot(z));
  }
  double best_side = std::numeric_limits<double>::infinity(), best_angle = 0;
  Eigen::Vector2d best_mid = Eigen::Vector2d::Zero();
  for (int step = 0; step <= 90; ++step) {
    const int deg = step % 2 == 0 ? step / 2 : -(step + 1) / 2;  // 0, -1, 1, -2, 2, ... 45
    const double a = deg * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d hi = -lo;
    for (const auto& q : in_plane) {
      const Eigen::Vector2d r(c * q.x() + s * q.y(), -s * q.x() + c * q.y());
      lo = lo.cwiseMin(r);
      hi = hi.cwiseMax(r);
    }
    const double side = (hi - lo).maxCoeff();
    if (side < best_side * 0.995) {
      best_side = side;
      best_angle = a;
      const Eigen::Vector2d mid = (lo + hi) / 2;
      best_mid = Eigen::Vector2d(c * mid.x() - s * mid.y(), s * mid.x() + c * mid.y());
    }
  }
  centre += best_mid.x() * y + best_mid.y() * z;
  const double c = std::cos(best_angle), s = std::sin(best_angle);
  const Eigen::Vector3d y2 = c * y + s * z, z2 = -s * y + c * z;
  rotation.col(0) = x;
  rotation.col(1) = y2;
  rotation.col(2) = z2;
}

CloseUpMapping write_close_up(const CloseUp& v, int n, const std::string& path) {
  CloseUpMapping m;
  m.px_per_m = kMarkerShare * n / v.size_m;
  m.centre_x = m.centre_y = n / 2.0;
  const double u = n / 800.0;
  Surface surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, n, n));
  check(surface.get(), "cannot allocate the picture");
  Context ctx(cairo_create(surface.get()));
  cairo_t* cr = ctx.get();
  from_hex(kCloseUpBackground).use(cr);
  cairo_paint(cr);
  const double half = v.size_m / 2 * m.px_per_m;

  if (v.family != nullptr) {
    // The decoded grid: row 0 at the top of the printed image (tag +z), column 0 at its left.
    const auto cells = v.family->render(v.code);
    const int w = v.family->total_width;
    auto edge = [&](int k) { return -half + 2 * half * k / w; };
    for (int r = 0; r < w; ++r)
      for (int c = 0; c < w; ++c) {
        from_hex(cells[static_cast<size_t>(r * w + c)] ? kWhiteCell : kBlackCell).use(cr);
        cairo_rectangle(cr, m.centre_x + edge(c), m.centre_y + edge(r), edge(c + 1) - edge(c),
                        edge(r + 1) - edge(r));
        cairo_fill(cr);
      }
    cairo_set_source_rgba(cr, 0.4, 0.4, 0.4, 0.6);
    cairo_set_line_width(cr, 0.8 * u);
    for (int k = 0; k <= w; ++k) {
      cairo_move_to(cr, m.centre_x + edge(k), m.centre_y - half);
      cairo_line_to(cr, m.centre_x + edge(k), m.centre_y + half);
      cairo_move_to(cr, m.centre_x - half, m.centre_y + edge(k));
      cairo_line_to(cr, m.centre_x + half, m.centre_y + edge(k));
    }
    cairo_stroke(cr);
  }

  // The points in the plane, grey by intensity between the cluster's 5th and 95th percentiles
  // (the decoder's black and white levels come from the same spread).
  std::vector<float> levels;
  for (const auto& p : v.points) levels.push_back(p.intensity);
  float lo = 0, hi = 255;
  if (levels.size() >= 2) {
    std::sort(levels.begin(), levels.end());
    lo = levels[levels.size() * 5 / 100];
    hi = levels[levels.size() * 95 / 100];
    if (hi <= lo) hi = lo + 1;
  }
  const Eigen::Matrix3d rt = v.rotation.transpose();
  const double radius = std::max(1.5, 2.6 * u);
  cairo_set_line_width(cr, 0.7 * u);
  for (const auto& p : v.points) {
    const Eigen::Vector3d q = rt * (Eigen::Vector3d(p.x, p.y, p.z) - v.centre);
    const double x = m.centre_x + q.y() * m.px_per_m, y = m.centre_y - q.z() * m.px_per_m;
    if (x < -radius || y < -radius || x > n + radius || y > n + radius) continue;
    const double g = std::clamp((p.intensity - lo) / (hi - lo), 0.0f, 1.0f);
    cairo_arc(cr, x, y, radius, 0, 2 * M_PI);
    cairo_set_source_rgb(cr, g, g, g);
    cairo_fill_preserve(cr);
    cairo_set_source_rgb(cr, 0.5, 0.5, 0.5);
    cairo_stroke(cr);
  }

  // The fitted black square (solid), or a marker of the size asked for (dashed), for scale.
  if (v.fitted) {
    for (size_t k = 0; k < 4; ++k) {
      const Eigen::Vector3d q = rt * (v.corners[k] - v.centre);
      const double x = m.centre_x + q.y() * m.px_per_m, y = m.centre_y - q.z() * m.px_per_m;
      if (k == 0)
        cairo_move_to(cr, x, y);
      else
        cairo_line_to(cr, x, y);
    }
    cairo_close_path(cr);
    from_hex(kFittedSquare).use(cr);
    cairo_set_line_width(cr, 3.0 * u);
    cairo_stroke(cr);
  } else {
    const double dash[] = {8 * u, 6 * u};
    cairo_set_dash(cr, dash, 2, 0);
    square_path(cr, m.centre_x, m.centre_y, half);
    from_hex(kFittedSquare).use(cr);
    cairo_set_line_width(cr, 2.0 * u);
    cairo_stroke(cr);
    if (v.measured_side_m > 0) {
      square_path(cr, m.centre_x, m.centre_y, v.measured_side_m / 2 * m.px_per_m);
      from_hex(kMeasuredSide).use(cr);
      cairo_stroke(cr);
    }
    cairo_set_dash(cr, nullptr, 0, 0);
  }
  if (!v.cells_read.empty() && v.cells_width > 0) {
    const double side = 0.16 * n;
    cells_inset(cr, v, n - side - 16 * u, 16 * u, side, u);
  }

  // Title, legend, scale bar.
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  double y = 26 * u;
  // Left of the inset; a line too long is drawn smaller.
  const double room = n - 32 * u - (v.cells_read.empty() ? 0.0 : 0.16 * n + 16 * u);
  for (const auto& line : v.title) {
    const bool first = y < 30 * u;
    double size = (first ? 17 : 14) * u;
    const double w = text_width(cr, line, size, first);
    if (w > room) size *= room / w;
    draw_text(cr, line, 16 * u, y, size, Align::kLeft, first);
    y += 21 * u;
  }
  double x = 16 * u;
  const double ly = n - 44 * u;
  auto swatch = [&](uint32_t colour, const std::string& text, bool round) {
    from_hex(colour).use(cr);
    if (round)
      cairo_arc(cr, x + 7 * u, ly - 5 * u, 5 * u, 0, 2 * M_PI);
    else
      cairo_rectangle(cr, x, ly - 11 * u, 14 * u, 12 * u);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
    draw_text(cr, text, x + 20 * u, ly, 13 * u);
    x += 28 * u + text_width(cr, text, 13 * u);
  };
  if (v.family != nullptr) {
    swatch(kBlackCell, "decoded black cell", false);
    swatch(kWhiteCell, "white cell", false);
  }
  swatch(0x202020, "dark return", true);
  swatch(0xe0e0e0, "bright return", true);
  swatch(kFittedSquare, v.fitted ? "fitted square" : "a marker of the size asked for", false);
  if (!v.fitted && v.measured_side_m > 0) swatch(kMeasuredSide, "side measured", false);
  const double bar = nice_length(v.size_m / 3);
  cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
  cairo_rectangle(cr, 16 * u, n - 22 * u, bar * m.px_per_m, 4 * u);
  cairo_fill(cr);
  draw_text(cr, format_number(bar * 100, 1) + " cm", 24 * u + bar * m.px_per_m, n - 16 * u, 13 * u);
  draw_text(cr, "seen from the front, in the tag's plane", n - 16 * u, n - 16 * u, 12 * u,
            Align::kRight);
  check(cr, "cannot draw '" + path + "'");
  ctx.reset();
  write_png(surface.get(), path);
  return m;
}

}  // namespace lidartag::draw
