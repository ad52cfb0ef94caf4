#include "lidartag/driver/velodyne/io/capture_reader.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <thread>
#include <vector>

#include "../driver/synthetic_stream.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"

namespace lidartag::velodyne {
namespace {

using namespace std::chrono_literals;

const std::string kCaptures = LIDARTAG_SHARED_DIR "/captures/";

struct Summary {
  size_t rotations = 0, complete = 0, points = 0;
  uint32_t packets = 0;
};

Summary read_all(CaptureReader& reader) {
  Summary s;
  while (const Scan* scan = reader.next()) {
    ++s.rotations;
    s.complete += scan->complete ? 1 : 0;
    s.points += scan->point_count();
    s.packets += scan->packets;
  }
  return s;
}

// Copies a capture, rewriting the product byte of every data packet.
std::string with_product_byte(const std::string& from, uint8_t product, const std::string& name) {
  const std::string to = (std::filesystem::temp_directory_path() /
                          ("lidartag_capture_reader_" + std::to_string(::getpid()) + name))
                             .string();
  driver::PcapSource source(from);
  driver::PcapWriter writer(to);
  driver::RawPacket p;
  std::vector<uint8_t> payload;
  while (source.next(p, 0ms) == driver::ReadStatus::kPacket) {
    payload.assign(p.payload.begin(), p.payload.end());
    if (payload.size() == kDataPacketSize) payload[kProductIdOffset] = product;
    writer.write_udp(payload, p.receive_time_ns, p.destination_port);
  }
  writer.close();
  return to;
}

TEST(CaptureReader, DecodesEveryPacketOfARealCaptureIntoRotations) {
  const std::string path = kCaptures + "vlp16_mrpt_gps.pcap";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "capture not available: " << path;
  CaptureReader reader(path, {});
  const Summary s = read_all(reader);
  ASSERT_TRUE(reader.model());
  EXPECT_EQ(*reader.model(), Model::kVLP16);
  EXPECT_EQ(reader.return_mode(), ReturnMode::kStrongest);
  EXPECT_TRUE(reader.model_mismatch().empty()) << reader.model_mismatch();
  const CaptureCounts& c = reader.counts();
  EXPECT_EQ(c.data_packets, 293u);
  EXPECT_EQ(c.decoded, 293u);  // the probed packets were decoded too
  EXPECT_EQ(c.position_packets, 57u);
  EXPECT_EQ(c.gprmc_valid, 57u);
  EXPECT_EQ(c.pps, PpsStatus::kLocked);
  EXPECT_EQ(c.last_nmea.rfind("$GPRMC", 0), 0u) << c.last_nmea;
  EXPECT_EQ(reader.clock().source(), TimeSource::kGps);
  EXPECT_GE(s.complete, 2u);
  EXPECT_EQ(s.rotations, reader.batcher_stats().rotations);
  EXPECT_EQ(s.packets, 293u + s.rotations - 1)  // a packet split by a cut counts in both
      << "rotations " << s.rotations;
  EXPECT_GT(s.points, 50000u);
}

TEST(CaptureReader, WrongProductByteIsReportedAndModelOptionDecodesIt) {
  const std::string original = kCaptures + "vlp16_mrpt_gps.pcap";
  if (!std::filesystem::exists(original)) GTEST_SKIP() << "capture not available: " << original;
  const std::string path = with_product_byte(original, 0x21, "hdl.pcap");  // says HDL-32E
  {
    CaptureReader reader(path, {});
    read_all(reader);
    ASSERT_TRUE(reader.model());
    EXPECT_EQ(*reader.model(), Model::kHDL32E);  // the product byte wins without --model
    EXPECT_EQ(reader.model_check().timing_model(), Model::kVLP16);
    EXPECT_NE(reader.model_mismatch().find("vlp16"), std::string::npos) << reader.model_mismatch();
  }
  CaptureReaderOptions options;
  options.model = Model::kVLP16;
  CaptureReader reader(path, options);
  CaptureReader original_reader(original, {});
  const Summary forced = read_all(reader), reference = read_all(original_reader);
  EXPECT_EQ(forced.points, reference.points);
  EXPECT_EQ(forced.complete, reference.complete);
  std::filesystem::remove(path);
}

TEST(CaptureReader, UnknownProductByteFallsBackToTiming) {
  const std::string original = kCaptures + "vlp16_rlu.pcap";
  if (!std::filesystem::exists(original)) GTEST_SKIP() << "capture not available: " << original;
  const std::string path = with_product_byte(original, 0x00, "none.pcap");
  CaptureReader reader(path, {});
  const Summary s = read_all(reader);
  ASSERT_TRUE(reader.model());
  EXPECT_EQ(*reader.model(), Model::kVLP16);
  EXPECT_EQ(reader.counts().decoded, 84u);
  EXPECT_GT(s.points, 0u);
  std::filesystem::remove(path);
}

TEST(CaptureReader, CutAngleMovesTheRotationBoundary) {
  const std::string path = kCaptures + "vlp16_dual_nebula.pcap";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "capture not available: " << path;
  for (double cut : {0.0, 90.0, 180.0, 270.0}) {
    SCOPED_TRACE(cut);
    CaptureReaderOptions options;
    options.batcher.cut_azimuth_deg = cut;
    CaptureReader reader(path, options);
    size_t complete = 0;
    while (const Scan* scan = reader.next()) {
      if (!scan->complete) continue;
      ++complete;
      EXPECT_EQ(scan->returns, 2);
      // A complete rotation starts just after the cut.
      const double from_cut = std::fmod(scan->column_azimuth_deg[0] - cut + 360.0, 360.0);
      EXPECT_LT(from_cut, 1.0) << scan->column_azimuth_deg[0];
    }
    EXPECT_GE(complete, 3u);
    EXPECT_EQ(reader.return_mode(), ReturnMode::kDual);
  }
}

// `n` payloads of `size` bytes to `port`, then the end; notes what the reader watching it had
// counted when the last one went out.
class ScriptedSource final : public driver::PacketSource {
 public:
  ScriptedSource(size_t n, uint16_t port, size_t size) : n_(n), port_(port), size_(size) {}
  driver::ReadStatus next(driver::RawPacket& out, std::chrono::milliseconds) override {
    if (sent_ == n_) return driver::ReadStatus::kEnd;
    if (sent_ + 1 == n_ && reader != nullptr) {
      counted_before_end = reader->counts().data_packets + reader->counts().position_packets;
    }
    payload_.assign(size_, static_cast<uint8_t>(sent_));
    out.payload = payload_;
    out.receive_time_ns = 1'700'000'000'000'000'000 + static_cast<int64_t>(sent_) * 1'000'000;
    out.destination_port = port_;
    ++sent_;
    ++stats_.packets;
    return driver::ReadStatus::kPacket;
  }
  driver::SourceStats stats() const override { return stats_; }
  const CaptureReader* reader = nullptr;
  uint64_t counted_before_end = 0;

