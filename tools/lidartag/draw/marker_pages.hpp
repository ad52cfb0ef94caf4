// Draws tag markers at their exact printed size on the pages of a Layout and writes them as PDF
// (one file, a page per page), SVG or PNG (one file per page).
#pragma once

#include <string>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "lidartag/draw/cairo_util.hpp"
#include "lidartag/draw/tag_layout.hpp"

namespace lidartag::draw {

struct MarkerJob {
  const tags::TagFamily* family = nullptr;
  std::vector<int> ids;  // codes of `family`, one marker each
  double outer_mm = 0;   // the full marker, white ring included
  SheetOptions sheet;
  OutputFormat format = OutputFormat::kPdf;
  std::string path;       // the output file (numbered per page for SVG and PNG)
  double dpi = 300;       // PNG only
  std::string generator;  // printed in the footer and the PDF's metadata, e.g. "lidartag 0.1.0"
};

// The black square's edge (AprilTag 3's tag size) of a marker of `outer_mm`.
double black_size_mm(const tags::TagFamily& family, double outer_mm);

// The file names of a job with `pages` pages: the path itself for a PDF or a single page, else
// "stem-01.ext", "stem-02.ext", ...
std::vector<std::string> page_files(const MarkerJob& job, size_t pages);

// Draws every page of `layout` and writes the files; returns their names. Throws
// std::runtime_error when a file cannot be written or an image would be too large.
std::vector<std::string> write_marker_pages(const MarkerJob& job, const Layout& layout);

// Image size of a page at `dpi`, pixels (rounded to the nearest pixel).
int page_pixels(double mm, double dpi);

// Largest PNG page drawn, pixels (about 1 GB of memory).
inline constexpr double kMaxPngPixels = 250e6;

}  // namespace lidartag::draw
