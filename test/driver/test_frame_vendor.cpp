// The assembly behind its seam with a vendor of its own: a synthetic frame-numbered sensor (like
// an Ouster: each packet says which frame, i.e. rotation, its columns belong to) whose decoder
// writes known points. Linked against the shared assembly alone: no Velodyne code is involved.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <deque>
#include <memory>
#include <new>
#include <vector>

#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/scan_batcher.hpp"

namespace lidartag::driver {
namespace {

// The test sensor: 8 beams, 128 columns per frame, a frame every 100 ms (600 rpm), 4 columns per
// packet. Frames start at azimuth 90 deg, so that a cut at the default 180 deg would split them:
// rotations that hold whole frames were cut by the frame id.
constexpr int kRings = 8;
constexpr int kFrameColumns = 128;
constexpr int kPacketColumns = 4;
constexpr int kPacketsPerFrame = kFrameColumns / kPacketColumns;
constexpr double kColumnPeriodUs = 781.25;
constexpr double kFrameStartDeg = 90.0;
// Payload: per column its measurement id (uint16), then per ring a range in mm (uint16).
constexpr size_t kColumnBytes = 2 + 2 * kRings;
constexpr size_t kPayloadBytes = kPacketColumns * kColumnBytes;

uint16_t range_mm(int measurement, int ring) {
  return static_cast<uint16_t>(1000 + measurement * 10 + ring);
}

// The vendor's parsed packet: the assembly's header plus what its decoder needs.
struct FramePacket : ColumnPacket {
  int first_measurement = 0;  // the measurement id of column 0 (read back by write_batch)
};

class FrameDecoder final : public ColumnDecoder {
 public:
  FrameDecoder() {
    for (int r = 0; r < kRings; ++r) laser_of_ring_[static_cast<size_t>(r)] = uint8_t(7 - r);
  }

  static SensorLayout layout() {
    SensorLayout l;
    l.model = 42;
    l.rings = kRings;
    l.column_period_us = kColumnPeriodUs;
    l.packet_columns_single = l.packet_columns_dual = kPacketColumns;
    l.max_payload_bytes = kPayloadBytes;
    l.delimiter = RotationDelimiter::kFrameId;
    l.frame_id_bits = 16;
    l.frame_columns = kFrameColumns;
    return l;
  }

  // The packet's header from its bytes (a real vendor reads them from the wire).
  void parse(const std::vector<uint8_t>& bytes, uint32_t frame_id, int64_t stamp_ns,
             FramePacket& out) const {
    out.columns = kPacketColumns;
    out.rings = kRings;
    out.returns = 1;
    out.return_mode = 7;
    out.has_frame_id = true;
    out.frame_id = frame_id;
    out.stamp_ns = stamp_ns;
    out.laser_of_ring = laser_of_ring_.data();
    uint16_t first = 0;
    std::memcpy(&first, bytes.data(), 2);
    out.first_measurement = first;
    for (int c = 0; c < kPacketColumns; ++c) {
      const auto uc = static_cast<size_t>(c);
      out.column_azimuth_deg[uc] = static_cast<float>(
          std::fmod(kFrameStartDeg + (first + c) * 360.0 / kFrameColumns, 360.0));
      out.column_time_us[uc] = c * kColumnPeriodUs;
      out.rate_deg[uc] = static_cast<float>(360.0 / (kFrameColumns * kColumnPeriodUs));
    }
    out.decoder = this;
    out.payload = bytes.data();
    out.payload_size = bytes.size();
  }

  ColumnPacket* copy_packet(const ColumnPacket& packet,
                            std::span<std::byte> storage) const override {
    ++copies;
    return new (storage.data()) FramePacket(static_cast<const FramePacket&>(packet));
  }

  // x: the range, y: the measurement id (from the derived packet: proves the held copies are
  // whole), z: the ring, intensity: the laser.
  void write_batch(const ColumnBatch& batch, const PointSink& sink) const override {
    ++batches;
    columns_written += batch.columns;
    size_t k = 0;
    for (int i = 0; i < batch.runs; ++i) {
      const ColumnBatch::Run& run = batch.run[static_cast<size_t>(i)];
      const auto& pk = static_cast<const FramePacket&>(*run.packet);
      for (int c = run.first; c < run.first + run.count; ++c, ++k) {
        const uint8_t* column = pk.payload + static_cast<size_t>(c) * kColumnBytes;
        for (int r = 0; r < kRings; ++r) {
          const size_t cell = static_cast<size_t>(r) * sink.ring_stride + k;
          uint16_t mm = 0;
          std::memcpy(&mm, column + 2 + 2 * r, 2);
          sink.x[cell] = sink.range[cell] = static_cast<float>(mm) * 1e-3f;
          sink.y[cell] = static_cast<float>(pk.first_measurement + c);
          sink.z[cell] = static_cast<float>(r);
          sink.azimuth_deg[cell] = pk.column_azimuth_deg[static_cast<size_t>(c)];
          sink.time[cell] =
              run.time_offset +
              static_cast<float>(pk.column_time_us[static_cast<size_t>(c)]) * sink.time_scale;
          sink.intensity[cell] = laser_of_ring_[static_cast<size_t>(r)];
          sink.return_type[cell] = ReturnType::kStrongest;
        }
      }
    }
  }

