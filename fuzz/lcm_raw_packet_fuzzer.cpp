// Fuzz target: the bytes of one raw_packet_t message as the daemon decodes it from a replayed
// LCM log (LcmLogSource: length checks, then LCM's generated decode inside try/catch). The input
// is the message; the target wraps it in one well-formed log event on the raw channel. Checks:
// the event is either counted as malformed or delivered as a packet whose payload is the
// message's data, on a port in 1..65535, at a receive time a capture can hold.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "fuzz_util.hpp"
#include "lidartag/daemon/lcm_log_source.hpp"

using namespace lidartag;

namespace {
void put_be32(std::vector<uint8_t>& b, uint32_t v) {
  for (int i = 3; i >= 0; --i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void put_be64(std::vector<uint8_t>& b, uint64_t v) {
  for (int i = 7; i >= 0; --i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > 1 << 20) return 0;
  static fuzz::MemFile file;
  static std::vector<uint8_t> log;
  // LCM log event: sync word, event number, timestamp (us), channel length, data length (all
  // big-endian), channel, data.
  const std::string channel = "LIDARTAG_RAW";
  log.clear();
  put_be32(log, 0xEDA1DA01u);
  put_be64(log, 0);
  put_be64(log, 1'700'000'000'000'000ULL);
  put_be32(log, static_cast<uint32_t>(channel.size()));
  put_be32(log, static_cast<uint32_t>(size));
  log.insert(log.end(), channel.begin(), channel.end());
  log.insert(log.end(), data, data + size);
  daemon::LcmLogSource source(file.write(log), daemon::LcmLogSourceOptions{});
  driver::RawPacket packet;
  const driver::ReadStatus status = source.next(packet, std::chrono::milliseconds(0));
  const driver::SourceStats s = source.stats();
  fuzz::check(source.events() == 1, "the event was not read");
  if (status == driver::ReadStatus::kPacket) {
    fuzz::check(s.packets == 1 && s.malformed == 0, "a packet delivered and not counted");
    fuzz::check(packet.payload.size() <= size, "a payload larger than the message");
    fuzz::check(packet.destination_port > 0, "port 0 delivered");
    fuzz::check(packet.receive_time_ns >= 0 && packet.receive_time_ns < driver::kMaxReceiveTimeNs,
                "a receive time out of range");
  } else {
    fuzz::check(status == driver::ReadStatus::kEnd, "neither a packet nor the end");
    fuzz::check(s.malformed == 1 && s.packets == 0, "a message refused and not counted");
  }
  return 0;
}
