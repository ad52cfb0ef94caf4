// Colours of the pictures `lidartag render` draws: intensity maps and one colour per pipeline
// stage, shared by the pictures and their legends (and the tests that read the pictures).
#pragma once

#include <cairo.h>

#include <cstdint>

#include "lidartag/detector/detector.hpp"

namespace lidartag::draw {

struct Colour {
  double r = 0, g = 0, b = 0;
  uint32_t rgb() const;  // 0xRRGGBB
  void use(cairo_t* cr, double alpha = 1.0) const;
};

constexpr Colour from_hex(uint32_t rgb) {
  return {((rgb >> 16) & 0xff) / 255.0, ((rgb >> 8) & 0xff) / 255.0, (rgb & 0xff) / 255.0};
}

// Viridis (perceptually uniform, readable in grey), t in [0, 1].
Colour viridis(double t);

// A rejected cluster's colour: the stage that dropped it.
Colour stage_colour(detector::Stage stage);

// Bird's-eye view.
inline constexpr uint32_t kBackground = 0x0e1116;
inline constexpr uint32_t kDetection = 0xffffff;
inline constexpr uint32_t kRangeRings = 0x3a4048;
// Close-ups: the decoded grid under the points.
inline constexpr uint32_t kBlackCell = 0x35557f;
inline constexpr uint32_t kWhiteCell = 0xefe2b8;
inline constexpr uint32_t kCloseUpBackground = 0xf4f4f4;
inline constexpr uint32_t kFittedSquare = 0x1aa64b;
inline constexpr uint32_t kMeasuredSide = 0xe8710a;
// The inset of what the points read: darker and stronger than the grid's cells.
inline constexpr uint32_t kReadBlack = 0x1d2f4a;
inline constexpr uint32_t kReadWhite = 0xf2c94c;

}  // namespace lidartag::draw
