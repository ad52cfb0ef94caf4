// Owning handles for Cairo objects, text helpers, and the surfaces of the three file formats in
// millimetres (user units are mm on every surface).
#pragma once

#include <cairo.h>

#include <memory>
#include <string>

namespace lidartag::draw {

struct SurfaceDeleter {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextDeleter {
  void operator()(cairo_t* c) const { cairo_destroy(c); }
};
using Surface = std::unique_ptr<cairo_surface_t, SurfaceDeleter>;
using Context = std::unique_ptr<cairo_t, ContextDeleter>;

enum class OutputFormat { kPdf, kSvg, kPng };

// "pdf", "svg", "png".
const char* format_name(OutputFormat f);
// From a file name's extension (any case); false when it is none of the three.
bool format_from_path(const std::string& path, OutputFormat& out);

// A context on `surface` whose user unit is 1 mm (`units_per_mm`: 72/25.4 for PDF and SVG,
// dpi/25.4 for images). Throws std::runtime_error on a Cairo error.
Context mm_context(cairo_surface_t* surface, double units_per_mm);

// Throws std::runtime_error naming `what` when the surface or context is in an error state
// (e.g. the file cannot be written).
void check(cairo_surface_t* surface, const std::string& what);
void check(cairo_t* cr, const std::string& what);

enum class Align { kLeft, kCentre, kRight };
// Draws `text` with its baseline at y, `size_mm` high (the font's em), sans-serif.
void draw_text(cairo_t* cr, const std::string& text, double x, double y, double size_mm,
               Align align = Align::kLeft, bool bold = false);
double text_width(cairo_t* cr, const std::string& text, double size_mm, bool bold = false);

// Frees Cairo's font caches and fontconfig's configuration (loaded for the text drawn) when it
// goes out of scope: declared before any surface of a command, so that it runs after they are
// gone, on success and on an error alike, and leak checkers see no memory still held.
struct FontCacheRelease {
  FontCacheRelease() = default;
  FontCacheRelease(const FontCacheRelease&) = delete;
  FontCacheRelease& operator=(const FontCacheRelease&) = delete;
  ~FontCacheRelease();
};

// Writes an image surface as PNG with its resolution (a pHYs chunk, when dpi > 0) so that it
// prints at size; throws std::runtime_error on failure.
void write_png(cairo_surface_t* image, const std::string& path, double dpi = 0);

}  // namespace lidartag::draw
