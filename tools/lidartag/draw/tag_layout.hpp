// Where markers go on paper: a sheet of several per page, or one marker larger than the page
// tiled across several pages. Pure geometry in millimetres, page origin at the top-left corner,
// y down (as Cairo and every page description language draw).
#pragma once

#include <string>
#include <vector>

#include "lidartag/draw/units.hpp"

namespace lidartag::draw {

enum class Orientation { kAuto, kPortrait, kLandscape };

struct SheetOptions {
  PaperSize paper = {"A4", 210, 297};
  // The page is sized to the content (a near-square grid of all markers) instead of `paper`.
  bool fit = false;
  // Auto: whichever of portrait and landscape needs fewer pages (portrait on a tie).
  Orientation orientation = Orientation::kAuto;
  // Unprinted border on every side (most printers cannot print the last 3-6 mm), mm.
  double margin_mm = 10.0;
  // Only the marker: the page is exactly the marker (white ring included), one per page, no
  // caption, footer or marks. For textures and for pasting into other documents.
  bool bare = false;
  // Band above the bottom margin for the footer (family, sizes, scale bar), mm.
  double footer_mm = 20.0;
  // Below each marker of a sheet: its family and id, mm.
  double caption_mm = 9.0;
  // Between markers of a sheet, mm; leaves room for the cut marks of both neighbours.
  double gap_mm = 8.0;
};

// One marker, or the part of it that a tile shows, on a page.
struct Placement {
  int index = 0;  // into the list of markers
  // The visible part in marker coordinates (mm from the marker's top-left outer corner).
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  // Where the visible part's top-left corner is on the page, mm.
  double page_x = 0, page_y = 0;
  bool tile = false;  // a part of a marker larger than the page
};

struct PageLayout {
  double width_mm = 0, height_mm = 0;
  std::vector<Placement> markers;
  // Tiled pages: this tile's row and column (0-based) in a grid of tile_rows x tile_cols.
  int tile_row = -1, tile_col = -1, tile_rows = 0, tile_cols = 0;
  bool tiled() const { return tile_rows > 0; }
};

struct Layout {
  std::vector<PageLayout> pages;
  std::string paper;   // "A4 portrait", "fit", "bare"
  bool tiled = false;  // the marker is larger than the printable area
  int per_page = 0;    // markers per page of a sheet
  int tile_rows = 0, tile_cols = 0;
};

// Lays out `count` markers of `outer_mm` (white ring included). Throws std::invalid_argument when
// the margins leave no room on the paper.
Layout layout_markers(int count, double outer_mm, const SheetOptions& options);

// The printable area of a page (inside the margins, above the footer).
struct Area {
  double x = 0, y = 0, width = 0, height = 0;
};
Area content_area(double page_width_mm, double page_height_mm, const SheetOptions& options);

}  // namespace lidartag::draw
