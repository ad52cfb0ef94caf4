#include "lidartag/draw/tag_layout.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lidartag::draw {
namespace {

// Vertical space between a caption and the next row of a sheet, mm.
constexpr double kRowGapMm = 4.0;
// A fitted page is at least this wide so that the footer and a 100 mm scale bar fit.
constexpr double kFitMinWidthMm = 130.0;

Layout bare_layout(int count, double outer_mm) {
  Layout l;
  l.paper = "bare";
  l.per_page = 1;
  for (int i = 0; i < count; ++i) {
    PageLayout p;
    p.width_mm = p.height_mm = outer_mm;
    p.markers.push_back({i, 0, 0, outer_mm, outer_mm, 0, 0});
    l.pages.push_back(p);
  }
  return l;
}

// Rows and columns of a sheet on `area`; 0 when one marker does not fit.
void grid(const Area& area, double outer_mm, const SheetOptions& o, int& cols, int& rows) {
  cols = static_cast<int>(std::floor((area.width + o.gap_mm) / (outer_mm + o.gap_mm) + 1e-9));
  rows = static_cast<int>(
      std::floor((area.height + kRowGapMm) / (outer_mm + o.caption_mm + kRowGapMm) + 1e-9));
}

// Places markers first..first+n-1 as a centred block of at most `cols` columns.
void place_block(PageLayout& page, const Area& area, int first, int n, int cols, double outer_mm,
                 const SheetOptions& o) {
  const int used_cols = std::min(cols, n);
  const int used_rows = (n + used_cols - 1) / used_cols;
  const double block_w = used_cols * outer_mm + (used_cols - 1) * o.gap_mm;
  const double block_h = used_rows * (outer_mm + o.caption_mm) + (used_rows - 1) * kRowGapMm;
  const double x0 = area.x + (area.width - block_w) / 2;
  const double y0 = area.y + (area.height - block_h) / 2;
  for (int k = 0; k < n; ++k) {
    const int r = k / used_cols, c = k % used_cols;
    page.markers.push_back({first + k, 0, 0, outer_mm, outer_mm, x0 + c * (outer_mm + o.gap_mm),
                            y0 + r * (outer_mm + o.caption_mm + kRowGapMm)});
  }
}

Layout paper_layout(int count, double outer_mm, const SheetOptions& o, double w, double h,
                    const std::string& name) {
  Layout l;
  l.paper = name;
  const Area area = content_area(w, h, o);
  int cols = 0, rows = 0;
  grid(area, outer_mm, o, cols, rows);
  if (cols >= 1 && rows >= 1) {
    l.per_page = cols * rows;
    for (int first = 0; first < count; first += l.per_page) {
      PageLayout page;
      page.width_mm = w;
      page.height_mm = h;
      place_block(page, area, first, std::min(l.per_page, count - first), cols, outer_mm, o);
      l.pages.push_back(page);
    }
    return l;
  }
  // Tiles of equal size, each at most the printable area, at its top-left corner.
  l.tiled = true;
  l.tile_cols = static_cast<int>(std::ceil(outer_mm / area.width - 1e-9));
  l.tile_rows = static_cast<int>(std::ceil(outer_mm / area.height - 1e-9));
  for (int i = 0; i < count; ++i)
    for (int r = 0; r < l.tile_rows; ++r)
      for (int c = 0; c < l.tile_cols; ++c) {
        PageLayout page;
        page.width_mm = w;
        page.height_mm = h;
        page.tile_row = r;
        page.tile_col = c;
        page.tile_rows = l.tile_rows;
        page.tile_cols = l.tile_cols;
        // Tile edges from the marker's size, not accumulated, so that neighbours meet exactly.
        const double x0 = outer_mm * c / l.tile_cols, x1 = outer_mm * (c + 1) / l.tile_cols;
        const double y0 = outer_mm * r / l.tile_rows, y1 = outer_mm * (r + 1) / l.tile_rows;
        page.markers.push_back({i, x0, y0, x1, y1, area.x, area.y, true});
        l.pages.push_back(page);
      }
  return l;
}

}  // namespace

Area content_area(double w, double h, const SheetOptions& o) {
  return {o.margin_mm, o.margin_mm, w - 2 * o.margin_mm, h - 2 * o.margin_mm - o.footer_mm};
}

Layout layout_markers(int count, double outer_mm, const SheetOptions& o) {
  if (count < 1) throw std::invalid_argument("no marker to lay out");
  if (!(outer_mm > 0)) throw std::invalid_argument("the marker size must be positive");
  if (o.bare) return bare_layout(count, outer_mm);
  if (o.fit) {
    const int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count)) - 1e-9));
    const int rows = (count + cols - 1) / cols;
    const double w =
        std::max(kFitMinWidthMm, 2 * o.margin_mm + cols * outer_mm + (cols - 1) * o.gap_mm);
    const double h =
        2 * o.margin_mm + o.footer_mm + rows * (outer_mm + o.caption_mm) + (rows - 1) * kRowGapMm;
    Layout l;
    l.paper = "fit";
    l.per_page = count;
    PageLayout page;
    page.width_mm = w;
    page.height_mm = h;
    place_block(page, content_area(w, h, o), 0, count, cols, outer_mm, o);
    l.pages.push_back(page);
    return l;
  }
  const double short_side = std::min(o.paper.width_mm, o.paper.height_mm);
  const double long_side = std::max(o.paper.width_mm, o.paper.height_mm);
  const Area probe = content_area(short_side, long_side, o);
  if (probe.width < 10 || probe.height < 10)
    throw std::invalid_argument("the margins leave no room on " + o.paper.name + " paper");
  const Layout portrait =
      paper_layout(count, outer_mm, o, short_side, long_side, o.paper.name + " portrait");
  const Layout landscape =
      paper_layout(count, outer_mm, o, long_side, short_side, o.paper.name + " landscape");
  switch (o.orientation) {
    case Orientation::kPortrait:
      return portrait;
    case Orientation::kLandscape:
      return landscape;
    case Orientation::kAuto:
      break;
  }
  return landscape.pages.size() < portrait.pages.size() ? landscape : portrait;
}

}  // namespace lidartag::draw
