// `lidartag tag`: the printed markers are rasterised as a printer would (poppler's pdftoppm for
// PDF, librsvg's rsvg-convert for SVG, the PNG as written) and read back cell by cell: every
// family, several ids, the physical size from the page size and resolution, a 1.2 m marker tiled
// on A4 pages and reassembled, a family from a JSON file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "png_image.hpp"
#include "run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using lidartag::tags::TagFamily;
using lidartag::testing::Image;
using lidartag::testing::read_png;
using lidartag::testing::run_command;
using lidartag::testing::run_split;
using Result = lidartag::testing::ToolResult;

const std::string kCli = LIDARTAG_CLI;

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("lidartag_tag_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

bool have(const char* program) {
  return run_command(std::string("command -v ") + program + " >/dev/null 2>&1").exit_code == 0;
}

#define REQUIRE_PROGRAM(p) \
  if (!have(p)) GTEST_SKIP() << p << " not installed (scripts/install-deps.sh installs it)"

// One "page P: id I marker X0-X1 x Y0-Y1 mm at X,Y mm" line of the tool's output.
struct Placed {
  int page = 0, id = 0;
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0, page_x = 0, page_y = 0;
};

std::vector<Placed> placements(const std::string& out) {
  static const std::regex line(
      R"(page (\d+): id (\d+) marker ([\d.]+)-([\d.]+) x ([\d.]+)-([\d.]+) mm at ([\d.]+),([\d.]+) mm)");
  std::vector<Placed> v;
  for (std::sregex_iterator it(out.begin(), out.end(), line), end; it != end; ++it) {
    const auto& m = *it;
    v.push_back({std::stoi(m[1]), std::stoi(m[2]), std::stod(m[3]), std::stod(m[4]),
                 std::stod(m[5]), std::stod(m[6]), std::stod(m[7]), std::stod(m[8])});
  }
  return v;
}

// pdftoppm's name for page p of a document of 10-99 pages.
std::string fmt_page(int p) {
  return (p < 10 ? "0" : "") + std::to_string(p) + ".png";
}

// The cells of a marker whose top-left outer corner is at (x, y) pixels, `size` pixels across:
// the mean grey of each cell's central half, 1 = white.
std::vector<uint8_t> read_cells(const Image& img, double x, double y, double size, int n) {
  std::vector<uint8_t> cells;
  const double cell = size / n;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      long sum = 0, count = 0;
      for (int py = static_cast<int>(y + (r + 0.25) * cell); py < y + (r + 0.75) * cell; ++py)
        for (int px = static_cast<int>(x + (c + 0.25) * cell); px < x + (c + 0.75) * cell; ++px) {
          sum += img.grey(px, py);
          ++count;
        }
      cells.push_back(count > 0 && sum / count > 128 ? 1 : 0);
    }
  return cells;
}

// Width in pixels of the black square along the row through the marker's centre: from the first
// to the last dark pixel (the border's cells are black at both ends of every row).
double black_width_px(const Image& img, double x, double y, double size) {
  const int row = static_cast<int>(y + size / 2);
  int first = -1, last = -1;
  for (int px = std::max(0, static_cast<int>(x)); px < std::min(img.width, int(x + size)); ++px)
    if (img.grey(px, row) < 128) {
      if (first < 0) first = px;
      last = px;
    }
  return first < 0 ? 0 : last - first + 1;
}

std::string cells_text(const std::vector<uint8_t>& cells, int n) {
  std::string s;
  for (size_t i = 0; i < cells.size(); ++i) {
    if (i % size_t(n) == 0) s += '\n';  // appended piecewise: GCC 12's -Wrestrict at -O3
    s += std::to_string(cells[i]);
  }
  return s;
}

