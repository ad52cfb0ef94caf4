// Whole rotations: cut at the point, loss, duplicates, reordering, FOV gaps, restarts, timeouts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>

#include "../detector/count_allocations.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "synthetic_stream.hpp"

namespace lidartag::velodyne {
namespace {

// Feeds the batcher a fresh scan after every finished rotation and keeps them all; scans of
// `capacity` columns (0: sized by the batcher on first use).
struct Rig {
  const ModelSpec& spec;
  ReturnMode mode;
  Decoder decoder;
  SensorClock clock;
  driver::ScanBatcher batcher;
  DecodedPacket pk;
  int capacity;
  std::deque<std::unique_ptr<Scan>> all;  // the scan in progress is the last one
  std::vector<Scan*> scans;               // finished rotations, in order
  Rig(Model m, ReturnMode md, driver::BatcherOptions o = {}, int capacity_columns = 0)
      : spec(model_spec(m)),
        mode(md),
        decoder(Calibration::builtin(m)),
        batcher(make_batcher(spec, md, o)),
        capacity(capacity_columns) {
    fresh();
  }
  void fresh() {
    all.push_back(std::make_unique<Scan>());
    if (capacity > 0) all.back()->reserve(spec.lasers, mode == ReturnMode::kDual ? 2 : 1, capacity);
  }
  Scan& current() { return *all.back(); }
  void keep(bool finished) {
    if (!finished) return;
    scans.push_back(&current());
    fresh();
  }
  void feed(const testing::StreamPacket& p) {
    ASSERT_EQ(decoder.decode(p.bytes, clock, p.time_ns, pk), DecodeStatus::kOk);
    keep(batcher.add(pk, current()));
  }
  void feed_all(const std::vector<testing::StreamPacket>& v) {
    for (const auto& p : v) feed(p);
  }
  void flush() {
    while (batcher.flush(current())) keep(true);  // what the reorder window held, then the rest
  }
  void idle(double silent_s) { keep(batcher.idle(silent_s, current())); }
};

double ahead_of_cut(double az, double cut) {
  return std::fmod(az - cut + 720.0, 360.0);
}

TEST(ScanBatcher, CutsWholeRotationsAtTheAzimuthInsideAPacket) {
  for (Model m : all_models()) {
    driver::BatcherOptions o;
    o.cut_azimuth_deg = 123.45;  // not on a packet boundary
    Rig rig(m, ReturnMode::kStrongest, o);
    const int per_rotation_packets =
        static_cast<int>(std::ceil(rig.spec.packet_rate_hz(ReturnMode::kStrongest) / 10.0));
    const auto stream =
        testing::make_stream(rig.spec, ReturnMode::kStrongest, per_rotation_packets * 3 + 5);
    rig.feed_all(stream);
    rig.flush();
    const auto& scans = rig.scans;
    ASSERT_EQ(scans.size(), 4u) << rig.spec.name;  // partial, 2 whole, partial
    EXPECT_FALSE(scans[0]->complete);
    EXPECT_FALSE(scans[0]->starts_at_cut);
    EXPECT_FALSE(scans[3]->complete);
    const double step = 600.0 * 360.0 / 60e6 * rig.spec.firing_period_us;
    const int expected_columns = static_cast<int>(std::lround(360.0 / step));
    for (int i = 1; i <= 2; ++i) {
      const Scan& s = *scans[static_cast<size_t>(i)];
      EXPECT_TRUE(s.complete) << rig.spec.name;
      EXPECT_NEAR(s.columns, expected_columns, 1) << rig.spec.name;
      for (int ring = 0; ring < s.rings; ++ring)
        EXPECT_EQ(s.laser_id[static_cast<size_t>(ring)], rig.spec.laser_of_ring(ring));
      EXPECT_NEAR(s.rpm, 600.0, 1.0);
      // First column at most one step past the cut, last column at most one step before it.
      EXPECT_LT(ahead_of_cut(s.column_azimuth_deg[0], o.cut_azimuth_deg), step + 0.011);
      EXPECT_GT(
          ahead_of_cut(s.column_azimuth_deg[static_cast<size_t>(s.columns - 1)], o.cut_azimuth_deg),
          360.0 - step - 0.011);
      EXPECT_EQ(s.column_time_s[0], 0.0);
      for (int c = 1; c < s.columns; ++c)
        EXPECT_NEAR(
            s.column_time_s[static_cast<size_t>(c)] - s.column_time_s[static_cast<size_t>(c - 1)],
            rig.spec.firing_period_us * 1e-6, 1.01e-6);  // packet stamps are whole us
      // The first column is not the first of its packet: that packet fed both rotations.
      const int64_t since_start = s.stamp_ns - stream[0].time_ns;
      const double packet_ns = rig.spec.packet_period_us(ReturnMode::kStrongest) * 1e3;
      if (rig.spec.columns_per_packet(ReturnMode::kStrongest) > 1) {
        EXPECT_GT(std::fmod(static_cast<double>(since_start), packet_ns), 1.0) << rig.spec.name;
      }
      // Consecutive rotations join without a missing or repeated column.
      const Scan& prev = *scans[static_cast<size_t>(i - 1)];
      const double prev_last_t = static_cast<double>(prev.stamp_ns) * 1e-9 +
                                 prev.column_time_s[static_cast<size_t>(prev.columns - 1)];
      EXPECT_NEAR(static_cast<double>(s.stamp_ns) * 1e-9 - prev_last_t,
                  rig.spec.firing_period_us * 1e-6, 1.01e-6);
    }
    EXPECT_EQ(rig.batcher.stats().complete, 2u);
    EXPECT_EQ(rig.batcher.stats().missing_packets, 0u);
  }
}

TEST(ScanBatcher, PerPointTimeAndAzimuthAreMonotonicPerRing) {
  Rig rig(Model::kVLP32C, ReturnMode::kStrongest);
  rig.feed_all(testing::make_stream(rig.spec, ReturnMode::kStrongest, 400));
  ASSERT_GE(rig.scans.size(), 2u);
  const Scan& s = *rig.scans[1];
  ASSERT_TRUE(s.complete);
  for (int ring = 0; ring < s.rings; ++ring) {
    double prev_t = -1, prev_az = -1, ref = -1;
    for (int c = 0; c < s.columns; ++c) {
      const size_t i = s.at(0, ring, c);
      if (!s.valid(i)) continue;
      EXPECT_GT(s.time_s[i], prev_t);
      // Each laser has its own azimuth offset: unwrap from just before its column 0.
      if (ref < 0) ref = s.azimuth_deg[i] - 0.001 - 0.19907 * c;
      const double az = ahead_of_cut(s.azimuth_deg[i], ref);
      EXPECT_GT(az, prev_az);
      prev_t = s.time_s[i];
      prev_az = az;
    }
  }
}

TEST(ScanBatcher, LostPacketsAreCountedAndMarkTheRotationIncomplete) {
  Rig rig(Model::kVLP16, ReturnMode::kStrongest);
  auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 260);
  // Rotation 1 spans packets 36..111 (start azimuth 10, cut 180, 75.4 packets a turn).
  stream.erase(stream.begin() + 100, stream.begin() + 103);
  rig.feed_all(stream);
  rig.flush();
  ASSERT_GE(rig.scans.size(), 3u);
  EXPECT_EQ(rig.scans[1]->missing_packets, 3u);
  EXPECT_FALSE(rig.scans[1]->complete);
  EXPECT_TRUE(rig.scans[2]->complete);
  EXPECT_EQ(rig.batcher.stats().missing_packets, 3u);
}

TEST(ScanBatcher, HeavyRandomLossIsCountedAsMissingNeverAsStray) {
  // Half (or more) of the packets lost at random, the first and last kept: every lost packet is
  // missing, none of those that arrived is taken for a stray one.
  for (const Model m : {Model::kVLP16, Model::kVLP32C, Model::kVLS128}) {
    for (const double loss : {0.2, 0.5, 0.7}) {
      Rig rig(m, ReturnMode::kStrongest);
      const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 3000);
      uint32_t seed = 11;
      uint64_t lost = 0;
      for (size_t i = 0; i < stream.size(); ++i) {
        seed = seed * 1664525u + 1013904223u;
        const bool drop =
            i > 0 && i + 1 < stream.size() && static_cast<double>(seed >> 8) / 16777216.0 < loss;
        if (drop) {
          ++lost;
          continue;
        }
        rig.feed(stream[i]);
      }
      rig.flush();
      const std::string what = std::string(rig.spec.name) + " loss " + std::to_string(loss);
      EXPECT_EQ(rig.batcher.stats().inconsistent, 0u) << what;
      EXPECT_EQ(rig.batcher.stats().missing_packets, lost) << what;
    }
  }
}

