// Every real capture in ../shared/captures decodes into whole rotations (skipped when absent).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <filesystem>
#include <memory>

#include "driver/keep_all.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"

namespace lidartag::velodyne {
namespace {

std::string capture(const std::string& name) {
  return std::string(LIDARTAG_SHARED_DIR) + "/captures/" + name;
}

using testing::KeepAll;

struct Decoded {
  Model model{};
  ReturnMode mode{};
  std::string mismatch;
  size_t data = 0, position = 0, gprmc = 0, decode_errors = 0;
  PpsStatus pps = PpsStatus::kAbsent;
  // Counted from the raw bytes, independently of the decoder and the batcher:
  int raw_cut_crossings = 0;        // block azimuths crossing the cut
  double raw_rpm = 0;               // mean azimuth advance over the packet clock
  std::vector<size_t> raw_returns;  // non-zero distances per laser
  std::vector<size_t> raw_cells;    // cells per laser
  driver::BatcherStats stats;
  std::unique_ptr<KeepAll> sink;
};

constexpr double kCut = 180.0;

Decoded decode_capture(const std::string& path) {
  Decoded d;
  std::vector<std::vector<uint8_t>> data;
  std::vector<int64_t> times;
  {
    driver::PcapSource src(path);
    driver::RawPacket pk;
    ModelCheck check;
    while (src.next(pk, std::chrono::milliseconds(0)) == driver::ReadStatus::kPacket) {
      if (pk.payload.size() == kDataPacketSize) {
        check.add(pk.payload);
        data.emplace_back(pk.payload.begin(), pk.payload.end());
        times.push_back(pk.receive_time_ns);
      } else if (pk.payload.size() == kPositionPacketSize) {
        PositionPacket pos;
        if (parse_position_packet(pk.payload, pos) == PositionStatus::kOk) {
          ++d.position;
          d.gprmc += pos.has_gprmc ? 1u : 0u;
          d.pps = pos.pps;
        }
      }
    }
    d.model = check.timing_model().value_or(Model::kVLP16);
    d.mode = check.return_mode().value_or(ReturnMode::kStrongest);
    d.mismatch = check.mismatch();
  }
  d.data = data.size();
  const ModelSpec& spec = model_spec(d.model);
  Decoder decoder(Calibration::builtin(d.model));
  SensorClock clock;
  d.sink = std::make_unique<KeepAll>();
  driver::BatcherOptions bo;
  bo.cut_azimuth_deg = kCut;
  driver::ScanBatcher batcher = velodyne::make_batcher(spec, d.mode, bo);
  DecodedPacket out;
  double prev_az = -1;
  std::vector<double> steps;
  d.raw_returns.assign(static_cast<size_t>(spec.lasers), 0);
  d.raw_cells.assign(static_cast<size_t>(spec.lasers), 0);
  for (size_t i = 0; i < data.size(); ++i) {
    for (size_t b = 0; b < kBlocks; ++b) {
      const uint8_t* blk = data[i].data() + b * kBlockSize;
      const uint16_t flag = read_u16(blk);
      size_t bank = 0;
      while (bank < 4 && kBankFlags[bank] != flag) ++bank;
      if (bank == 4) continue;
      for (size_t ch = 0; ch < 32; ++ch) {
        const size_t laser = bank * 32 + (spec.lasers == 16 ? ch % 16 : ch);
        ++d.raw_cells[laser];
        d.raw_returns[laser] += read_u16(blk + 4 + 3 * ch) != 0 ? 1u : 0u;
      }
    }
    if (decoder.decode(data[i], clock, times[i], out) != DecodeStatus::kOk) {
      ++d.decode_errors;
      continue;
    }
    d.sink->keep(batcher.add(out, d.sink->current()));
    for (size_t b = 0; b < kBlocks; ++b) {
      const double az = read_u16(data[i].data() + b * kBlockSize + 2) * 0.01;
      if (prev_az >= 0) {
        const double step = std::fmod(az - prev_az + 360.0, 360.0);
        if (step > 0 && step < 5.0) steps.push_back(step);
        const double to_cut = std::fmod(kCut - prev_az + 360.0, 360.0);
        if (to_cut > 0 && to_cut <= step) ++d.raw_cut_crossings;
      }
      prev_az = az;
    }
  }
  while (batcher.flush(d.sink->current())) d.sink->keep(true);
  d.stats = batcher.stats();
  // Median step between blocks of distinct azimuth; such blocks are one block duration apart.
  std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
  const double block_us = spec.firings_per_block * spec.firing_period_us;
  d.raw_rpm = steps[steps.size() / 2] / block_us * 1e6 / 6.0;
  return d;
}

struct Expect {
  const char* file;
  Model model;
  ReturnMode mode;
  size_t position_packets;
  bool gprmc;
  PpsStatus pps;
};

class Captures : public ::testing::TestWithParam<Expect> {};

TEST_P(Captures, DecodeIntoWholeRotations) {
  const Expect e = GetParam();
  const std::string path = capture(e.file);
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "real captures not found at " << path;
  const Decoded d = decode_capture(path);
  const ModelSpec& spec = model_spec(e.model);
  EXPECT_EQ(d.model, e.model);
  EXPECT_EQ(d.mode, e.mode);
  EXPECT_EQ(d.mismatch, "");
  EXPECT_EQ(d.decode_errors, 0u);
  EXPECT_EQ(d.position, e.position_packets);
  if (e.gprmc) {
    EXPECT_EQ(d.gprmc, e.position_packets) << "every position packet carries a valid $GPRMC";
    EXPECT_EQ(d.pps, e.pps);
  }
  EXPECT_EQ(d.stats.missing_packets, 0u);
  // Every cut crossing of the raw azimuths ends a rotation; the ones between two are whole.
  ASSERT_GE(d.raw_cut_crossings, 1);
  EXPECT_EQ(d.stats.complete, static_cast<uint64_t>(d.raw_cut_crossings - 1));
  EXPECT_EQ(d.stats.rotations, static_cast<uint64_t>(d.raw_cut_crossings + 1));
  for (const Scan* s : d.sink->scans) {
    if (!s->complete) continue;
    EXPECT_NEAR(s->rpm, d.raw_rpm, 0.03 * d.raw_rpm);  // the median step is whole 0.01 deg
    for (int ring = 0; ring < s->rings; ++ring) {
      const auto laser = static_cast<size_t>(spec.laser_of_ring(ring));
      size_t n = 0;
      double ref = -1, prev = -1;
      for (int c = 0; c < s->columns; ++c) {
        for (int r = 0; r < s->returns; ++r) {
          const size_t i = s->at(r, ring, c);
          ASSERT_FALSE(std::isnan(s->x[i]) || std::isnan(s->y[i]) || std::isnan(s->z[i]));
          if (!s->valid(i)) continue;
          ++n;
          ASSERT_GE(s->range[i], spec.min_range_m);
          ASSERT_LE(s->range[i], spec.max_range_m);
          if (r != 0) continue;
          // Unwrap from this laser's azimuth at column 0 (each laser has its own offset).
          if (ref < 0)
            ref = s->azimuth_deg[i] - 0.001 -
                  std::fmod(s->column_azimuth_deg[static_cast<size_t>(c)] -
                                s->column_azimuth_deg[0] + 360.0,
                            360.0);
          const double az = std::fmod(s->azimuth_deg[i] - ref + 720.0, 360.0);
          EXPECT_GT(az, prev) << e.file << " ring " << ring << " column " << c;
          prev = az;
        }
      }
      // Real sensors have dead or nearly blind lasers (the VLP-16 dual capture's laser 0, the
      // HDL-32E's laser 11, the VLS-128's laser 82 never return): a ring must be populated when
      // its laser returns in more than 5 % of its firings across the capture.
      if (d.raw_returns[laser] * 20 > d.raw_cells[laser]) {
        EXPECT_GT(n, 0u) << e.file << ": ring " << ring << " (laser " << laser << ") is empty";
      }
      if (d.raw_returns[laser] == 0) {
        EXPECT_EQ(n, 0u);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Real, Captures,
    ::testing::Values(
        Expect{"vlp16_mrpt_gps.pcap", Model::kVLP16, ReturnMode::kStrongest, 57, true,
               PpsStatus::kLocked},
        Expect{"vlp16_rlu.pcap", Model::kVLP16, ReturnMode::kStrongest, 0, false, {}},
        Expect{"vlp16_dual_nebula.pcap", Model::kVLP16, ReturnMode::kDual, 0, false, {}},
        Expect{"vlp32c_nebula_fov.pcap", Model::kVLP32C, ReturnMode::kStrongest, 0, false, {}},
        Expect{"vls128_nebula.pcap", Model::kVLS128, ReturnMode::kStrongest, 0, false, {}},
        Expect{"hdl32e_mrpt.pcap", Model::kHDL32E, ReturnMode::kStrongest, 0, false, {}},
        // This HDL-32E's firmware reports no PPS state in its position packets.
        Expect{"hdl32e_rlu_gps.pcap", Model::kHDL32E, ReturnMode::kStrongest, 100, true,
               PpsStatus::kAbsent}),
    [](const ::testing::TestParamInfo<Expect>& param_info) {
      std::string n = param_info.param.file;
      n = n.substr(0, n.find('.'));
      return n;
    });

}  // namespace
}  // namespace lidartag::velodyne
