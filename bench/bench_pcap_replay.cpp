// pcap replay throughput: PcapSource reading a VLP-16-like capture as fast as possible, and the
// whole CaptureReader pipeline (decode + batch) on the same file. Run: build/bin/bench_pcap_replay
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/driver/velodyne/encoder.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace {

using namespace lidartag::driver;
using namespace lidartag::velodyne;
using namespace std::chrono_literals;

constexpr int kPackets = 7540;  // 10 s of VLP-16 single return

// A capture of kPackets VLP-16 data packets at 600 rpm with every laser returning 10 m.
const std::string& capture() {
  static const std::string path = [] {
    const std::string p = (std::filesystem::temp_directory_path() /
                           ("lidartag_bench_replay_" + std::to_string(::getpid()) + ".pcap"))
                              .string();
    const ModelSpec& spec = model_spec(Model::kVLP16);
    const int columns = spec.columns_per_packet(ReturnMode::kStrongest);
    std::vector<FiringColumn> firing(static_cast<size_t>(columns));
    std::array<uint8_t, kDataPacketSize> packet{};
    PcapWriter writer(p);
    const double deg_per_column = 360.0 * 10.0 * spec.firing_period_us * 1e-6;
    const int64_t t0 = 1'700'000'000'000'000'000;
    for (int i = 0; i < kPackets; ++i) {
      for (int c = 0; c < columns; ++c) {
        const double az = std::fmod((i * columns + c) * deg_per_column, 360.0);
        auto& f = firing[static_cast<size_t>(c)];
        f.azimuth_centideg = static_cast<uint16_t>(az * 100.0);
        f.echo[0].distance.fill(5000);
        f.echo[0].intensity.fill(40);
      }
      const double t_us = i * spec.packet_period_us(ReturnMode::kStrongest);
      encode_data_packet(spec, ReturnMode::kStrongest, firing,
                         static_cast<uint32_t>(std::fmod(t_us, 3.6e9)), packet);
      writer.write_udp(packet, t0 + static_cast<int64_t>(t_us * 1e3), kDefaultDataPort);
    }
    writer.close();
    return p;
  }();
  return path;
}

void BM_PcapSourceRead(benchmark::State& state) {
  const std::string& path = capture();
  for (auto _ : state) {
    PcapSource source(path);
    RawPacket p;
    int64_t n = 0;
    while (source.next(p, 0ms) == ReadStatus::kPacket) ++n;
    benchmark::DoNotOptimize(n);
  }
  state.SetItemsProcessed(state.iterations() * kPackets);
  state.SetBytesProcessed(state.iterations() * kPackets * static_cast<int64_t>(kDataPacketSize));
}
BENCHMARK(BM_PcapSourceRead)->Unit(benchmark::kMillisecond);

void BM_CaptureReaderRotations(benchmark::State& state) {
  const std::string& path = capture();
  for (auto _ : state) {
    CaptureReader reader(path, {});
    int64_t rotations = 0;
    while (reader.next() != nullptr) ++rotations;
    benchmark::DoNotOptimize(rotations);
  }
  state.SetItemsProcessed(state.iterations() * kPackets);
}
BENCHMARK(BM_CaptureReaderRotations)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::filesystem::remove(capture());
  return 0;
}
