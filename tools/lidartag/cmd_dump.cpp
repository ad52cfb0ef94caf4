// `lidartag dump CAPTURE --out DIR [--organized] [--force]`: one binary PCD per rotation, its
// stamp in the header (pcd.hpp); `--format mcap --out FILE`: the clouds in one MCAP file for
// Foxglove (mcap_output.hpp). Any capture the source seam opens (common.hpp open_capture): Ouster
// captures one per frame, destaggered. A bag's PointCloud2 topic: one per cloud. A PCD file
// (another driver's too): its cloud as the detector reads it, rewritten (e.g. organised) or into
// MCAP.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <system_error>

#include "lidartag/bag_clouds.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/exit_codes.hpp"
#include "lidartag/mcap_output.hpp"
#include "lidartag/progress.hpp"

namespace lidartag::cli {
namespace {

namespace fs = std::filesystem;

struct DumpArgs {
  CaptureArgs capture;
  OusterArgs ouster;
  std::string out;
  bool partial = false;
  bool organized = false;
  bool force = false;
  int rings = 0;                // PointCloud2 without a ring field and no --model: beams
  double resolution_deg = 0.0;  // PointCloud2 or PCD: width of a column (0: the cloud's own)
  std::string format = "pcd";   // pcd: a folder of PCD files; mcap: one MCAP file (--out FILE)
  McapArgs mcap;
};

// The files dump writes: rotation_NNNNNN.pcd, NNNNNN the rotation's sequence number (six digits or
// more); scan_NNNNNN.pcd is what earlier builds wrote (--force removes those too).
bool is_dump_file(const fs::path& p) {
  static const std::regex pattern(R"((rotation|scan)_[0-9]{6,}\.pcd)");
  return std::regex_match(p.filename().string(), pattern);
}

// An existing folder must be empty, so that old rotations never mix with new ones; --force removes
// the files a dump writes (by name) and leaves everything else alone.
void prepare_output(const DumpArgs& args) {
  std::error_code ec;
  if (fs::exists(args.out, ec) && fs::is_directory(args.out, ec)) {
    size_t ours = 0, others = 0;
    for (const auto& entry : fs::directory_iterator(args.out, ec))
      ++(entry.is_regular_file(ec) && is_dump_file(entry.path()) ? ours : others);
    if (ec) throw driver::IoError("cannot list '" + args.out + "': " + ec.message());
    if (ours + others > 0 && !args.force) {
      throw UsageError(fmt::format(
          "output folder '{}' is not empty ({} PCD file{} of an earlier dump, {} other entr{}); "
          "choose an empty or new folder, or --force to delete those PCD files first",
          args.out, ours, ours == 1 ? "" : "s", others, others == 1 ? "y" : "ies"));
    }
    if (ours > 0) {
      for (const auto& entry : fs::directory_iterator(args.out, ec)) {
        if (!entry.is_regular_file(ec) || !is_dump_file(entry.path())) continue;
        if (!fs::remove(entry.path(), ec) || ec)
          throw driver::IoError("cannot remove '" + entry.path().string() +
                                "': " + (ec ? ec.message() : "not removed"));
      }
      spdlog::info("removed {} PCD file{} of an earlier dump from {}", ours, ours == 1 ? "" : "s",
                   args.out);
    }
  }
  fs::create_directories(args.out, ec);
  if (ec || !fs::is_directory(args.out)) {
    throw driver::IoError("cannot create output directory '" + args.out + "'" +
                          (ec ? ": " + ec.message() : std::string()));
  }
}

// --format mcap: the MCAP file's options; an existing file is replaced with --force only.
McapArgs mcap_args(const DumpArgs& args) {
  std::error_code ec;
  if (fs::exists(args.out, ec) && !args.force) {
    throw UsageError(fmt::format("output file '{}' exists; --force replaces it", args.out));
  }
  McapArgs mcap = args.mcap;
  mcap.path = args.out;
  return mcap;
}

// --format mcap: the rotations' clouds in one MCAP file (foxglove.PointCloud, docs/foxglove.md).
template <typename Reader>
int dump_mcap(const DumpArgs& args, Reader& reader) {
  McapOutput out(mcap_args(args), args.capture.capture);
  std::error_code ec;
  Progress progress(fs::file_size(args.capture.capture, ec));
  size_t written = 0, skipped = 0;
  while (const Scan* scan = reader.next()) {
    if (!scan->complete && !args.partial) {
      ++skipped;
      continue;
    }
    out.rotation(*scan, {}, "", false);
    ++written;
    progress.update(capture_bytes_read(reader), fmt::format("{} rotations", written));
  }
  progress.done();
  out.close();
  warn_model_mismatch(reader, args.capture);
  fmt::print("wrote {} rotations to {}", written, args.out);
  if (skipped > 0) fmt::print("; skipped {} incomplete rotations (--partial keeps them)", skipped);
  fmt::print("\n");
  require_rotations(reader, args.capture, written, skipped, "writes them");
  return 0;
}

// Writes the rotations (Ouster: the frames) of a Velodyne or an Ouster reader.
template <typename Reader>
int dump_rotations(const DumpArgs& args, Reader& reader) {
  if (args.format == "mcap") return dump_mcap(args, reader);
  prepare_output(args);
  std::error_code ec;
  Progress progress(fs::file_size(args.capture.capture, ec));
  size_t written = 0, skipped = 0, points = 0;
  while (const Scan* scan = reader.next()) {
    if (!scan->complete && !args.partial) {
      ++skipped;
      continue;
    }
    // Named by the rotation's sequence number, as detect, the daemon and Python number it.
    const std::string path =
        (fs::path(args.out) / fmt::format("rotation_{:06d}.pcd", scan->sequence)).string();
    points += velodyne::write_pcd(path, *scan, {velodyne::PcdFormat::kBinary, args.organized});
    ++written;
    progress.update(capture_bytes_read(reader), fmt::format("{} files", written));
  }
  progress.done();
  warn_model_mismatch(reader, args.capture);
  fmt::print("wrote {} PCD files ({} points) to {}", written, points, args.out);
  if (skipped > 0) fmt::print("; skipped {} incomplete rotations (--partial keeps them)", skipped);
  fmt::print("\n");
  require_rotations(reader, args.capture, written, skipped, "writes them");
  return 0;
}

// A PCD file: its one cloud, as the detector reads it (rings, columns, header), rewritten as
// a rotation is (organised with --organized) or into an MCAP file; any PCD, another driver's too.
int dump_pcd(const DumpArgs& args) {
  Scan scan;
  load_pcd_scan(args.capture, args.rings, args.resolution_deg, scan);
  if (args.format == "mcap") {
    McapOutput out(mcap_args(args), args.capture.capture);
    out.rotation(scan, {}, "", false);
    out.close();
    fmt::print("wrote 1 cloud to {}\n", args.out);
    return 0;
  }
  prepare_output(args);
  const std::string path =
      (fs::path(args.out) / fmt::format("rotation_{:06d}.pcd", scan.sequence)).string();
  const size_t points =
      velodyne::write_pcd(path, scan, {velodyne::PcdFormat::kBinary, args.organized});
  fmt::print("wrote 1 PCD file ({} points) to {}\n", points, args.out);
  return 0;
}

int run_dump(const DumpArgs& args) {
  if (is_pcd(args.capture.capture)) return dump_pcd(args);
  if (is_point_cloud_bag(args.capture)) {  // a bag's PointCloud2 topic: one file per cloud
    if (args.format == "mcap") {  // each cloud as a rotation's, as the packets' path writes them
      McapOutput out(mcap_args(args), args.capture.capture);
      const size_t written =
          for_each_bag_cloud(args.capture, args.rings, args.resolution_deg, [&](const Scan& scan) {
            out.rotation(scan, {}, "", false);
            return true;
          });
      out.close();
      if (written == 0)
        throw UsageError(fmt::format("{}: no point cloud could be read{}", args.capture.capture,
                                     args.capture.windowed() ? " in --start/--duration" : ""));
      fmt::print("wrote {} clouds to {}\n", written, args.out);
      return 0;
    }
    prepare_output(args);
    dump_bag_clouds(args.capture, args.rings, args.resolution_deg, args.out, args.organized);
    return 0;
  }
  OpenedCapture opened = open_capture(args.capture, args.ouster);
  return opened.visit([&](auto& reader) { return dump_rotations(args, reader); });
}

const Registrar kDump(
    "dump", "Write each rotation of a capture as a binary PCD file",
    [](CLI::App& app) -> RunFunction {
      auto args = std::make_shared<DumpArgs>();
      add_capture_options(app, args->capture);
      add_ouster_options(app, args->ouster, true);
      app.add_option("--out", args->out,
                     "Output directory (created; must be empty unless --force): one "
                     "rotation_NNNNNN.pcd per rotation, NNNNNN its number (rotation_000001.pcd, "
                     "...); with --format mcap the MCAP file")
          ->required();
      app.add_option("--format", args->format,
                     "pcd: one PCD file per rotation; mcap: every rotation's cloud in one MCAP "
                     "file for Foxglove (docs/foxglove.md)")
          ->capture_default_str()
          ->check(CLI::IsMember({"pcd", "mcap"}));
      add_mcap_options(app, args->mcap);
      app.add_flag("--partial", args->partial,
                   "Also write incomplete rotations (first, last, lossy)");
      app.add_flag("--organized", args->organized,
                   "Organised clouds as PCL expects: WIDTH = columns, HEIGHT = rings (x returns), "
                   "NaN where a laser had no return");
      app.add_flag("--force", args->force,
                   "Write into a non-empty directory: the PCD files an earlier dump wrote there "
                   "(rotation_*.pcd, "
                   "scan_*.pcd) are deleted first, "
                   "other files are kept");
      app.add_option("--rings", args->rings,
                     "PointCloud2 or PCD without a ring field: beams to estimate (or --model)");
      app.add_option("--resolution", args->resolution_deg, kResolutionHelp)
          ->check(CLI::Range(0.01, 5.0));
      return [args] { return run_dump(*args); };
    });

}  // namespace
}  // namespace lidartag::cli
