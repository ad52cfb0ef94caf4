// Fuzz target: an LCM log file (event framing, channels, raw_packet_t messages) through the
// daemon's LcmLogSource and CaptureReader, as `lidartagd --replay-lcm FILE` reads it. Checks: a
// file refused at open throws IoError; otherwise the replay ends, every rotation is within its
// model's bounds, every event is delivered, ignored or counted as malformed, and every packet
// delivered is counted once by the reader.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "fuzz_util.hpp"
#include "lidartag/daemon/lcm_log_source.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "read_rotations.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static fuzz::MemFile file;
  const std::string& path = file.write({data, size});
  std::unique_ptr<daemon::LcmLogSource> owned;
  try {
    owned = std::make_unique<daemon::LcmLogSource>(path, daemon::LcmLogSourceOptions{});
  } catch (const driver::IoError&) {
    return 0;
  }
  const daemon::LcmLogSource* source = owned.get();
  velodyne::CaptureReader reader(std::move(owned), velodyne::CaptureReaderOptions{});
  (void)fuzz::read_rotations(reader, size);
  const driver::SourceStats s = reader.source_stats();
  fuzz::check(s.packets + s.ignored + s.malformed == source->events(),
              "events neither delivered, ignored nor malformed");
  const velodyne::CaptureCounts& c = reader.counts();
  uint64_t errors = 0;
  for (uint64_t e : c.decode_errors) errors += e;
  // Raw packets carry any port: those on neither sensor port are not the reader's to count.
  fuzz::check(c.data_packets + c.position_packets <= s.packets, "more packets counted than read");
  fuzz::check(c.decoded + errors + c.undecodable == c.data_packets,
              "data packets not counted exactly once");
  fuzz::check(c.position_ok + c.position_errors == c.position_packets,
              "position packets not counted exactly once");
  return 0;
}
