// Reading the same Velodyne packets from a ROS 2 bag (sqlite3, CDR VelodyneScan) and from the pcap
// they were recorded beside (../shared/captures, bags/README.md): the packet sources alone, and the
// whole capture reader (decode + batch). Run: build/bin/bench_bag_read (one thread); the ratio of
// the *Bag* to the *Pcap* times per pair is what docs/bags.md reports.
#include <benchmark/benchmark.h>

#include <array>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "lidartag/driver/bag/bag_packet_source.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace {

using namespace lidartag;
using namespace std::chrono_literals;

struct Pair {
  const char* bag;
  const char* pcap;
};
constexpr std::array<Pair, 3> kPairs = {{{"bags/rosbag2/vlp16_dual", "vlp16_dual_nebula.pcap"},
                                         {"bags/rosbag2/vlp32c", "vlp32c_nebula_fov.pcap"},
                                         {"bags/rosbag2/vls128", "vls128_nebula.pcap"}}};

std::string path(const char* name) {
  return std::string(LIDARTAG_SHARED_DIR) + "/captures/" + name;
}

bool available(benchmark::State& state, const Pair& p) {
  if (std::filesystem::exists(path(p.bag)) && std::filesystem::exists(path(p.pcap))) return true;
  state.SkipWithError("../shared/captures/bags not available");
  return false;
}

template <class Source>
void drain(benchmark::State& state, const std::function<std::unique_ptr<Source>()>& open) {
  uint64_t packets = 0;
  for (auto _ : state) {
    const auto source = open();
    driver::RawPacket packet;
    while (source->next(packet, 0ms) == driver::ReadStatus::kPacket) {
      benchmark::DoNotOptimize(packet.payload.data());
      ++packets;
    }
  }
  state.SetItemsProcessed(static_cast<int64_t>(packets));
}

void BM_PcapPackets(benchmark::State& state) {
  const Pair& p = kPairs[static_cast<size_t>(state.range(0))];
  if (!available(state, p)) return;
  drain<driver::PcapSource>(state,
                            [&] { return std::make_unique<driver::PcapSource>(path(p.pcap)); });
}

void BM_BagPackets(benchmark::State& state) {
  const Pair& p = kPairs[static_cast<size_t>(state.range(0))];
  if (!available(state, p)) return;
  drain<driver::bag::BagPacketSource>(
      state, [&] { return std::make_unique<driver::bag::BagPacketSource>(path(p.bag)); });
}

void rotations(benchmark::State& state, const char* file) {
  uint64_t n = 0;
  for (auto _ : state) {
    velodyne::CaptureReader reader(path(file), velodyne::CaptureReaderOptions{});
    while (const Scan* s = reader.next()) {
      benchmark::DoNotOptimize(s->x.data());
      ++n;
    }
  }
  state.SetItemsProcessed(static_cast<int64_t>(n));
}

void BM_PcapRotations(benchmark::State& state) {
  const Pair& p = kPairs[static_cast<size_t>(state.range(0))];
  if (available(state, p)) rotations(state, p.pcap);
}

void BM_BagRotations(benchmark::State& state) {
  const Pair& p = kPairs[static_cast<size_t>(state.range(0))];
  if (available(state, p)) rotations(state, p.bag);
}

BENCHMARK(BM_PcapPackets)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BagPackets)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PcapRotations)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BagRotations)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