// Reads back every placed marker of a page image at `px_per_mm` and checks code and size.
void expect_markers(const Image& img, const std::vector<Placed>& placed, int page,
                    const TagFamily& f, double outer_mm, double px_per_mm) {
  size_t checked = 0;
  for (const Placed& p : placed) {
    if (p.page != page) continue;
    SCOPED_TRACE(f.name + " id " + std::to_string(p.id));
    ASSERT_DOUBLE_EQ(p.x1 - p.x0, outer_mm);
    const double x = p.page_x * px_per_mm, y = p.page_y * px_per_mm, s = outer_mm * px_per_mm;
    const auto cells = read_cells(img, x, y, s, f.total_width);
    const auto expected = f.render(f.codes[static_cast<size_t>(p.id)]);
    EXPECT_EQ(cells, expected) << "read" << cells_text(cells, f.total_width) << "\nexpected"
                               << cells_text(expected, f.total_width);
    const double black_mm = outer_mm * f.width_at_border / f.total_width;
    EXPECT_NEAR(black_width_px(img, x, y, s), black_mm * px_per_mm, 1.5);
    ++checked;
  }
  EXPECT_GT(checked, 0u) << "page " << page;
}

TEST(CliTag, EveryFamilyReadsBackFromThePdfAtItsSize) {
  REQUIRE_PROGRAM("pdftoppm");
  TempDir dir;
  for (const std::string& name : lidartag::tags::builtin_family_names()) {
    SCOPED_TRACE(name);
    const TagFamily& f = lidartag::tags::builtin_family(name);
    const int last = f.ncodes() - 1;
    const std::string ids = "0,1," + std::to_string(last / 2) + "," + std::to_string(last);
    const std::string pdf = dir / (name + ".pdf");
    const Result r = run_split(kCli + " tag " + name + " --id " + ids +
                               " --outer-size 50mm --page A4 -o " + pdf);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto placed = placements(r.out);
    ASSERT_EQ(placed.size(), 4u) << r.out;
    // 254 dpi: 10 pixels per millimetre; A4 is 2100 x 2970 pixels.
    ASSERT_EQ(run_command("pdftoppm -r 254 -png -singlefile " + pdf + " " + (dir / name)).exit_code,
              0);
    const Image img = read_png(dir / (name + ".png"));
    ASSERT_FALSE(img.empty());
    EXPECT_NEAR(img.width, 2100, 1);
    EXPECT_NEAR(img.height, 2970, 1);
    expect_markers(img, placed, 1, f, 50.0, 10.0);
  }
}

TEST(CliTag, TheMarginStatesBothSizeConventions) {
  REQUIRE_PROGRAM("pdftotext");
  TempDir dir;
  const std::string pdf = dir / "t.pdf";
  const Result r =
      run_split(kCli + " tag tag36h11 --id 2-4 --black-size 120mm --page Letter -o " + pdf);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // tag36h11: 10 cells across, the black square 8 of them.
  EXPECT_NE(r.out.find("marker 150 mm outer (white ring included; lidartag --tag-size 0.15) = "
                       "120 mm black square"),
            std::string::npos)
      << r.out;
  const Result text = run_command("pdftotext -layout " + pdf + " -");
  ASSERT_EQ(text.exit_code, 0);
  for (const char* words :
       {"tag36h11 id 2", "tag36h11 id 3", "tag36h11 id 4", "marker 150 mm outer",
        "120 mm black square (AprilTag 3 tag size)", "--tag-size 0.15", "must measure 100 mm",
        "outer 150 mm, black 120 mm", "page 3 of 3"}) {
    EXPECT_NE(text.out.find(words), std::string::npos) << words << "\n" << text.out;
  }
  // Letter is 215.9 x 279.4 mm: 612 x 792 points.
  const Result info = run_command("pdfinfo " + pdf);
  EXPECT_NE(info.out.find("612 x 792 pts"), std::string::npos) << info.out;
}

