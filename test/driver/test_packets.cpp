// Bad input, position packets, time joining and model autodetection.
#include <gtest/gtest.h>

#include <random>

#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/sensor_clock.hpp"
#include "synthetic_stream.hpp"

namespace lidartag::velodyne {
namespace {

constexpr int64_t kHour = 3'600'000'000'000LL;

std::vector<uint8_t> one_packet(Model m, ReturnMode mode = ReturnMode::kStrongest) {
  return testing::make_stream(model_spec(m), mode, 1)[0].bytes;
}

TEST(DecodeErrors, WrongSizeIsRejected) {
  Decoder d(Calibration::builtin(Model::kVLP16));
  SensorClock clock;
  DecodedPacket out;
  auto p = one_packet(Model::kVLP16);
  EXPECT_EQ(d.decode(std::span(p).first(1205), clock, 0, out), DecodeStatus::kWrongSize);
  p.push_back(0);
  EXPECT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kWrongSize);
  EXPECT_EQ(d.decode({}, clock, 0, out), DecodeStatus::kWrongSize);
}

TEST(DecodeErrors, CorruptFlagAzimuthAndModeAreRejected) {
  Decoder d(Calibration::builtin(Model::kVLP32C));
  SensorClock clock;
  DecodedPacket out;
  auto good = one_packet(Model::kVLP32C);
  ASSERT_EQ(d.decode(good, clock, 0, out), DecodeStatus::kOk);
  auto p = good;
  p[5 * kBlockSize] = 0x00;  // flag of block 5
  EXPECT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kBadBlockFlag);
  p = good;
  write_u16(p.data() + 3 * kBlockSize + 2, 36000);
  EXPECT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kBadAzimuth);
  p = good;
  p[kReturnModeOffset] = 0x40;
  EXPECT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kBadReturnMode);
  p = good;
  p[kReturnModeOffset] = 0x00;  // old firmware: no return-mode byte, strongest
  EXPECT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kOk);
  EXPECT_EQ(out.mode(), ReturnMode::kStrongest);
}

TEST(DecodeErrors, VlsBankFlagsAreChecked) {
  Decoder d(Calibration::builtin(Model::kVLS128));
  SensorClock clock;
  DecodedPacket out;
  auto p = one_packet(Model::kVLS128);
  ASSERT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kOk);
  write_u16(p.data() + 1 * kBlockSize, kBankFlags[0]);  // bank 0 twice in one firing
  EXPECT_EQ(d.decode(p, clock, 0, out), DecodeStatus::kBadBlockFlag);
  // A VLP-32C packet (all EE flags) is not a VLS-128 packet.
  EXPECT_EQ(d.decode(one_packet(Model::kVLP32C), clock, 0, out), DecodeStatus::kBadBlockFlag);
}

TEST(DecodeErrors, RandomBytesNeverCrashAndNeverYieldNaN) {
  std::mt19937 rng(7);
  for (Model m : all_models()) {
    Decoder d(Calibration::builtin(m));
    SensorClock clock;
    DecodedPacket out;
    auto base = one_packet(m);
    int ok = 0;
    for (int trial = 0; trial < 2000; ++trial) {
      auto p = base;
      const int flips = 1 + static_cast<int>(rng() % 40);
      for (int f = 0; f < flips; ++f) p[rng() % p.size()] = static_cast<uint8_t>(rng());
      if (d.decode(p, clock, 0, out) != DecodeStatus::kOk) continue;
      ++ok;
      for (int r = 0; r < out.returns; ++r)
        for (int c = 0; c < out.columns; ++c)
          for (int ring = 0; ring < out.rings; ++ring) {
            const auto i = static_cast<size_t>(out.at(r, c, ring));
            ASSERT_TRUE(std::isfinite(out.x[i]) && std::isfinite(out.y[i]) &&
                        std::isfinite(out.z[i]));
            ASSERT_GE(out.azimuth_deg[i], 0.0f);
            ASSERT_LT(out.azimuth_deg[i], 360.0f);
          }
    }
    EXPECT_GT(ok, 0) << "some corruptions only touch distances and must still decode";
  }
}