  mutable int copies = 0, batches = 0, columns_written = 0;

 private:
  std::array<uint8_t, kRings> laser_of_ring_{};
};

// One packet on the wire: its bytes, frame id and time.
struct WirePacket {
  std::vector<uint8_t> bytes;
  uint32_t frame_id;
  int64_t stamp_ns;
};

// Packets of frames `first` .. `first + count - 1`, back to back in time (frame ids modulo 2^16).
std::vector<WirePacket> frames(uint32_t first, int count, int64_t start_ns = 1'000'000'000) {
  std::vector<WirePacket> out;
  for (int f = 0; f < count; ++f) {
    for (int p = 0; p < kPacketsPerFrame; ++p) {
      WirePacket w;
      w.frame_id = (first + static_cast<uint32_t>(f)) & 0xFFFFu;
      const int column0 = f * kFrameColumns + p * kPacketColumns;
      w.stamp_ns = start_ns + std::llround(column0 * kColumnPeriodUs * 1e3);
      w.bytes.resize(kPayloadBytes);
      for (int c = 0; c < kPacketColumns; ++c) {
        const int m = p * kPacketColumns + c;
        uint8_t* column = w.bytes.data() + static_cast<size_t>(c) * kColumnBytes;
        const auto id = static_cast<uint16_t>(m);
        std::memcpy(column, &id, 2);
        for (int r = 0; r < kRings; ++r) {
          const uint16_t mm = range_mm(m, r);
          std::memcpy(column + 2 + 2 * r, &mm, 2);
        }
      }
      out.push_back(std::move(w));
    }
  }
  return out;
}

// The packets through a batcher; every rotation delivered, in a scan of its own.
struct Stream {
  FrameDecoder decoder;
  SensorLayout layout = FrameDecoder::layout();
  ScanBatcher batcher{layout, 7, 1, BatcherOptions{}};
  std::deque<Scan> scans{1};
  std::vector<Scan*> done;