TEST(ScanBatcher, DuplicatesAreDroppedAndAReorderedPairIsPutInPlace) {
  Rig rig(Model::kHDL32E, ReturnMode::kStrongest);
  auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 500);
  stream.insert(stream.begin() + 200, stream[199]);  // duplicate
  std::swap(stream[300], stream[301]);               // reordered pair
  rig.feed_all(stream);
  rig.flush();
  const driver::BatcherStats& st = rig.batcher.stats();
  EXPECT_EQ(st.duplicates, 1u);
  EXPECT_EQ(st.reordered, 1u);     // put back in place by the reorder window
  EXPECT_EQ(st.late_packets, 1u);  // only the duplicate was dropped
  EXPECT_EQ(st.missing_packets, 0u);
  EXPECT_EQ(st.inconsistent, 0u);
  size_t complete = 0;
  for (const Scan* s : rig.scans) complete += s->complete ? 1u : 0u;
  // 500 packets of 552.96 us = 2.76 rotations: partial, two whole ones, partial.
  EXPECT_EQ(st.rotations, 4u);
  EXPECT_EQ(complete, 2u);
}

// Clean rotations of a stream, for comparison with a disturbed one.
std::vector<Scan*> complete_of(const Rig& rig) {
  std::vector<Scan*> v;
  for (Scan* s : rig.scans)
    if (s->complete) v.push_back(s);
  return v;
}