TEST(PositionPacket, ParsesCounterPpsAndGprmc) {
  std::array<uint8_t, kPositionPacketSize> buf{};
  const std::string nmea = "$GPRMC,101530.25,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E*44";
  encode_position_packet(930'250'000u, PpsStatus::kLocked, nmea, buf);
  PositionPacket pos;
  ASSERT_EQ(parse_position_packet(buf, pos), PositionStatus::kOk);
  EXPECT_EQ(pos.usec_since_hour, 930'250'000u);
  EXPECT_EQ(pos.pps, PpsStatus::kLocked);
  EXPECT_EQ(pos.sentence(), nmea);
  EXPECT_TRUE(pos.has_gprmc);
  // 1994-11-19 10:15:30.25 UTC
  EXPECT_EQ(pos.gps_fix_ns, 785240130'250'000'000LL);
}

TEST(PositionPacket, BadInputIsReportedNotTrusted) {
  std::array<uint8_t, kPositionPacketSize> buf{};
  PositionPacket pos;
  EXPECT_EQ(parse_position_packet(std::span(buf).first(511), pos), PositionStatus::kWrongSize);
  encode_position_packet(1, static_cast<PpsStatus>(9), "$GPRMC,xx", buf);
  EXPECT_EQ(parse_position_packet(buf, pos), PositionStatus::kBadPps);
  EXPECT_FALSE(pos.has_gprmc);
  // A void fix ('V') is not used as time; control bytes are neutralised.
  encode_position_packet(1, PpsStatus::kLocked,
                         "$GPRMC,101530,V,4916.45,N,12311.12,W,000.5,054.7,191194,,*10", buf);
  ASSERT_EQ(parse_position_packet(buf, pos), PositionStatus::kOk);
  EXPECT_FALSE(pos.has_gprmc);
  buf[kNmeaOffset + 3] = 0x07;
  ASSERT_EQ(parse_position_packet(buf, pos), PositionStatus::kOk);
  EXPECT_EQ(pos.sentence().substr(0, 4), "$GP?");
  // No terminator in 128 bytes: the sentence is cut, never read past.
  std::fill(buf.begin() + kNmeaOffset, buf.end(), uint8_t{'A'});
  ASSERT_EQ(parse_position_packet(buf, pos), PositionStatus::kOk);
  EXPECT_EQ(pos.sentence().size(), kNmeaMaxLength);
}

TEST(SensorClock, JoinsTheHourCounterWithTheReference) {
  const int64_t hour = 490'000 * kHour;  // some top of the hour
  // Same hour.
  EXPECT_EQ(join_hour(1'000'000, hour + 2'000'000'000LL), hour + 1'000'000'000LL);
  // Counter just before the hour, reference just after it: previous hour.
  EXPECT_EQ(join_hour(3'599'900'000u, hour + 50'000'000LL), hour - 100'000'000LL);
  // Counter just after the hour, reference just before it: next hour.
  EXPECT_EQ(join_hour(100'000, hour - 50'000'000LL), hour + 100'000'000LL);
}

TEST(SensorClock, UsesGpsTimeWhenPpsIsLocked) {
  SensorClock clock;
  std::array<uint8_t, kPositionPacketSize> buf{};
  encode_position_packet(930'250'000u, PpsStatus::kLocked,
                         "$GPRMC,101530,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E*6D", buf);
  PositionPacket pos;
  ASSERT_EQ(parse_position_packet(buf, pos), PositionStatus::kOk);
  clock.update(pos, 1'700'000'000'000'000'000LL);
  EXPECT_EQ(clock.source(), TimeSource::kGps);
  const int64_t hour_1994 = 785'240'130'000'000'000LL - (15 * 60 + 30) * 1'000'000'000LL;
  // The host clock is ignored (it is years off).
  EXPECT_EQ(clock.join(5'000'000, 1'700'000'000'000'000'000LL), hour_1994 + 5'000'000'000LL);
  // Without lock, the host clock stays in charge.
  SensorClock host;
  pos.pps = PpsStatus::kSynchronizing;
  host.update(pos, 1'700'000'000'000'000'000LL);
  EXPECT_EQ(host.source(), TimeSource::kHost);
}

// A position packet with a locked fix at `fix_s` (seconds since the epoch, whole hour + 930 s).
PositionPacket fix_at(int64_t fix_s) {
  PositionPacket p;
  p.pps = PpsStatus::kLocked;
  p.has_gprmc = true;
  p.gps_fix_ns = fix_s * 1'000'000'000LL;
  p.usec_since_hour = static_cast<uint32_t>((fix_s % 3600) * 1'000'000);
  return p;
}

TEST(PositionPacket, AWrongOrMissingChecksumIsNoTime) {
  // Anyone on the network can send a position packet: an RMC sentence is trusted only with its
  // checksum right (forged ones once moved utime to 2004 or 2079 while the status said GPS).
  std::array<uint8_t, kPositionPacketSize> buf{};
  PositionPacket pos;
  for (const char* nmea : {"$GPRMC,101530,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E*6C",
                           "$GPRMC,101530,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E"}) {
    SCOPED_TRACE(nmea);
    encode_position_packet(930'000'000u, PpsStatus::kLocked, nmea, buf);
    EXPECT_EQ(parse_position_packet(buf, pos), PositionStatus::kBadChecksum);
    EXPECT_FALSE(pos.has_gprmc);
    SensorClock clock;
    clock.update(pos, 1'700'000'000'000'000'000LL);
    EXPECT_EQ(clock.source(), TimeSource::kHost);
  }
  EXPECT_TRUE(
      nmea_checksum_ok("$GPRMC,101530,A,4916.45,N,12311.12,W,000.5,054.7,191194,020.3,E*6d"));
}

TEST(SensorClock, AStaleGpsReferenceFallsBackToTheHost) {
  // Position packets stop: 40 minutes later a kept reference stamped packets an hour early.
  const int64_t t = 1'700'000'000;
  SensorClock clock;
  clock.update(fix_at(t), t * 1'000'000'000LL);
  ASSERT_EQ(clock.source(), TimeSource::kGps);
  clock.expire((t + 5) * 1'000'000'000LL);
  EXPECT_EQ(clock.source(), TimeSource::kGps);
  const int64_t later = (t + 40 * 60) * 1'000'000'000LL;
  clock.expire(later);
  EXPECT_EQ(clock.source(), TimeSource::kHost);
  EXPECT_EQ(clock.stale(), 1u);
  const auto usec = static_cast<uint32_t>(((t + 40 * 60) % 3600) * 1'000'000);
  EXPECT_EQ(clock.join(usec, later), later);
}

TEST(SensorClock, AFixFromTheLastWeekRolloverIsMovedToItsEra) {
  const int64_t t = 1'700'000'000;               // 2023-11-14
  const int64_t era_s = 1024LL * 7 * 24 * 3600;  // 2004 for 2023
  SensorClock clock;
  clock.update(fix_at(t - era_s), t * 1'000'000'000LL);
  EXPECT_EQ(clock.source(), TimeSource::kGps);
  EXPECT_EQ(clock.era_corrections(), 1u);
  const auto usec = static_cast<uint32_t>((t % 3600) * 1'000'000);
  EXPECT_EQ(clock.join(usec, 0), t * 1'000'000'000LL);
}

TEST(SensorClock, AJumpIsAdoptedOnlyWhenFixesConfirmIt) {
  const int64_t t = 1'700'000'000, ns = 1'000'000'000;
  SensorClock clock;
  clock.update(fix_at(t), t * ns);
  // A forged fix an hour and a half later (checksum right), one second on: not adopted.
  clock.update(fix_at(t + 5400), (t + 1) * ns);
  EXPECT_EQ(clock.rejected_fixes(), 1u);
  const auto usec = static_cast<uint32_t>(((t + 1) % 3600) * 1'000'000);
  EXPECT_EQ(clock.join(usec, 0), (t + 1) * ns);
  // The real receiver goes on: adopted, and the forgery did not count towards a new time.
  clock.update(fix_at(t + 2), (t + 2) * ns);
  EXPECT_EQ(clock.rejected_fixes(), 1u);
  // The GPS time really moves (a receiver reset): three fixes in a row agree, then it is used.
  for (int i = 3; i <= 5; ++i) clock.update(fix_at(t + 600 + i), (t + i) * ns);
  EXPECT_EQ(clock.rejected_fixes(), 3u);
  const auto usec5 = static_cast<uint32_t>(((t + 605) % 3600) * 1'000'000);
  EXPECT_EQ(clock.join(usec5, 0), (t + 605) * ns);
}

TEST(ModelCheck, DetectsTheModelFromTheProductByteAndTiming) {
  for (Model m : all_models()) {
    for (ReturnMode mode : {ReturnMode::kStrongest, ReturnMode::kDual}) {
      ModelCheck check;
      for (const auto& p : testing::make_stream(model_spec(m), mode, 40)) check.add(p.bytes);
      EXPECT_EQ(check.product_model(), m);
      EXPECT_EQ(check.timing_model(), m) << model_spec(m).name;
      EXPECT_EQ(check.return_mode(), mode);
      EXPECT_EQ(check.mismatch(), "");
    }
  }
}

TEST(ModelCheck, ReportsAProductByteThatContradictsTheTiming) {
  // VLP-16 layout and timing with the HDL-32E product byte, as in real captures.
  ModelCheck check;
  for (auto p : testing::make_stream(model_spec(Model::kVLP16), ReturnMode::kStrongest, 40)) {
    p.bytes[kProductIdOffset] = 0x21;
    check.add(p.bytes);
  }
  EXPECT_EQ(check.product_model(), Model::kHDL32E);
  EXPECT_EQ(check.timing_model(), Model::kVLP16);
  EXPECT_NE(check.mismatch().find("fit vlp16"), std::string::npos) << check.mismatch();
  EXPECT_NEAR(check.packet_period_us(), 1327, 1);
}

TEST(ModelCheck, HeavyLossDoesNotMakeAnotherModelOfTheTiming) {
  // Half of a VLP-32C's packets lost at random: the steps between the others are 664 us, 1327 us
  // (a VLP-16's period), 1991 us... The period must stay the VLP-32C's, as must the model.
  for (const double loss : {0.5, 0.7}) {
    ModelCheck check;
    uint32_t seed = 7;
    for (const auto& p :
         testing::make_stream(model_spec(Model::kVLP32C), ReturnMode::kStrongest, 400)) {
      seed = seed * 1664525u + 1013904223u;
      if (static_cast<double>(seed >> 8) / 16777216.0 < loss) continue;
      check.add(p.bytes);
    }
    EXPECT_NEAR(check.packet_period_us(), 664, 1) << "loss " << loss;
    EXPECT_EQ(check.timing_model(), Model::kVLP32C) << "loss " << loss;
    EXPECT_EQ(check.mismatch(), "") << "loss " << loss;
  }
}

}  // namespace
}  // namespace lidartag::velodyne
