// bench_size_check: tags as they are mounted and typed (issue 33, items 2 and 3).
//
// Boards: tags of 0.2-1.2 m at their working ranges, diamond and square mounted, on boards with
// bare margins of 0, 5, 10 and 20 cm a side, the detector given the tag's size only; per cell:
// rotations with the right ID, the centre's error (median), wrong IDs. Target: every margin
// within 5 points and 1 mm of the same tag without one.
//
// The size check: a tag of a true size is detected with the
// size typed right, and 5 % or more off (smaller and larger, and the 0.75 and 0.89 m for a
// 0.8 m tag); per cell, over its runs: rotations with the right ID, the share of them warned
// about (Detection::size_warning), the measured size against the truth (median and p95 of the
// relative error) and the centre's error.
//
//   bench_size_check [--runs N] [--rotations R] [--quick] [--out DIR]
//
// --out DIR writes DIR/size-check.md. Exit status 1 when a target is not met: a size 5 % or more
// off warned about in fewer than 95 % of the rotations where the tag is found, the measured size
// more than 2 % off the truth (median), any warning at the right size, or a wrong ID.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bench_args.hpp"
#include "bench_report.hpp"
#include "lidartag/detector/detector.hpp"
#include "sim_scans.hpp"

namespace {

using namespace lidartag;
namespace fs = std::filesystem;
using bench_report::fmt;
using bench_report::machine;
using bench_report::quantile;

struct Args {
  int runs = 10;
  int rotations = 10;
  bool quick = false;
  std::string out;
  std::string command = "build/bin/bench_size_check";
};

// A tag on a board with a bare margin.
struct BoardCell {
  velodyne::Model model{};
  double size = 0.8, distance = 4.0, margin = 0.0;
  int rotation_deg = 45;  // 45: diamond, 0: square
  const char* family = "tag16h5";
  int rotations = 0, found = 0, wrong = 0;
  std::vector<double> centre_mm;
};

void run_board(BoardCell& c, int run, int rotations) {
  const int code = (7 * run + static_cast<int>(10 * c.distance)) % 30;
  const double above = (((11 * run) % 10 + 0.5) / 10.0 - 0.5) * 0.2 * c.distance / 6.0;
  sim::Scene scene = eval::accuracy_scene(c.model, c.distance, 0, code, c.size, above);
  scene.tags[0].family = c.family;
  scene.tags[0].rotation_deg = c.rotation_deg;
  scene.tags[0].board.margin = c.margin;
  const sim::Simulator simulator(scene);
  eval::SimScans scans(simulator);
  detector::DetectorOptions options;
  options.tag_sizes_m = {c.size};
  options.families = {c.family};
  detector::Detector det(options);
  detector::ScanResult result;
  std::vector<std::vector<detector::Detection>> found;
  const sim::Truth truth =
      scans.run(rotations, static_cast<uint64_t>(700 + 31 * run), [&](const Scan& scan, size_t) {
        det.detect(scan, result);
        found.push_back(result.detections);
      });
  for (size_t k = 1; k < found.size() && k < truth.rotations.size(); ++k) {
    const sim::TagTruth& tag = truth.rotations[k].tags.front();
    ++c.rotations;
    bool right = false;
    for (const detector::Detection& d : found[k]) {
      if (!eval::at_tag(d, tag)) continue;
      if (d.id != tag.id) {
        ++c.wrong;
        continue;
      }
      if (!right) c.centre_mm.push_back(1e3 * (d.position - tag.position).norm());
      right = true;
    }
    c.found += right ? 1 : 0;
  }
}

struct Cell {
  velodyne::Model model{};
  double size = 0.8;  // printed, m
  double distance = 4.0;
  int angle = 0;
  double typed = 0.8;  // configured, m
  int rotations = 0, found = 0, warned = 0, measured = 0, wrong = 0;
  std::vector<double> size_error, centre_mm;  // |measured / truth - 1|; centre error, mm