// Every cell of `got` equals `want`'s, field by field (the two may differ in capacity), and the
// shapes agree.
void expect_same_cells(const Scan& got, const Scan& want) {
  ASSERT_EQ(got.returns, want.returns);
  ASSERT_EQ(got.columns, want.columns);
  for (int r = 0; r < want.returns; ++r)
    for (int ring = 0; ring < want.rings; ++ring)
      for (int c = 0; c < want.columns; ++c) {
        const size_t i = got.at(r, ring, c), j = want.at(r, ring, c);
        ASSERT_EQ(got.range[i], want.range[j]) << r << " " << ring << " " << c;
        ASSERT_EQ(got.x[i], want.x[j]);
        ASSERT_EQ(got.y[i], want.y[j]);
        ASSERT_EQ(got.z[i], want.z[j]);
        ASSERT_EQ(got.azimuth_deg[i], want.azimuth_deg[j]);
        ASSERT_EQ(got.time_s[i], want.time_s[j]);
        ASSERT_EQ(got.intensity[i], want.intensity[j]);
        ASSERT_EQ(got.return_type[i], want.return_type[j]);
      }
}

// Storage full of values no decoder writes, so that a cell left unwritten shows.
void poison(Scan& scan) {
  for (auto* v : {&scan.x, &scan.y, &scan.z, &scan.range, &scan.azimuth_deg, &scan.time_s})
    std::fill(v->begin(), v->end(), 12345.0f);
  std::fill(scan.intensity.begin(), scan.intensity.end(), uint8_t{0xab});
  std::fill(scan.return_type.begin(), scan.return_type.end(), ReturnType::kSecond);
}

// The same stamp and every cell the same, field by field (the disturbance must leave no trace).
void expect_same_rotation(const Scan& a, const Scan& b) {
  ASSERT_EQ(a.stamp_ns, b.stamp_ns);
  expect_same_cells(a, b);
}

TEST(ScanBatcher, PacketsReorderedByOneToThreeKeepRotationsComplete) {
  for (int shift : {1, 2, 3}) {
    Rig clean(Model::kVLP16, ReturnMode::kStrongest);
    Rig rig(Model::kVLP16, ReturnMode::kStrongest);
    const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 300);
    clean.feed_all(stream);
    clean.flush();
    // Every 10th packet arrives `shift` packets late.
    auto late = stream;
    int moved = 0;
    for (size_t i = 20; i + static_cast<size_t>(shift) < late.size(); i += 10) {
      std::rotate(late.begin() + static_cast<long>(i), late.begin() + static_cast<long>(i) + 1,
                  late.begin() + static_cast<long>(i) + shift + 1);
      ++moved;
    }
    rig.feed_all(late);
    rig.flush();
    const driver::BatcherStats& st = rig.batcher.stats();
    EXPECT_EQ(st.reordered, static_cast<uint64_t>(moved)) << "shift " << shift;
    EXPECT_EQ(st.missing_packets, 0u);
    EXPECT_EQ(st.late_packets, 0u);
    const auto a = complete_of(clean), b = complete_of(rig);
    ASSERT_EQ(a.size(), 3u);
    ASSERT_EQ(b.size(), a.size()) << "shift " << shift;
    for (size_t i = 0; i < a.size(); ++i) expect_same_rotation(*a[i], *b[i]);
  }
}

TEST(ScanBatcher, APacketLaterThanTheWindowIsReorderedNotMissing) {
  Rig rig(Model::kVLP16, ReturnMode::kStrongest);
  auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 300);
  // Packet 100 arrives 8 packets late: beyond the reorder window, so its columns cannot be put
  // in place; it did arrive, so it is not counted as missing.
  std::rotate(stream.begin() + 100, stream.begin() + 101, stream.begin() + 109);
  rig.feed_all(stream);
  rig.flush();
  const driver::BatcherStats& st = rig.batcher.stats();
  EXPECT_EQ(st.reordered, 1u);
  EXPECT_EQ(st.late_packets, 1u);
  EXPECT_EQ(st.missing_packets, 0u);
  // The rotation that lacks its columns is not complete.
  ASSERT_GE(rig.scans.size(), 3u);
  EXPECT_FALSE(rig.scans[1]->complete);
  EXPECT_EQ(rig.scans[1]->missing_packets, 1u);
}

TEST(ScanBatcher, DuplicatesAreCountedOnceAndChangeNothing) {
  Rig clean(Model::kVLP32C, ReturnMode::kStrongest);
  Rig rig(Model::kVLP32C, ReturnMode::kStrongest);
  const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 600);
  clean.feed_all(stream);
  clean.flush();
  std::vector<testing::StreamPacket> twice;
  for (size_t i = 0; i < stream.size(); ++i) {
    twice.push_back(stream[i]);
    if (i % 7 == 3) twice.push_back(stream[i]);                 // right away
    if (i % 11 == 5 && i >= 3) twice.push_back(stream[i - 3]);  // a little later
  }
  rig.feed_all(twice);
  rig.flush();
  const driver::BatcherStats& st = rig.batcher.stats();
  EXPECT_EQ(st.duplicates, twice.size() - stream.size());
  EXPECT_EQ(st.late_packets, st.duplicates);
  EXPECT_EQ(st.reordered, 0u);
  EXPECT_EQ(st.missing_packets, 0u);
  EXPECT_EQ(st.rotations, clean.batcher.stats().rotations);
  const auto a = complete_of(clean), b = complete_of(rig);
  ASSERT_EQ(b.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) expect_same_rotation(*a[i], *b[i]);
}

// A well-formed packet of the same model with a random azimuth, stamped like its neighbours.
testing::StreamPacket spoof(const ModelSpec& spec, const testing::StreamPacket& like,
                            uint32_t seed) {
  testing::StreamOptions o;
  o.start_azimuth_deg = static_cast<double>((seed * 2654435761u) % 36000u) * 0.01;
  o.start_ns = like.time_ns + 1000 * static_cast<int64_t>(seed % 500);
  return testing::make_stream(spec, ReturnMode::kStrongest, 1, o)[0];
}

