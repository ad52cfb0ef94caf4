// Fuzz target: a ros-drivers calibration file through load_calibration_file. The first byte picks
// the model the file is loaded for, the rest is the file. Checks: bad files throw
// CalibrationError; a calibration accepted decodes a data packet of its model (every return at
// the farthest distance a packet can carry) into finite points within the model's range plus the
// documented offset limits, with every laser on a ring.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fuzz_util.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/encoder.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static fuzz::MemFile file;
  const auto models = velodyne::all_models();
  const velodyne::Model model = models[data[0] % models.size()];
  const std::string& path = file.write({data + 1, size - 1});
  velodyne::Calibration calibration;
  try {
    calibration = velodyne::load_calibration_file(path, model);
  } catch (const velodyne::CalibrationError&) {
    return 0;
  }
  const velodyne::ModelSpec& spec = velodyne::model_spec(model);
  fuzz::check(calibration.model == model, "calibration for another model");
  fuzz::check(calibration.lasers.size() == static_cast<size_t>(spec.lasers), "laser count");
  fuzz::check(calibration.ring_of_laser.size() == calibration.lasers.size(), "ring count");
  std::vector<bool> ring_used(calibration.lasers.size(), false);
  for (int ring : calibration.ring_of_laser) {
    fuzz::check(ring >= 0 && static_cast<size_t>(ring) < ring_used.size() &&
                    !ring_used[static_cast<size_t>(ring)],
                "rings are not a permutation of the lasers");
    ring_used[static_cast<size_t>(ring)] = true;
  }
  // Far returns on every laser, one packet of single strongest returns.
  const velodyne::ReturnMode mode = velodyne::ReturnMode::kStrongest;
  std::vector<velodyne::FiringColumn> columns(static_cast<size_t>(spec.columns_per_packet(mode)));
  for (size_t c = 0; c < columns.size(); ++c) {
    columns[c].azimuth_centideg = static_cast<uint16_t>((c * 20) % 36000);
    for (int l = 0; l < spec.lasers; ++l) {
      columns[c].echo[0].distance[static_cast<size_t>(l)] =
          static_cast<uint16_t>(std::min(65535.0, (spec.max_range_m - 1.0) / spec.distance_unit_m));
      columns[c].echo[0].intensity[static_cast<size_t>(l)] = 100;
    }
  }
  std::array<uint8_t, velodyne::kDataPacketSize> packet{};
  velodyne::encode_data_packet(spec, mode, columns, 1000, packet);
  velodyne::Decoder decoder(calibration);
  velodyne::SensorClock clock;
  static velodyne::DecodedPacket out;
  const auto status = decoder.decode(packet, clock, 1'700'000'000'000'000'000, out);
  fuzz::check(status == velodyne::DecodeStatus::kOk, "a packet of the model not decoded");
  // Documented limits: offsets within 10 m, so points within the range plus 20 m.
  const float limit = static_cast<float>(spec.max_range_m) + 20.0f;
  for (int r = 0; r < out.returns; ++r)
    for (int ring = 0; ring < out.rings; ++ring)
      for (int c = 0; c < out.columns; ++c) {
        const auto i = static_cast<size_t>(out.at(r, c, ring));
        if (out.range[i] <= 0.0f) continue;
        fuzz::check(std::isfinite(out.x[i]) && std::isfinite(out.y[i]) && std::isfinite(out.z[i]) &&
                        std::fabs(out.x[i]) < limit && std::fabs(out.y[i]) < limit &&
                        std::fabs(out.z[i]) < limit,
                    "a point outside the model's range");
        fuzz::check(out.azimuth_deg[i] >= 0.0f && out.azimuth_deg[i] < 360.0f,
                    "azimuth out of [0, 360)");
      }
  return 0;
}
