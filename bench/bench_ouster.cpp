// Ouster decoding and frame assembly throughput, one core: the real captures of
// ../shared/captures/ouster replayed as a longer stream (each pass's frame ids and timestamps
// moved on, so that the frames follow each other), parsed by the Ouster decoder and assembled by
// the shared ScanBatcher into the caller's scans (two, alternating), as the daemon would.
//   build/bin/bench_ouster --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/scan_batcher.hpp"

namespace lidartag::driver::ouster {
namespace {

const std::string kDir = std::string(LIDARTAG_SHARED_DIR) + "/captures/ouster/pcaps/";
constexpr int kPasses = 10;

void add_le(uint8_t* p, size_t n, uint64_t v) {
  const uint64_t sum = read_le(p, n) + v;
  for (size_t i = 0; i < n; ++i) p[i] = static_cast<uint8_t>(sum >> (8 * i));
}

struct Stream {
  SensorInfo info;
  std::vector<std::vector<uint8_t>> packets;
  size_t frames = 0;
};

// kPasses copies of the capture's lidar packets, each pass's frame ids and times moved on.
bool load(const std::string& pcap, const std::string& metadata, Stream& s) {
  if (!std::filesystem::exists(kDir + pcap + ".pcap")) return false;
  s.info = load_metadata(kDir + metadata + ".json");
  const PacketFormat f = PacketFormat::of(s.info);
  PcapSourceOptions o;
  o.data_port = kLidarPort;
  o.position_port = kImuPort;
  PcapSource source(kDir + pcap + ".pcap", o);
  std::vector<std::vector<uint8_t>> one;
  RawPacket raw;
  while (source.next(raw, std::chrono::milliseconds(0)) == ReadStatus::kPacket)
    if (raw.destination_port == kLidarPort)
      one.emplace_back(raw.payload.begin(), raw.payload.end());
  if (one.empty()) return false;
  const PacketHeader first = read_packet_header(one.front().data(), f);
  const PacketHeader last = read_packet_header(one.back().data(), f);
  const uint32_t frames = last.frame_id - first.frame_id + 1;
  const uint64_t t0 = read_column_header(one.front().data(), f, 0).timestamp_ns;
  const uint64_t t1 = read_column_header(one.back().data(), f, 0).timestamp_ns;
  const uint64_t span_ns =
      t1 - t0 + static_cast<uint64_t>(std::llround(s.info.column_period_us() * 1e3 * f.columns));
  for (int pass = 0; pass < kPasses; ++pass) {
    for (std::vector<uint8_t> p : one) {
      const auto k = static_cast<uint64_t>(pass);
      for (int c = 0; c < f.columns; ++c) {
        uint8_t* col = p.data() + f.header_bytes + static_cast<size_t>(c) * f.column_bytes;
        add_le(col, 8, k * span_ns);
        if (f.profile == Profile::kLegacy) add_le(col + 10, 2, k * frames);
      }
      if (f.spec->fusa_header)
        add_le(p.data() + 4, 4, k * frames);
      else if (f.profile != Profile::kLegacy)
        add_le(p.data() + 2, 2, k * frames);
      s.packets.push_back(std::move(p));
    }
  }
  s.frames = kPasses * frames;
  return true;
}

void BM_OusterDecodeAndAssemble(benchmark::State& state, const char* pcap, const char* metadata) {
  Stream s;
  if (!load(pcap, metadata, s)) {
    state.SkipWithError("Ouster captures not found");
    return;
  }
  Decoder decoder(s.info);
  const auto mode = static_cast<uint8_t>(kReturnModeBase + uint8_t(s.info.profile));
  std::array<Scan, 2> scans;
  size_t frames = 0, points = 0;
  for (auto _ : state) {
    ScanBatcher batcher(decoder.layout(), mode, s.info.returns(), BatcherOptions{});
    size_t current = 0;
    PacketColumns parsed;
    for (const auto& p : s.packets) {
      if (decoder.parse(p, parsed) != DecodeStatus::kOk) continue;
      if (batcher.add(parsed, scans[current])) {
        ++frames;
        points += static_cast<size_t>(scans[current].columns * scans[current].rings);
        current ^= 1;
      }
    }
    while (batcher.flush(scans[current])) {
      ++frames;
      current ^= 1;
    }
  }
  if (frames != s.frames * static_cast<size_t>(state.iterations()))
    state.SkipWithError("frames lost in the replayed stream");
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsRate);
  state.counters["cells_per_s"] =
      benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
  // Sensor seconds processed per second of CPU.
  state.counters["x_realtime"] = benchmark::Counter(
      static_cast<double>(frames) / s.info.mode_rate_hz, benchmark::Counter::kIsRate);
}

BENCHMARK_CAPTURE(BM_OusterDecodeAndAssemble, os1_128_rng15, "OS-1-128_v2.3.0_1024x10_lb_n3",
                  "OS-1-128_v2.3.0_1024x10")
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OusterDecodeAndAssemble, os2_128_rng19, "OS-2-128-U1_v2.3.0_1024x10",
                  "OS-2-128-U1_v2.3.0_1024x10")
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OusterDecodeAndAssemble, os0_32_rng19_dual, "OS-0-32-U1_v2.2.0_1024x10",
                  "OS-0-32-U1_v2.2.0_1024x10")
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OusterDecodeAndAssemble, os1_32_legacy, "OS-1-32-G_v2.1.1_1024x10",
                  "OS-1-32-G_v2.1.1_1024x10")
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace lidartag::driver::ouster

BENCHMARK_MAIN();