TEST(ScanBatcher, SpoofedPacketsDoNotMultiplyRotations) {
  Rig clean(Model::kVLP32C, ReturnMode::kStrongest);
  Rig rig(Model::kVLP32C, ReturnMode::kStrongest);
  const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 1507);  // 1 s
  clean.feed_all(stream);
  clean.flush();
  // 20 % of what arrives is foreign: well-formed, random in-range azimuths.
  std::vector<testing::StreamPacket> mixed;
  uint64_t spoofed = 0;
  for (size_t i = 0; i < stream.size(); ++i) {
    mixed.push_back(stream[i]);
    if (i % 4 == 1) {
      mixed.push_back(spoof(rig.spec, stream[i], static_cast<uint32_t>(i)));
      ++spoofed;
    }
  }
  rig.feed_all(mixed);
  rig.flush();
  const driver::BatcherStats& st = rig.batcher.stats();
  EXPECT_EQ(st.rotations, clean.batcher.stats().rotations);
  EXPECT_EQ(st.inconsistent, spoofed);
  EXPECT_EQ(st.azimuth_jumps, 0u);
  EXPECT_EQ(st.missing_packets, 0u);
  const auto a = complete_of(clean), b = complete_of(rig);
  ASSERT_EQ(a.size(), 9u);
  ASSERT_EQ(b.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) expect_same_rotation(*a[i], *b[i]);
}

TEST(ScanBatcher, ASecondCoherentStreamOnThePortIsRejectedWhileTheFirstLives) {
  // Another sensor's packets agree with each other but not with the stream: as long as the
  // stream goes on they are foreign, never a restart.
  Rig clean(Model::kVLP16, ReturnMode::kStrongest);
  Rig rig(Model::kVLP16, ReturnMode::kStrongest);
  const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 400);
  testing::StreamOptions other;
  other.start_azimuth_deg = 200.0;
  other.start_ns = stream[0].time_ns + 300'000;
  const auto foreign = testing::make_stream(rig.spec, ReturnMode::kStrongest, 400, other);
  clean.feed_all(stream);
  clean.flush();
  for (size_t i = 0; i < stream.size(); ++i) {
    rig.feed(stream[i]);
    rig.feed(foreign[i]);
  }
  rig.flush();
  EXPECT_EQ(rig.batcher.stats().inconsistent, foreign.size());
  EXPECT_EQ(rig.batcher.stats().rotations, clean.batcher.stats().rotations);
  EXPECT_EQ(complete_of(rig).size(), complete_of(clean).size());
}

TEST(ScanBatcher, ReplayLoopIsANewStreamNotStrayPackets) {
  Rig rig(Model::kVLP32C, ReturnMode::kStrongest);
  const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 700);
  rig.feed_all(stream);
  rig.feed_all(stream);  // the capture starts over: time and azimuth jump back
  rig.flush();
  const driver::BatcherStats& st = rig.batcher.stats();
  EXPECT_EQ(st.azimuth_jumps, 1u);
  EXPECT_EQ(st.inconsistent, 0u);
  EXPECT_EQ(st.duplicates, 0u);
  // Each pass: partial, two whole rotations (700 packets = 4.6 turns from 10 deg), partial.
  EXPECT_EQ(complete_of(rig).size(), 2u * (complete_of(rig).size() / 2));
  EXPECT_GE(complete_of(rig).size(), 6u);
}

TEST(ScanBatcher, ACutAmongTheLastPacketsOfAStreamStillEndsItsRotation) {
  // A replay loops (or the sensor restarts) a packet or three after a cut: those packets wait in
  // the reorder window when the new stream is recognised. The rotation must end at the cut as
  // without the restart, the tail must be a rotation of its own, and no column may be lost.
  // From 10 deg at 600 rpm the 5th cut (180 deg) falls in packet 673 of a VLP-32C stream: n puts
  // it among the last packets, or just before them.
  for (int n = 670; n < 682; ++n) {
    Rig once(Model::kVLP32C, ReturnMode::kStrongest);
    const auto stream = testing::make_stream(once.spec, ReturnMode::kStrongest, n);
    once.feed_all(stream);
    once.flush();
    Rig twice(Model::kVLP32C, ReturnMode::kStrongest);
    twice.feed_all(stream);
    twice.feed_all(stream);
    twice.flush();
    ASSERT_EQ(twice.scans.size(), 2 * once.scans.size()) << n << " packets";
    int columns_once = 0, columns_twice = 0;
    for (size_t i = 0; i < once.scans.size(); ++i) {
      for (size_t pass : {size_t{0}, once.scans.size()}) {
        const Scan& a = *once.scans[i];
        const Scan& b = *twice.scans[pass + i];
        EXPECT_EQ(b.columns, a.columns) << n << " packets, rotation " << i;
        EXPECT_EQ(b.complete, a.complete) << n << " packets, rotation " << i;
        EXPECT_EQ(b.ends_at_cut, a.ends_at_cut) << n << " packets, rotation " << i;
        columns_twice += b.columns;
      }
      columns_once += once.scans[i]->columns;
    }
    EXPECT_EQ(columns_twice, 2 * columns_once) << n << " packets";
    EXPECT_EQ(twice.batcher.stats().azimuth_jumps, 1u);
  }
}

