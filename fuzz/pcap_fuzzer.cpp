// Fuzz target: a capture file (classic pcap in every byte order and time resolution, pcapng; any
// link type libpcap knows) through CaptureReader, as `lidartag info/detect` and the daemon's
// replay read it. The file lives in memory (fuzz_util.hpp's MemFile). Checks: a file refused at
// open is refused with IoError; otherwise the reader ends, every rotation is within its model's
// bounds and every packet delivered is counted once.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "read_rotations.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static fuzz::MemFile file;
  const std::string& path = file.write({data, size});
  std::unique_ptr<velodyne::CaptureReader> reader;
  try {
    reader = std::make_unique<velodyne::CaptureReader>(path, velodyne::CaptureReaderOptions{});
  } catch (const driver::IoError&) {
    return 0;  // not a capture libpcap opens, or a link type without IPv4: refused, named
  }
  (void)fuzz::read_rotations(*reader, size);
  const velodyne::CaptureCounts& c = reader->counts();
  uint64_t errors = 0;
  for (uint64_t e : c.decode_errors) errors += e;
  fuzz::check(c.data_packets + c.position_packets == reader->source_stats().packets,
              "packets neither data nor position");
  fuzz::check(c.decoded + errors + c.undecodable == c.data_packets,
              "data packets not counted exactly once");
  fuzz::check(c.position_ok + c.position_errors == c.position_packets,
              "position packets not counted exactly once");
  fuzz::check(reader->source_stats().bytes <= size, "more payload bytes than file bytes");
  return 0;
}
