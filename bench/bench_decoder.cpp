// Decoding and scan assembly throughput per model and return mode: packets and points per second
// and the multiple of the sensor's real-time rate (sensor seconds processed per second, one core).
//   build/bin/bench_decoder --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <array>
#include <deque>
#include <memory>

#include "../test/driver/synthetic_stream.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"

namespace lidartag::velodyne {
namespace {

struct Fixture {
  const ModelSpec& spec;
  ReturnMode mode;
  std::vector<testing::StreamPacket> packets;
  explicit Fixture(Model m, ReturnMode md) : spec(model_spec(m)), mode(md) {
    // Half a second of packets: several rotations, realistic azimuth steps.
    packets = testing::make_stream(spec, md, static_cast<int>(spec.packet_rate_hz(md) / 2));
  }
};

void report(benchmark::State& state, const Fixture& f, size_t packets, size_t points) {
  state.counters["packets_per_s"] =
      benchmark::Counter(static_cast<double>(packets), benchmark::Counter::kIsRate);
  state.counters["points_per_s"] =
      benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
  // Sensor seconds decoded per second of CPU = multiple of real time.
  state.counters["x_realtime"] = benchmark::Counter(
      static_cast<double>(packets) / f.spec.packet_rate_hz(f.mode), benchmark::Counter::kIsRate);
}

void BM_Decode(benchmark::State& state, Model m, ReturnMode mode) {
  Fixture f(m, mode);
  Decoder decoder(Calibration::builtin(m));
  SensorClock clock;
  DecodedPacket out;
  size_t packets = 0, points = 0;
  for (auto _ : state) {
    for (const auto& p : f.packets) {
      const DecodeStatus st = decoder.decode(p.bytes, clock, p.time_ns, out);
      benchmark::DoNotOptimize(st);
      benchmark::DoNotOptimize(out.x.data());
      points += static_cast<size_t>(out.columns * out.rings * out.returns);
    }
    packets += f.packets.size();
  }
  report(state, f, packets, points);
}

// Packets -> whole rotations in the caller's scans (two, alternating), as the daemon fills the
// slots of its scan buffer: parse() reads the packet's columns, the batcher has the decoder write
// them straight into the scan (reorder window and screening included).
void BM_DecodeAndAssemble(benchmark::State& state, Model m, ReturnMode mode) {
  Fixture f(m, mode);
  Decoder decoder(Calibration::builtin(m));
  SensorClock clock;
  PacketColumns out;
  driver::ScanBatcher batcher = velodyne::make_batcher(f.spec, mode);
  std::array<Scan, 2> scans;
  size_t current = 0;
  size_t packets = 0, points = 0;
  int64_t shift = 0;
  const int64_t span = f.packets.back().time_ns - f.packets.front().time_ns +
                       static_cast<int64_t>(f.spec.packet_period_us(mode) * 1e3);
  for (auto _ : state) {
    for (const auto& p : f.packets) {
      (void)decoder.parse(p.bytes, clock, p.time_ns + shift, out);
      out.stamp_ns = p.time_ns + shift;  // keep time running across iterations
      if (batcher.add(out, scans[current])) current = 1 - current;
      points += static_cast<size_t>(out.columns * out.rings * out.returns);
    }
    shift += span;
    packets += f.packets.size();
  }
  report(state, f, packets, points);
}

#define LIDARTAG_MODEL_BENCH(fn, model, mode)                                 \
  BENCHMARK_CAPTURE(fn, model##_##mode, Model::k##model, ReturnMode::k##mode) \
      ->Unit(benchmark::kMillisecond)

LIDARTAG_MODEL_BENCH(BM_Decode, VLP16, Strongest);
LIDARTAG_MODEL_BENCH(BM_Decode, VLP16, Dual);
LIDARTAG_MODEL_BENCH(BM_Decode, PuckHiRes, Strongest);
LIDARTAG_MODEL_BENCH(BM_Decode, PuckHiRes, Dual);
LIDARTAG_MODEL_BENCH(BM_Decode, VLP32C, Strongest);
LIDARTAG_MODEL_BENCH(BM_Decode, VLP32C, Dual);
LIDARTAG_MODEL_BENCH(BM_Decode, HDL32E, Strongest);
LIDARTAG_MODEL_BENCH(BM_Decode, HDL32E, Dual);
LIDARTAG_MODEL_BENCH(BM_Decode, VLS128, Strongest);
LIDARTAG_MODEL_BENCH(BM_Decode, VLS128, Dual);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, VLP16, Strongest);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, VLP16, Dual);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, PuckHiRes, Strongest);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, PuckHiRes, Dual);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, VLP32C, Strongest);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, VLP32C, Dual);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, HDL32E, Strongest);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, HDL32E, Dual);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, VLS128, Strongest);
LIDARTAG_MODEL_BENCH(BM_DecodeAndAssemble, VLS128, Dual);

}  // namespace
}  // namespace lidartag::velodyne

BENCHMARK_MAIN();
