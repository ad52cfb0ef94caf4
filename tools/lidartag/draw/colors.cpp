#include "lidartag/draw/colors.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace lidartag::draw {

uint32_t Colour::rgb() const {
  auto c = [](double v) {
    return static_cast<uint32_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255));
  };
  return c(r) << 16 | c(g) << 8 | c(b);
}

void Colour::use(cairo_t* cr, double alpha) const {
  if (alpha >= 1.0)
    cairo_set_source_rgb(cr, r, g, b);
  else
    cairo_set_source_rgba(cr, r, g, b, alpha);
}

Colour viridis(double t) {
  // The colour map at t = 0, 0.1, ..., 1 (matplotlib's viridis), linearly interpolated.
  static constexpr std::array<uint32_t, 11> kAnchors = {0x440154, 0x482475, 0x414487, 0x355f8d,
                                                        0x2a788e, 0x21918c, 0x22a884, 0x44bf70,
                                                        0x7ad151, 0xbddf26, 0xfde725};
  const double x = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * 10.0;
  const auto i = std::min<size_t>(9, static_cast<size_t>(x));
  const double f = x - static_cast<double>(i);
  const Colour a = from_hex(kAnchors[i]), b = from_hex(kAnchors[i + 1]);
  return {a.r + f * (b.r - a.r), a.g + f * (b.g - a.g), a.b + f * (b.b - a.b)};
}

Colour stage_colour(detector::Stage stage) {
  switch (stage) {
    case detector::Stage::kFeatures:
    case detector::Stage::kClustering:
      return from_hex(0x9aa0a6);  // grey: too few rings or features, or too large, to be a tag
    case detector::Stage::kValidation:
      return from_hex(0xf5a623);  // orange: point counts
    case detector::Stage::kPlane:
      return from_hex(0x9b59ff);  // purple: not planar
    case detector::Stage::kCorners:
      return from_hex(0xf8e71c);  // yellow: no square of a configured size
    case detector::Stage::kPose:
      return from_hex(0x2ec4d6);  // cyan: the fit
    case detector::Stage::kDecode:
      return from_hex(0xff3b8d);  // pink: no code
    case detector::Stage::kCount:
      break;
  }
  return from_hex(0xffffff);
}

}  // namespace lidartag::draw
