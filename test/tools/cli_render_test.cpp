// `lidartag render`: the pictures are read back and checked against what `detect --json` reports
// for the same rotation: the detections' outlines where their corners project, the rejected
// clusters in their stage's colour, each close-up's grid showing the decoded code at the tag's
// size, and the options (rotation, range, size, prefix, PCD input, errors).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/draw/colors.hpp"
#include "png_image.hpp"
#include "run_tool.hpp"

namespace {

namespace fs = std::filesystem;
namespace draw = lidartag::draw;
using lidartag::testing::Image;
using lidartag::testing::read_png;
using lidartag::testing::Rgb;
using lidartag::testing::run_split;
using Result = lidartag::testing::ToolResult;

const std::string kCli = LIDARTAG_CLI;
const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";
const std::string kSizes = " --tag-size 0.8 --tag-size 0.6";

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("lidartag_render_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
};

// "wrote FILE: ..., N px per metre, sensor|centre at pixel X,Y" lines.
struct Picture {
  std::string file;
  double px_per_m = 0, cx = 0, cy = 0;
};

std::vector<Picture> pictures(const std::string& out) {
  static const std::regex line(
      R"(wrote (\S+): .*, ([\d.]+) px per metre, (?:sensor|centre) at pixel ([\d.]+),([\d.]+))");
  std::vector<Picture> v;
  for (std::sregex_iterator it(out.begin(), out.end(), line), end; it != end; ++it)
    v.push_back({(*it)[1], std::stod((*it)[2]), std::stod((*it)[3]), std::stod((*it)[4])});
  return v;
}

nlohmann::json detect_rotation(const std::string& args, int rotation) {
  const Result r = run_split(kCli + " detect --json --clusters " + args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  for (int n = 0; std::getline(lines, line); ++n)
    if (n == rotation) return nlohmann::json::parse(line);
  return {};
}

bool same(const Rgb& p, uint32_t rgb, int tolerance = 0) {
  return std::abs(p.r - int((rgb >> 16) & 0xff)) <= tolerance &&
         std::abs(p.g - int((rgb >> 8) & 0xff)) <= tolerance &&
         std::abs(p.b - int(rgb & 0xff)) <= tolerance;
}

// Whether a pixel of colour `rgb` lies within `radius` pixels of (x, y).
bool colour_near(const Image& img, double x, double y, uint32_t rgb, int radius) {
  for (int dy = -radius; dy <= radius; ++dy)
    for (int dx = -radius; dx <= radius; ++dx) {
      const int px = int(std::lround(x)) + dx, py = int(std::lround(y)) + dy;
      if (px >= 0 && py >= 0 && px < img.width && py < img.height && same(img.at(px, py), rgb, 8))
        return true;
    }
  return false;
}

TEST(CliRender, BirdsEyeShowsDetectionsAndRejectedClustersWhereDetectFindsThem) {
  TempDir dir;
  const nlohmann::json rotation = detect_rotation(kDemo + kSizes, 3);
  ASSERT_EQ(rotation["detections"].size(), 2u);
  const Result r =
      run_split(kCli + " render " + kDemo + kSizes + " --rotation 3 -o " + (dir / "demo"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u) << r.out;  // the bird's-eye view and one close-up per tag
  EXPECT_EQ(pics[0].file, dir / "demo-rotation3.png");
  EXPECT_EQ(pics[1].file, dir / "demo-rotation3-tag16h5-0.png");
  EXPECT_EQ(pics[2].file, dir / "demo-rotation3-tag16h5-1.png");
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir.str())) files += e.path().extension() == ".png";
  EXPECT_EQ(files, 3u);

  const Image img = read_png(pics[0].file);
  ASSERT_EQ(img.width, 1000);
  const Picture& m = pics[0];
  auto project = [&](const nlohmann::json& p) {
    return std::array<double, 2>{m.cx - p[1].get<double>() * m.px_per_m,
                                 m.cy - p[0].get<double>() * m.px_per_m};
  };
  // The outline through the four corners, in the detection colour, all along.
  for (const auto& d : rotation["detections"]) {
    const auto& c = d["corners"];
    size_t on = 0, samples = 0;
    for (size_t k = 0; k < 4; ++k) {
      const auto a = project(c[k]), b = project(c[(k + 1) % 4]);
      for (double t = 0.1; t < 0.95; t += 0.1, ++samples)
        on += colour_near(img, a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), draw::kDetection,
                          2);
    }
    EXPECT_GE(on, samples * 9 / 10) << "tag " << d["id"];
  }
  // No detection colour far from the detections (points use the intensity map).
  EXPECT_FALSE(colour_near(img, m.cx, m.cy + 2.0 * m.px_per_m, draw::kDetection, 10));
  // Each rejected cluster's box in the colour of the stage that dropped it.
  size_t boxes = 0;
  for (const auto& c : rotation["cluster_diagnostics"]) {
    if (c["result"] == "accepted") continue;
    const auto& box = c["box"];  // min_x, max_x, min_y, max_y
    const double x0 = m.cx - box[3].get<double>() * m.px_per_m - 2;
    const double y0 = m.cy - box[1].get<double>() * m.px_per_m - 2;
    const double x1 = m.cx - box[2].get<double>() * m.px_per_m + 2;
    if (x0 < 0 || y0 < 0 || x1 >= img.width) continue;
    lidartag::detector::Stage stage = lidartag::detector::Stage::kCount;
    for (int s = 0; s < lidartag::detector::kStageCount; ++s)
      if (lidartag::detector::stage_name(static_cast<lidartag::detector::Stage>(s)) ==
          c["stage"].get<std::string>())
        stage = static_cast<lidartag::detector::Stage>(s);
    const uint32_t colour = draw::stage_colour(stage).rgb();
    EXPECT_TRUE(colour_near(img, (x0 + x1) / 2, y0, colour, 2))
        << "cluster " << c["index"] << " " << c["stage"] << " at " << (x0 + x1) / 2 << "," << y0;
    ++boxes;
  }
  EXPECT_GT(boxes, 10u);
}

