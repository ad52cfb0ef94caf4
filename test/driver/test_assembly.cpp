// The parts of scan assembly, each alone: ReorderWindow, StreamScreen, RotationAssembler (with its
// ColumnWriter). ScanBatcher, which joins them, is tested in test_scan_batcher.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "lidartag/driver/assembly/reorder_window.hpp"
#include "lidartag/driver/assembly/rotation_assembler.hpp"
#include "lidartag/driver/assembly/stream_screen.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "synthetic_stream.hpp"

namespace lidartag::velodyne {
namespace {

// A VLP-16 stream at 600 rpm, parsed packet by packet (their bytes stay in `stream`).
struct Parsed {
  const ModelSpec& spec = model_spec(Model::kVLP16);
  const driver::SensorLayout layout = sensor_layout(spec);
  Decoder decoder{Calibration::builtin(Model::kVLP16)};
  SensorClock clock;
  std::vector<testing::StreamPacket> stream;
  std::vector<PacketColumns> packets;
  const PacketColumns& operator[](int i) const { return packets[static_cast<size_t>(i)]; }
  explicit Parsed(int count, testing::StreamOptions o = {}) {
    stream = testing::make_stream(spec, ReturnMode::kStrongest, count, o);
    packets.resize(stream.size());
    for (size_t i = 0; i < stream.size(); ++i) {
      EXPECT_EQ(decoder.parse(stream[i].bytes, clock, stream[i].time_ns, packets[i]),
                DecodeStatus::kOk);
    }
  }
};

TEST(ReorderWindow, KeepsPacketsSortedByTimeAndSaysWhichCameLate) {
  Parsed p(6);
  driver::ReorderWindow w(p.layout.max_payload_bytes);
  bool reordered = true;
  ASSERT_TRUE(w.insert(p[0], reordered));
  EXPECT_FALSE(reordered);
  ASSERT_TRUE(w.insert(p[2], reordered));
  EXPECT_FALSE(reordered);
  ASSERT_TRUE(w.insert(p[1], reordered));  // arrived after a later one
  EXPECT_TRUE(reordered);
  ASSERT_EQ(w.size(), 3);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(w.oldest(i).stamp_ns, p[i].stamp_ns);
  // The held copy does not point at the caller's bytes.
  EXPECT_NE(w.oldest(0).payload, p[0].payload);
  EXPECT_TRUE(w.holds(p[1].stamp_ns, p[1].column_azimuth_deg[0]));
  EXPECT_FALSE(w.holds(p[1].stamp_ns, p[1].column_azimuth_deg[0] + 1.0f));
  EXPECT_TRUE(w.overlaps(p[1].stamp_ns + 1000, p[1].stamp_ns + 2000));
  EXPECT_FALSE(w.overlaps(p[5].stamp_ns, p[5].stamp_ns + 10));

  const int slot = w.pop_oldest();
  EXPECT_EQ(w.packet(slot).stamp_ns, p[0].stamp_ns);
  EXPECT_EQ(w.size(), 2);
  w.remove(p[2].stamp_ns);
  ASSERT_EQ(w.size(), 1);
  EXPECT_EQ(w.oldest(0).stamp_ns, p[1].stamp_ns);
}

TEST(ReorderWindow, AFullSetOfSlotsRefusesAndAFreedSlotIsUsedAgain) {
  Parsed p(driver::ReorderWindow::kSlots + 1);
  driver::ReorderWindow w(p.layout.max_payload_bytes);
  bool reordered = false;
  for (int i = 0; i < driver::ReorderWindow::kSlots; ++i) ASSERT_TRUE(w.insert(p[i], reordered));
  EXPECT_FALSE(w.insert(p[driver::ReorderWindow::kSlots], reordered));
  w.free(w.pop_oldest());
  EXPECT_TRUE(w.insert(p[driver::ReorderWindow::kSlots], reordered));
}

TEST(StreamScreen, DuplicatesLatePacketsStraysAndANewStream) {
  Parsed p(12);
  driver::StreamScreen screen(p.layout, 0.25);
  driver::ReorderWindow w(p.layout.max_payload_bytes);
  bool reordered = false;
  using V = driver::StreamScreen::Verdict;
  EXPECT_EQ(screen.screen(p[0], w, std::nullopt), V::kAccept);  // no stream yet
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(screen.screen(p[i], w, std::nullopt), V::kAccept) << i;
    w.insert(p[i], reordered);
    screen.taken(p[i]);
  }
  EXPECT_EQ(screen.screen(p[2], w, std::nullopt), V::kDuplicate);  // in the window
  const int slot = w.pop_oldest();
  screen.released(w.packet(slot));
  EXPECT_EQ(screen.screen(p[0], w, std::nullopt), V::kDuplicate);  // released lately
  // Older than the newest column written into the rotation: too late to be put in place.
  PacketColumns late = p[1];
  late.column_azimuth_deg[0] += 0.01f;  // not the same packet
  EXPECT_EQ(screen.screen(late, w, p[2].stamp_ns), V::kTooLate);
  // A packet where the sensor did not point at that time: suspect, held as a candidate.
  PacketColumns stray = p[4];
  for (auto& a : stray.column_azimuth_deg) a = static_cast<float>(std::fmod(a + 90.0f, 360.0f));
  EXPECT_EQ(screen.screen(stray, w, std::nullopt), V::kSuspect);
  EXPECT_EQ(screen.add_candidate(stray), driver::StreamScreen::Candidate::kHeld);
  // The stream goes on: its next packet fits, the candidate is forgotten by the caller.
  EXPECT_EQ(screen.screen(p[4], w, std::nullopt), V::kAccept);
  EXPECT_EQ(screen.clear_candidates(), 1);
  // Candidates that continue each other make a new stream's three packets.
  Parsed other(6, {.start_azimuth_deg = 270.0, .start_ns = p[0].stamp_ns + 5'000'000'000LL});
  for (int i = 0; i < driver::StreamScreen::kNewStreamPackets; ++i) {
    EXPECT_EQ(screen.screen(other[i], w, std::nullopt), V::kSuspect);
    EXPECT_EQ(screen.add_candidate(other[i]), driver::StreamScreen::Candidate::kHeld);
  }
  EXPECT_EQ(screen.candidates(), driver::StreamScreen::kNewStreamPackets);
  EXPECT_EQ(screen.candidate(0).stamp_ns, other[0].stamp_ns);
  // A fourth is not held (the caller adopts the three first).
  EXPECT_EQ(screen.add_candidate(other[3]), driver::StreamScreen::Candidate::kDropped);
}

TEST(StreamScreen, AStrayPacketThatFittedIsRecognisedByTheNextOne) {
  Parsed p(100);
  driver::StreamScreen screen(p.layout, 0.25);
  driver::ReorderWindow w(p.layout.max_payload_bytes);
  bool reordered = false;
  for (int i = 0; i < 3; ++i) {
    w.insert(p[i], reordered);
    screen.taken(p[i]);
  }
  // A stray packet 106 ms ahead that happens to point where the stream would then: taken.
  const PacketColumns& stray = p[80];
  ASSERT_EQ(screen.screen(stray, w, std::nullopt), driver::StreamScreen::Verdict::kAccept);
  w.insert(stray, reordered);
  screen.taken(stray);
  // The stream's next packet fits the packet before the stray one, not the stray one (it is 77
  // packet periods before it: no reordered packet is that late).
  EXPECT_EQ(screen.screen(p[3], w, std::nullopt),
            driver::StreamScreen::Verdict::kAcceptHeadWasStray);
  w.remove(screen.head().stamp_ns);
  screen.drop_head();
  EXPECT_EQ(screen.head().stamp_ns, p[2].stamp_ns);
  EXPECT_EQ(w.size(), 3);
}

// Packets straight into the assembler (no window): every rotation it ends, and its counts.
struct Assembly {
  driver::ReorderWindow held;
  driver::BatcherStats stats;
  driver::RotationAssembler assembler;
  std::vector<Scan> scans;
  explicit Assembly(const driver::SensorLayout& layout, driver::BatcherOptions o = {})
      : held(layout.max_payload_bytes),
        assembler(layout, static_cast<uint8_t>(ReturnMode::kStrongest), 1, o, held, stats) {
    scans.emplace_back();
  }
  void add(const PacketColumns& pk) {
    if (!assembler.add_packet(pk, -1, scans.back(), true)) return;
    scans.emplace_back();
    assembler.resume(pk, -1, scans.back());
  }
};

TEST(RotationAssembler, EndsRotationsAtTheCutAndCountsLossInBothSidesOfIt) {
  Parsed p(250);  // VLP-16: 75.4 packets per rotation
  driver::BatcherOptions o;
  o.cut_azimuth_deg = 90.0;
  Assembly a(p.layout, o);
  // Lose the packets around the second cut: the loss straddles it.
  const int n = static_cast<int>(p.packets.size());
  int crossing = -1;
  for (int i = 101; i < n && crossing < 0; ++i) {
    if (p[i].column_azimuth_deg[0] < 90.0f && p[i].column_azimuth_deg[0] > 80.0f) crossing = i;
  }
  ASSERT_GT(crossing, 0);
  for (int i = 0; i < n; ++i) {
    if (i >= crossing && i < crossing + 3) continue;  // 3 lost, across the cut
    a.add(p[i]);
  }
  (void)a.assembler.end_stream(a.scans.back());
  ASSERT_EQ(a.scans.size(), 5u);  // cuts in packets 17, 92, 165-167 (lost), 242
  EXPECT_FALSE(a.scans[0].starts_at_cut);
  EXPECT_TRUE(a.scans[0].ends_at_cut);
  EXPECT_TRUE(a.scans[1].complete);
  // The loss is counted once in the stream and in both rotations it touches.
  EXPECT_EQ(a.stats.missing_packets, 3u);
  EXPECT_EQ(a.scans[2].missing_packets, 3u);
  EXPECT_EQ(a.scans[3].missing_packets, 3u);
  EXPECT_FALSE(a.scans[2].complete);
  EXPECT_FALSE(a.scans[3].complete);
  for (size_t i = 0; i < a.scans.size(); ++i) EXPECT_EQ(a.scans[i].sequence, i);
  EXPECT_EQ(a.stats.rotations, 5u);
  EXPECT_EQ(a.stats.complete, 1u);
  // A packet that was counted lost and arrived after all is not lost.
  a.assembler.forgive_loss(p[crossing + 1].stamp_ns);
  EXPECT_EQ(a.stats.missing_packets, 2u);
}

TEST(RotationAssembler, AJumpEndsTheRotationAndAFieldOfViewGapDoesNot) {
  Parsed p(40);
  Assembly a(p.layout);
  for (int i = 0; i < 10; ++i) a.add(p[i]);
  // A pause outside the field of view: time jumps 30 packet periods, azimuth goes on.
  for (int i = 10; i < 20; ++i) {
    PacketColumns pk = p[i];
    pk.stamp_ns += 30 * static_cast<int64_t>(p.spec.packet_period_us(pk.mode()) * 1e3);
    a.add(pk);
  }
  EXPECT_EQ(a.stats.fov_gaps, 1u);
  EXPECT_EQ(a.stats.missing_packets, 0u);
  EXPECT_EQ(a.scans.size(), 1u);  // no rotation ended
  // Time goes back: a discontinuity ends the rotation in progress.
  a.add(p[0]);
  EXPECT_EQ(a.stats.azimuth_jumps, 1u);
  ASSERT_EQ(a.scans.size(), 2u);
  EXPECT_EQ(a.scans[0].azimuth_jumps, 1u);
  EXPECT_FALSE(a.scans[0].ends_at_cut);
}

}  // namespace
}  // namespace lidartag::velodyne