  double off() const { return typed / size - 1.0; }
};

void run_cell(Cell& c, int run, int rotations) {
  const int code = (7 * run + c.angle + static_cast<int>(10 * c.distance)) % 30;
  // The centre moved over one beam spacing across the runs, as bench_tracker does, so that no
  // cell is one lucky or unlucky crossing of the rings.
  const double above = (((11 * run) % 10 + 0.5) / 10.0 - 0.5) * 0.2 * c.distance / 6.0;
  const sim::Scene scene = eval::accuracy_scene(c.model, c.distance, c.angle, code, c.size, above);
  const sim::Simulator simulator(scene);
  eval::SimScans scans(simulator);
  detector::DetectorOptions options;
  options.tag_sizes_m = {c.typed};
  detector::Detector det(options);
  detector::ScanResult result;
  std::vector<std::vector<detector::Detection>> found;
  const sim::Truth truth = scans.run(rotations, static_cast<uint64_t>(900 + 31 * run + c.angle),
                                     [&](const Scan& scan, size_t) {
                                       det.detect(scan, result);
                                       found.push_back(result.detections);
                                     });
  for (size_t k = 1; k < found.size() && k < truth.rotations.size(); ++k) {
    const sim::TagTruth& tag = truth.rotations[k].tags.front();
    ++c.rotations;
    for (const detector::Detection& d : found[k]) {
      if (!eval::at_tag(d, tag)) continue;
      if (d.id != tag.id) {
        ++c.wrong;
        continue;
      }
      ++c.found;
      c.warned += d.size_warning ? 1 : 0;
      c.centre_mm.push_back(1e3 * (d.position - tag.position).norm());
      if (d.measured_size_m > 0) {
        ++c.measured;
        c.size_error.push_back(std::abs(d.measured_size_m / c.size - 1.0));
      }
      break;
    }
  }
}

int run(const Args& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const int runs = args.quick ? 2 : args.runs;
  const int rotations = args.quick ? 4 : args.rotations;
  int missed = 0;

  // Boards: each tag at its working range, with each margin beside the same tag without one.
  struct BoardSetup {
    velodyne::Model model;
    double size, distance;
    const char* family;
  };
  const BoardSetup board_setups[] = {{velodyne::Model::kVLP32C, 0.2, 2.0, "tag36h11"},
                                     {velodyne::Model::kVLP32C, 0.4, 3.0, "tag36h11"},
                                     {velodyne::Model::kVLP32C, 0.8, 6.0, "tag16h5"},
                                     {velodyne::Model::kVLP16, 1.2, 5.0, "tag16h5"}};
  std::ostringstream boards;
  boards << "| sensor | tag | distance | mount | margin | rotations | found | points from no "
            "margin | centre off: median | mm from no margin | wrong IDs | target |\n"
         << "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (const BoardSetup& s : board_setups)
    for (int rotation_deg : {45, 0}) {
      double base_pct = 0.0, base_mm = 0.0;
      for (double margin : {0.0, 0.05, 0.1, 0.2}) {
        BoardCell c;
        c.model = s.model;
        c.size = s.size;
        c.distance = s.distance;
        c.family = s.family;
        c.margin = margin;
        c.rotation_deg = rotation_deg;
        for (int r = 0; r < runs; ++r) run_board(c, r, rotations);
        const double pct = c.rotations ? 100.0 * c.found / c.rotations : 0.0;
        const double mm = quantile(c.centre_mm, 0.5);
        if (margin == 0.0) {
          base_pct = pct;
          base_mm = mm;
        }
        const bool met =
            c.wrong == 0 && pct >= base_pct - 5.0 && (c.centre_mm.empty() || mm <= base_mm + 1.0);
        missed += met ? 0 : 1;
        const char* mount = rotation_deg == 45 ? "diamond" : "square";
        std::printf(
            "board: %-7s %s %.1f m at %.0f m %-7s margin %.2f m: found %5.1f %% (%+.1f), centre "
            "%.1f mm (%+.1f), wrong %d%s\n",
            std::string(velodyne::model_spec(c.model).name).c_str(), s.family, s.size, s.distance,
            mount, margin, pct, pct - base_pct, mm, mm - base_mm, c.wrong, met ? "" : "  NOT MET");
        std::fflush(stdout);
        boards << "| " << velodyne::model_spec(c.model).display_name << " | " << fmt(s.size, 1)
               << " m `" << s.family << "` | " << fmt(s.distance, 0) << " m | " << mount << " | "
               << fmt(100 * margin, 0) << " cm | " << c.rotations << " | " << fmt(pct, 1) << " % | "
               << fmt(pct - base_pct, 1) << " | " << fmt(mm, 1) << " mm | " << fmt(mm - base_mm, 1)
               << " | " << c.wrong << " | "
               << (margin == 0.0 ? "the reference"
                   : met         ? "met"
                                 : "**not met**")
               << " |\n";
      }
    }

  struct Setup {
    velodyne::Model model;
    double size;
    std::vector<double> distances;
  };
  const Setup setups[] = {{velodyne::Model::kVLP32C, 0.8, {3.0, 6.0, 10.0}},
                          {velodyne::Model::kVLP32C, 0.4, {2.0, 4.0}},
                          {velodyne::Model::kVLP16, 1.2, {4.0, 6.0}}};
  std::vector<Cell> cells;
  for (const Setup& s : setups)
    for (double d : s.distances)
      for (int angle : {0, 45}) {
        std::vector<double> typed = {s.size, 0.95 * s.size, 1.05 * s.size};
        if (s.size == 0.8) typed.insert(typed.end(), {0.75, 0.89});
        for (double t : typed) {
          Cell c;
          c.model = s.model;
          c.size = s.size;
          c.distance = d;
          c.angle = angle;
          c.typed = t;
          cells.push_back(c);
        }
      }
  std::ostringstream table;
  table << "| sensor | printed | distance | angle | typed | rotations | found | warned | measured "
           "size off the truth: median, p95 | centre off: median | wrong IDs | target |\n"
        << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (Cell& c : cells) {
    for (int r = 0; r < runs; ++r) run_cell(c, r, rotations);
    const double warned = c.found ? 100.0 * c.warned / c.found : NAN;
    const double med = quantile(c.size_error, 0.5), p95 = quantile(c.size_error, 0.95);
    const bool right = std::abs(c.off()) < 1e-9;
    const bool off = std::abs(c.off()) >= 0.05 - 1e-9;
    bool met = c.wrong == 0 && (c.measured == 0 || med <= 0.02);
    if (right) met = met && c.warned == 0;
    if (off) met = met && c.found > 0 && warned >= 95.0;
    missed += met ? 0 : 1;
    const std::string name(velodyne::model_spec(c.model).display_name);
    std::printf(
        "%-8s %.2f m at %4.1f m %2d deg typed %.3f m (%+5.1f %%): found %3d of %3d, warned %5.1f "
        "%%, size off %.2f / %.2f %%, centre %.1f mm, wrong %d%s\n",
        std::string(velodyne::model_spec(c.model).name).c_str(), c.size, c.distance, c.angle,
        c.typed, 100 * c.off(), c.found, c.rotations, warned, 100 * med, 100 * p95,
        quantile(c.centre_mm, 0.5), c.wrong, met ? "" : "  NOT MET");
    std::fflush(stdout);
    table << "| " << name << " | " << fmt(c.size, 2) << " m | " << fmt(c.distance, 0) << " m | "
          << c.angle << "° | " << fmt(c.typed, 2) << " m (" << (c.off() >= 0 ? "+" : "")
          << fmt(100 * c.off(), 1) << " %) | " << c.rotations << " | " << c.found << " | "
          << fmt(warned, 1) << " % | " << fmt(100 * med, 2) << " %, " << fmt(100 * p95, 2)
          << " % | " << fmt(quantile(c.centre_mm, 0.5), 1) << " mm | " << c.wrong << " | "
          << (right ? "0 warnings"
              : off ? "≥ 95 % warned"
                    : "-")
          << ": " << (met ? "met" : "**not met**") << " |\n";
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%.0f s; %d cells not met\n", seconds, missed);
  if (!args.out.empty()) {
    fs::create_directories(args.out);
    std::ofstream md(fs::path(args.out) / "size-check.md");
    md << "# Tags on boards, and sizes typed wrong (simulated)\n\nProduced by `" << args.command
       << "` (" << fmt(seconds, 0) << " s on " << machine()
       << "; source: `bench/bench_size_check.cpp`; how it works: `docs/detector.md`, \"Tags on "
          "boards\" and \"The size check\").\n\n## Tags on boards\n\nEach tag at a working "
          "range, diamond (45°) or square (0°) mounted on an easel, on a board with a bare margin "
          "of 0 to 20 cm a side; "
       << runs << " runs per cell of " << rotations
       << " rotations (the first, partial one left out), each run with its own code, noise seed "
          "and tag height; the detector is given the tag's size and family only (default "
          "`corners.board_margin_m`: 0.2 m). Found: rotations with the right ID at the tag. "
          "Target (issue 33): with a margin, the rate within 5 points and the centre's median "
          "error within 1 mm of the same tag without one.\n\n"
       << boards.str()
       << "\n## A size typed wrong\n\nA `tag16h5` of the printed size on an easel stand, diamond "
          "mount, at the "
          "distance and angle shown, "
       << runs << " runs per cell of " << rotations
       << " rotations (the first, partial one left out), each run with its own code, noise seed "
          "and tag height (spread over one VLP-16 beam spacing); the detector is given the typed "
          "size only. Found: rotations with the right ID at the tag. Warned: of those, the share "
          "with `Detection::size_warning` (the measured size more than `pose.size_warning_ratio` "
          "off the typed one). The measured size (`Detection::measured_size_m`) against the "
          "printed one, and the detection's centre against the truth.\n\n"
       << table.str();
    std::printf("wrote %s\n", (fs::path(args.out) / "size-check.md").string().c_str());
  }
  return missed == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs") {
      args.runs = bench_args::count("bench_size_check", argc, argv, i, "--runs", 1, args.command);
    } else if (a == "--rotations") {
      args.rotations =
          bench_args::count("bench_size_check", argc, argv, i, "--rotations", 2, args.command);
    } else if (a == "--quick") {
      args.quick = true;
      args.command += " --quick";
    } else if (a == "--out") {
      args.out = bench_args::value("bench_size_check", argc, argv, i, "--out");
      args.command += " --out " + args.out;
    } else {
      std::fprintf(stderr, "bench_size_check: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  return bench_args::run_reporting_errors("bench_size_check", [&] { return run(args); });
}
