// The simulator: a scene into a capture file and its truth, or straight into rotations (the
// packets decoded in memory by the driver, as a capture of them would be).
#include <pybind11/stl.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/packet_source.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/sim/ouster_sim.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::python {
namespace {

// Packets kept in memory, replayed as a PacketSource.
class MemorySource final : public driver::PacketSource {
 public:
  struct Packet {
    std::vector<uint8_t> payload;
    int64_t time_ns;
    uint16_t port;
  };
  explicit MemorySource(std::vector<Packet> packets) : packets_(std::move(packets)) {}

  driver::ReadStatus next(driver::RawPacket& out, std::chrono::milliseconds) override {
    if (next_ == packets_.size()) return driver::ReadStatus::kEnd;
    const Packet& p = packets_[next_++];
    out.payload = p.payload;
    out.receive_time_ns = p.time_ns;
    out.source_ipv4 = driver::PcapWriter::kDefaultSourceIpv4;
    out.destination_port = p.port;
    ++stats_.packets;
    stats_.bytes += p.payload.size();
    return driver::ReadStatus::kPacket;
  }
  driver::SourceStats stats() const override { return stats_; }

 private:
  std::vector<Packet> packets_;
  size_t next_ = 0;
  driver::SourceStats stats_{};
};

struct SimOutput {
  std::string truth_json;
  std::vector<Rotation> rotations;
  uint64_t data_packets = 0, position_packets = 0, points = 0;
};

// `scene` is a file (is_path) or YAML text. With `out`, writes the capture there; without, decodes
// the packets into rotations (complete ones, or all with `partial`).
SimOutput simulate(const std::string& scene_text, bool is_path, const std::string& out,
                   std::optional<int> rotations, std::optional<uint64_t> seed, bool partial) {
  py::gil_scoped_release release;
  sim::Scene scene = is_path ? sim::load_scene(scene_text) : sim::parse_scene(scene_text, "scene");
  const int n = rotations.value_or(scene.rotations);
  if (n < 1 || n > 100000) throw py::value_error("rotations must be within 1..100000");
  const uint64_t s = seed.value_or(scene.seed);
  // An Ouster sensor's metadata: written beside the capture (NAME.json, as `lidartag sim` does),
  // or what the packets are decoded with in memory.
  std::optional<driver::ouster::SensorInfo> info;
  std::string metadata;
  if (scene.sensor.ouster) {
    info = sim::ouster_sensor_info(scene.sensor);
    if (!out.empty()) {
      metadata = std::filesystem::path(out).replace_extension(".json").string();
      if (metadata == out)
        throw py::value_error("out: '" + out +
                              "' is where the Ouster capture's metadata goes: name it NAME.pcap");
    }
  }
  const auto model = scene.sensor.model;
  const double cut = scene.sensor.cut_azimuth_deg;
  sim::Simulator simulator(std::move(scene));
  sim::RunStats stats;
  SimOutput result;
  sim::Truth truth;
  if (!out.empty()) {
    driver::PcapWriter writer(out);
    truth = simulator.run(
        n, s,
        [&](std::span<const uint8_t> payload, int64_t time_ns, uint16_t port) {
          writer.write_udp(payload, time_ns, port);
        },
        &stats);
    writer.close();
    if (info) driver::ouster::write_metadata(*info, metadata);
  } else {
    std::vector<MemorySource::Packet> packets;
    truth = simulator.run(
        n, s,
        [&](std::span<const uint8_t> payload, int64_t time_ns, uint16_t port) {
          packets.push_back({{payload.begin(), payload.end()}, time_ns, port});
        },
        &stats);
    auto source = std::make_unique<MemorySource>(std::move(packets));
    if (info) {
      // Ouster: frames by frame id, destaggered, as a pcap of the packets with its metadata.
      driver::ouster::CaptureReader reader(std::move(source), *info);
      const std::string name = driver::ouster::model_name(*info);
      while (const Scan* scan = reader.next())
        if (scan->complete || partial) {
          result.rotations.push_back(Rotation::copy_of(*scan));
          result.rotations.back().sensor_model = name;
        }
    } else {
      velodyne::CaptureReaderOptions options;
      options.model = model;
      options.batcher.cut_azimuth_deg = cut;
      velodyne::CaptureReader reader(std::move(source), options);
      while (const Scan* scan = reader.next())
        if (scan->complete || partial) result.rotations.push_back(Rotation::copy_of(*scan));
    }
  }
  result.truth_json = sim::truth_to_json(truth).dump();
  result.data_packets = stats.data_packets;
  result.position_packets = stats.position_packets;
  result.points = stats.points;
  return result;
}

}  // namespace

void bind_sim(py::module_& m) {
  m.def(
      "_simulate",
      [](const std::string& scene, bool is_path, const std::string& out,
         std::optional<int> rotations, std::optional<uint64_t> seed, bool partial) {
        SimOutput r = simulate(scene, is_path, out, rotations, seed, partial);
        py::dict stats;
        stats["data_packets"] = r.data_packets;
        stats["position_packets"] = r.position_packets;
        stats["points"] = r.points;
        return py::make_tuple(r.truth_json, std::move(r.rotations), stats);
      },
      py::arg("scene"), py::arg("is_path"), py::arg("out"), py::arg("rotations"), py::arg("seed"),
      py::arg("partial"));
}

}  // namespace lidartag::python
