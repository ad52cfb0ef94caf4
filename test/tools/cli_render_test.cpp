// `lidartag render`: the pictures are read back and checked against what `detect --json` reports
// for the same rotation: the detections' outlines where their corners project, the rejected
// clusters in their stage's colour, each close-up's grid showing the decoded code at the tag's
// size, and the options (rotation, range, size, prefix, PCD input, errors).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
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
  while (std::getline(lines, line)) {
    nlohmann::json j = nlohmann::json::parse(line);
    if (j["sequence"] == rotation) return j;
  }
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

// The inset of the cells the points read: the bounding box of its two colours, each cell's colour
// at its centre (1 = read white, 0 = read black, 2 = no evidence drawn).
std::vector<uint8_t> read_inset(const Image& img, int cells) {
  int x0 = img.width, y0 = img.height, x1 = -1, y1 = -1;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      if (same(img.at(x, y), draw::kReadBlack) || same(img.at(x, y), draw::kReadWhite)) {
        x0 = std::min(x0, x);
        y0 = std::min(y0, y);
        x1 = std::max(x1, x);
        y1 = std::max(y1, y);
      }
  std::vector<uint8_t> grid;
  if (x1 < 0) return grid;
  // The outermost squares are the smallest possible (35 % of a cell): the box is within a cell
  // of the inset's edges; cell centres are found from the box of the squares' centres instead.
  const double pitch = (x1 - x0 + 1) / (cells - 0.3);
  for (int r = 0; r < cells; ++r)
    for (int c = 0; c < cells; ++c) {
      const Rgb& p = img.at(int(x0 + (c + 0.35) * pitch), int(y0 + (r + 0.35) * pitch));
      grid.push_back(same(p, draw::kReadWhite, 8) ? 1 : same(p, draw::kReadBlack, 8) ? 0 : 2);
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
    // What the points read (the inset) is the code too inside the white ring (both tags score
    // 1.00; the ring's corners get few returns on a board turned by 45 degrees).
    const auto read = read_inset(img, family.total_width);
    const auto code = family.render(family.codes[static_cast<size_t>(tags[k].first)]);
    ASSERT_EQ(read.size(), code.size());
    const int w = family.total_width;
    for (int row = 1; row + 1 < w; ++row)
      for (int col = 1; col + 1 < w; ++col)
        EXPECT_EQ(read[size_t(row * w + col)], code[size_t(row * w + col)]) << row << "," << col;
    // The fitted square: the black square's edge, in its colour.
    const double black = side * family.width_at_border / family.total_width;
    EXPECT_TRUE(
        colour_near(img, pics[k + 1].cx - black / 2, pics[k + 1].cy, draw::kFittedSquare, 2));
  }
}

