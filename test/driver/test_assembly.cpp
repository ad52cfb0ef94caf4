// The parts of scan assembly, each alone: the scan's storage, ReorderWindow, StreamScreen,
// RotationAssembler (with its ColumnWriter). ScanBatcher, which joins them, is tested in
// test_scan_batcher.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <thread>
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

// Every cell field of `s` set to `v` (storage whose content is unknown: reused memory).
void poison(Scan& s, float v) {
  for (auto* f : {&s.x, &s.y, &s.z, &s.range, &s.azimuth_deg, &s.time_s})
    std::fill(f->begin(), f->end(), v);
  std::fill(s.intensity.begin(), s.intensity.end(), uint8_t{0xab});
  std::fill(s.return_type.begin(), s.return_type.end(), ReturnType::kSecond);
}

// Cell (ret, ring, col) reads as zeroed storage (every field).
bool zeroed(const Scan& s, int ret, int ring, int col) {
  const size_t i = s.at(ret, ring, col);
  return s.x[i] == 0.0f && s.y[i] == 0.0f && s.z[i] == 0.0f && s.range[i] == 0.0f &&
         s.azimuth_deg[i] == 0.0f && s.time_s[i] == 0.0f && s.intensity[i] == 0 &&
         s.return_type[i] == ReturnType::kNone;
}

TEST(ScanStorage, LazyStorageIsZeroedColumnByColumnButForTheCellsTheWriterWritesWhole) {
  Scan s;
  s.reserve_lazily(3, 2, 100);
  ASSERT_EQ(s.x.size(), 600u);
  poison(s, 7.0f);  // what unzeroed storage may hold
  // Columns [0, 10): every cell zeroed.
  s.prepare_columns(10);
  // Columns [10, 20): those of return 0 from column 15 on are the writer's (left as they are).
  s.prepare_columns(20, 15, 1);
  for (int ret = 0; ret < 2; ++ret)
    for (int ring = 0; ring < 3; ++ring)
      for (int col = 0; col < 30; ++col) {
        const bool writers = ret == 0 && col >= 15 && col < 20;
        EXPECT_EQ(zeroed(s, ret, ring, col), col < 20 && !writers) << ret << ring << col;
      }
  // Prepared columns are not zeroed again (they hold what was written since).
  s.range[s.at(1, 2, 5)] = 3.0f;
  s.prepare_columns(15);
  EXPECT_EQ(s.range[s.at(1, 2, 5)], 3.0f);
  // A new shape first zeroes what the old one left unprepared, then keeps the storage (large
  // enough) as it is: nothing of it is fresh.
  s.reserve_lazily(2, 1, 300);
  EXPECT_EQ(s.fresh_from, Scan::kNoFreshCells);
  EXPECT_EQ(s.x.size(), 600u);
  EXPECT_EQ(s.x[599], 0.0f);  // column 99 of return 1, ring 2 of the old shape
  EXPECT_EQ(s.x[15], 7.0f);   // the writer's cell of the old shape, kept
}

TEST(ScanStorage, LazyStorageGrownFromAnotherShapeKeepsWhatItHad) {
  // The storage that was there reads as it did (Scan::reserve never cleared it); only what the
  // new shape adds is fresh, and zeroed when reached.
  Scan s;
  s.reserve(2, 1, 10);  // 20 cells, zeroed
  std::fill(s.x.begin(), s.x.end(), 5.0f);
  s.reserve_lazily(2, 1, 40);  // 80 cells: 60 fresh
  EXPECT_EQ(s.fresh_from, 20u);
  std::fill(s.x.begin() + 20, s.x.end(), 7.0f);  // unknown content
  s.prepare_columns(40);
  for (int ring = 0; ring < 2; ++ring)
    for (int col = 0; col < 40; ++col) {
      const size_t i = s.at(0, ring, col);
      EXPECT_EQ(s.x[i], i < 20 ? 5.0f : 0.0f) << ring << " " << col;
    }
  EXPECT_EQ(s.fresh_from, Scan::kNoFreshCells);
}

TEST(ScanStorage, AScanReservedEagerlyReadsAsZero) {
  Scan s;
  s.reserve(4, 2, 50);
  for (int ret = 0; ret < 2; ++ret)
    for (int ring = 0; ring < 4; ++ring)
      for (int col = 0; col < 50; ++col) ASSERT_TRUE(zeroed(s, ret, ring, col));
  EXPECT_EQ(s.fresh_from, Scan::kNoFreshCells);
}

TEST(ScanStorage, TheBlocksOfAFreedScanAreReusedByTheNextOfTheSameShape) {
  // A reader opened after another gets the pages the last one faulted in, not fresh ones.
  const float* first = nullptr;
  {
    Scan a;
    a.reserve_lazily(16, 2, 3979);
    first = a.x.data();
  }
  Scan b;
  b.reserve_lazily(16, 2, 3979);
  const std::vector<const void*> blocks{b.x.data(),     b.y.data(),           b.z.data(),
                                        b.range.data(), b.azimuth_deg.data(), b.time_s.data()};
  EXPECT_NE(std::find(blocks.begin(), blocks.end(), first), blocks.end());
  // Each thread keeps its own (freed when it ends).
  bool reused = false;
  std::thread([&] {
    const float* was = nullptr;
    {
      Scan c;
      c.reserve_lazily(16, 2, 3979);
      was = c.x.data();
    }
    Scan d;
    d.reserve_lazily(16, 2, 3979);
    reused = d.x.data() == was || d.y.data() == was || d.z.data() == was || d.range.data() == was ||
             d.azimuth_deg.data() == was || d.time_s.data() == was;
  }).join();
  EXPECT_TRUE(reused);
}

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