 private:
  size_t n_, sent_ = 0;
  uint16_t port_;
  size_t size_;
  std::vector<uint8_t> payload_;
  driver::SourceStats stats_{};
};

TEST(CaptureReader, TrafficThatNeverCompletesTheProbeIsNotHeldWithoutBound) {
  // Position packets only, or datagrams of another size on the data port: no model can be
  // decided, and holding them all back for it would grow without bound on a live source.
  for (const auto& [port, size] : {std::pair<uint16_t, size_t>{kDefaultPositionPort, 512},
                                   std::pair<uint16_t, size_t>{kDefaultDataPort, 1000}}) {
    SCOPED_TRACE(port);
    const size_t n = 20000;
    auto source = std::make_unique<ScriptedSource>(n, port, size);
    ScriptedSource* watch = source.get();
    CaptureReader reader(std::move(source), {});
    watch->reader = &reader;
    EXPECT_EQ(reader.next(), nullptr);
    EXPECT_GE(watch->counted_before_end, n - 1100) << "held back instead of counted";
    const CaptureCounts& c = reader.counts();
    EXPECT_EQ(c.data_packets + c.position_packets, n);
    EXPECT_EQ(c.undecodable, c.data_packets);
    EXPECT_FALSE(reader.model());
  }
}

// A synthetic sensor stream on the data port, then silence (each call waits its timeout) until
// `ended` is set, then the end.
class StreamSource final : public driver::PacketSource {
 public:
  explicit StreamSource(std::vector<testing::StreamPacket> packets)
      : packets_(std::move(packets)) {}
  driver::ReadStatus next(driver::RawPacket& out, std::chrono::milliseconds timeout) override {
    if (sent_ < packets_.size()) {
      const auto& p = packets_[sent_++];
      out.payload = p.bytes;
      out.receive_time_ns = p.time_ns;
      out.destination_port = kDefaultDataPort;
      ++stats_.packets;
      return driver::ReadStatus::kPacket;
    }
    if (ended) return driver::ReadStatus::kEnd;
    std::this_thread::sleep_for(timeout);
    return driver::ReadStatus::kTimeout;
  }
  driver::SourceStats stats() const override { return stats_; }
  bool ended = false;

