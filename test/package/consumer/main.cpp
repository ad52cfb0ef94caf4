// Uses the installed libraries the way a downstream project would: reads the installed demo
// capture, detects with the installed demo configuration, round-trips the detections through the
// LCM type, reads a calibration file and a scene.
#include <cstdio>
#include <filesystem>
#include <lidartag/daemon/config.hpp>
#include <lidartag/detector/detector.hpp>
#include <lidartag/driver/velodyne/io/calibration_file.hpp>
#include <lidartag/driver/velodyne/io/capture_reader.hpp>
#include <lidartag/sim/scene.hpp>
#include <lidartag/tag_detections_t.hpp>
#include <vector>

int main() {
  const std::string data = DATA_DIR;
  const auto options = lidartag::daemon::load_detector_config(data + "/demo.yaml");
  lidartag::detector::Detector detector(options);
  lidartag::detector::ScanResult result;
  lidartag::velodyne::CaptureReader reader(data + "/demo.pcap", {});
  int rotations = 0, detections = 0, decoded = 0;
  while (const lidartag::Scan* scan = reader.next()) {
    if (!scan->complete) continue;
    ++rotations;
    detector.detect(*scan, result);
    lidartag::tag_detections_t message;
    message.ndetections = static_cast<int32_t>(result.detections.size());
    for (const auto& d : result.detections) {
      lidartag::tag_detection_t t{};
      t.family = std::string(d.family);
      t.id = d.id;
      message.detections.push_back(t);
    }
    std::vector<uint8_t> bytes(static_cast<size_t>(message.getEncodedSize()));
    message.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    lidartag::tag_detections_t back;
    if (back.decode(bytes.data(), 0, static_cast<int>(bytes.size())) < 0) return 1;
    detections += static_cast<int>(result.detections.size());
    decoded += back.ndetections;
  }
  const auto scene = lidartag::sim::parse_scene("sensor: {model: hdl32e}\n");
  const auto spec = lidartag::velodyne::model_spec(scene.sensor.model);
  int lcm_files = 0;
  for (const auto& f : std::filesystem::directory_iterator(LCMTYPES_DIR))
    lcm_files += f.path().extension() == ".lcm";
  std::printf("rotations %d detections %d decoded %d scene %s lcm files %d\n", rotations,
              detections, decoded, std::string(spec.name).c_str(), lcm_files);
  return 0;
}
