#include "lidartag/mcap_output.hpp"

#include <fmt/format.h>

#include <filesystem>
#include <system_error>

#include "lidartag/driver/io/errors.hpp"

namespace lidartag::cli {
namespace {

foxglove::SceneRecorderOptions recorder_options(const McapArgs& args, const std::string& capture) {
  std::error_code ec;
  if (std::filesystem::equivalent(args.path, capture, ec)) {
    throw driver::IoError("--mcap " + args.path + " is the capture itself: choose another file");
  }
  foxglove::SceneRecorderOptions o;
  o.mcap.compression = driver::bag::parse_mcap_compression(args.compression);
  return o;
}

}  // namespace

void add_mcap_options(CLI::App& app, McapArgs& args) {
  app.add_option("--mcap-compression", args.compression,
                 "Chunk compression of the MCAP file: zstd, lz4 or none")
      ->capture_default_str()
      ->check(CLI::IsMember({"zstd", "lz4", "none"}));
  app.add_option("--mcap-frame", args.frame_id,
                 "Frame of the MCAP file's clouds, parent of its tag_<family>_<id> frames")
      ->capture_default_str();
}

McapOutput::McapOutput(const McapArgs& args, const std::string& capture)
    : frame_id_(args.frame_id), recorder_(args.path, recorder_options(args, capture)) {}

void McapOutput::rotation(const Scan& scan, std::span<const detector::Detection> detections,
                          std::string_view detections_json, bool detected) {
  foxglove::scan_points(scan, points_);
  foxglove::RotationRecord r;
  r.frame_id = frame_id_;
  r.sequence = scan.sequence;
  r.stamp_ns = scan.stamp_ns;
  r.cloud = &points_;
  r.detected = detected;
  r.detections = detections;
  r.detections_json = detections_json;
  if (!recorder_.write_rotation(r)) {
    throw driver::IoError(recorder_.writer().error().empty()
                              ? recorder_.writer().path() + ": a message was refused"
                              : recorder_.writer().error());
  }
}

void McapOutput::close() {
  recorder_.close();
  const auto& s = recorder_.writer().stats();
  fmt::print(stderr, "wrote {}: {} messages ({} rotations) in {} chunks, {} bytes\n",
             recorder_.writer().path(), s.messages, recorder_.counts().clouds, s.chunks, s.bytes);
}

}  // namespace lidartag::cli
