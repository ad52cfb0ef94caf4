// Fuzz target: a stream of data and position packets (fuzz_util.hpp's record form) through
// CaptureReader, the path every source of the daemon and the tools takes: model check, decoder,
// position packets and the sensor clock, scan assembly. Built once per model (LIDARTAG_FUZZ_MODEL,
// the decoder fixed to it, as with `model:` in the configuration) and once with "auto" (the model
// from the product byte and the timing); each corpus holds all three return modes (shared with
// the decode_<model> target, which takes the packets one at a time without assembly).
// Checks: every rotation handed out is within its model's bounds (test/io/scan_invariants.hpp),
// every packet is counted exactly once, and the rotation counts agree.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "fuzz_util.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "read_rotations.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::optional<velodyne::Model> model =
      velodyne::model_from_name(LIDARTAG_FUZZ_MODEL);
  velodyne::CaptureReaderOptions options;
  options.model = model;
  velodyne::CaptureReader reader(
      std::make_unique<fuzz::RecordSource>(std::span<const uint8_t>(data, size)), options);
  const auto [rotations, complete] = fuzz::read_rotations(reader, size);
  const velodyne::CaptureCounts& c = reader.counts();
  const driver::SourceStats source = reader.source_stats();
  uint64_t errors = 0;
  for (uint64_t e : c.decode_errors) errors += e;
  fuzz::check(c.data_packets + c.position_packets == source.packets,
              "packets neither data nor position");
  fuzz::check(c.decoded + errors + c.undecodable == c.data_packets,
              "data packets not counted exactly once");
  fuzz::check(c.position_ok + c.position_errors == c.position_packets,
              "position packets not counted exactly once");
  const driver::BatcherStats b = reader.batcher_stats();
  fuzz::check(b.rotations == rotations, "rotations delivered != rotations counted");
  fuzz::check(b.complete == complete && b.complete + b.incomplete == b.rotations,
              "complete + incomplete != rotations");
  if (model) fuzz::check(reader.model() == model, "the configured model was not used");
  // The model probe: only payloads laid out as data packets vote, so a stream none of whose
  // data packets is laid out as one decides no model (junk never locks the reader).
  if (!model && reader.model()) {
    fuzz::check(reader.model_check().packets() > 0 || c.failed_probes > 0 || c.decoded > 0,
                "a model decided from no data packet");
  }
  return 0;
}
