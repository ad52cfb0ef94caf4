#include "lidartag/driver/velodyne/packet.hpp"

#include <algorithm>
#include <charconv>

namespace lidartag::velodyne {
namespace {

// Days since 1970-01-01 of a civil date (proleptic Gregorian).
int64_t days_from_civil(int64_t y, int64_t m, int64_t d) {
  y -= m <= 2 ? 1 : 0;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const int64_t yoe = y - era * 400;
  const int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

bool parse_digits(std::string_view s, int& out) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

}  // namespace

std::string_view pps_status_name(PpsStatus s) {
  switch (s) {
    case PpsStatus::kAbsent:
      return "absent";
    case PpsStatus::kSynchronizing:
      return "synchronizing";
    case PpsStatus::kLocked:
      return "locked";
    case PpsStatus::kError:
      return "error";
  }
  return "invalid";
}

bool nmea_checksum_ok(std::string_view sentence) {
  const size_t star = sentence.rfind('*');
  if (sentence.empty() || sentence[0] != '$' || star == std::string_view::npos ||
      star + 3 != sentence.size()) {
    return false;
  }
  uint8_t sum = 0;
  for (size_t i = 1; i < star; ++i) sum = static_cast<uint8_t>(sum ^ sentence[i]);
  unsigned sent = 0;
  const auto r = std::from_chars(sentence.data() + star + 1, sentence.data() + star + 3, sent, 16);
  return r.ec == std::errc() && r.ptr == sentence.data() + star + 3 && sent == sum;
}

bool parse_gprmc_time(std::string_view sentence, int64_t& utc_ns, bool& valid_fix) {
  // $GPRMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,...
  if (sentence.size() < 7 || sentence[0] != '$' || sentence.substr(3, 3) != "RMC") return false;
  std::array<std::string_view, 10> field{};
  size_t start = 7, n = 0;
  while (n < field.size() && start <= sentence.size()) {
    const size_t comma = sentence.find(',', start);
    const size_t end = comma == std::string_view::npos ? sentence.size() : comma;
    field[n++] = sentence.substr(start, end - start);
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (n < 9) return false;
  const std::string_view time = field[0], date = field[8];
  valid_fix = field[1] == "A";
  int hh, mm, ss, dd, mo, yy;
  if (time.size() < 6 || date.size() != 6) return false;
  if (!parse_digits(time.substr(0, 2), hh) || !parse_digits(time.substr(2, 2), mm) ||
      !parse_digits(time.substr(4, 2), ss) || !parse_digits(date.substr(0, 2), dd) ||
      !parse_digits(date.substr(2, 2), mo) || !parse_digits(date.substr(4, 2), yy))
    return false;
  if (hh > 23 || mm > 59 || ss > 60 || dd < 1 || dd > 31 || mo < 1 || mo > 12) return false;
  int64_t frac_ns = 0;
  if (time.size() > 7 && time[6] == '.') {
    int64_t scale = 100000000;
    for (size_t i = 7; i < time.size() && scale > 0; ++i, scale /= 10) {
      if (time[i] < '0' || time[i] > '9') return false;
      frac_ns += (time[i] - '0') * scale;
    }
  }
  const int64_t days = days_from_civil(yy < 80 ? 2000 + yy : 1900 + yy, mo, dd);  // NMEA years
  utc_ns = ((days * 24 + hh) * 3600 + mm * 60 + ss) * 1'000'000'000LL + frac_ns;
  return true;
}

PositionStatus parse_position_packet(std::span<const uint8_t> payload, PositionPacket& out) {
  if (payload.size() != kPositionPacketSize) return PositionStatus::kWrongSize;
  const uint8_t* p = payload.data();
  out = PositionPacket{};
  out.usec_since_hour = read_u32(p + kPositionTimestampOffset);
  const uint8_t pps = p[kPpsStatusOffset];
  // Keep printable characters only: a corrupt sentence must not carry control bytes onward.
  size_t n = 0;
  for (; n < kNmeaMaxLength; ++n) {
    const char c = static_cast<char>(p[kNmeaOffset + n]);
    if (c == '\0' || c == '\r' || c == '\n') break;
    out.nmea[n] = (c >= 0x20 && c < 0x7F) ? c : '?';
  }
  out.nmea[n] = '\0';
  int64_t utc_ns = 0;
  bool valid = false;
  const bool rmc = parse_gprmc_time(out.sentence(), utc_ns, valid);
  // A sentence that fails its checksum (corrupt, or forged by hand) is no time source.
  const bool checked = !rmc || nmea_checksum_ok(out.sentence());
  if (rmc && checked && valid) {
    out.has_gprmc = true;
    out.gps_fix_ns = utc_ns;
  }
  if (pps > 3) return PositionStatus::kBadPps;
  out.pps = static_cast<PpsStatus>(pps);
  return checked ? PositionStatus::kOk : PositionStatus::kBadChecksum;
}

}  // namespace lidartag::velodyne
