// `lidartag tag FAMILY --id LIST (--outer-size L | --black-size L | --size L --convention C)
// -o FILE`: draws markers of any family at their exact printed size as PDF, SVG or PNG: one tag,
// a sheet of several, or one tag tiled across pages when it is larger than the paper.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/commands.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/draw/marker_pages.hpp"
#include "lidartag/draw/tag_layout.hpp"
#include "lidartag/draw/units.hpp"
#include "lidartag/exit_codes.hpp"
#include "lidartag/version.hpp"

namespace lidartag::cli {
namespace {

struct TagArgs {
  std::string family;
  std::string ids = "0";
  std::string outer_size, black_size, size, convention;
  std::string out;
  std::string format;
  std::string page = "A4";
  std::string orientation = "auto";
  std::string margin = "10mm";
  bool margin_given = false;  // --margin on the command line (else the default may shrink)
  double dpi = 300;
  bool bare = false;
};

// "0", "3-7", "0,2,5-9", "all" -> ids, checked against the family's codes.
std::vector<int> parse_ids(const std::string& text, const tags::TagFamily& f) {
  const int n = f.ncodes();
  const auto range_error = [&](const std::string& what) {
    return UsageError(fmt::format("--id {}: {} ({} has ids 0-{})", text, what, f.name, n - 1));
  };
  std::vector<int> ids;
  if (text == "all") {
    for (int i = 0; i < n; ++i) ids.push_back(i);
    return ids;
  }
  size_t at = 0;
  while (at <= text.size()) {
    const size_t comma = std::min(text.find(',', at), text.size());
    const std::string item = text.substr(at, comma - at);
    const size_t dash = item.find('-', 1);
    auto number = [&](const std::string& s) {
      if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos)
        throw range_error("'" + item + "' is not an id or a range such as 3-7");
      return std::stoi(s);
    };
    const int first = number(item.substr(0, dash));
    const int last = dash == std::string::npos ? first : number(item.substr(dash + 1));
    if (last < first) throw range_error("'" + item + "' is an empty range");
    if (last >= n) throw range_error(fmt::format("id {} does not exist", last));
    for (int i = first; i <= last; ++i) ids.push_back(i);
    at = comma + 1;
  }
  return ids;
}

double length_option(const std::string& name, const std::string& text) {
  try {
    return draw::parse_length_mm(text);
  } catch (const std::invalid_argument& e) {
    throw UsageError(name + ": " + e.what());
  }
}

// The outer size (white ring included) from whichever convention the user named.
double outer_size_mm(const TagArgs& a, const tags::TagFamily& f) {
  const int given = !a.outer_size.empty() + !a.black_size.empty() + !a.size.empty();
  if (given == 0)
    throw UsageError(
        "give the marker's size and say which size it is: --outer-size (the full printed marker, "
        "white ring included: what lidartag detect --tag-size and lidartagd's tag_sizes_m take) "
        "or --black-size (the black square's edge: AprilTag 3's tag size), e.g. --outer-size "
        "1.2m");
  if (given > 1) throw UsageError("give only one of --outer-size, --black-size and --size");
  std::string convention = a.convention;
  std::string text = a.size;
  if (!a.outer_size.empty()) {
    convention = "outer";
    text = a.outer_size;
  } else if (!a.black_size.empty()) {
    convention = "black";
    text = a.black_size;
  } else if (convention.empty()) {
    throw UsageError(
        "--size " + a.size +
        ": say which size it is with --convention outer (the full printed marker, white ring "
        "included: lidartag's tag size) or --convention black (the black square's edge: "
        "AprilTag 3's tag size); they differ by " +
        fmt::format("{}/{}", f.total_width, f.width_at_border) + " for " + f.name);
  }
  const double mm = length_option(!a.outer_size.empty()   ? "--outer-size"
                                  : !a.black_size.empty() ? "--black-size"
                                                          : "--size",
                                  text);
  const double outer = convention == "black" ? mm * f.total_width / f.width_at_border : mm;
  if (outer < 5.0 || outer > 20000.0)
    throw UsageError(fmt::format(
        "a marker of {} outer is not printable (5 mm to 20 m); a number without a unit is metres: "
        "say 200mm for 200 millimetres",
        draw::format_mm(outer)));
  return outer;
}

int run_tag(const TagArgs& a) {
  const draw::FontCacheRelease release_fonts;  // after every surface below
  const tags::TagFamily family = tags::resolve_family(a.family);
  draw::MarkerJob job;
  job.family = &family;
  job.ids = parse_ids(a.ids, family);
  job.outer_mm = outer_size_mm(a, family);
  job.path = a.out;
  job.dpi = a.dpi;
  job.generator = std::string("lidartag ") + lidartag::kVersionString;
  if (!a.format.empty()) {
    draw::format_from_path("." + a.format, job.format);
  } else if (!draw::format_from_path(a.out, job.format)) {
    throw UsageError("-o " + a.out + ": name a .pdf, .svg or .png file, or give --format");
  }

  draw::SheetOptions& sheet = job.sheet;
  sheet.bare = a.bare;
  if (a.page == "fit" || a.page == "FIT") {
    sheet.fit = true;
  } else {
    try {
      sheet.paper = draw::parse_paper_size(a.page);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--page: ") + e.what());
    }
  }
  sheet.orientation = a.orientation == "portrait"    ? draw::Orientation::kPortrait
                      : a.orientation == "landscape" ? draw::Orientation::kLandscape
                                                     : draw::Orientation::kAuto;
  sheet.margin_mm = length_option("--margin", a.margin);
  draw::Layout layout;
  try {
    layout = draw::layout_markers(static_cast<int>(job.ids.size()), job.outer_mm, sheet);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  // A marker cut in two (or more) pages only for the default margin's sake: the largest margin
  // down to kMinMargin_mm that keeps each marker on one page is taken, and said; with --margin
  // given, the tiling stays and the margin that would avoid it is named.
  constexpr double kMinMargin_mm = 3.0;  // most printers print to 3-6 mm of the edge
  if (layout.tiled && !sheet.bare && !sheet.fit) {
    draw::SheetOptions smaller = sheet;
    std::optional<draw::Layout> whole;
    for (double m = sheet.margin_mm - 0.5; m >= kMinMargin_mm - 1e-9 && !whole; m -= 0.5) {
      smaller.margin_mm = m;
      try {
        draw::Layout l =
            draw::layout_markers(static_cast<int>(job.ids.size()), job.outer_mm, smaller);
        if (!l.tiled) whole = std::move(l);
      } catch (const std::invalid_argument&) {
      }
    }
    const size_t tiles = static_cast<size_t>(layout.tile_cols * layout.tile_rows);
    if (whole && !a.margin_given) {
      spdlog::warn(
          "a {} marker does not fit {} inside {} margins: printed with {} margins, one "
          "marker a page, instead of {} pages each (--margin {} keeps the margin and "
          "tiles)",
          draw::format_mm(job.outer_mm), layout.paper, draw::format_mm(sheet.margin_mm),
          draw::format_mm(smaller.margin_mm), tiles, a.margin);
      sheet.margin_mm = smaller.margin_mm;
      layout = std::move(*whole);
    } else if (whole) {
      spdlog::warn("each marker is tiled over {} pages; --margin {} fits one a page", tiles,
                   draw::format_mm(smaller.margin_mm));
    } else {
      spdlog::warn("each {} marker is tiled over {} pages of {} (cut along the marks)",
                   draw::format_mm(job.outer_mm), tiles, layout.paper);
    }
  }
  const auto files = draw::write_marker_pages(job, layout);

  // What was written and where every marker is, for cutting, assembling and checking.
  const double black = draw::black_size_mm(family, job.outer_mm);
  fmt::print(
      "{}: marker {} outer (white ring included; lidartag --tag-size {}) = {} black square "
      "(AprilTag 3 tag size), {} cells of {}\n",
      family.name, draw::format_mm(job.outer_mm), draw::format_m(job.outer_mm),
      draw::format_mm(black), family.total_width,
      draw::format_mm(job.outer_mm / family.total_width));
  const auto& first = layout.pages.front();
  fmt::print("{} page{} {} ({} x {} mm){}", layout.pages.size(),
             layout.pages.size() == 1 ? "" : "s", layout.paper,
             draw::format_number(first.width_mm, 2), draw::format_number(first.height_mm, 2),
             job.format == draw::OutputFormat::kPng ? fmt::format(" at {} dpi", job.dpi) : "");
  if (layout.tiled)
    fmt::print(
        ", each marker tiled {} x {} (columns x rows): cut along the marks and butt the "
        "tiles",
        layout.tile_cols, layout.tile_rows);
  fmt::print("\n");
  for (size_t i = 0; i < layout.pages.size(); ++i) {
    for (const auto& p : layout.pages[i].markers) {
      fmt::print("page {}: id {} marker {}-{} x {}-{} mm at {},{} mm", i + 1,
                 job.ids[static_cast<size_t>(p.index)], draw::format_number(p.x0, 3),
                 draw::format_number(p.x1, 3), draw::format_number(p.y0, 3),
                 draw::format_number(p.y1, 3), draw::format_number(p.page_x, 3),
                 draw::format_number(p.page_y, 3));
      if (p.tile)
        fmt::print(" (tile row {} column {})", layout.pages[i].tile_row + 1,
                   layout.pages[i].tile_col + 1);
      fmt::print("\n");
    }
  }
  for (const auto& f : files) fmt::print("wrote {}\n", f);
  return 0;
}

const Registrar kTag(
    "tag", "Draw tag markers at their exact printed size (PDF, SVG, PNG) to print them",
    [](CLI::App& app) -> RunFunction {
      auto a = std::make_shared<TagArgs>();
      std::string families;
      for (const auto& name : tags::builtin_family_names())
        families += (families.empty() ? "" : ", ") + name;
      app.add_option("family", a->family, "Tag family (" + families + ") or FILE.json[:NAME]")
          ->required()
          ->type_name("FAMILY");
      app.add_option("--id", a->ids, "Ids to draw: 3, 0-9, 0,4,7-9 or all; one marker each")
          ->type_name("IDS")
          ->capture_default_str();
      auto* outer =
          app.add_option("--outer-size", a->outer_size,
                         "Size of the full printed marker, white ring included (lidartag's "
                         "convention: what "
                         "detect --tag-size takes), e.g. 1.2m, 200mm, 8in; metres without a unit")
              ->type_name("LENGTH");
      auto* black =
          app.add_option("--black-size", a->black_size,
                         "Size of the black square's edge (AprilTag 3's tag size convention)")
              ->type_name("LENGTH");
      auto* size = app.add_option("--size", a->size, "Marker size in the --convention named")
                       ->type_name("LENGTH");
      app.add_option("--convention", a->convention,
                     "What --size measures: outer (white ring included) or black (the black "
                     "square)")
          ->check(CLI::IsMember({"outer", "black"}))
          ->needs(size);
      outer->excludes(black)->excludes(size);
      black->excludes(size);
      app.add_option("-o,--out", a->out,
                     "Output file: .pdf (all pages in one), .svg or .png "
                     "(one file per page: NAME-01.svg, ...)")
          ->required();
      app.add_option("--format", a->format, "Output format when the file name does not say")
          ->check(CLI::IsMember({"pdf", "svg", "png"}));
      std::string papers;
      for (const auto& p : draw::named_paper_sizes()) papers += p.name + ",";
      app.add_option("--page", a->page,
                     "Paper: a named size, WxH in mm (600x900) or inches (24x36in), or fit (the "
                     "page is the content)")
          ->type_name("{" + papers + "fit}|WxH")
          ->capture_default_str();
      app.add_option("--orientation", a->orientation,
                     "Paper orientation; auto takes whichever needs fewer pages")
          ->check(CLI::IsMember({"auto", "portrait", "landscape"}))
          ->capture_default_str();
      auto* margin = app.add_option("--margin", a->margin,
                                    "Unprinted border on every side (not given: shrunk to as "
                                    "little as 3 mm when that keeps a marker on one page)")
                         ->type_name("LENGTH")
                         ->capture_default_str();
      app.add_option("--dpi", a->dpi, "PNG resolution, dots per inch")
          ->check(CLI::Range(10.0, 2400.0))
          ->capture_default_str();
      app.add_flag("--bare", a->bare,
                   "Only the marker: the page is the marker (white ring included), one per page, "
                   "no caption, footer or marks");
      return [a, margin] {
        a->margin_given = margin->count() > 0;
        return run_tag(*a);
      };
    });

}  // namespace
}  // namespace lidartag::cli
