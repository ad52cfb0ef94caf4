#include "lidartag/draw/marker_pages.hpp"

#include <cairo-pdf.h>
#include <cairo-svg.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace lidartag::draw {
namespace {

constexpr double kGrey = 0.45;         // marks
constexpr double kTextGrey = 0.15;     // captions and footer
constexpr double kLineMm = 0.2;        // marks' line width
constexpr double kMarkOffsetMm = 1.0;  // marks start this far outside the marker or tile
constexpr double kMarkLengthMm = 4.0;

// The black cells of `code` as one path (one fill: no hairline seams between neighbours), the
// marker's top-left outer corner at (x, y); cell edges computed from the size, not accumulated.
void marker_path(cairo_t* cr, const tags::TagFamily& f, uint64_t code, double x, double y,
                 double size) {
  const std::vector<uint8_t> cells = f.render(code);
  const int n = f.total_width;
  auto edge = [&](int k) { return size * k / n; };
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c)
      if (cells[static_cast<size_t>(r * n + c)] == 0)
        cairo_rectangle(cr, x + edge(c), y + edge(r), edge(c + 1) - edge(c), edge(r + 1) - edge(r));
}

void line(cairo_t* cr, double x0, double y0, double x1, double y1) {
  cairo_move_to(cr, x0, y0);
  cairo_line_to(cr, x1, y1);
}

// Cut marks outside the four corners of a whole marker (the white ring is white paper).
void corner_marks(cairo_t* cr, double x, double y, double s) {
  const double a = kMarkOffsetMm, b = kMarkOffsetMm + kMarkLengthMm;
  for (const double cx : {x, x + s})
    for (const double cy : {y, y + s}) {
      const double sx = cx == x ? -1 : 1, sy = cy == y ? -1 : 1;
      line(cr, cx + sx * a, cy, cx + sx * b, cy);
      line(cr, cx, cy + sy * a, cx, cy + sy * b);
    }
  cairo_set_source_rgb(cr, kGrey, kGrey, kGrey);
  cairo_set_line_width(cr, kLineMm);
  cairo_stroke(cr);
}

// A tile's trim marks (its edges extended outward at each corner) and ticks where cell edges
// cross its border, so that neighbouring tiles line up.
void tile_marks(cairo_t* cr, const Placement& p, int cells, double outer_mm) {
  const double w = p.x1 - p.x0, h = p.y1 - p.y0;
  const double a = kMarkOffsetMm, b = kMarkOffsetMm + 2 * kMarkLengthMm;
  for (const double cx : {p.page_x, p.page_x + w})
    for (const double cy : {p.page_y, p.page_y + h}) {
      const double sx = cx == p.page_x ? -1 : 1, sy = cy == p.page_y ? -1 : 1;
      line(cr, cx + sx * a, cy, cx + sx * b, cy);
      line(cr, cx, cy + sy * a, cx, cy + sy * b);
    }
  for (int k = 0; k <= cells; ++k) {
    const double e = outer_mm * k / cells;
    if (e > p.x0 && e < p.x1) {
      const double x = p.page_x + e - p.x0;
      line(cr, x, p.page_y - a, x, p.page_y - a - kMarkLengthMm / 2);
      line(cr, x, p.page_y + h + a, x, p.page_y + h + a + kMarkLengthMm / 2);
    }
    if (e > p.y0 && e < p.y1) {
      const double y = p.page_y + e - p.y0;
      line(cr, p.page_x - a, y, p.page_x - a - kMarkLengthMm / 2, y);
      line(cr, p.page_x + w + a, y, p.page_x + w + a + kMarkLengthMm / 2, y);
    }
  }
  cairo_set_source_rgb(cr, kGrey, kGrey, kGrey);
  cairo_set_line_width(cr, kLineMm);
  cairo_stroke(cr);
}

// A bar of `length` mm in tenths, alternately black and white, with 0 and the length written.
void scale_bar(cairo_t* cr, double x, double y, double length) {
  constexpr double kBarMm = 1.6;
  for (int k = 0; k < 10; ++k)
    if (k % 2 == 0) cairo_rectangle(cr, x + length * k / 10, y, length / 10, kBarMm);
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_fill(cr);
  cairo_rectangle(cr, x, y, length, kBarMm);
  cairo_set_line_width(cr, 0.15);
  cairo_stroke(cr);
  cairo_set_source_rgb(cr, kTextGrey, kTextGrey, kTextGrey);
  draw_text(cr, "0", x, y + kBarMm + 2.6, 2.2, Align::kCentre);
  draw_text(cr, format_number(length, 1) + " mm", x + length, y + kBarMm + 2.6, 2.2,
            Align::kCentre);
}

// Text shrunk to fit `max_width` when needed.
void fitted_text(cairo_t* cr, const std::string& text, double x, double y, double size,
                 double max_width, Align align = Align::kLeft, bool bold = false) {
  const double w = text_width(cr, text, size, bold);
  if (w > max_width && w > 0) size *= max_width / w;
  draw_text(cr, text, x, y, size, align, bold);
}