// The close-up's coloured cells: the bounding box of the cell colours is the marker; each cell's
// colour (the majority of cell-coloured pixels around its centre; points are grey) is read.
std::vector<uint8_t> read_grid(const Image& img, int cells, double& side_px) {
  int x0 = img.width, y0 = img.height, x1 = -1, y1 = -1;
  // Above the legend (its swatches show the same colours) at the bottom.
  for (int y = 0; y < img.height * 90 / 100; ++y)
    for (int x = 0; x < img.width; ++x)
      if (same(img.at(x, y), draw::kBlackCell) || same(img.at(x, y), draw::kWhiteCell)) {
        x0 = std::min(x0, x);
        y0 = std::min(y0, y);
        x1 = std::max(x1, x);
        y1 = std::max(y1, y);
      }
  side_px = x1 - x0 + 1;
  EXPECT_NEAR(y1 - y0 + 1, side_px, 2);
  const double cell = side_px / cells;
  std::vector<uint8_t> grid;
  for (int r = 0; r < cells; ++r)
    for (int c = 0; c < cells; ++c) {
      int black = 0, white = 0;
      for (int y = int(y0 + (r + 0.2) * cell); y < y0 + (r + 0.8) * cell; ++y)
        for (int x = int(x0 + (c + 0.2) * cell); x < x0 + (c + 0.8) * cell; ++x) {
          black += same(img.at(x, y), draw::kBlackCell);
          white += same(img.at(x, y), draw::kWhiteCell);
        }
      grid.push_back(white > black ? 1 : 0);
    }
  return grid;
}

TEST(CliRender, CloseUpsShowTheDecodedCodeAtTheTagsSize) {
  TempDir dir;
  const Result r = run_split(kCli + " render " + kDemo + kSizes + " -o " + (dir / "demo"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u);
  const auto& family = lidartag::tags::builtin_family("tag16h5");
  const std::pair<int, double> tags[] = {{0, 0.8}, {1, 0.6}};  // the demo's truth
  for (size_t k = 0; k < 2; ++k) {
    SCOPED_TRACE(pics[k + 1].file);
    const Image img = read_png(pics[k + 1].file);
    ASSERT_EQ(img.width, 800);
    double side = 0;
    const auto grid = read_grid(img, family.total_width, side);
    EXPECT_EQ(grid, family.render(family.codes[static_cast<size_t>(tags[k].first)]));
    EXPECT_NEAR(side, tags[k].second * pics[k + 1].px_per_m, 2.0);
    // The fitted square: the black square's edge, in its colour.
    const double black = side * family.width_at_border / family.total_width;
    EXPECT_TRUE(
        colour_near(img, pics[k + 1].cx - black / 2, pics[k + 1].cy, draw::kFittedSquare, 2));
  }
}

TEST(CliRender, RotationRangeSizePrefixAndPcdInput) {
  TempDir dir;
  Result r = run_split(kCli + " render " + kDemo + kSizes + " --rotation 9 --range 3 --size 400 " +
                       "-o " + dir.str() + "/");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u);
  EXPECT_EQ(pics[0].file, dir / "demo-rotation9.png");
  EXPECT_NEAR(pics[0].px_per_m, 400.0 / 2 / 3, 1e-3);
  const Image small = read_png(pics[0].file);
  EXPECT_EQ(small.width, 400);
  EXPECT_EQ(read_png(pics[1].file).width, 320);

  // A PCD of rotation 0 gives the same tags.
  ASSERT_EQ(run_split(kCli + " dump " + kDemo + " --out " + (dir / "pcd")).exit_code, 0);
  r = run_split(kCli + " render " + (dir / "pcd/scan_000000.pcd") + kSizes + " -o " +
                (dir / "cloud"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u) << r.out;
  EXPECT_EQ(pics[1].file, dir / "cloud-rotation0-tag16h5-0.png");
}

TEST(CliRender, BadArgumentsAreUsageErrors) {
  TempDir dir;
  Result r = run_split(kCli + " render " + kDemo + " --rotation 10 -o " + (dir / "x"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("has 10 complete rotations (0-9)"), std::string::npos) << r.err;
  r = run_split(kCli + " render " + kDemo + " --cluster 100000 -o " + (dir / "x"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("detect --clusters"), std::string::npos) << r.err;
  EXPECT_EQ(run_split(kCli + " render " + kDemo + " --size 50 -o " + (dir / "x")).exit_code, 2);
  EXPECT_EQ(run_split(kCli + " render " + kDemo + " --family tag99h1 -o " + (dir / "x")).exit_code,
            2);
  r = run_split(kCli + " render " + kDemo + " -o /nonexistent-dir/x");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("/nonexistent-dir/x-rotation0.png"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_empty(dir.str()));
}

}  // namespace
