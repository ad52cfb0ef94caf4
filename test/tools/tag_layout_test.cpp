// The geometry of `lidartag tag`: lengths and paper sizes as typed, sheets that keep markers,
// captions and marks off the margins and footer, tiles that cover a large marker exactly once.
#include "lidartag/draw/tag_layout.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

#include "lidartag/draw/units.hpp"

namespace lidartag::draw {
namespace {

TEST(Units, LengthsInEveryUnitAndMetresWithout) {
  EXPECT_DOUBLE_EQ(parse_length_mm("1.2m"), 1200.0);
  EXPECT_DOUBLE_EQ(parse_length_mm("1.2"), 1200.0);
  EXPECT_DOUBLE_EQ(parse_length_mm("120cm"), 1200.0);
  EXPECT_DOUBLE_EQ(parse_length_mm(" 200 mm "), 200.0);
  EXPECT_DOUBLE_EQ(parse_length_mm("8in"), 203.2);
  EXPECT_DOUBLE_EQ(parse_length_mm("8\""), 203.2);
  EXPECT_DOUBLE_EQ(parse_length_mm("0.5M"), 500.0);
  for (const char* bad : {"", "m", "-1m", "0", "1.2 furlongs", "1e999", "nan", "inf", "1.2.3m"})
    EXPECT_THROW(parse_length_mm(bad), std::invalid_argument) << bad;
}

TEST(Units, PaperSizesByNameAndCustom) {
  EXPECT_DOUBLE_EQ(parse_paper_size("a4").width_mm, 210.0);
  EXPECT_DOUBLE_EQ(parse_paper_size("A0").height_mm, 1189.0);
  EXPECT_DOUBLE_EQ(parse_paper_size("letter").width_mm, 215.9);
  EXPECT_DOUBLE_EQ(parse_paper_size("Tabloid").height_mm, 431.8);
  const PaperSize roll = parse_paper_size("914x1500");
  EXPECT_DOUBLE_EQ(roll.width_mm, 914.0);
  EXPECT_DOUBLE_EQ(roll.height_mm, 1500.0);
  EXPECT_EQ(roll.name, "914x1500 mm");
  const PaperSize poster = parse_paper_size("24x36in");
  EXPECT_DOUBLE_EQ(poster.width_mm, 609.6);
  EXPECT_DOUBLE_EQ(poster.height_mm, 914.4);
  for (const char* bad : {"B5", "x", "100x", "0x100", "100x100furlongs", ""})
    EXPECT_THROW(parse_paper_size(bad), std::invalid_argument) << bad;
}

TEST(Units, Formatting) {
  EXPECT_EQ(format_mm(1200), "1200 mm");
  EXPECT_EQ(format_mm(213.3333), "213.33 mm");
  EXPECT_EQ(format_mm(37.5), "37.5 mm");
  EXPECT_EQ(format_m(1200), "1.2");
  EXPECT_EQ(format_m(162.5), "0.1625");
  EXPECT_EQ(format_number(-0.0001, 2), "0");
}

// Every marker, its caption and its cut marks (1-5 mm outside) inside the page's printable area.
void expect_inside(const Layout& l, double outer, const SheetOptions& o) {
  for (const auto& page : l.pages) {
    const Area a = content_area(page.width_mm, page.height_mm, o);
    for (const auto& p : page.markers) {
      EXPECT_GE(p.page_x, a.x - 1e-9);
      EXPECT_GE(p.page_y, a.y - 1e-9);
      EXPECT_LE(p.page_x + (p.x1 - p.x0), a.x + a.width + 1e-9);
      const double below = p.tile ? 0 : o.caption_mm;
      EXPECT_LE(p.page_y + (p.y1 - p.y0) + below, a.y + a.height + 1e-9);
      if (!p.tile) {
        EXPECT_DOUBLE_EQ(p.x1 - p.x0, outer);
        EXPECT_DOUBLE_EQ(p.y1 - p.y0, outer);
      }
    }
    // Neighbours on a sheet: at least the gap apart (room for both cut marks).
    for (size_t i = 0; i < page.markers.size(); ++i)
      for (size_t j = i + 1; j < page.markers.size(); ++j) {
        const auto &a1 = page.markers[i], &a2 = page.markers[j];
        const double dx = std::abs(a1.page_x - a2.page_x), dy = std::abs(a1.page_y - a2.page_y);
        EXPECT_TRUE(dx >= outer + o.gap_mm - 1e-9 || dy >= outer + o.caption_mm - 1e-9);
      }
  }
}

TEST(TagLayout, SheetsOfSmallMarkers) {
  SheetOptions o;  // A4, 10 mm margins, 20 mm footer: 190 x 257 mm printable
  Layout l = layout_markers(6, 60, o);
  EXPECT_FALSE(l.tiled);
  EXPECT_EQ(l.per_page, 6);  // 2 columns (2 x 60 + 8 <= 190) x 3 rows (3 x 69 + 2 x 4 <= 257)
  ASSERT_EQ(l.pages.size(), 1u);
  EXPECT_EQ(l.pages[0].markers.size(), 6u);
  expect_inside(l, 60, o);

  // 30 of them: 8 per page in landscape (4 x 2), 6 in portrait.
  l = layout_markers(30, 60, o);
  EXPECT_EQ(l.paper, "A4 landscape");
  EXPECT_EQ(l.pages.size(), 4u);
  o.orientation = Orientation::kPortrait;
  l = layout_markers(30, 60, o);
  EXPECT_EQ(l.pages.size(), 5u);
  for (size_t i = 0; i < l.pages.size(); ++i)
    for (size_t k = 0; k < l.pages[i].markers.size(); ++k)
      EXPECT_EQ(l.pages[i].markers[k].index, static_cast<int>(i * 6 + k));
  expect_inside(l, 60, o);

  // One marker: centred on the page.
  o.orientation = Orientation::kAuto;
  l = layout_markers(1, 100, o);
  const auto& p = l.pages[0].markers[0];
  EXPECT_NEAR(p.page_x + 50, 105, 1e-9);
  EXPECT_EQ(l.paper, "A4 portrait");
}

TEST(TagLayout, AutoOrientationTakesFewerPages) {
  SheetOptions o;
  // A4 printable: 190 x 257 mm portrait, 277 x 170 mm landscape. 230 mm: 2 x 1 tiles portrait,
  // 1 x 2 landscape: a tie, portrait.
  Layout l = layout_markers(1, 230, o);
  EXPECT_TRUE(l.tiled);
  EXPECT_EQ(l.pages.size(), 2u);
  EXPECT_EQ(l.paper, "A4 portrait");
  // 130 mm: one per page portrait, two side by side landscape.
  l = layout_markers(4, 130, o);
  EXPECT_EQ(l.paper, "A4 landscape");
  EXPECT_EQ(l.pages.size(), 2u);
  o.orientation = Orientation::kPortrait;
  l = layout_markers(4, 130, o);
  EXPECT_EQ(l.paper, "A4 portrait");
  EXPECT_EQ(l.pages.size(), 4u);
  expect_inside(l, 130, o);
}

TEST(TagLayout, TilesCoverALargeMarkerExactlyOnce) {
  SheetOptions o;
  for (const double outer : {200.0, 1200.0, 2000.0}) {
    SCOPED_TRACE(outer);
    const Layout l = layout_markers(2, outer, o);
    ASSERT_TRUE(l.tiled);
    ASSERT_EQ(l.pages.size(), static_cast<size_t>(2 * l.tile_rows * l.tile_cols));
    expect_inside(l, outer, o);
    for (int m = 0; m < 2; ++m) {
      double area = 0;
      for (const auto& page : l.pages) {
        ASSERT_EQ(page.markers.size(), 1u);
        const auto& p = page.markers[0];
        if (p.index != m) continue;
        EXPECT_TRUE(p.tile);
        area += (p.x1 - p.x0) * (p.y1 - p.y0);
        // Edges shared with the neighbours: the next column starts where this one ends.
        EXPECT_DOUBLE_EQ(p.x0, outer * page.tile_col / page.tile_cols);
        EXPECT_DOUBLE_EQ(p.x1, outer * (page.tile_col + 1) / page.tile_cols);
        EXPECT_DOUBLE_EQ(p.y0, outer * page.tile_row / page.tile_rows);
        EXPECT_DOUBLE_EQ(p.y1, outer * (page.tile_row + 1) / page.tile_rows);
      }
      EXPECT_NEAR(area, outer * outer, 1e-6 * outer * outer);
    }
  }
  // Large-format paper: a 1.2 m marker on A0 (821 x 1149 mm printable) needs 2 x 2 tiles, on a
  // 1300 mm wide sheet one page.
  o.paper = parse_paper_size("A0");
  EXPECT_EQ(layout_markers(1, 1200, o).pages.size(), 4u);
  o.paper = parse_paper_size("1300x1400");
  EXPECT_EQ(layout_markers(1, 1200, o).pages.size(), 1u);
}

TEST(TagLayout, FitAndBarePages) {
  SheetOptions o;
  o.fit = true;
  Layout l = layout_markers(5, 50, o);  // 3 columns, 2 rows
  ASSERT_EQ(l.pages.size(), 1u);
  EXPECT_DOUBLE_EQ(l.pages[0].width_mm, 2 * 10 + 3 * 50 + 2 * 8);
  EXPECT_DOUBLE_EQ(l.pages[0].height_mm, 2 * 10 + 20 + 2 * (50 + 9) + 4);
  expect_inside(l, 50, o);
  // A small marker: the page is wide enough for the footer.
  EXPECT_DOUBLE_EQ(layout_markers(1, 20, o).pages[0].width_mm, 130);

  o.fit = false;
  o.bare = true;
  l = layout_markers(3, 75, o);
  ASSERT_EQ(l.pages.size(), 3u);
  for (const auto& page : l.pages) {
    EXPECT_DOUBLE_EQ(page.width_mm, 75);
    EXPECT_DOUBLE_EQ(page.height_mm, 75);
    EXPECT_DOUBLE_EQ(page.markers[0].page_x, 0);
  }
}

TEST(TagLayout, MarginsThatLeaveNoRoomAreRefused) {
  SheetOptions o;
  o.margin_mm = 120;
  EXPECT_THROW(layout_markers(1, 50, o), std::invalid_argument);
  EXPECT_THROW(layout_markers(0, 50, SheetOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace lidartag::draw
