// `lidartag dump CAPTURE --out DIR [--organized]`: one binary PCD per rotation, its stamp in the
// header (pcd.hpp).
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>

#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/driver/io/capture_reader.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/io/pcd.hpp"

namespace lidartag::cli {
namespace {

struct DumpArgs {
  CaptureArgs capture;
  std::string out;
  bool partial = false;
  bool organized = false;
};

int run_dump(const DumpArgs& args) {
  std::error_code ec;
  std::filesystem::create_directories(args.out, ec);
  if (ec || !std::filesystem::is_directory(args.out)) {
    throw velodyne::IoError("cannot create output directory '" + args.out + "'" +
                            (ec ? ": " + ec.message() : std::string()));
  }
  velodyne::CaptureReader reader(args.capture.capture, reader_options(args.capture));
  size_t written = 0, skipped = 0, points = 0;
  while (const Scan* scan = reader.next()) {
    if (!scan->complete && !args.partial) {
      ++skipped;
      continue;
    }
    const std::string path =
        (std::filesystem::path(args.out) / fmt::format("scan_{:06d}.pcd", written)).string();
    points += velodyne::write_pcd(path, *scan, {velodyne::PcdFormat::kBinary, args.organized});
    ++written;
  }
  warn_model_mismatch(reader, args.capture);
  fmt::print("wrote {} PCD files ({} points) to {}", written, points, args.out);
  if (skipped > 0) fmt::print("; skipped {} incomplete rotations (--partial keeps them)", skipped);
  fmt::print("\n");
  return 0;
}

const Registrar kDump(
    "dump", "Write each rotation of a capture as a binary PCD file",
    [](CLI::App& app) -> RunFunction {
      auto args = std::make_shared<DumpArgs>();
      add_capture_options(app, args->capture);
      app.add_option("--out", args->out, "Output directory (created)")->required();
      app.add_flag("--partial", args->partial,
                   "Also write incomplete rotations (first, last, lossy)");
      app.add_flag("--organized", args->organized,
                   "Organised clouds as PCL expects: WIDTH = columns, HEIGHT = rings (x returns), "
                   "NaN where a laser had no return");
      return [args] { return run_dump(*args); };
    });

}  // namespace
}  // namespace lidartag::cli