  void feed(const std::vector<WirePacket>& packets) {
    FramePacket pk;
    for (const WirePacket& w : packets) {
      decoder.parse(w.bytes, w.frame_id, w.stamp_ns, pk);
      if (batcher.add(pk, scans.back())) next();
    }
  }
  void end() {
    while (batcher.flush(scans.back())) next();
  }
  void next() {
    done.push_back(&scans.back());
    scans.emplace_back();
  }
};

// Every column of a rotation that holds frame columns [from, from + n): the decoder's points, in
// place.
void expect_columns(const Scan& s, int from, int n) {
  ASSERT_EQ(s.columns, n);
  ASSERT_EQ(s.rings, kRings);
  for (int c = 0; c < n; ++c) {
    const int m = from + c;
    for (int r = 0; r < kRings; ++r) {
      const size_t i = s.at(0, r, c);
      ASSERT_FLOAT_EQ(s.range[i], range_mm(m, r) * 1e-3f) << "column " << c << " ring " << r;
      ASSERT_EQ(s.y[i], static_cast<float>(m));
      ASSERT_EQ(s.z[i], static_cast<float>(r));
    }
  }
  for (int r = 0; r < kRings; ++r) EXPECT_EQ(s.laser_id[static_cast<size_t>(r)], 7 - r);
}

TEST(FrameIdDelimiter, RotationsAreTheSensorsFramesWhateverTheCutAzimuth) {
  Stream run;
  // The stream joins frame 10 a quarter in: the first rotation is partial.
  auto packets = frames(10, 5);
  packets.erase(packets.begin(), packets.begin() + kPacketsPerFrame / 4);
  run.feed(packets);
  run.end();
  ASSERT_EQ(run.done.size(), 5u);
  expect_columns(*run.done[0], kFrameColumns / 4, kFrameColumns * 3 / 4);
  EXPECT_FALSE(run.done[0]->starts_at_cut);
  EXPECT_TRUE(run.done[0]->ends_at_cut);
  for (int i = 1; i < 4; ++i) {
    const Scan& s = *run.done[static_cast<size_t>(i)];
    expect_columns(s, 0, kFrameColumns);
    EXPECT_TRUE(s.complete) << i;
    EXPECT_EQ(s.packets, static_cast<uint32_t>(kPacketsPerFrame));
    EXPECT_EQ(s.model, 42);
    EXPECT_EQ(s.return_mode, 7);
    EXPECT_NEAR(s.rpm, 600.0f, 0.1f);
    // Whole frames start at 90 deg: not cut at 180.
    EXPECT_FLOAT_EQ(s.column_azimuth_deg[0], static_cast<float>(kFrameStartDeg));
    EXPECT_NEAR(s.column_time_s[kFrameColumns - 1], (kFrameColumns - 1) * kColumnPeriodUs * 1e-6,
                1e-9);
  }
  // The last frame is complete in its columns, but the stream ended: not at its end for sure.
  expect_columns(*run.done[4], 0, kFrameColumns);
  EXPECT_FALSE(run.done[4]->ends_at_cut);
  const BatcherStats& st = run.batcher.stats();
  EXPECT_EQ(st.rotations, 5u);
  EXPECT_EQ(st.complete, 3u);
  EXPECT_EQ(st.missing_packets + st.azimuth_jumps + st.inconsistent + st.duplicates, 0u);
  // The decoder is called per batch of columns, not per column or packet.
  EXPECT_GE(run.decoder.columns_written, kFrameColumns * 4);
  EXPECT_LE(run.decoder.batches * 16, run.decoder.columns_written);
}

TEST(FrameIdDelimiter, PacketsLostInsideAFrameAreCountedInIt) {
  Stream run;
  auto packets = frames(10, 4);
  // Frame 12 (the third) loses its packets 5 and 6.
  const auto lost = packets.begin() + 2 * kPacketsPerFrame + 5;
  packets.erase(lost, lost + 2);
  run.feed(packets);
  run.end();
  ASSERT_EQ(run.done.size(), 4u);
  EXPECT_TRUE(run.done[1]->complete);
  const Scan& s = *run.done[2];
  EXPECT_EQ(s.missing_packets, 2u);
  EXPECT_FALSE(s.complete);
  EXPECT_TRUE(s.starts_at_cut);
  EXPECT_TRUE(s.ends_at_cut);
  EXPECT_EQ(s.columns, kFrameColumns - 2 * kPacketColumns);
  EXPECT_EQ(run.batcher.stats().missing_packets, 2u);
  EXPECT_EQ(run.done[3]->missing_packets, 0u);
}

TEST(FrameIdDelimiter, AWholeFrameLostIsLossInBothRotationsAroundIt) {
  Stream run;
  auto packets = frames(10, 4);
  // Frame 12 never arrives: its azimuths repeat frame 11's, only the frame id tells.
  packets.erase(packets.begin() + 2 * kPacketsPerFrame, packets.begin() + 3 * kPacketsPerFrame);
  run.feed(packets);
  run.end();
  ASSERT_EQ(run.done.size(), 3u);
  EXPECT_EQ(run.batcher.stats().missing_packets, static_cast<uint64_t>(kPacketsPerFrame));
  EXPECT_EQ(run.done[1]->missing_packets, static_cast<uint32_t>(kPacketsPerFrame));
  EXPECT_EQ(run.done[2]->missing_packets, static_cast<uint32_t>(kPacketsPerFrame));
  EXPECT_FALSE(run.done[1]->complete);
  expect_columns(*run.done[2], 0, kFrameColumns);
  EXPECT_EQ(run.batcher.stats().fov_gaps, 0u);
}

TEST(FrameIdDelimiter, AFrameIdThatGoesBackIsAJumpAndOneThatWrapsIsNot) {
  Stream run;
  // Frames 65534, 65535, 0, 1 (the 16-bit counter wraps), then the counter restarts at 0 while
  // time and azimuth go on (the sensor was reconfigured).
  auto packets = frames(65534, 4);
  auto restart =
      frames(0, 2, packets.back().stamp_ns + std::llround(kPacketColumns * kColumnPeriodUs * 1e3));
  packets.insert(packets.end(), restart.begin(), restart.end());
  run.feed(packets);
  run.end();
  ASSERT_EQ(run.done.size(), 6u);
  EXPECT_TRUE(run.done[1]->complete);  // 65535
  EXPECT_TRUE(run.done[2]->complete);  // 0: the wrap is the next frame
  // Frame 1 ends where the counter went back: at a jump, not at a frame's end.
  EXPECT_FALSE(run.done[3]->ends_at_cut);
  EXPECT_EQ(run.done[3]->azimuth_jumps, 1u);
  EXPECT_FALSE(run.done[3]->complete);
  expect_columns(*run.done[3], 0, kFrameColumns);
  // The new count's first frame did not start at a frame boundary the batcher saw.
  EXPECT_FALSE(run.done[4]->starts_at_cut);
  EXPECT_TRUE(run.done[4]->ends_at_cut);
  EXPECT_EQ(run.batcher.stats().azimuth_jumps, 1u);
  EXPECT_EQ(run.batcher.stats().missing_packets, 0u);
}

TEST(FrameIdDelimiter, HeldPacketsAreCopiedByTheirDecoderAsTheirOwnType) {
  Stream run;
  run.feed(frames(10, 2));
  run.end();
  // Every packet went through the reorder window: copied by its decoder, as its own type (the
  // measurement ids written come from the copies: expect_columns checked them above too).
  EXPECT_EQ(run.decoder.copies, 2 * kPacketsPerFrame);
  expect_columns(*run.done[1], 0, kFrameColumns);
}

}  // namespace
}  // namespace lidartag::driver
