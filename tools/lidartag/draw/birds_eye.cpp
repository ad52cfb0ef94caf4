#include "lidartag/draw/birds_eye.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "lidartag/draw/cairo_util.hpp"
#include "lidartag/draw/colors.hpp"
#include "lidartag/draw/units.hpp"

namespace lidartag::draw {
namespace {

namespace det = detector;

// Height of the strip below the map (title, legend, bars) at 1000 pixels.
constexpr double kStripPx = 100.0;
constexpr uint32_t kStrip = 0x1b1f24;

// Intensities above this are all drawn in the brightest colour (most surfaces are below 100;
// retro-reflective ones reach 255).
constexpr double kIntensityTop = 150.0;

Colour intensity_colour(double intensity) {
  return viridis(0.15 + 0.85 * std::min(intensity, kIntensityTop) / kIntensityTop);
}

// A step of 1, 2 or 5 times a power of ten close to `target`.
double nice_step(double target) {
  const double p = std::pow(10.0, std::floor(std::log10(target)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= target) return m * p;
  return 10 * p;
}

// The caller chose which clusters to draw (the rejected ones of them are drawn).
bool shown(const det::ClusterDiagnostic& d) {
  return d.rejection != det::Rejection::kNone;
}

// Reached the plane fit or later.
bool advanced(const det::ClusterDiagnostic& d) {
  return shown(d) &&
         static_cast<int>(det::stage_of(d.rejection)) >= static_cast<int>(det::Stage::kPlane);
}

void label(cairo_t* cr, const std::string& text, double x, double y, double size,
           const Colour& colour, bool box = true, Align align = Align::kLeft) {
  if (box) {
    const double w = text_width(cr, text, size);
    cairo_rectangle(cr, x - 2, y - size, w + 4, size * 1.3);
    cairo_set_source_rgba(cr, 0, 0, 0, 0.6);
    cairo_fill(cr);
  }
  colour.use(cr);
  draw_text(cr, text, x, y, size, align);
}

}  // namespace

double auto_range_m(const Scan& scan, const det::ScanResult& result,
                    const std::vector<ViewCluster>& clusters) {
  double far = 0;
  for (const auto& d : result.detections) far = std::max(far, d.position.head<2>().norm());
  for (const auto& c : clusters) {
    if (!advanced(*c.diagnostic)) continue;
    const auto& d = *c.diagnostic;
    for (const float x : {d.min_x, d.max_x})
      for (const float y : {d.min_y, d.max_y})
        far = std::max(far, std::hypot(double(x), double(y)));
  }
  if (far > 0) return std::max(5.0, 1.25 * far + 1.0);
  // Nothing of interest: most of the points (their 80th percentile of horizontal range).
  std::vector<float> r;
  for (int ret = 0; ret < scan.returns; ++ret)
    for (int ring = 0; ring < scan.rings; ++ring)
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(ret, ring, col);
        if (scan.valid(i)) r.push_back(std::hypot(scan.x[i], scan.y[i]));
      }
  if (r.empty()) return 10.0;
  auto at = r.begin() + static_cast<long>(r.size() * 8 / 10);
  std::nth_element(r.begin(), at, r.end());
  return std::clamp(static_cast<double>(*at), 5.0, 100.0);
}

BirdsEyeMapping write_birds_eye(const Scan& scan, const det::ScanResult& result,
                                const std::vector<ViewCluster>& clusters, const BirdsEyeOptions& o,
                                const std::string& path) {
  const int n = o.size_px;
  BirdsEyeMapping m;
  m.range_m = o.range_m > 0 ? o.range_m : auto_range_m(scan, result, clusters);
  m.px_per_m = n / 2.0 / m.range_m;
  m.centre_x = m.centre_y = n / 2.0;
  auto px = [&](double x, double y) {
    return std::array<double, 2>{m.centre_x - y * m.px_per_m, m.centre_y - x * m.px_per_m};
  };
  const double u = n / 1000.0;  // line widths and text scale with the picture

  Surface surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, n,
                                             n + static_cast<int>(std::lround(kStripPx * u))));
  check(surface.get(), "cannot allocate the picture");
  Context ctx(cairo_create(surface.get()));
  cairo_t* cr = ctx.get();
  from_hex(kBackground).use(cr);
  cairo_paint(cr);

  // Range rings and the sensor.
  const double step = nice_step(m.range_m / 4);
  cairo_set_line_width(cr, 1.0 * u);
  for (double r = step; r < m.range_m * 1.5; r += step) {
    cairo_arc(cr, m.centre_x, m.centre_y, r * m.px_per_m, 0, 2 * M_PI);
    from_hex(kRangeRings).use(cr);
    cairo_stroke(cr);
    label(cr, format_number(r, 1) + " m", m.centre_x + 3 * u, m.centre_y - r * m.px_per_m - 3 * u,
          11 * u, from_hex(0x6a717a), false);
  }

  // Every return, coloured by intensity.
  const double dot = std::max(1.0, 1.6 * u);
  for (int ret = 0; ret < scan.returns; ++ret)
    for (int ring = 0; ring < scan.rings; ++ring)
      for (int c = 0; c < scan.columns; ++c) {
        const size_t i = scan.at(ret, ring, c);
        if (!scan.valid(i)) continue;
        const auto p = px(scan.x[i], scan.y[i]);
        if (p[0] < -dot || p[1] < -dot || p[0] > n + dot || p[1] > n + dot) continue;
        intensity_colour(scan.intensity[i]).use(cr);
        cairo_rectangle(cr, p[0] - dot / 2, p[1] - dot / 2, dot, dot);
        cairo_fill(cr);
      }

  // Rejected clusters, by stage: their points when kept, else their x-y box.
  for (const ViewCluster& c : clusters) {
    const auto& d = *c.diagnostic;
    if (!shown(d)) continue;
    const Colour colour = stage_colour(det::stage_of(d.rejection));
    const bool hi = c.index == o.highlight;
    if (!c.points.empty()) {
      colour.use(cr);
      const double s = (hi ? 3.0 : 2.2) * u;
      for (const auto& p : c.points) {
        const auto q = px(p.x, p.y);
        cairo_rectangle(cr, q[0] - s / 2, q[1] - s / 2, s, s);
      }
      cairo_fill(cr);
    }
    const auto a = px(d.max_x, d.max_y), b = px(d.min_x, d.min_y);
    cairo_rectangle(cr, a[0] - 2 * u, a[1] - 2 * u, b[0] - a[0] + 4 * u, b[1] - a[1] + 4 * u);
    colour.use(cr);
    cairo_set_line_width(cr, (hi ? 3.0 : 2.0) * u);
    cairo_stroke(cr);
    if (advanced(d) || hi)
      label(cr, fmt::format("#{} {}", c.index, det::rejection_name(d.rejection)), a[0],
            a[1] - 5 * u, (hi ? 14 : 11) * u, colour);
  }

  // Detections: the tag's axes (x, its normal, red; y green; z blue), the square seen from above
  // over them, family and id.
  for (const auto& d : result.detections) {
    const auto centre = px(d.position.x(), d.position.y());
    const Eigen::Matrix3d R = d.orientation.toRotationMatrix();
    const std::array<uint32_t, 3> axis_colours = {0xff4d4d, 0x4dff6a, 0x4d8dff};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d tip = d.position + R.col(k) * (0.6 * d.size_m);
      const auto q = px(tip.x(), tip.y());
      cairo_move_to(cr, centre[0], centre[1]);
      cairo_line_to(cr, q[0], q[1]);
      from_hex(axis_colours[static_cast<size_t>(k)]).use(cr);
      cairo_set_line_width(cr, 2.0 * u);
      cairo_stroke(cr);
    }
    for (size_t k = 0; k <= 4; ++k) {
      const auto& c = d.corners[k % 4];
      const auto q = px(c.x(), c.y());
      if (k == 0)
        cairo_move_to(cr, q[0], q[1]);
      else
        cairo_line_to(cr, q[0], q[1]);
    }
    from_hex(kDetection).use(cr);
    cairo_set_line_width(cr, 3.0 * u);
    cairo_stroke(cr);
    // Beside the outline, right of its rightmost corner.
    double right = centre[0];
    for (const auto& c : d.corners) right = std::max(right, px(c.x(), c.y())[0]);
    label(cr, fmt::format("{} id {}", d.family, d.id), right + 10 * u, centre[1] + 5 * u, 15 * u,
          from_hex(kDetection));
  }

  // Below the map, so that nothing of it is hidden: title, legend, intensity and scale bars.
  const double strip = n;
  cairo_rectangle(cr, 0, strip, n, kStripPx * u);
  from_hex(kStrip).use(cr);
  cairo_fill(cr);
  cairo_move_to(cr, 0, strip + 0.5);
  cairo_line_to(cr, n, strip + 0.5);
  from_hex(kRangeRings).use(cr);
  cairo_set_line_width(cr, 1.0);
  cairo_stroke(cr);
  double y = strip + 22 * u;
  std::string title;
  for (const auto& line : o.title) title += (title.empty() ? "" : "; ") + line;
  label(cr, title, 14 * u, y, 15 * u, from_hex(0xe8eaed), false);
  struct Entry {
    Colour colour;
    std::string text;
  };
  std::vector<Entry> legend = {
      {from_hex(kDetection), fmt::format("detection ({})", result.detections.size())}};
  const std::array<const char*, det::kStageCount> what = {"",
                                                          "clustering: too few rings, too large",
                                                          "validation: point counts",
                                                          "plane: not flat",
                                                          "corners: no tag-sized square",
                                                          "pose: fit cost, coverage",
                                                          "decode: no code"};
  for (int s = 1; s < det::kStageCount; ++s) {
    const auto stage = static_cast<det::Stage>(s);
    size_t count = 0;
    for (const auto& c : clusters)
      count += shown(*c.diagnostic) && det::stage_of(c.diagnostic->rejection) == stage ? 1u : 0u;
    legend.push_back(
        {stage_colour(stage), fmt::format("{} ({})", what[static_cast<size_t>(s)], count)});
  }
  // Two rows of four entries.
  for (size_t k = 0; k < legend.size(); ++k) {
    const double x = 14 * u + static_cast<double>(k % 4) * 245 * u;
    const double yy = strip + (k < 4 ? 46 : 68) * u;
    legend[k].colour.use(cr);
    cairo_rectangle(cr, x, yy - 10 * u, 14 * u, 10 * u);
    cairo_fill(cr);
    label(cr, legend[k].text, x + 20 * u, yy, 13 * u, from_hex(0xe8eaed), false);
  }
  // Intensity colour bar and scale bar: a round length of about a tenth of the map.
  const double by = strip + 90 * u;
  for (int k = 0; k < 100; ++k) {
    intensity_colour(kIntensityTop * k / 99.0).use(cr);
    cairo_rectangle(cr, 14 * u + k * 1.4 * u, by - 10 * u, 1.5 * u, 10 * u);
    cairo_fill(cr);
  }
  label(cr, fmt::format("intensity 0 - {:.0f}+", kIntensityTop), 164 * u, by, 13 * u,
        from_hex(0xe8eaed), false);
  const double bar = nice_step(m.range_m / 5);
  const double bx = 320 * u;
  cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
  cairo_rectangle(cr, bx, by - 6 * u, bar * m.px_per_m, 4 * u);
  cairo_fill(cr);
  label(cr, format_number(bar, 1) + " m", bx + bar * m.px_per_m + 8 * u, by, 13 * u,
        from_hex(0xe8eaed), false);
  label(cr, "seen from above: x forward up, y left left", n - 14 * u, by, 12 * u,
        from_hex(0x9aa0a6), false, Align::kRight);

  check(cr, "cannot draw '" + path + "'");
  ctx.reset();
  write_png(surface.get(), path);
  return m;
}

}  // namespace lidartag::draw