 private:
  std::vector<testing::StreamPacket> packets_;
  size_t sent_ = 0;
  driver::SourceStats stats_{};
};

TEST(CaptureReader, ReadFillsTheCallersScanAndKeepsTheRotationInProgressAcrossTimeouts) {
  const ModelSpec& spec = model_spec(Model::kVLP16);
  // 10 deg -> the cut at 180, then a third of a turn: one partial rotation, one in progress.
  auto stream = testing::make_stream(spec, ReturnMode::kStrongest, 75);
  CaptureReaderOptions options;
  options.model = Model::kVLP16;
  options.batcher.flush_timeout_s = 60;  // the silence below does not end the rotation
  auto owned = std::make_unique<StreamSource>(stream);
  StreamSource& source = *owned;
  CaptureReader reader(std::move(owned), options);
  Scan a, b;  // empty: sized by the reader
  ASSERT_EQ(reader.read(a, 10s), CaptureReader::ReadResult::kRotation);
  EXPECT_EQ(a.rings, 16);
  EXPECT_FALSE(a.starts_at_cut);
  EXPECT_TRUE(a.ends_at_cut);
  // The rest of the stream goes into b, then the source is silent: b holds it, in progress.
  ASSERT_EQ(reader.read(b, 200ms), CaptureReader::ReadResult::kTimeout);
  const int columns = b.columns;
  EXPECT_EQ(a.columns + columns, 75 * spec.columns_per_packet(ReturnMode::kStrongest));
  EXPECT_EQ(reader.read(b, 10ms), CaptureReader::ReadResult::kTimeout);
  EXPECT_EQ(b.columns, columns);
  // The source ends: the rotation in progress is delivered, then nothing more.
  source.ended = true;
  ASSERT_EQ(reader.read(b, 10s), CaptureReader::ReadResult::kRotation);
  EXPECT_FALSE(b.ends_at_cut);
  EXPECT_EQ(b.columns, columns);
  EXPECT_EQ(reader.read(a, 10ms), CaptureReader::ReadResult::kEnd);
  EXPECT_EQ(reader.read(a, 10ms), CaptureReader::ReadResult::kEnd);
}

TEST(CaptureReader, ASilentSourceDeliversTheRotationInProgress) {
  const ModelSpec& spec = model_spec(Model::kVLP16);
  auto stream = testing::make_stream(spec, ReturnMode::kStrongest, 75);
  CaptureReaderOptions options;
  options.model = Model::kVLP16;
  options.batcher.flush_timeout_s = 0.05;
  CaptureReader reader(std::make_unique<StreamSource>(stream), options);
  Scan a, b;
  ASSERT_EQ(reader.read(a, 10s), CaptureReader::ReadResult::kRotation);
  const auto before = std::chrono::steady_clock::now();
  CaptureReader::ReadResult r = CaptureReader::ReadResult::kTimeout;
  int calls = 0;
  for (; calls < 100 && r == CaptureReader::ReadResult::kTimeout; ++calls) r = reader.read(b, 20ms);
  ASSERT_EQ(r, CaptureReader::ReadResult::kRotation);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 50ms) << calls << " calls";
  EXPECT_FALSE(b.ends_at_cut);
  EXPECT_GT(b.columns, 0);
  EXPECT_EQ(reader.batcher_stats().rotations, 2u);
}

TEST(CaptureReader, ReadReturnsAtTheDeadlineWhilePacketsKeepComing) {
  // A source that never runs dry must not keep read() (and the daemon's receiver loop, which
  // checks for a stop request between calls) from returning.
  const ModelSpec& spec = model_spec(Model::kVLS128);
  auto source =
      std::make_unique<StreamSource>(testing::make_stream(spec, ReturnMode::kStrongest, 200));
  CaptureReaderOptions options;
  options.model = Model::kVLS128;
  CaptureReader reader(std::move(source), options);
  Scan a;
  EXPECT_EQ(reader.read(a, 0ms), CaptureReader::ReadResult::kTimeout);
  EXPECT_EQ(reader.counts().decoded, 1u);  // one packet per call at a zero timeout
  EXPECT_EQ(reader.read(a, 0ms), CaptureReader::ReadResult::kTimeout);
  EXPECT_EQ(reader.counts().decoded, 2u);
}

TEST(CaptureReader, AnotherModelMidStreamIsNoticedAndDecodedAsThatModel) {
  // VLP-16 packets after VLP-32C packets on the same port, the model detected.
  const auto first = testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 1507);
  testing::StreamOptions later;
  later.start_ns = first.back().time_ns + 100'000'000;
  later.start_azimuth_deg = 77.0;
  const auto second =
      testing::make_stream(model_spec(Model::kVLP16), ReturnMode::kStrongest, 754 * 2, later);
  auto stream = first;
  stream.insert(stream.end(), second.begin(), second.end());
  auto owned = std::make_unique<StreamSource>(stream);
  owned->ended = true;
  CaptureReader reader(std::move(owned), {});
  size_t vlp32c_complete = 0, vlp16_complete = 0, after_switch_other = 0;
  bool switched = false;
  while (const Scan* scan = reader.next()) {
    if (scan->rings == 16) switched = true;
    if (switched && scan->rings != 16) ++after_switch_other;
    if (!scan->complete) continue;
    (scan->rings == 32 ? vlp32c_complete : vlp16_complete) += 1;
    EXPECT_EQ(scan->model,
              static_cast<uint8_t>(scan->rings == 32 ? Model::kVLP32C : Model::kVLP16));
  }
  EXPECT_EQ(reader.model(), Model::kVLP16);
  EXPECT_GE(vlp32c_complete, 8u);
  EXPECT_GE(vlp16_complete, 15u);  // 2 s at 600 rpm: the first fraction decoded as a VLP-32C
  EXPECT_EQ(after_switch_other, 0u);
  EXPECT_GT(reader.counts().model_mismatch, 0u);
  EXPECT_NE(reader.model_mismatch().find("vlp32c -> vlp16"), std::string::npos)
      << reader.model_mismatch();
}