std::string ids_text(const std::vector<int>& ids) {
  if (ids.size() == 1) return fmt::format("id {}", ids.front());
  return fmt::format("{} ids", ids.size());
}

void footer(cairo_t* cr, const MarkerJob& job, const PageLayout& page, size_t page_index,
            size_t page_count) {
  const tags::TagFamily& f = *job.family;
  const double m = job.sheet.margin_mm;
  const double top = page.height_mm - m - job.sheet.footer_mm;
  const double width = page.width_mm - 2 * m;
  // Tiled pages: a map of the tiles with this one filled, at the right, beside the text lines.
  double map_width = 0;
  if (page.tiled()) {
    const double cell = std::min(2.5, 8.0 / std::max(page.tile_rows, page.tile_cols));
    map_width = cell * page.tile_cols + 3;
    const double x0 = page.width_mm - m - cell * page.tile_cols;
    const double y0 = top + 15.3 - cell * page.tile_rows;
    for (int r = 0; r < page.tile_rows; ++r)
      for (int c = 0; c < page.tile_cols; ++c) {
        cairo_rectangle(cr, x0 + c * cell, y0 + r * cell, cell, cell);
        if (r == page.tile_row && c == page.tile_col) {
          cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
          cairo_fill_preserve(cr);
        }
        cairo_set_source_rgb(cr, kGrey, kGrey, kGrey);
        cairo_set_line_width(cr, 0.12);
        cairo_stroke(cr);
      }
  }
  std::string what = f.name;
  if (page.markers.size() == 1)
    what += fmt::format(" id {}", job.ids[static_cast<size_t>(page.markers[0].index)]);
  cairo_set_source_rgb(cr, kTextGrey, kTextGrey, kTextGrey);
  fitted_text(cr,
              fmt::format("{}: marker {} outer (white ring included; lidartag --tag-size {}) = "
                          "{} black square (AprilTag 3 tag size), {}x{} cells of {}",
                          what, format_mm(job.outer_mm), format_m(job.outer_mm),
                          format_mm(black_size_mm(f, job.outer_mm)), f.total_width, f.total_width,
                          format_mm(job.outer_mm / f.total_width)),
              m, top + 9.5, 2.6, width - map_width);
  // The longest bar of 100, 50, 20 or 10 mm that leaves room for the page text.
  double bar = 100;
  while (bar > 10 && bar > width * 0.6) bar /= bar == 100 ? 2 : 2.5;
  fitted_text(cr,
              fmt::format("Print at 100 % (actual size, no scaling): the bar below must measure "
                          "{} mm. {}",
                          format_number(bar, 1), job.generator),
              m, top + 13.0, 2.2, width - map_width);
  scale_bar(cr, m, top + 15.0, bar);
  std::string where = fmt::format("page {} of {}", page_index + 1, page_count);
  if (page.tiled())
    where = fmt::format("tile row {} of {}, column {} of {} (left to right, top to bottom); ",
                        page.tile_row + 1, page.tile_rows, page.tile_col + 1, page.tile_cols) +
            where;
  cairo_set_source_rgb(cr, kTextGrey, kTextGrey, kTextGrey);
  fitted_text(cr, where, page.width_mm - m, top + 19.2, 2.2, width - bar - 8, Align::kRight);
}

void caption(cairo_t* cr, const MarkerJob& job, const Placement& p) {
  const tags::TagFamily& f = *job.family;
  const double s = job.outer_mm;
  const double cx = p.page_x + s / 2;
  cairo_set_source_rgb(cr, kTextGrey, kTextGrey, kTextGrey);
  fitted_text(cr, fmt::format("{} id {}", f.name, job.ids[static_cast<size_t>(p.index)]), cx,
              p.page_y + s + 4.2, 3.0, s + job.sheet.gap_mm - 1, Align::kCentre, true);
  fitted_text(cr, fmt::format("outer {}, black {}", format_mm(s), format_mm(black_size_mm(f, s))),
              cx, p.page_y + s + 7.6, 2.2, s + job.sheet.gap_mm - 1, Align::kCentre);
}

void draw_page(cairo_t* cr, const MarkerJob& job, const PageLayout& page, size_t index,
               size_t count) {
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  const tags::TagFamily& f = *job.family;
  for (const Placement& p : page.markers) {
    const uint64_t code = f.codes[static_cast<size_t>(job.ids[static_cast<size_t>(p.index)])];
    cairo_save(cr);
    cairo_rectangle(cr, p.page_x, p.page_y, p.x1 - p.x0, p.y1 - p.y0);
    cairo_clip(cr);
    // Image pixels are either black or white: no grey edges where a cell edge splits a pixel.
    if (job.format == OutputFormat::kPng) cairo_set_antialias(cr, CAIRO_ANTIALIAS_NONE);
    marker_path(cr, f, code, p.page_x - p.x0, p.page_y - p.y0, job.outer_mm);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_fill(cr);
    cairo_restore(cr);
    if (job.sheet.bare) continue;
    if (p.tile) {
      tile_marks(cr, p, f.total_width, job.outer_mm);
    } else {
      corner_marks(cr, p.page_x, p.page_y, job.outer_mm);
      caption(cr, job, p);
    }
  }
  if (!job.sheet.bare) footer(cr, job, page, index, count);
}

}  // namespace

