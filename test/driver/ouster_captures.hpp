// The real Ouster captures of ../shared/captures/ouster (README there): where they are and their
// packets, read with the project's pcap source (lidar on 7502, IMU on 7503).
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/ouster/packet.hpp"

namespace lidartag::driver::ouster::testing {

inline std::string ouster_dir() {
  return std::string(LIDARTAG_SHARED_DIR) + "/captures/ouster";
}

struct CaptureFile {
  std::string pcap;      // stem of pcaps/NAME.pcap
  std::string metadata;  // stem of pcaps/NAME.json
  bool has_digest;
  size_t lidar_packets, imu_packets, frames;
  int rings, returns;
};

// The README's table, with the IMU packets counted from the files.
inline const std::vector<CaptureFile>& capture_files() {
  static const std::vector<CaptureFile> files = {
      {"OS-1-32-G_v2.1.1_1024x10", "OS-1-32-G_v2.1.1_1024x10", true, 64, 0, 1, 32, 1},
      {"OS-2-32-U0_v2.0.0_1024x10", "OS-2-32-U0_v2.0.0_1024x10", true, 64, 0, 1, 32, 1},
      {"OS-0-32-U1_v2.2.0_1024x10", "OS-0-32-U1_v2.2.0_1024x10", true, 64, 10, 1, 32, 2},
      {"OS-0-128-U1_v2.3.0_1024x10", "OS-0-128-U1_v2.3.0_1024x10", true, 64, 10, 1, 128, 1},
      {"OS-2-128-U1_v2.3.0_1024x10", "OS-2-128-U1_v2.3.0_1024x10", true, 64, 10, 1, 128, 1},
      {"OS-1-128_v2.3.0_1024x10_lb_n3", "OS-1-128_v2.3.0_1024x10", false, 192, 30, 3, 128, 1},
      {"OS-1-128_767798045_1024x10_20230712_120049", "OS-1-128_767798045_1024x10_20230712_120049",
       false, 8, 2, 1, 128, 2},
  };
  return files;
}

struct Packets {
  std::vector<std::vector<uint8_t>> lidar;
  size_t imu = 0;
  size_t imu_wrong_size = 0;
};

inline Packets read_packets(const std::string& path) {
  PcapSourceOptions o;
  o.data_port = kLidarPort;
  o.position_port = kImuPort;
  PcapSource source(path, o);
  Packets out;
  RawPacket raw;
  while (source.next(raw, std::chrono::milliseconds(0)) == ReadStatus::kPacket) {
    if (raw.destination_port == kLidarPort) {
      out.lidar.emplace_back(raw.payload.begin(), raw.payload.end());
    } else {
      ++(raw.payload.size() == kImuPacketSize ? out.imu : out.imu_wrong_size);
    }
  }
  return out;
}

}  // namespace lidartag::driver::ouster::testing