// What a VLP-32C stream of 1507 packets (1 s) gave when read alone, and with something before it.
struct Outcome {
  std::optional<Model> model;
  uint64_t decoded = 0;
  size_t complete = 0;
  CaptureCounts counts;
};

Outcome read_stream(std::vector<testing::StreamPacket> stream) {
  auto owned = std::make_unique<StreamSource>(std::move(stream));
  owned->ended = true;
  CaptureReader reader(std::move(owned), {});
  Outcome o;
  while (const Scan* scan = reader.next()) o.complete += scan->complete ? 1 : 0;
  o.model = reader.model();
  o.decoded = reader.counts().decoded;
  o.counts = reader.counts();
  return o;
}

// `n` datagrams of the probe's size before `stream`, 100 us apart, ending 1 ms before it.
std::vector<testing::StreamPacket> after_junk(const std::vector<testing::StreamPacket>& stream,
                                              size_t n, const char* kind) {
  std::vector<testing::StreamPacket> out;
  uint32_t seed = 12345;
  for (size_t i = 0; i < n; ++i) {
    testing::StreamPacket p{
        std::vector<uint8_t>(kDataPacketSize, 0),
        stream.front().time_ns - 1'000'000 - static_cast<int64_t>(n - i) * 100'000};
    if (std::string(kind) == "vlp16 byte") p.bytes[kProductIdOffset] = 0x22;
    if (std::string(kind) == "random") {
      for (auto& b : p.bytes) {
        seed = seed * 1664525u + 1013904223u;
        b = static_cast<uint8_t>(seed >> 24);
      }
    }
    out.push_back(std::move(p));
  }
  out.insert(out.end(), stream.begin(), stream.end());
  return out;
}

TEST(CaptureReader, JunkBeforeTheSensorDecidesNothing) {
  // Zero-filled datagrams of the probe's size once made the probe decide "unknown" for good
  // (32 of them: every later packet undecodable), one with a VLP-16 product byte locked the
  // reader to VLP-16. Junk is not laid out as data packets: it neither votes nor times.
  const auto sensor =
      testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 1507);
  const Outcome alone = read_stream(sensor);
  ASSERT_EQ(alone.model, Model::kVLP32C);
  ASSERT_EQ(alone.decoded, 1507u);
  for (const char* kind : {"zeros", "vlp16 byte", "random"}) {
    for (const size_t n :
         {size_t{1}, size_t{31}, size_t{32}, size_t{33}, size_t{200}, size_t{3000}}) {
      SCOPED_TRACE(std::string(kind) + " x " + std::to_string(n));
      const Outcome o = read_stream(after_junk(sensor, n, kind));
      EXPECT_EQ(o.model, Model::kVLP32C);
      EXPECT_EQ(o.decoded, 1507u);
      EXPECT_EQ(o.complete, alone.complete);
      EXPECT_EQ(o.counts.data_packets, 1507u + n);
      uint64_t errors = 0;
      for (uint64_t e : o.counts.decode_errors) errors += e;
      EXPECT_EQ(errors + o.counts.undecodable, n);  // every junk datagram counted, once
    }
  }
}