// Configured for 1.2 m tags, the demo's 0.8 and 0.6 m tags are rejected for their size: their
// clusters are drawn in the plane of their points, beside a dashed 1.2 m marker and the side
// measured, so that the picture shows why.
TEST(CliRender, ATagNotFoundIsDrawnFromItsRejectedCluster) {
  TempDir dir;
  const nlohmann::json rotation = detect_rotation(kDemo, 1);
  ASSERT_TRUE(rotation["detections"].empty());
  std::vector<nlohmann::json> rejected;  // reached the plane fit or later: each gets a close-up
  for (const auto& c : rotation["cluster_diagnostics"])
    for (const char* stage : {"plane", "corners", "pose", "decode"})
      if (c["stage"] == stage) rejected.push_back(c);
  const Result r = run_split(kCli + " render " + kDemo + " -o " + (dir / "demo"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), rejected.size() + 1) << r.out;
  const Image top = read_png(pics[0].file);
  int boards = 0;  // the demo's two boards, measured and rejected for their size
  for (size_t k = 0; k < rejected.size(); ++k) {
    const auto& c = rejected[k];
    SCOPED_TRACE("cluster " + c["index"].dump());
    EXPECT_EQ(pics[k + 1].file, dir / ("demo-rotation1-cluster" + c["index"].dump() + ".png"));
    const std::string stage = c["stage"], result = c["result"];
    EXPECT_NE(r.out.find("cluster " + c["index"].dump() + " (" + stage + "/" + result + ")"),
              std::string::npos);
    if (stage != "corners") continue;  // not measured: no side to draw
    ASSERT_EQ(result, "wrong_size");
    ++boards;
    // Bird's-eye: the cluster's points in the corners stage's colour inside its box.
    const uint32_t yellow = draw::stage_colour(lidartag::detector::Stage::kCorners).rgb();
    const auto& box = c["box"];
    const Picture& m = pics[0];
    int coloured = 0;
    for (int y = int(m.cy - box[1].get<double>() * m.px_per_m);
         y <= int(m.cy - box[0].get<double>() * m.px_per_m); ++y)
      for (int x = int(m.cx - box[3].get<double>() * m.px_per_m);
           x <= int(m.cx - box[2].get<double>() * m.px_per_m); ++x)
        coloured += same(top.at(x, y), yellow, 8);
    EXPECT_GT(coloured, 40);

    const Image img = read_png(pics[k + 1].file);
    const Picture& p = pics[k + 1];
    // The dashed 1.2 m marker and the side measured (about 0.89 and 0.69 m: the boards).
    auto dashed = [&](double side_m, uint32_t colour) {
      const int x = int(std::lround(p.cx - side_m / 2 * p.px_per_m));
      int on = 0, n = 0;
      for (double y = p.cy - side_m / 3 * p.px_per_m; y < p.cy + side_m / 3 * p.px_per_m; ++y, ++n)
        on += colour_near(img, x, y, colour, 1);
      return double(on) / n;
    };
    EXPECT_GT(dashed(1.2, draw::kFittedSquare), 0.4);
    EXPECT_GT(dashed(c["side_m"].get<double>(), draw::kMeasuredSide), 0.4);
    // Every point lies inside the 1.2 m marker: the band outside it (below the title, above the
    // legend) is empty.
    const double half = 0.6 * p.px_per_m;
    int outside = 0, points = 0;
    for (int y = 100; y < img.height - 70; ++y)
      for (int x = 0; x < img.width; ++x) {
        const bool in = std::abs(x - p.cx) < half - 3 && std::abs(y - p.cy) < half - 3;
        const bool near_edge =
            std::abs(std::abs(x - p.cx) - half) < 4 || std::abs(std::abs(y - p.cy) - half) < 4;
        const bool drawn = !same(img.at(x, y), draw::kCloseUpBackground, 2);
        if (in && drawn) ++points;
        if (!in && !near_edge && drawn) ++outside;
      }
    EXPECT_EQ(outside, 0);
    EXPECT_GT(points, 1000);
  }
  EXPECT_EQ(boards, 2);
}