double black_size_mm(const tags::TagFamily& family, double outer_mm) {
  return outer_mm * family.width_at_border / family.total_width;
}

int page_pixels(double mm, double dpi) {
  return static_cast<int>(std::lround(mm / 25.4 * dpi));
}

std::vector<std::string> page_files(const MarkerJob& job, size_t pages) {
  if (job.format == OutputFormat::kPdf || pages == 1) return {job.path};
  const std::filesystem::path path(job.path);
  const int digits = static_cast<int>(std::to_string(pages).size());
  std::vector<std::string> files;
  for (size_t i = 0; i < pages; ++i) {
    std::filesystem::path p = path;
    p.replace_filename(fmt::format("{}-{:0{}d}{}", path.stem().string(), i + 1, std::max(2, digits),
                                   path.extension().string()));
    files.push_back(p.string());
  }
  return files;
}

std::vector<std::string> write_marker_pages(const MarkerJob& job, const Layout& layout) {
  constexpr double kPointsPerMm = 72.0 / 25.4;
  const auto files = page_files(job, layout.pages.size());
  const size_t count = layout.pages.size();
  if (job.format == OutputFormat::kPdf) {
    const PageLayout& first = layout.pages.front();
    Surface surface(cairo_pdf_surface_create(job.path.c_str(), first.width_mm * kPointsPerMm,
                                             first.height_mm * kPointsPerMm));
    check(surface.get(), "cannot write '" + job.path + "'");
    cairo_pdf_surface_set_metadata(surface.get(), CAIRO_PDF_METADATA_TITLE,
                                   fmt::format("{} {}, marker {}", job.family->name,
                                               ids_text(job.ids), format_mm(job.outer_mm))
                                       .c_str());
    cairo_pdf_surface_set_metadata(surface.get(), CAIRO_PDF_METADATA_CREATOR,
                                   job.generator.c_str());
    Context cr = mm_context(surface.get(), kPointsPerMm);
    for (size_t i = 0; i < count; ++i) {
      const PageLayout& page = layout.pages[i];
      cairo_pdf_surface_set_size(surface.get(), page.width_mm * kPointsPerMm,
                                 page.height_mm * kPointsPerMm);
      draw_page(cr.get(), job, page, i, count);
      cairo_show_page(cr.get());
    }
    check(cr.get(), "cannot write '" + job.path + "'");
    cr.reset();
    cairo_surface_finish(surface.get());
    check(surface.get(), "cannot write '" + job.path + "'");
    return files;
  }
  for (size_t i = 0; i < count; ++i) {
    const PageLayout& page = layout.pages[i];
    if (job.format == OutputFormat::kSvg) {
      Surface surface(cairo_svg_surface_create(files[i].c_str(), page.width_mm * kPointsPerMm,
                                               page.height_mm * kPointsPerMm));
      check(surface.get(), "cannot write '" + files[i] + "'");
      // Physical units in the file (width="210mm"), so that it prints at size.
      cairo_svg_surface_set_document_unit(surface.get(), CAIRO_SVG_UNIT_PT);
      {
        Context cr = mm_context(surface.get(), kPointsPerMm);
        draw_page(cr.get(), job, page, i, count);
        check(cr.get(), "cannot write '" + files[i] + "'");
      }
      cairo_surface_finish(surface.get());
      check(surface.get(), "cannot write '" + files[i] + "'");
    } else {
      const int w = page_pixels(page.width_mm, job.dpi), h = page_pixels(page.height_mm, job.dpi);
      if (static_cast<double>(w) * h > kMaxPngPixels)
        throw std::runtime_error(fmt::format(
            "a {} x {} mm page at {} dpi is {} x {} pixels, more than {:.0f} million: lower --dpi "
            "or write a PDF",
            format_number(page.width_mm, 1), format_number(page.height_mm, 1), job.dpi, w, h,
            kMaxPngPixels / 1e6));
      Surface surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h));
      check(surface.get(), "cannot allocate the image");
      {
        Context cr(cairo_create(surface.get()));
        // Scaled so that the page fills the whole pixels exactly.
        cairo_scale(cr.get(), w / page.width_mm, h / page.height_mm);
        draw_page(cr.get(), job, page, i, count);
        check(cr.get(), "cannot draw '" + files[i] + "'");
      }
      write_png(surface.get(), files[i], job.dpi);
    }
  }
  return files;
}

}  // namespace lidartag::draw
