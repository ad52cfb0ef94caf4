// Fuzz target: the model probe alone (ModelCheck), on the data payloads of a record-form stream
// (the packets_auto corpus). Checks, against a count kept here: only payloads laid out as data
// packets are counted (junk of the probe's size never votes), the product model is the byte more
// than half of them carry and nothing else, a stream with no such payload decides no model, and
// the timing's model fits the period measured.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fuzz_util.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  velodyne::ModelCheck check;
  std::array<size_t, 256> votes{};
  size_t laid_out = 0, probe_size = 0;
  fuzz::RecordSource source({data, size});
  driver::RawPacket raw;
  while (source.next(raw, std::chrono::milliseconds(0)) == driver::ReadStatus::kPacket) {
    if (raw.destination_port != velodyne::kDefaultDataPort) continue;
    check.add(raw.payload);
    if (raw.payload.size() != velodyne::kDataPacketSize) continue;
    ++probe_size;
    if (!velodyne::looks_like_data_packet(raw.payload)) continue;
    ++laid_out;
    ++votes[raw.payload[velodyne::kProductIdOffset]];
  }
  fuzz::check(check.packets() == laid_out, "a payload not laid out as a data packet counted");
  fuzz::check(check.packets() + check.rejected() == probe_size,
              "a payload of the probe's size neither counted nor rejected");
  size_t best = 0;
  for (size_t b = 0; b < votes.size(); ++b)
    if (votes[b] > votes[best]) best = b;
  const auto expected = 2 * votes[best] > laid_out
                            ? velodyne::model_from_product_id(static_cast<uint8_t>(best))
                            : std::nullopt;
  fuzz::check(check.product_model() == expected, "the product model is not the majority's byte");
  if (laid_out == 0) {
    fuzz::check(!check.product_model() && !check.timing_model() && !check.return_mode(),
                "a model decided from no data packet");
  }
  if (const auto m = check.timing_model()) {
    const double period = check.packet_period_us();
    const double expected_period = velodyne::model_spec(*m).packet_period_us(
        check.return_mode().value_or(velodyne::ReturnMode::kStrongest));
    fuzz::check(std::abs(period - expected_period) < 0.03 * expected_period,
                "the timing's model does not fit the period measured");
  }
  return 0;
}
