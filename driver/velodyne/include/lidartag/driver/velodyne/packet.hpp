// Velodyne UDP payload layouts (velodyne.md). Little-endian on the wire.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>

#include "lidartag/driver/packet_source.hpp"

namespace lidartag::velodyne {

inline constexpr size_t kDataPacketSize = 1206;     // UDP payload, port 2368
inline constexpr size_t kPositionPacketSize = 512;  // UDP payload, port 8308
inline constexpr size_t kBlocks = 12;
inline constexpr size_t kBlockSize = 100;  // flag(2) azimuth(2) 32 x (distance(2) refl(1))
inline constexpr size_t kChannelsPerBlock = 32;
inline constexpr size_t kTimestampOffset = 1200;  // uint32, us since the top of the hour
inline constexpr size_t kReturnModeOffset = 1204;
inline constexpr size_t kProductIdOffset = 1205;
inline constexpr uint16_t kMaxAzimuth = 35999;  // hundredths of a degree
using driver::kDefaultDataPort;                 // 2368 (the io sources' defaults)
using driver::kDefaultPositionPort;             // 8308

// Block flags as read little-endian: FF EE -> 0xEEFF. VLS-128 banks 0..3 use EE, DD, CC, BB.
inline constexpr std::array<uint16_t, 4> kBankFlags = {0xEEFF, 0xDDFF, 0xCCFF, 0xBBFF};

inline constexpr size_t kPositionTimestampOffset = 198;
inline constexpr size_t kPpsStatusOffset = 202;
inline constexpr size_t kNmeaOffset = 206;
inline constexpr size_t kNmeaMaxLength = 128;

inline uint16_t read_u16(const uint8_t* p) {
  return static_cast<uint16_t>(p[0] | (p[1] << 8));
}
inline uint32_t read_u32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}
inline void write_u16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v & 0xFF);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline void write_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>((v >> (8 * i)) & 0xFF);
}

enum class PpsStatus : uint8_t { kAbsent = 0, kSynchronizing = 1, kLocked = 2, kError = 3 };
std::string_view pps_status_name(PpsStatus s);

// Position (telemetry) packet contents.
struct PositionPacket {
  uint32_t usec_since_hour = 0;
  PpsStatus pps = PpsStatus::kAbsent;
  std::array<char, kNmeaMaxLength + 1> nmea{};  // NUL-terminated sentence as sent
  bool has_gprmc = false;                       // a $GPRMC sentence with a valid ('A') fix
  int64_t gps_fix_ns = 0;                       // UTC of the GPRMC fix, ns since epoch, when valid
  std::string_view sentence() const { return {nmea.data(), std::strlen(nmea.data())}; }
};

// kBadChecksum: a $GPRMC whose NMEA checksum (*hh, mandatory for RMC) is missing or wrong; its
// time is not used (has_gprmc false).
enum class PositionStatus : uint8_t { kOk, kWrongSize, kBadPps, kBadChecksum };

// Pure parse; never throws, never reads outside `payload`.
[[nodiscard]] PositionStatus parse_position_packet(std::span<const uint8_t> payload,
                                                   PositionPacket& out);

// True when `sentence` ends in "*hh" and hh is the XOR of the characters between '$' and '*'.
bool nmea_checksum_ok(std::string_view sentence);

// UTC seconds since the epoch of a GPRMC time (hhmmss.ss) and date (ddmmyy); false if malformed.
bool parse_gprmc_time(std::string_view sentence, int64_t& utc_ns, bool& valid_fix);

}  // namespace lidartag::velodyne
