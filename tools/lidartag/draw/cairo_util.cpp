#include "lidartag/draw/cairo_util.hpp"

#include <fontconfig/fontconfig.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace lidartag::draw {

const char* format_name(OutputFormat f) {
  switch (f) {
    case OutputFormat::kPdf:
      return "pdf";
    case OutputFormat::kSvg:
      return "svg";
    case OutputFormat::kPng:
      return "png";
  }
  return "?";
}

bool format_from_path(const std::string& path, OutputFormat& out) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".pdf")
    out = OutputFormat::kPdf;
  else if (ext == ".svg")
    out = OutputFormat::kSvg;
  else if (ext == ".png")
    out = OutputFormat::kPng;
  else
    return false;
  return true;
}

void check(cairo_surface_t* surface, const std::string& what) {
  const cairo_status_t s = cairo_surface_status(surface);
  if (s != CAIRO_STATUS_SUCCESS) throw std::runtime_error(what + ": " + cairo_status_to_string(s));
}

void check(cairo_t* cr, const std::string& what) {
  const cairo_status_t s = cairo_status(cr);
  if (s != CAIRO_STATUS_SUCCESS) throw std::runtime_error(what + ": " + cairo_status_to_string(s));
}

Context mm_context(cairo_surface_t* surface, double units_per_mm) {
  Context cr(cairo_create(surface));
  check(cr.get(), "cannot draw");
  cairo_scale(cr.get(), units_per_mm, units_per_mm);
  return cr;
}

namespace {
void select_font(cairo_t* cr, double size_mm, bool bold) {
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL,
                         bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size_mm);
}
}  // namespace

double text_width(cairo_t* cr, const std::string& text, double size_mm, bool bold) {
  select_font(cr, size_mm, bold);
  cairo_text_extents_t e;
  cairo_text_extents(cr, text.c_str(), &e);
  return e.x_advance;
}

void draw_text(cairo_t* cr, const std::string& text, double x, double y, double size_mm,
               Align align, bool bold) {
  const double w = text_width(cr, text, size_mm, bold);
  const double x0 = align == Align::kLeft ? x : align == Align::kCentre ? x - w / 2 : x - w;
  cairo_move_to(cr, x0, y);
  cairo_show_text(cr, text.c_str());
  cairo_new_path(cr);
}

FontCacheRelease::~FontCacheRelease() {
  cairo_debug_reset_static_data();
}

void write_png(cairo_surface_t* image, const std::string& path, double dpi) {
  cairo_surface_flush(image);
  std::string png;
  const cairo_status_t s = cairo_surface_write_to_png_stream(
      image,
      [](void* closure, const unsigned char* data, unsigned int length) {
        static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
        return CAIRO_STATUS_SUCCESS;
      },
      &png);
  if (s != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error("cannot encode '" + path + "': " + cairo_status_to_string(s));
  // Cairo writes no resolution: a pHYs chunk (pixels per metre) goes right after IHDR, which is
  // the first chunk (8 bytes of signature, then 4 length + 4 type + 13 data + 4 CRC).
  constexpr size_t kAfterIhdr = 8 + 4 + 4 + 13 + 4;
  if (dpi > 0 && png.size() > kAfterIhdr && png.compare(12, 4, "IHDR") == 0) {
    const auto ppm = static_cast<uint32_t>(std::lround(dpi / 0.0254));
    std::string chunk;
    auto put32 = [&](uint32_t v) {
      for (int shift = 24; shift >= 0; shift -= 8) chunk += static_cast<char>((v >> shift) & 0xff);
    };
    put32(9);
    chunk += "pHYs";
    put32(ppm);
    put32(ppm);
    chunk += '\1';  // unit: metre
    const auto* typed = reinterpret_cast<const Bytef*>(chunk.data() + 4);
    put32(static_cast<uint32_t>(crc32(crc32(0L, Z_NULL, 0), typed, 4 + 9)));
    png.insert(kAfterIhdr, chunk);
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(png.data(), static_cast<std::streamsize>(png.size()));
  out.close();
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
}

}  // namespace lidartag::draw