TEST(CaptureReader, APacketLaidOutRightButWithAnotherProductByteDoesNotDecide) {
  // A valid-looking VLP-16 packet (a spoof, or another sensor's one packet) before a VLP-32C:
  // the product byte is the one most packets carry.
  auto sensor = testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 1507);
  auto spoof = testing::make_stream(model_spec(Model::kVLP16), ReturnMode::kStrongest, 3);
  for (auto& p : spoof) p.time_ns = sensor.front().time_ns - 5'000'000 + p.time_ns % 1'000'000;
  spoof.insert(spoof.end(), sensor.begin(), sensor.end());
  const Outcome o = read_stream(spoof);
  EXPECT_EQ(o.model, Model::kVLP32C);
  EXPECT_GE(o.decoded, 1507u);
}

TEST(CaptureReader, AProbeNoModelFitsStartsOverOnTheNextPackets) {
  // 100 packets laid out as data packets whose byte names no model and whose timing fits none
  // (3 ms apart), then a VLP-32C: the first probe fails, the next one finds the sensor.
  const auto sensor =
      testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 1507);
  auto odd = testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 100);
  for (size_t i = 0; i < odd.size(); ++i) {
    auto& p = odd[i];
    p.bytes[kProductIdOffset] = 0x00;
    const auto usec = static_cast<uint32_t>(i * 3000);
    std::memcpy(p.bytes.data() + kTimestampOffset, &usec, sizeof usec);
    p.time_ns = sensor.front().time_ns - 400'000'000 + static_cast<int64_t>(i) * 3'000'000;
  }
  odd.insert(odd.end(), sensor.begin(), sensor.end());
  const Outcome o = read_stream(odd);
  EXPECT_EQ(o.model, Model::kVLP32C);
  EXPECT_GE(o.counts.failed_probes, 1u);
  EXPECT_GE(o.decoded, 1507u);
  EXPECT_GE(o.complete, 8u);
}

TEST(CaptureReader, AWrongFirstDecisionChangesWithEvidence) {
  // The first 40 packets carry a VLP-16 product byte in a VLP-32C's layout and timing (the byte
  // decides, as for real VLP-16s with an HDL-32E byte); then the sensor's own packets say
  // VLP-32C in byte and timing. The decision follows the evidence, once, with a reason.
  auto stream = testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 3014);
  for (size_t i = 0; i < 40; ++i) stream[i].bytes[kProductIdOffset] = 0x22;
  auto owned = std::make_unique<StreamSource>(stream);
  owned->ended = true;
  CaptureReader reader(std::move(owned), {});
  size_t complete32 = 0;
  while (const Scan* scan = reader.next())
    complete32 += (scan->complete && scan->rings == 32) ? 1 : 0;
  EXPECT_EQ(reader.model(), Model::kVLP32C);
  EXPECT_EQ(reader.counts().model_changes, 1u);
  EXPECT_NE(reader.model_mismatch().find("vlp16 -> vlp32c"), std::string::npos)
      << reader.model_mismatch();
  EXPECT_GE(complete32, 15u);
}

