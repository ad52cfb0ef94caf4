// The real Ouster captures assembled into frames by the shared assembly (ScanBatcher, frame-id
// delimited) through lidartag's Ouster decoder: frame, column and point counts, and every point's
// xyz against an independent evaluation of Ouster's published range-to-xyz formula (double
// precision, from the metadata alone) to 0.1 mm.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>
#include <filesystem>
#include <numbers>
#include <random>

#include "driver/ouster_captures.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/scan_batcher.hpp"

namespace lidartag::driver::ouster {
namespace {

namespace fs = std::filesystem;
using testing::capture_files;
using testing::ouster_dir;

struct Assembled {
  std::deque<Scan> scans;
  BatcherStats stats{};
  DecoderStats decoder{};
};

// The packets through the decoder and a batcher; every rotation in a scan of its own.
Assembled assemble(Decoder& decoder, const std::vector<std::vector<uint8_t>>& packets) {
  const SensorLayout layout = sensor_layout(decoder.info());
  const auto mode = static_cast<uint8_t>(kReturnModeBase + uint8_t(decoder.info().profile));
  ScanBatcher batcher(layout, mode, decoder.info().returns(), BatcherOptions{});
  Assembled out;
  out.scans.emplace_back();
  for (const auto& p : packets) {
    PacketColumns parsed;
    if (decoder.parse(p, parsed) != DecodeStatus::kOk) continue;
    if (batcher.add(parsed, out.scans.back())) out.scans.emplace_back();
  }
  while (batcher.flush(out.scans.back())) out.scans.emplace_back();
  out.scans.pop_back();  // the one being filled when the stream ended: empty
  out.stats = batcher.stats();
  out.decoder = decoder.stats();
  return out;
}

// Ouster's range-to-xyz in the sensor frame, metres, evaluated directly from the metadata.
std::array<double, 3> reference_xyz(const SensorInfo& s, int beam, int measurement_id,
                                    double range_mm) {
  const double pi = std::numbers::pi;
  const auto b = static_cast<size_t>(beam);
  const double theta_e = 2 * pi * (1.0 - double(measurement_id) / s.columns_per_frame);
  const double theta_a = -2 * pi * s.beam_azimuth_deg[b] / 360.0;
  const double phi = 2 * pi * s.beam_altitude_deg[b] / 360.0;
  const double n = s.lidar_origin_to_beam_origin_mm;
  const double x =
      (range_mm - n) * std::cos(theta_e + theta_a) * std::cos(phi) + n * std::cos(theta_e);
  const double y =
      (range_mm - n) * std::sin(theta_e + theta_a) * std::cos(phi) + n * std::sin(theta_e);
  const double z = (range_mm - n) * std::sin(phi);
  const auto& t = s.lidar_to_sensor_transform;
  return {(t[0] * x + t[1] * y + t[2] * z + t[3]) * 1e-3,
          (t[4] * x + t[5] * y + t[6] * z + t[7]) * 1e-3,
          (t[8] * x + t[9] * y + t[10] * z + t[11]) * 1e-3};
}

class OusterPoints : public ::testing::TestWithParam<size_t> {};

TEST_P(OusterPoints, FramesOfTheSharedAssemblyHoldEveryPointWhereTheFormulaPutsIt) {
  const auto& cf = capture_files()[GetParam()];
  const std::string stem = ouster_dir() + "/pcaps/" + cf.pcap;
  if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
  const SensorInfo info = load_metadata(ouster_dir() + "/pcaps/" + cf.metadata + ".json");
  Decoder decoder(info);
  const PacketFormat& f = decoder.format();
  const auto packets = testing::read_packets(stem + ".pcap");
  const Assembled run = assemble(decoder, packets.lidar);
  ASSERT_EQ(run.scans.size(), cf.frames);
  EXPECT_EQ(run.decoder.rejected(), 0u);
  EXPECT_EQ(run.stats.missing_packets + run.stats.azimuth_jumps + run.stats.inconsistent, 0u);

  // Rings by elevation, ring 0 the lowest beam.
  const Scan& first = run.scans.front();
  ASSERT_EQ(first.rings, f.pixels);
  for (int r = 1; r < first.rings; ++r)
    EXPECT_LE(info.beam_altitude_deg[first.laser_id[size_t(r - 1)]],
              info.beam_altitude_deg[first.laser_id[size_t(r)]]);
  EXPECT_LT(info.beam_altitude_deg[first.laser_id[0]],
            info.beam_altitude_deg[first.laser_id[size_t(first.rings - 1)]]);

  const FieldSpec* range_field[2] = {find_field(*f.spec, Field::kRange),
                                     find_field(*f.spec, Field::kRange2)};
  const FieldSpec* refl_field[2] = {find_field(*f.spec, Field::kReflectivity),
                                    find_field(*f.spec, Field::kReflectivity2)};
  size_t packet = 0, points = 0, max_checked = 0;
  double worst_m = 0;
  for (const Scan& s : run.scans) {
    SCOPED_TRACE("scan " + std::to_string(s.sequence));
    ASSERT_EQ(s.returns, cf.returns);
    ASSERT_EQ(s.model, kScanModel);
    // The frame's packets, in file order (the captures lose none): scan column c is packet
    // c / columns_per_packet's column c % columns_per_packet.
    const size_t frame_packets = static_cast<size_t>(s.columns / f.columns);
    ASSERT_EQ(s.columns % f.columns, 0);
    ASSERT_LE(packet + frame_packets, packets.lidar.size());
    const uint64_t t0 = read_column_header(packets.lidar[packet].data(), f, 0).timestamp_ns;
    size_t expected_points = 0;
    for (int c = 0; c < s.columns; ++c) {
      const auto& p = packets.lidar[packet + static_cast<size_t>(c / f.columns)];
      const int pc = c % f.columns;
      const ColumnHeader h = read_column_header(p.data(), f, pc);
      EXPECT_NEAR(s.column_time_s[size_t(c)], double(h.timestamp_ns - t0) * 1e-9, 1e-7);
      for (int ret = 0; ret < s.returns; ++ret) {
        for (int ring = 0; ring < s.rings; ++ring) {
          const int beam = s.laser_id[size_t(ring)];
          const size_t i = s.at(ret, ring, c);
          const uint32_t mm =
              h.valid() ? field_value(f.pixel(p.data(), pc, beam), *range_field[ret]) : 0;
          if (mm == 0) {
            ASSERT_EQ(s.range[i], 0.0f) << "a hole, not a point";
            ASSERT_EQ(s.return_type[i], ReturnType::kNone);
            continue;
          }
          ++expected_points;
          const auto want = reference_xyz(info, beam, h.measurement_id, mm);
          const double err = std::max(
              {std::abs(s.x[i] - want[0]), std::abs(s.y[i] - want[1]), std::abs(s.z[i] - want[2])});
          worst_m = std::max(worst_m, err);
          ASSERT_LT(err, 1e-4) << "column " << c << " ring " << ring << " return " << ret;
          ASSERT_EQ(s.range[i], static_cast<float>(mm * 1e-3));
          ASSERT_EQ(s.intensity[i], field_value(f.pixel(p.data(), pc, beam), *refl_field[ret]));
          ASSERT_EQ(s.return_type[i], ret == 0 ? ReturnType::kStrongest : ReturnType::kSecond);
          ASSERT_NEAR(s.time_s[i], double(h.timestamp_ns - t0) * 1e-9, 1e-6);
          // The cell's azimuth is the point's, clockwise from +x as Velodyne's (beyond 5 m,
          // where the beam origin's offset moves it by less than 0.2 deg).
          if (mm > 5000) {
            const double az = -std::atan2(want[1], want[0]) * 180.0 / std::numbers::pi;
            double d = s.azimuth_deg[i] - az;
            d -= 360.0 * std::round(d / 360.0);
            ASSERT_LT(std::abs(d), 0.2) << "column " << c << " ring " << ring;
            ASSERT_GE(s.azimuth_deg[i], 0.0f);
            ASSERT_LT(s.azimuth_deg[i], 360.0f);
          }
        }
      }
    }
    EXPECT_EQ(s.point_count(), expected_points);
    EXPECT_GT(expected_points, static_cast<size_t>(s.columns));  // the captures see things
    points += expected_points;
    max_checked = std::max(max_checked, static_cast<size_t>(s.columns));
    packet += frame_packets;
  }
  EXPECT_EQ(packet, packets.lidar.size()) << "every packet's columns in a frame";
  std::cout << cf.pcap << ": " << run.scans.size() << " frames, " << points
            << " points, worst xyz difference " << worst_m * 1e3 << " mm\n";
  // Whole frames hold every column of the lidar mode (the FUSA capture: part of one frame).
  if (cf.lidar_packets >= 64) {
    EXPECT_EQ(max_checked, static_cast<size_t>(info.columns_per_frame));
  }
}

INSTANTIATE_TEST_SUITE_P(Captures, OusterPoints, ::testing::Values(0, 1, 2, 3, 4, 5, 6),
                         [](const auto& p) {
                           std::string n = capture_files()[p.param].pcap;
                           for (char& c : n)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });

TEST(OusterPoints, DestaggeringAppliesThePixelShiftSoThatAColumnPointsOneWay) {
  size_t frames = 0;
  for (const auto& cf : capture_files()) {
    const std::string stem = ouster_dir() + "/pcaps/" + cf.pcap;
    if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
    SCOPED_TRACE(cf.pcap);
    const SensorInfo info = load_metadata(ouster_dir() + "/pcaps/" + cf.metadata + ".json");
    Decoder decoder(info);
    Assembled run = assemble(decoder, testing::read_packets(stem + ".pcap").lidar);
    for (Scan& s : run.scans) {
      if (s.columns != info.columns_per_frame) {
        const Scan before = s;
        EXPECT_FALSE(decoder.destagger(s)) << "a partial frame";
        // Its filled cells unchanged (the storage past them holds nothing defined).
        for (int ret = 0; ret < s.returns; ++ret)
          for (int ring = 0; ring < s.rings; ++ring)
            EXPECT_EQ(std::memcmp(s.x.data() + s.at(ret, ring, 0),
                                  before.x.data() + before.at(ret, ring, 0),
                                  static_cast<size_t>(s.columns) * sizeof(float)),
                      0);
        continue;
      }
      const Scan staggered = s;
      ASSERT_TRUE(decoder.destagger(s));
      ++frames;
      const int w = s.columns;
      const double step = 360.0 / w;
      for (int ret = 0; ret < s.returns; ++ret)
        for (int ring = 0; ring < s.rings; ++ring) {
          const int shift = info.pixel_shift_by_row[s.laser_id[size_t(ring)]];
          for (int c = 0; c < w; ++c) {
            const size_t from = staggered.at(ret, ring, c);
            const size_t to = s.at(ret, ring, ((c + shift) % w + w) % w);
            ASSERT_EQ(s.x[to], staggered.x[from]);
            ASSERT_EQ(s.range[to], staggered.range[from]);
            ASSERT_EQ(s.intensity[to], staggered.intensity[from]);
            ASSERT_EQ(s.time_s[to], staggered.time_s[from]);
          }
        }
      // Every column's cells now point within a column step of each other (staggered they are
      // up to the beams' azimuth spread apart, several degrees).
      double worst = 0, worst_staggered = 0;
      for (int c = 0; c < w; ++c) {
        auto spread = [&](const Scan& x) {
          const double ref = x.azimuth_deg[x.at(0, 0, c)];
          double lo = 0, hi = 0;
          for (int ring = 0; ring < x.rings; ++ring) {
            double d = x.azimuth_deg[x.at(0, ring, c)] - ref;
            d -= 360.0 * std::round(d / 360.0);
            lo = std::min(lo, d);
            hi = std::max(hi, d);
          }
          return hi - lo;
        };
        worst = std::max(worst, spread(s));
        worst_staggered = std::max(worst_staggered, spread(staggered));
      }
      EXPECT_LT(worst, step) << "destaggered";
      const auto [lo, hi] =
          std::minmax_element(info.pixel_shift_by_row.begin(), info.pixel_shift_by_row.end());
      if (*hi - *lo >= 8) {
        EXPECT_GT(worst_staggered, 4 * step) << "staggered";
      }
    }
  }
  EXPECT_EQ(frames, 8u);  // the whole frames of the captures
}

TEST(OusterPoints, ColumnsWhoseStatusBitIsClearAreHoles) {
  const std::string stem = ouster_dir() + "/pcaps/OS-0-128-U1_v2.3.0_1024x10";
  if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
  Decoder decoder(load_metadata(stem + ".json"));
  const PacketFormat& f = decoder.format();
  auto packets = testing::read_packets(stem + ".pcap").lidar;
  // Columns 3 and 4 of packet 10 marked invalid (their data left as it was).
  for (int c : {3, 4}) packets[10][f.header_bytes + size_t(c) * f.column_bytes + 10] = 0;
  const Assembled run = assemble(decoder, packets);
  ASSERT_EQ(run.scans.size(), 1u);
  const Scan& s = run.scans.front();
  EXPECT_EQ(s.columns, 1024);  // the columns stay, empty
  EXPECT_EQ(run.decoder.invalid_columns, 2u);
  for (int c : {10 * 16 + 3, 10 * 16 + 4})
    for (int ring = 0; ring < s.rings; ++ring) {
      EXPECT_EQ(s.range[s.at(0, ring, c)], 0.0f);
      EXPECT_EQ(s.return_type[s.at(0, ring, c)], ReturnType::kNone);
    }
  // Their neighbours keep their points.
  size_t neighbour = 0;
  for (int ring = 0; ring < s.rings; ++ring) neighbour += s.valid(s.at(0, ring, 10 * 16 + 5));
  EXPECT_GT(neighbour, 0u);
}

TEST(OusterPoints, CorruptedPacketsAreRefusedOrDecodedNeverACrash) {
  // Every capture's packets with random bytes changed (a few per packet, some in the headers),
  // some cut short or lengthened, through the decoder and the assembly (run under ASan by
  // scripts/run-tests.sh): every packet is decoded or refused with a counted reason.
  std::mt19937 rng(32);
  for (const auto& cf : capture_files()) {
    const std::string stem = ouster_dir() + "/pcaps/" + cf.pcap;
    if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
    SCOPED_TRACE(cf.pcap);
    Decoder decoder(load_metadata(ouster_dir() + "/pcaps/" + cf.metadata + ".json"));
    auto packets = testing::read_packets(stem + ".pcap").lidar;
    for (auto& p : packets) {
      const int kind = std::uniform_int_distribution<int>(0, 9)(rng);
      if (kind == 0) p.resize(p.size() / 2);
      if (kind == 1) p.push_back(0);
      std::uniform_int_distribution<size_t> where(0, std::min<size_t>(p.size() - 1, 64));
      std::uniform_int_distribution<size_t> anywhere(0, p.size() - 1);
      for (int i = 0; i < 4; ++i) {
        p[where(rng)] = static_cast<uint8_t>(rng());
        p[anywhere(rng)] = static_cast<uint8_t>(rng());
      }
    }
    const Assembled run = assemble(decoder, packets);
    uint64_t outcomes = 0;
    for (uint64_t n : run.decoder.by_status) outcomes += n;
    EXPECT_EQ(outcomes, packets.size());
    EXPECT_GT(run.decoder.rejected(), 0u);
    for (const Scan& s : run.scans) {
      EXPECT_LE(s.columns, s.column_capacity);
      for (int c = 0; c < s.columns; ++c)
        for (int ring = 0; ring < s.rings; ++ring) {
          const size_t i = s.at(0, ring, c);
          ASSERT_TRUE(std::isfinite(s.x[i]) && std::isfinite(s.y[i]) && std::isfinite(s.z[i]));
          ASSERT_GE(s.range[i], 0.0f);
        }
    }
  }
}

TEST(OusterPoints, SignalIntensityIsTheSignalFieldClampedTo255) {
  const std::string stem = ouster_dir() + "/pcaps/OS-2-128-U1_v2.3.0_1024x10";
  if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
  DecoderOptions o;
  o.intensity = IntensitySource::kSignal;
  Decoder decoder(load_metadata(stem + ".json"), o);
  const PacketFormat& f = decoder.format();
  const auto packets = testing::read_packets(stem + ".pcap").lidar;
  const Assembled run = assemble(decoder, packets);
  ASSERT_EQ(run.scans.size(), 1u);
  const Scan& s = run.scans.front();
  const FieldSpec* signal = find_field(*f.spec, Field::kSignal);
  size_t clamped = 0;
  for (int c = 0; c < s.columns; ++c)
    for (int ring = 0; ring < s.rings; ++ring) {
      const size_t i = s.at(0, ring, c);
      if (!s.valid(i)) continue;
      const auto& p = packets[size_t(c / f.columns)];
      const uint32_t v =
          field_value(f.pixel(p.data(), c % f.columns, s.laser_id[size_t(ring)]), *signal);
      ASSERT_EQ(s.intensity[i], std::min<uint32_t>(v, 255u));
      clamped += v > 255;
    }
  EXPECT_GT(clamped, 0u);  // the clamp was exercised
}

}  // namespace
}  // namespace lidartag::driver::ouster
