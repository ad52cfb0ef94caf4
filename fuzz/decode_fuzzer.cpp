// Fuzz target: data and position packets one at a time, as the receiver meets them: for a data
// packet the model check (product byte, timing), the header and the decoder of the model the
// target is built for (LIDARTAG_FUZZ_MODEL, its built-in calibration); for a position packet the
// parser and the sensor clock. Input: fuzz_util.hpp's record form (the corpus is shared with the
// stream_<model> target, which adds scan assembly). Checks every decoded packet: columns and
// rings of the model, azimuths in [0, 360), finite column times, every return a finite point
// within the model's range (plus calibration offsets).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/sensor_clock.hpp"

using namespace lidartag;

namespace {

std::string packet_problem(const velodyne::DecodedPacket& p, const velodyne::ModelSpec& spec) {
  if (p.rings != spec.lasers) return "rings " + std::to_string(p.rings);
  if (p.returns != 1 && p.returns != 2) return "returns " + std::to_string(p.returns);
  if (p.columns < 1 || p.columns > velodyne::DecodedPacket::kMaxColumns)
    return "columns " + std::to_string(p.columns);
  if (p.returns * p.columns * p.rings > velodyne::DecodedPacket::kMaxCells) return "too many cells";
  const float limit = static_cast<float>(spec.max_range_m) + 10.0f;
  for (int c = 0; c < p.columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    if (!(p.column_azimuth_deg[uc] >= 0.0f && p.column_azimuth_deg[uc] < 360.0f))
      return "column azimuth " + std::to_string(p.column_azimuth_deg[uc]);
    if (!std::isfinite(p.column_time_us[uc]) || p.column_time_us[uc] < 0.0)
      return "column time " + std::to_string(p.column_time_us[uc]);
  }
  for (int r = 0; r < p.returns; ++r)
    for (int ring = 0; ring < p.rings; ++ring) {
      if (p.laser_of_ring != nullptr && p.laser_of_ring[ring] >= spec.lasers)
        return "ring " + std::to_string(ring) + " has no laser";
      for (int c = 0; c < p.columns; ++c) {
        const auto i = static_cast<size_t>(p.at(r, c, ring));
        if (!(p.range[i] >= 0.0f && p.range[i] <= limit))
          return "range " + std::to_string(p.range[i]);
        if (p.range[i] == 0.0f) continue;
        if (!(std::isfinite(p.x[i]) && std::isfinite(p.y[i]) && std::isfinite(p.z[i]) &&
              std::fabs(p.x[i]) <= limit && std::fabs(p.y[i]) <= limit &&
              std::fabs(p.z[i]) <= limit))
          return "point out of range";
        if (!(p.azimuth_deg[i] >= 0.0f && p.azimuth_deg[i] < 360.0f))
          return "point azimuth " + std::to_string(p.azimuth_deg[i]);
        if (!std::isfinite(p.time_us[i])) return "point time";
      }
    }
  return "";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const velodyne::Model model = *velodyne::model_from_name(LIDARTAG_FUZZ_MODEL);
  static const velodyne::Calibration calibration = velodyne::Calibration::builtin(model);
  static velodyne::DecodedPacket packet;  // 40 kB: once
  const velodyne::ModelSpec& spec = velodyne::model_spec(model);
  velodyne::Decoder decoder(calibration);
  velodyne::ModelCheck check;
  velodyne::SensorClock clock;
  fuzz::RecordSource source({data, size});
  driver::RawPacket raw;
  while (source.next(raw, std::chrono::milliseconds(0)) == driver::ReadStatus::kPacket) {
    if (raw.destination_port == velodyne::kDefaultPositionPort) {
      velodyne::PositionPacket position;
      if (velodyne::parse_position_packet(raw.payload, position) == velodyne::PositionStatus::kOk)
        clock.update(position, raw.receive_time_ns);
      continue;
    }
    check.add(raw.payload);
    velodyne::PacketHeader header;
    if (velodyne::read_header(raw.payload, header))
      fuzz::check(raw.payload.size() >= velodyne::kDataPacketSize, "a header of a short packet");
    const velodyne::DecodeStatus status =
        decoder.decode(raw.payload, clock, raw.receive_time_ns, packet);
    if (status != velodyne::DecodeStatus::kOk) continue;
    fuzz::check(raw.payload.size() == velodyne::kDataPacketSize,
                "a packet of the wrong size decoded");
    const std::string problem = packet_problem(packet, spec);
    fuzz::check(problem.empty(), "decoded packet: " + problem);
    fuzz::check(std::isfinite(decoder.rate_deg_per_us()), "rotation rate not finite");
  }
  (void)check.timing_model();
  (void)check.mismatch();
  return 0;
}