TEST(ScanBatcher, AReturnModeChangeRightAfterACutLosesNothing) {
  // The same at a return-mode change: the packets held after the cut end the old rotation's tail,
  // the new mode's packet (kept meanwhile) starts the next rotation.
  // The 10th cut falls in packet 713 of a VLP-16 stream.
  for (int n = 710; n < 722; ++n) {
    Rig rig(Model::kVLP16, ReturnMode::kStrongest);
    const auto a = testing::make_stream(rig.spec, ReturnMode::kStrongest, n);
    // The dual stream goes on where the strongest one stopped, in time and azimuth.
    const double t_us =
        n * rig.spec.columns_per_packet(ReturnMode::kStrongest) * rig.spec.firing_period_us;
    testing::StreamOptions next;
    next.start_ns = a.front().time_ns + static_cast<int64_t>(std::llround(t_us * 1e3));
    next.start_azimuth_deg = std::fmod(10.0 + 600.0 * 360.0 / 60e6 * t_us, 360.0);
    const auto b = testing::make_stream(rig.spec, ReturnMode::kDual, 400, next);
    rig.feed_all(a);
    rig.feed_all(b);
    rig.flush();
    int strongest = 0, dual = 0;
    for (const Scan* s : rig.scans) (s->returns == 2 ? dual : strongest) += s->columns;
    EXPECT_EQ(strongest, n * rig.spec.columns_per_packet(ReturnMode::kStrongest)) << n;
    EXPECT_EQ(dual, 400 * rig.spec.columns_per_packet(ReturnMode::kDual)) << n;
    EXPECT_EQ(rig.batcher.stats().mode_changes, 1u) << n;
  }
}

