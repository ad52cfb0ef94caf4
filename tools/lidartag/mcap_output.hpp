// `--mcap FILE` of `lidartag detect` and `lidartag dump --format mcap`: each rotation's cloud and
// detections written for Foxglove (lidartag/foxglove/scene_recorder.hpp).
#pragma once

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/cli11.hpp"
#include "lidartag/detector/result.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/foxglove/scene_recorder.hpp"

namespace lidartag::cli {

struct McapArgs {
  std::string path;                  // "" : no MCAP output
  std::string compression = "zstd";  // none, zstd, lz4
  std::string frame_id = "lidar";    // the clouds' frame, the tags' frames' parent
};

// --mcap-compression and --mcap-frame (the path option is the command's own).
void add_mcap_options(CLI::App& app, McapArgs& args);

class McapOutput {
 public:
  // Creates args.path; refuses the capture itself as the output. Throws driver::IoError.
  McapOutput(const McapArgs& args, const std::string& capture);
  // The rotation's cloud, tags, transforms and detections (`detections_json`: "" for the
  // recorder's own form); `detected` false: the cloud alone. Throws driver::IoError when the file
  // cannot be written.
  void rotation(const Scan& scan, std::span<const detector::Detection> detections,
                std::string_view detections_json, bool detected = true);
  // Completes the file and prints one line on stderr: messages, chunks, bytes.
  void close();

 private:
  std::string frame_id_;
  foxglove::SceneRecorder recorder_;
  foxglove::CloudPoints points_;
};

}  // namespace lidartag::cli