TEST(CaptureReader, CountersGoOnAcrossAModelChange) {
  // A VLP-16 stream with packets lost, then a VLP-32C: the batcher of the new model starts from
  // zero, the reader's counts must not (a status once saw missing packets fall 53 -> 0).
  auto first = testing::make_stream(model_spec(Model::kVLP16), ReturnMode::kStrongest, 2262);
  std::vector<testing::StreamPacket> lossy;
  for (size_t i = 0; i < first.size(); ++i)
    if (i % 10 != 5) lossy.push_back(first[i]);
  testing::StreamOptions later;
  later.start_ns = first.back().time_ns + 100'000'000;
  const auto second =
      testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 3014, later);
  lossy.insert(lossy.end(), second.begin(), second.end());
  auto owned = std::make_unique<StreamSource>(lossy);
  owned->ended = true;
  CaptureReader reader(std::move(owned), {});
  uint64_t max_missing = 0, max_rotations = 0;
  bool fell = false;
  std::vector<uint64_t> sequences;
  while (const Scan* scan = reader.next()) {
    sequences.push_back(scan->sequence);
    const driver::BatcherStats b = reader.batcher_stats();
    fell = fell || b.missing_packets < max_missing || b.rotations < max_rotations;
    max_missing = std::max(max_missing, b.missing_packets);
    max_rotations = std::max(max_rotations, b.rotations);
  }
  EXPECT_EQ(reader.model(), Model::kVLP32C);
  EXPECT_FALSE(fell);
  EXPECT_GE(reader.batcher_stats().missing_packets, 200u);  // the VLP-16's 226 lost packets
  // Rotations are numbered on across the change: dump names its files by these numbers, and the
  // daemon's consumers see them in order.
  ASSERT_GE(sequences.size(), 20u);
  for (size_t i = 1; i < sequences.size(); ++i)
    EXPECT_EQ(sequences[i], sequences[i - 1] + 1) << "rotation " << i;
}

TEST(CaptureReader, AConfiguredModelThePacketsContradictIsReported) {
  const auto stream = testing::make_stream(model_spec(Model::kVLP16), ReturnMode::kStrongest, 754);
  auto owned = std::make_unique<StreamSource>(stream);
  owned->ended = true;
  CaptureReaderOptions options;
  options.model = Model::kVLP32C;  // wrong
  CaptureReader reader(std::move(owned), options);
  size_t rotations = 0;
  while (const Scan* scan = reader.next()) {
    ++rotations;
    EXPECT_EQ(scan->rings, 32);  // decoded as told
  }
  EXPECT_GT(rotations, 0u);
  EXPECT_EQ(reader.model(), Model::kVLP32C);
  EXPECT_GE(reader.counts().model_mismatch, 600u);
  EXPECT_NE(reader.model_mismatch().find("configured model vlp32c"), std::string::npos)
      << reader.model_mismatch();
  EXPECT_NE(reader.model_mismatch().find("fit vlp16"), std::string::npos);
}

TEST(CaptureReader, TheRightModelIsNotReported) {
  for (Model m : all_models()) {
    const auto stream = testing::make_stream(model_spec(m), ReturnMode::kStrongest, 1000);
    for (bool configured : {false, true}) {
      auto owned = std::make_unique<StreamSource>(stream);
      owned->ended = true;
      CaptureReaderOptions options;
      if (configured) options.model = m;
      CaptureReader reader(std::move(owned), options);
      while (reader.next() != nullptr) {
      }
      EXPECT_EQ(reader.counts().model_mismatch, 0u) << model_spec(m).name;
      EXPECT_EQ(reader.model_mismatch(), "") << model_spec(m).name;
      EXPECT_EQ(reader.model(), m);
    }
  }
}

TEST(CaptureReader, CalibrationFileErrorsSurfaceAtSetup) {
  const std::string path = kCaptures + "vlp16_rlu.pcap";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "capture not available: " << path;
  CaptureReaderOptions options;
  options.model = Model::kVLP16;
  options.calibration_file = "/nonexistent-lidartag/VLP16.yaml";
  EXPECT_THROW(CaptureReader reader(path, options), CalibrationError);
  EXPECT_THROW(CaptureReader reader("/nonexistent-lidartag/x.pcap", {}), driver::IoError);
}

}  // namespace
}  // namespace lidartag::velodyne
