// Reads a PNG (through Cairo) into grey levels, for tests that check what a picture shows.
#pragma once

#include <cairo.h>

#include <cstdint>
#include <string>
#include <vector>

namespace lidartag::testing {

struct Rgb {
  int r = 0, g = 0, b = 0;
};

struct Image {
  int width = 0, height = 0;
  std::vector<Rgb> pixels;  // row-major
  bool empty() const { return width == 0; }
  const Rgb& at(int x, int y) const { return pixels[static_cast<size_t>(y * width + x)]; }
  int grey(int x, int y) const {
    const Rgb& p = at(x, y);
    return (p.r + p.g + p.b) / 3;
  }
};

// Empty on failure. Transparent pixels read as white (what paper shows).
inline Image read_png(const std::string& path) {
  Image img;
  cairo_surface_t* s = cairo_image_surface_create_from_png(path.c_str());
  if (cairo_surface_status(s) != CAIRO_STATUS_SUCCESS) {
    cairo_surface_destroy(s);
    return img;
  }
  cairo_surface_flush(s);
  const cairo_format_t format = cairo_image_surface_get_format(s);
  img.width = cairo_image_surface_get_width(s);
  img.height = cairo_image_surface_get_height(s);
  const int stride = cairo_image_surface_get_stride(s);
  const unsigned char* data = cairo_image_surface_get_data(s);
  img.pixels.resize(static_cast<size_t>(img.width) * static_cast<size_t>(img.height));
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      uint32_t v = 0;
      const unsigned char* p = data + y * stride + x * 4;
      v = static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
          static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
      const int a = format == CAIRO_FORMAT_ARGB32 ? static_cast<int>(v >> 24) : 255;
      // Premultiplied alpha over white.
      auto channel = [&](int shift) { return static_cast<int>((v >> shift) & 0xff) + (255 - a); };
      img.pixels[static_cast<size_t>(y * img.width + x)] = {channel(16), channel(8), channel(0)};
    }
  cairo_surface_destroy(s);
  return img;
}

}  // namespace lidartag::testing