TEST(ScanBatcher, RestrictedFieldOfViewGivesCompleteRotations) {
  // The sensor reports only 270..91 deg: it jumps over the blanked sector inside a packet without
  // a time gap, then pauses between packets with continuous azimuths (as the real VLP-32C capture).
  for (double cut : {180.0, 0.0}) {
    driver::BatcherOptions o;
    o.cut_azimuth_deg = cut;
    Rig rig(Model::kVLP32C, ReturnMode::kStrongest, o);
    const auto full = testing::make_stream(rig.spec, ReturnMode::kStrongest, 680);
    std::vector<testing::StreamPacket> fov;
    int64_t shift = 0;
    for (const auto& p : full) {
      const double az = read_u16(p.bytes.data() + 2) * 0.01;
      if (az > 91.0 && az < 270.0) {
        shift -= static_cast<int64_t>(rig.spec.packet_period_us(ReturnMode::kStrongest) * 1e3);
        continue;
      }
      auto q = p;
      q.time_ns += shift;
      // Re-stamp the hour counter consistently with the capture time.
      write_u32(q.bytes.data() + kTimestampOffset,
                static_cast<uint32_t>((q.time_ns / 1000) % 3'600'000'000LL));
      fov.push_back(q);
    }
    rig.feed_all(fov);
    rig.flush();
    EXPECT_EQ(rig.batcher.stats().missing_packets, 0u) << "cut " << cut;
    EXPECT_GE(rig.batcher.stats().fov_gaps, 3u);
    EXPECT_GE(rig.batcher.stats().complete, 3u) << "cut " << cut;
  }
}

TEST(ScanBatcher, SensorRestartEndsTheRotationIncomplete) {
  Rig rig(Model::kVLP16, ReturnMode::kStrongest);
  auto a = testing::make_stream(rig.spec, ReturnMode::kStrongest, 120);
  testing::StreamOptions later;
  later.start_ns = a.front().time_ns - 10'000'000'000LL;  // clock jumps back 10 s
  later.start_azimuth_deg = 300.0;
  auto b = testing::make_stream(rig.spec, ReturnMode::kStrongest, 120, later);
  rig.feed_all(a);
  rig.feed_all(b);
  rig.flush();
  EXPECT_EQ(rig.batcher.stats().azimuth_jumps, 1u);
  for (const Scan* s : rig.scans) EXPECT_FALSE(s->complete && s->azimuth_jumps > 0);
}

TEST(ScanBatcher, StreamThatStopsIsFlushedAfterTheTimeout) {
  driver::BatcherOptions o;
  o.flush_timeout_s = 0.2;
  Rig rig(Model::kVLP16, ReturnMode::kStrongest, o);
  const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 30);
  rig.feed_all(stream);
  rig.idle(0.1);  // a pause: the held packets go into the rotation, which goes on
  EXPECT_TRUE(rig.scans.empty());
  rig.idle(0.3);  // silence past flush_timeout_s: the rotation is delivered
  ASSERT_EQ(rig.scans.size(), 1u);
  EXPECT_FALSE(rig.scans[0]->ends_at_cut);
}

TEST(ScanBatcher, RpmChangeChangesColumnsPerRotation) {
  Rig rig(Model::kVLP32C, ReturnMode::kStrongest);
  testing::StreamOptions slow;
  slow.rpm = 300;
  auto a = testing::make_stream(rig.spec, ReturnMode::kStrongest, 1507 * 5 / 10, slow);
  testing::StreamOptions fast;
  fast.rpm = 1200;
  fast.start_ns = a.back().time_ns + static_cast<int64_t>(663.552e3);
  const double last_az = read_u16(a.back().bytes.data() + 11 * kBlockSize + 2) * 0.01;
  fast.start_azimuth_deg = last_az + 300 * 360.0 / 60e6 * 55.296;
  auto b = testing::make_stream(rig.spec, ReturnMode::kStrongest, 1507 / 2, fast);
  rig.feed_all(a);
  rig.feed_all(b);
  std::vector<const Scan*> complete;
  for (const Scan* s : rig.scans)
    if (s->complete) complete.push_back(s);
  ASSERT_GE(complete.size(), 3u);
  EXPECT_NEAR(complete.front()->rpm, 300, 2);
  EXPECT_NEAR(complete.front()->columns, 3617, 2);
  EXPECT_NEAR(complete.back()->rpm, 1200, 5);
  EXPECT_NEAR(complete.back()->columns, 904, 2);
}

TEST(ScanBatcher, DualReturnScansCarryBothEchoes) {
  Rig rig(Model::kVLP16, ReturnMode::kDual);
  rig.feed_all(testing::make_stream(rig.spec, ReturnMode::kDual, 400));
  ASSERT_GE(rig.scans.size(), 2u);
  const Scan& s = *rig.scans[1];
  EXPECT_TRUE(s.complete);
  EXPECT_EQ(s.returns, 2);
  size_t second = 0;
  for (int ring = 0; ring < s.rings; ++ring)
    for (int c = 0; c < s.columns; ++c) second += s.valid(s.at(1, ring, c)) ? 1u : 0u;
  EXPECT_GT(second, static_cast<size_t>(s.columns) * 8);
}

TEST(ScanBatcher, ScanThatFillsUpIsCutAndCounted) {
  Rig rig(Model::kVLP16, ReturnMode::kStrongest, {}, 500);
  rig.feed_all(testing::make_stream(rig.spec, ReturnMode::kStrongest, 100));
  EXPECT_GE(rig.batcher.stats().overflows, 1u);
  for (const Scan* s : rig.scans) EXPECT_LE(s->columns, 500);
}

TEST(ScanBatcher, AssemblesIntoTheCallersScanAndSizesItOnFirstUse) {
  // The scan the caller passes is the rotation: no pool, no copy. An empty scan is reserved for
  // the model; the columns after a cut wait in the batcher and open the next scan passed in.
  const ModelSpec& spec = model_spec(Model::kVLP32C);
  Decoder decoder(Calibration::builtin(Model::kVLP32C));
  SensorClock clock;
  driver::ScanBatcher batcher = velodyne::make_batcher(spec, ReturnMode::kStrongest);
  DecodedPacket pk;
  Scan a, b;
  const auto stream = testing::make_stream(spec, ReturnMode::kStrongest, 400);
  std::vector<int> ends;  // packet index of each finished rotation
  Scan* current = &a;
  for (size_t i = 0; i < stream.size(); ++i) {
    ASSERT_EQ(decoder.decode(stream[i].bytes, clock, stream[i].time_ns, pk), DecodeStatus::kOk);
    if (batcher.add(pk, *current)) {
      ends.push_back(static_cast<int>(i));
      EXPECT_EQ(current->rings, spec.lasers);
      EXPECT_EQ(current->column_capacity,
                driver::ScanBatcher::column_capacity(velodyne::sensor_layout(spec)));
      if (ends.size() >= 2) {
        EXPECT_TRUE(current->complete);
        // The other scan's last column and this one's first are consecutive firings.
        EXPECT_TRUE(batcher.in_progress());
      }
      current = current == &a ? &b : &a;
    }
  }
  ASSERT_GE(ends.size(), 3u);
  // 400 packets of 663.552 us at 600 rpm: the cut at 180 deg every 150.7 packets.
  EXPECT_NEAR(ends[2] - ends[1], 151, 1);
  EXPECT_TRUE(batcher.flush(*current));
  EXPECT_FALSE(current->ends_at_cut);
  EXPECT_FALSE(batcher.in_progress());
  EXPECT_FALSE(batcher.flush(*current));  // nothing left
}

TEST(ScanBatcher, ReturnModeChangeEndsTheRotationAndResizesTheNextScan) {
  Rig rig(Model::kVLP16, ReturnMode::kStrongest);
  const auto single = testing::make_stream(rig.spec, ReturnMode::kStrongest, 100);
  rig.feed_all(single);
  testing::StreamOptions later;
  later.start_ns = single.back().time_ns + 1'000'000;
  rig.feed_all(testing::make_stream(rig.spec, ReturnMode::kDual, 300, later));
  rig.flush();
  EXPECT_EQ(rig.batcher.stats().mode_changes, 1u);
  // Single: 10 -> 180 deg, 180 -> 128 deg (ended by the change); dual: 10 -> 180, a whole turn,
  // the flushed rest.
  ASSERT_EQ(rig.scans.size(), 5u);
  EXPECT_EQ(rig.scans[1]->returns, 1);
  EXPECT_FALSE(rig.scans[1]->ends_at_cut);
  EXPECT_EQ(rig.scans[2]->returns, 2);
  EXPECT_EQ(rig.scans[2]->return_mode, static_cast<uint8_t>(ReturnMode::kDual));
  EXPECT_FALSE(rig.scans[2]->starts_at_cut);
  EXPECT_TRUE(rig.scans[3]->complete);
  EXPECT_EQ(rig.scans[3]->returns, 2);
}

TEST(ScanBatcher, EveryCellOfARotationIsWrittenSoAReusedScanNeedsNoClearing) {
  // Scan::reserve keeps storage that is large enough as it is (not cleared): one scan handed to a
  // dual-return stream, then a single-return one, then dual again (a fuzz input after another, a
  // sensor reconfigured) is allocated once. That is right only if every cell of every column
  // appended is written: here the scan starts full of poison, and each rotation must equal, cell
  // by cell, the same packets assembled into new scans.
  const ModelSpec& spec = model_spec(Model::kVLP32C);
  Scan reused;
  reused.reserve(spec.lasers, 2,
                 driver::ScanBatcher::column_capacity(velodyne::sensor_layout(spec)));
  poison(reused);
  const float* storage = reused.x.data();
  for (ReturnMode mode : {ReturnMode::kDual, ReturnMode::kStrongest, ReturnMode::kDual}) {
    const auto stream = testing::make_stream(spec, mode, 800);
    Rig fresh(Model::kVLP32C, mode);
    fresh.feed_all(stream);
    Decoder decoder(Calibration::builtin(Model::kVLP32C));
    SensorClock clock;
    driver::ScanBatcher batcher = velodyne::make_batcher(spec, mode);
    DecodedPacket pk;
    size_t rotation = 0;
    for (const auto& p : stream) {
      ASSERT_EQ(decoder.decode(p.bytes, clock, p.time_ns, pk), DecodeStatus::kOk);
      if (!batcher.add(pk, reused)) continue;
      ASSERT_LT(rotation, fresh.scans.size());
      ASSERT_NO_FATAL_FAILURE(expect_same_cells(reused, *fresh.scans[rotation++]));
    }
    EXPECT_EQ(rotation, fresh.scans.size());
    EXPECT_GE(rotation, 2u);
    EXPECT_EQ(reused.x.data(), storage) << "the scan was allocated again";
  }
}

TEST(ScanBatcher, LazilyReservedStorageAssemblesAsZeroedStorage) {
  // The batcher sizes a scan with Scan::reserve_lazily: the storage it adds is not zeroed (and
  // may be blocks another scan used: CellAllocator reuses them) until the writer reaches each
  // column, and the decoder's cells are not zeroed at all. Here that storage starts full of
  // poison, and each rotation must equal, cell by cell, the same packets assembled into scans
  // reserved (and zeroed) beforehand; dual, then single (the scan is reshaped), then dual.
  const ModelSpec& spec = model_spec(Model::kVLP32C);
  const int capacity = driver::ScanBatcher::column_capacity(velodyne::sensor_layout(spec));
  Scan lazy;
  lazy.reserve_lazily(spec.lasers, 2, capacity);
  ASSERT_EQ(lazy.fresh_from, 0u);
  poison(lazy);
  for (ReturnMode mode : {ReturnMode::kDual, ReturnMode::kStrongest, ReturnMode::kDual}) {
    const auto stream = testing::make_stream(spec, mode, 800);
    Rig zeroed(Model::kVLP32C, mode, {}, capacity);
    zeroed.feed_all(stream);
    zeroed.flush();
    Decoder decoder(Calibration::builtin(Model::kVLP32C));
    SensorClock clock;
    driver::ScanBatcher batcher = velodyne::make_batcher(spec, mode);
    DecodedPacket pk;
    size_t rotation = 0;
    auto check = [&] {
      ASSERT_LT(rotation, zeroed.scans.size());
      ASSERT_NO_FATAL_FAILURE(expect_same_cells(lazy, *zeroed.scans[rotation++]));
    };
    for (const auto& p : stream) {
      ASSERT_EQ(decoder.decode(p.bytes, clock, p.time_ns, pk), DecodeStatus::kOk);
      if (batcher.add(pk, lazy)) check();
    }
    while (batcher.flush(lazy)) check();
    EXPECT_EQ(rotation, zeroed.scans.size());
    EXPECT_GE(rotation, 2u);
  }
}

TEST(ScanBatcher, ANewStreamThatMixesReturnModesLeavesNoCellUnwritten) {
  // A restart whose first packets disagree on the return mode (garbage, or a sensor switched
  // during the restart): the dual-return packet lands in a single-return scan, where the decoder
  // cannot write it. Its columns must hold no return, not what the reused scan held before.
  const ModelSpec& spec = model_spec(Model::kVLP32C);
  Decoder decoder(Calibration::builtin(Model::kVLP32C));
  SensorClock clock;
  driver::ScanBatcher batcher = velodyne::make_batcher(spec, ReturnMode::kStrongest);
  DecodedPacket pk;
  Scan scan;
  scan.reserve(spec.lasers, 1, driver::ScanBatcher::column_capacity(velodyne::sensor_layout(spec)));
  auto poison = [&] {
    std::fill(scan.range.begin(), scan.range.end(), 12345.0f);
    std::fill(scan.return_type.begin(), scan.return_type.end(), ReturnType::kSecond);
  };
  poison();
  std::vector<testing::StreamPacket> stream =
      testing::make_stream(spec, ReturnMode::kStrongest, 300);
  // 5 s later: one dual-return packet, then single-return ones that go on where it ended.
  const double fp = spec.firing_period_us, rate = 600.0 * 360.0 / 60e6;
  testing::StreamOptions b;
  b.start_ns = stream.back().time_ns + 5'000'000'000LL;
  b.start_azimuth_deg = 40.0;
  const auto dual = testing::make_stream(spec, ReturnMode::kDual, 1, b);
  const int dual_columns = spec.columns_per_packet(ReturnMode::kDual);
  b.start_ns += static_cast<int64_t>(std::llround(dual_columns * fp * 1e3));
  b.start_azimuth_deg += rate * dual_columns * fp;
  const auto single = testing::make_stream(spec, ReturnMode::kStrongest, 300, b);
  stream.insert(stream.end(), dual.begin(), dual.end());
  stream.insert(stream.end(), single.begin(), single.end());
  int rotations = 0;
  auto check = [&] {
    ++rotations;
    for (int ring = 0; ring < scan.rings; ++ring)
      for (int c = 0; c < scan.columns; ++c) {
        const size_t i = scan.at(0, ring, c);
        ASSERT_NE(scan.range[i], 12345.0f) << "rotation " << rotations << " ring " << ring
                                           << " column " << c << " was never written";
        ASSERT_NE(scan.return_type[i], ReturnType::kSecond);
      }
    poison();
  };
  for (const auto& p : stream) {
    ASSERT_EQ(decoder.decode(p.bytes, clock, p.time_ns, pk), DecodeStatus::kOk);
    if (batcher.add(pk, scan)) check();
  }
  while (batcher.flush(scan)) check();
  EXPECT_GE(batcher.stats().mode_changes, 1u) << "the mixed modes are counted";
  EXPECT_GE(rotations, 3);
}

TEST(ScanBatcher, APacketEndsAtMostOneRotation) {
  // Block azimuths that cross the cut several times inside one packet (garbage, or a spoofed
  // packet) cannot deliver rotations shorter than a packet.
  Rig rig(Model::kVLP32C, ReturnMode::kStrongest);
  auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 200);
  auto& bad = stream[60].bytes;
  for (size_t b = 0; b < kBlocks; ++b) {
    write_u16(bad.data() + b * kBlockSize + 2, static_cast<uint16_t>(b % 2 == 0 ? 17900 : 18100));
  }
  rig.feed_all(stream);
  rig.flush();
  size_t short_ones = 0;
  for (const Scan* s : rig.scans) short_ones += s->columns < 12 ? 1u : 0u;
  EXPECT_EQ(short_ones, 0u);
  EXPECT_LE(rig.batcher.stats().rotations, 4u);
}