// Configured for tag25h9, the demo's tag16h5 markers reach decoding and are rejected there: the
// close-up shows the best tag25h9 code found and the cells the points read.
TEST(CliRender, ADecodeRejectionShowsTheBestCodeAndTheCellsRead) {
  TempDir dir;
  const Result r =
      run_split(kCli + " render " + kDemo + kSizes + " --family tag25h9 -o " + (dir / "demo"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u) << r.out;
  const auto& family = lidartag::tags::builtin_family("tag25h9");
  static const std::regex best(R"(\(decode/\w+, best tag25h9 id (\d+)\))");
  std::vector<int> ids;
  for (std::sregex_iterator it(r.out.begin(), r.out.end(), best), end; it != end; ++it)
    ids.push_back(std::stoi((*it)[1]));
  ASSERT_EQ(ids.size(), 2u) << r.out;
  for (size_t k = 0; k < 2; ++k) {
    const Image img = read_png(pics[k + 1].file);
    double side = 0;
    const auto grid = read_grid(img, family.total_width, side);
    const auto code = family.render(family.codes[static_cast<size_t>(ids[k])]);
    EXPECT_EQ(grid, code);
    const auto read = read_inset(img, family.total_width);
    ASSERT_EQ(read.size(), code.size());
    // A tag of another family: most cells agree with the best code (the outer ring and the
    // border at least), not all.
    size_t agree = 0;
    for (size_t i = 0; i < code.size(); ++i) agree += read[i] == code[i];
    EXPECT_GT(agree, code.size() * 6 / 10);
    EXPECT_LT(agree, code.size());
  }
}

TEST(CliRender, OneClusterAskedFor) {
  TempDir dir;
  const nlohmann::json rotation = detect_rotation(kDemo + kSizes, 1);
  int accepted = -1;
  for (const auto& c : rotation["cluster_diagnostics"])
    if (c["result"] == "accepted" && accepted < 0) accepted = c["index"].get<int>();
  ASSERT_GE(accepted, 0);
  const Result r = run_split(kCli + " render " + kDemo + kSizes + " --cluster " +
                             std::to_string(accepted) + " -o " + (dir / "one"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 2u) << r.out;  // the bird's-eye view and that cluster
  EXPECT_EQ(pics[1].file, dir / ("one-rotation1-cluster" + std::to_string(accepted) + ".png"));
  EXPECT_NE(r.out.find("(accepted, best tag16h5 id "), std::string::npos) << r.out;
}

TEST(CliRender, RotationRangeSizePrefixAndPcdInput) {
  TempDir dir;
  Result r = run_split(kCli + " render " + kDemo + kSizes +
                       " --rotation 9 --range 300cm --size 400 " + "-o " + dir.str() + "/");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u);
  EXPECT_EQ(pics[0].file, dir / "demo-rotation9.png");
  EXPECT_NEAR(pics[0].px_per_m, 400.0 / 2 / 3, 1e-3);
  const Image small = read_png(pics[0].file);
  EXPECT_EQ(small.width, 400);
  EXPECT_EQ(read_png(pics[1].file).width, 320);

  // A PCD of rotation 1 (the first complete one) gives the same tags, named by the same number.
  ASSERT_EQ(run_split(kCli + " dump " + kDemo + " --out " + (dir / "pcd")).exit_code, 0);
  r = run_split(kCli + " render " + (dir / "pcd/rotation_000001.pcd") + kSizes + " -o " +
                (dir / "cloud"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  pics = pictures(r.out);
  ASSERT_EQ(pics.size(), 3u) << r.out;
  EXPECT_EQ(pics[1].file, dir / "cloud-rotation1-tag16h5-0.png");
}

TEST(CliRender, BadArgumentsAreUsageErrors) {
  TempDir dir;
  // Rotations by number: the demo has 0 to 11, the first and the last incomplete.
  Result r = run_split(kCli + " render " + kDemo + " --rotation 12 -o " + (dir / "x"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("has rotations 0-11"), std::string::npos) << r.err;
  r = run_split(kCli + " render " + kDemo + " --rotation 11 -o " + (dir / "x"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("rotation 11 of " + kDemo + " is incomplete"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--partial draws it"), std::string::npos) << r.err;
  r = run_split(kCli + " render " + kDemo + " --cluster 100000 -o " + (dir / "x"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("detect --clusters"), std::string::npos) << r.err;
  EXPECT_EQ(run_split(kCli + " render " + kDemo + " --size 50 -o " + (dir / "x")).exit_code, 2);
  EXPECT_EQ(run_split(kCli + " render " + kDemo + " --family tag99h1 -o " + (dir / "x")).exit_code,
            2);
  {
    std::ofstream pcd(dir / "xyz.pcd");
    pcd << "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n";
  }
  r = run_split(kCli + " render " + (dir / "xyz.pcd") + " --rings 16 -o " + (dir / "x"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no intensity field"), std::string::npos) << r.err;
  fs::remove(dir / "xyz.pcd");
  r = run_split(kCli + " render " + kDemo + " -o /nonexistent-dir/x");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("/nonexistent-dir/x-rotation1.png"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_empty(dir.str()));
}

}  // namespace