TEST(CliTag, SvgAndPngShowTheSameMarkersAtTheirSize) {
  REQUIRE_PROGRAM("rsvg-convert");
  TempDir dir;
  const TagFamily& f = lidartag::tags::builtin_family("tag25h9");
  Result r = run_split(kCli + " tag tag25h9 --id 3,7,34 --outer-size 45mm -o " + (dir / "t.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto placed = placements(r.out);
  ASSERT_EQ(placed.size(), 3u);
  ASSERT_EQ(run_command("rsvg-convert --dpi-x 254 --dpi-y 254 -o " + (dir / "svg.png") + " " +
                        (dir / "t.svg"))
                .exit_code,
            0);
  const Image svg = read_png(dir / "svg.png");
  EXPECT_NEAR(svg.width, 2100, 1);
  EXPECT_NEAR(svg.height, 2970, 1);
  expect_markers(svg, placed, 1, f, 45.0, 10.0);

  r = run_split(kCli + " tag tag25h9 --id 3,7,34 --outer-size 45mm --dpi 254 -o " +
                (dir / "t.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Image png = read_png(dir / "t.png");
  EXPECT_EQ(png.width, 2100);
  EXPECT_EQ(png.height, 2970);
  expect_markers(png, placements(r.out), 1, f, 45.0, 10.0);
  // The resolution is in the file (pHYs: 10000 pixels per metre), so that it prints at size.
  std::ifstream in(dir / "t.png", std::ios::binary);
  std::string head(64, '\0');
  in.read(head.data(), 64);
  const size_t phys = head.find("pHYs");
  ASSERT_NE(phys, std::string::npos);
  const auto* b = reinterpret_cast<const unsigned char*>(head.data() + phys + 4);
  EXPECT_EQ((b[0] << 24) | (b[1] << 16) | (b[2] << 8) | b[3], 10000);
  EXPECT_EQ(b[8], 1);  // metres
}

TEST(CliTag, AMarkerThatFitsWithASmallerMarginIsNotCutInTwo) {
  // Issue 36: four 200 mm markers on A4 were tiled over 2 pages each (8 pages), silently; a 4 mm
  // margin fits one a page. Without --margin the margin shrinks (said on standard error); with
  // it the tiling stays and the margin that fits is named.
  TempDir dir;
  const std::string pdf = dir / "a4.pdf";
  const Result shrunk =
      run_split(kCli + " tag tag16h5 --id 0-3 --outer-size 200mm --page A4 -o " + pdf);
  ASSERT_EQ(shrunk.exit_code, 0) << shrunk.err;
  EXPECT_EQ(placements(shrunk.out).size(), 4u) << shrunk.out;
  EXPECT_NE(shrunk.out.find("4 pages A4"), std::string::npos) << shrunk.out;
  EXPECT_EQ(shrunk.out.find("tiled"), std::string::npos) << shrunk.out;
  EXPECT_NE(shrunk.err.find("does not fit A4 portrait inside 10 mm margins: printed with"),
            std::string::npos)
      << shrunk.err;
  const Result kept = run_split(kCli + " tag tag16h5 --id 0-3 --outer-size 200mm --page A4 " +
                                "--margin 10mm -o " + pdf);
  ASSERT_EQ(kept.exit_code, 0) << kept.err;
  EXPECT_NE(kept.out.find("tiled"), std::string::npos) << kept.out;
  EXPECT_NE(kept.err.find("each marker is tiled over 2 pages; --margin "), std::string::npos)
      << kept.err;
}

TEST(CliTag, AMarkerLargerThanThePageIsTiledAndReassembles) {
  REQUIRE_PROGRAM("pdftoppm");
  TempDir dir;
  const TagFamily& f = lidartag::tags::builtin_family("tag16h5");
  const std::string pdf = dir / "big.pdf";
  const Result r = run_split(kCli + " tag tag16h5 --id 7 --outer-size 1.2m --page A4 -o " + pdf);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto placed = placements(r.out);
  // A4 holds 190 x 257 mm inside its margins and footer: 7 columns x 5 rows, portrait.
  ASSERT_EQ(placed.size(), 35u) << r.out;
  EXPECT_NE(r.out.find("35 pages A4 portrait (210 x 297 mm), each marker tiled 7 x 5"),
            std::string::npos)
      << r.out;
  // 50.8 dpi: 2 pixels per millimetre.
  constexpr double k = 2.0;
  ASSERT_EQ(run_command("pdftoppm -r 50.8 -png " + pdf + " " + (dir / "tile")).exit_code, 0);
  const int side = static_cast<int>(1200 * k);
  Image whole;
  whole.width = whole.height = side;
  whole.pixels.assign(static_cast<size_t>(side * side), {-1, -1, -1});
  double covered = 0;
  for (const Placed& p : placed) {
    const Image page = read_png(dir / ("tile-" + fmt_page(p.page)));
    ASSERT_FALSE(page.empty()) << p.page;
    EXPECT_NEAR(page.width, 420, 1);
    EXPECT_NEAR(page.height, 594, 1);
    EXPECT_EQ(p.id, 7);
    const int X0 = int(std::lround(p.x0 * k)), X1 = int(std::lround(p.x1 * k));
    const int Y0 = int(std::lround(p.y0 * k)), Y1 = int(std::lround(p.y1 * k));
    const int px = int(std::lround(p.page_x * k)), py = int(std::lround(p.page_y * k));
    for (int Y = Y0; Y < Y1; ++Y)
      for (int X = X0; X < X1; ++X)
        whole.pixels[static_cast<size_t>(Y * side + X)] = page.at(px + X - X0, py + Y - Y0);
    covered += (p.x1 - p.x0) * (p.y1 - p.y0);
  }
  EXPECT_NEAR(covered, 1200.0 * 1200.0, 1e-6);  // the tiles cover the marker once
  for (const auto& px : whole.pixels) ASSERT_GE(px.r, 0) << "a pixel no tile covers";
  const auto cells = read_cells(whole, 0, 0, side, f.total_width);
  EXPECT_EQ(cells, f.render(f.codes[7])) << cells_text(cells, f.total_width);
  // The black square: 900 mm = 1800 pixels; the white ring 150 mm on each side.
  EXPECT_NEAR(black_width_px(whole, 0, 0, side), 900 * k, 2);
}

TEST(CliTag, FamiliesFromJsonFiles) {
  REQUIRE_PROGRAM("pdftoppm");
  TempDir dir;
  // Two families in one file: FILE.json:NAME picks one. Layout of tag16h5, codes of our own.
  const TagFamily& base = lidartag::tags::builtin_family("tag16h5");
  auto list = [](const std::vector<int>& v) {
    std::string s;
    for (int x : v) {
      if (!s.empty()) s += ',';
      s += std::to_string(x);
    }
    return "[" + s + "]";
  };
  const std::string layout =
      "\"nbits\": 16, \"total_width\": 8, \"width_at_border\": 6, "
      "\"bit_x\": " +
      list(base.bit_x) + ", \"bit_y\": " + list(base.bit_y);
  {
    std::ofstream json(dir / "mine.json");
    json << "{\"first\": {" << layout << ", \"codes\": [\"0x1234\"]},\n \"second\": {" << layout
         << ", \"codes\": [\"0x0f0f\", \"0xbeef\"]}}\n";
  }
  const Result r = run_split(kCli + " tag " + (dir / "mine.json") + ":second --id 1 " +
                             "--outer-size 80mm --page fit -o " + (dir / "mine.pdf"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(
      run_command("pdftoppm -r 254 -png -singlefile " + (dir / "mine.pdf") + " " + (dir / "mine"))
          .exit_code,
      0);
  TagFamily mine = base;
  mine.name = "second";
  mine.codes = {0x0f0f, 0xbeef};
  expect_markers(read_png(dir / "mine.png"), placements(r.out), 1, mine, 80.0, 10.0);

  // Without :NAME a file of two families is refused, as by detect.
  const Result ambiguous =
      run_split(kCli + " tag " + (dir / "mine.json") + " --outer-size 80mm -o " + (dir / "x.pdf"));
  EXPECT_EQ(ambiguous.exit_code, 2);
  EXPECT_NE(ambiguous.err.find("holds several families"), std::string::npos) << ambiguous.err;

  // The shared reference file, when present: the paper's own markers.
  const std::string reference = LIDARTAG_SHARED_DIR "/reference/apriltag_families.json";
  if (!fs::exists(reference)) return;
  const Result paper = run_split(kCli + " tag " + reference + ":tag16h6_lidartag_paper --id 8 " +
                                 "--outer-size 80mm --page fit -o " + (dir / "paper.pdf"));
  ASSERT_EQ(paper.exit_code, 0) << paper.err;
  ASSERT_EQ(
      run_command("pdftoppm -r 254 -png -singlefile " + (dir / "paper.pdf") + " " + (dir / "paper"))
          .exit_code,
      0);
  expect_markers(read_png(dir / "paper.png"), placements(paper.out), 1,
                 lidartag::tags::builtin_family("tag16h6"), 80.0, 10.0);
}

TEST(CliTag, BarePngIsExactlyTheMarker) {
  TempDir dir;
  const TagFamily& f = lidartag::tags::builtin_family("tag36h10");
  const Result r = run_split(kCli + " tag tag36h10 --id 2319 --outer-size 100mm --bare --dpi 254 " +
                             "-o " + (dir / "bare.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Image img = read_png(dir / "bare.png");
  ASSERT_EQ(img.width, 1000);
  ASSERT_EQ(img.height, 1000);
  EXPECT_EQ(read_cells(img, 0, 0, 1000, f.total_width), f.render(f.codes[2319]));
  // The white ring is the outermost cell: 10 mm of white on every side.
  for (int i = 0; i < 1000; i += 7) {
    EXPECT_GT(img.grey(i, 50), 200);
    EXPECT_GT(img.grey(50, i), 200);
  }
}

TEST(CliTag, TheSizeConventionMustBeNamed) {
  TempDir dir;
  const std::string out = " -o " + (dir / "t.pdf");
  Result r = run_split(kCli + " tag tag16h5 --size 1.2m" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--convention outer"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--convention black"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("8/6"), std::string::npos) << r.err;
  r = run_split(kCli + " tag tag16h5" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--outer-size"), std::string::npos) << r.err;
  // The same marker named both ways.
  for (const char* size :
       {"--size 160mm --convention black", "--black-size 16cm", "--outer-size 213.3333333mm",
        "--size 0.2133333333 --convention outer"}) {
    r = run_split(kCli + " tag tag16h5 " + size + out);
    EXPECT_EQ(r.exit_code, 0) << size << r.err;
    EXPECT_NE(r.out.find("marker 213.33 mm outer"), std::string::npos) << size << r.out;
    EXPECT_NE(r.out.find("160 mm black square"), std::string::npos) << size << r.out;
  }
  EXPECT_EQ(run_split(kCli + " tag tag16h5 --outer-size 1m --black-size 1m" + out).exit_code, 2);
  EXPECT_EQ(run_split(kCli + " tag tag16h5 --outer-size 1m --convention black" + out).exit_code, 2);
}

TEST(CliTag, BadValuesAreUsageErrors) {
  TempDir dir;
  const std::string out = " -o " + (dir / "t.pdf");
  const std::pair<std::string, std::string> cases[] = {
      {"tag16h5 --outer-size 200" + out, "say 200mm"},
      {"tag16h5 --outer-size 12parsecs" + out, "not a length"},
      {"tag16h5 --outer-size -3mm" + out, "not a length"},
      {"tag16h5 --id 30 --outer-size 1m" + out, "tag16h5 has ids 0-29"},
      {"tag16h5 --id 5-2 --outer-size 1m" + out, "empty range"},
      {"tag16h5 --id x --outer-size 1m" + out, "not an id"},
      {"tag16h5 --outer-size 1m --page B5" + out, "unknown paper size 'B5'"},
      {"tag16h5 --outer-size 1m --page A4 --margin 110mm" + out, "no room"},
      {"tag16h5 --outer-size 1m -o " + (dir / "t.txt"), ".pdf, .svg or .png"},
      {"tag99h1 --outer-size 1m" + out, "unknown tag family 'tag99h1'"},
      {"tag16h5 --outer-size 1m --format jpeg" + out, ""},
  };
  for (const auto& [args, words] : cases) {
    const Result r = run_split(kCli + " tag " + args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.err;
    EXPECT_NE(r.err.find(words), std::string::npos) << args << ": " << r.err;
    EXPECT_FALSE(fs::exists(dir / "t.pdf")) << args;
  }
  // A file that cannot be written is a runtime failure.
  const Result r = run_split(kCli + " tag tag16h5 --outer-size 1m -o /nonexistent-dir/t.pdf");
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("/nonexistent-dir/t.pdf"), std::string::npos) << r.err;
}

}  // namespace