TEST(ScanBatcher, ScanThatFillsUpLosesNothingElse) {
  // The columns after an overflow go on into the next scan: every column is delivered once.
  Rig rig(Model::kVLP16, ReturnMode::kStrongest, {}, 500);
  const auto stream = testing::make_stream(rig.spec, ReturnMode::kStrongest, 100);
  rig.feed_all(stream);
  rig.flush();
  int columns = 0;
  for (const Scan* s : rig.scans) columns += s->columns;
  EXPECT_EQ(columns, 100 * rig.spec.columns_per_packet(ReturnMode::kStrongest));
}

TEST(ScanBatcher, PerPacketPathNeverAllocates) {
  // parse() + add() over every kind of packet the screening meets, once the scans are sized.
  for (ReturnMode mode : {ReturnMode::kStrongest, ReturnMode::kDual}) {
    for (Model m : all_models()) {
      const ModelSpec& spec = model_spec(m);
      const auto stream =
          testing::make_stream(spec, mode, static_cast<int>(spec.packet_rate_hz(mode)));
      std::vector<testing::StreamPacket> mixed;
      for (size_t i = 0; i < stream.size(); ++i) {
        mixed.push_back(stream[i]);
        if (i % 5 == 1) mixed.push_back(spoof(spec, stream[i], static_cast<uint32_t>(i)));
        if (i % 17 == 3) mixed.push_back(stream[i]);  // duplicate
        if (i % 23 == 7 && i > 3) std::swap(mixed[mixed.size() - 1], mixed[mixed.size() - 2]);
      }
      const auto again = stream;  // a replay loop: a new stream
      Decoder decoder(Calibration::builtin(m));
      SensorClock clock;
      driver::ScanBatcher batcher = velodyne::make_batcher(spec, mode);
      PacketColumns pk;
      std::array<Scan, 2> scans;
      for (Scan& s : scans)
        s.reserve(spec.lasers, mode == ReturnMode::kDual ? 2 : 1,
                  driver::ScanBatcher::column_capacity(velodyne::sensor_layout(spec)));
      size_t current = 0, rotations = 0;
      auto feed = [&](const std::vector<testing::StreamPacket>& v) {
        for (const auto& p : v) {
          if (decoder.parse(p.bytes, clock, p.time_ns, pk) != DecodeStatus::kOk) continue;
          if (batcher.add(pk, scans[current])) {
            current = 1 - current;
            ++rotations;
          }
        }
      };
      const long before = lidartag::testing::heap_allocations();
      feed(mixed);
      feed(again);
      while (batcher.flush(scans[current])) {
        current = 1 - current;
        ++rotations;
      }
      EXPECT_EQ(lidartag::testing::heap_allocations(), before) << spec.name;
      EXPECT_GE(rotations, 16u) << spec.name;
      EXPECT_GT(batcher.stats().inconsistent, 0u);
      EXPECT_GT(batcher.stats().duplicates, 0u);
    }
  }
}

}  // namespace
}  // namespace lidartag::velodyne
