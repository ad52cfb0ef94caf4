// A paced UDP sender of real capture payloads, with the faults of a bad network and a hostile
// one: loss, reordering, duplicates, a sensor restart, junk datagrams (0-65,507 bytes) to wrong
// ports and to the sensor's port. Loopback only (the load harness runs it inside its own network
// namespace); bounded by its duration, stops by itself.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

namespace lidartag::load {

struct SenderOptions {
  std::string capture;                       // pcap/pcapng: data (2368) and position (8308) packets
  std::string source_address = "127.0.0.1";  // the "sensor" address the datagrams come from
  std::string destination = "127.0.0.1";
  uint16_t data_port = 2368;  // where the daemon listens (the capture's own ports are mapped)
  uint16_t position_port = 8308;
  double rate = 1.0;            // multiple of the capture's pace; 0 = as fast as possible
  double seconds = 10.0;        // sending time (the capture loops seamlessly)
  double loss = 0.0;            // probability that a data packet is not sent
  double reorder = 0.0;         // probability that a data packet is sent after the next one
  double duplicate = 0.0;       // probability that a data packet is sent twice
  double junk_ratio = 0.0;      // junk datagrams per capture packet sent
  double junk_to_sensor = 0.1;  // fraction of the junk sent to the data port (never 1206 bytes)
  // Datagrams of a data packet's size (1206 bytes: the model probe's) sent to the data port
  // before the sensor's first packet: zeros, the first with a VLP-16 product byte (0x22).
  uint64_t probe_junk = 0;
  double restart_after_s = 0.0;    // > 0: after this long the sensor restarts: silence, then the
  double restart_silence_s = 2.0;  //   capture from its start with its original (earlier) clock
  uint32_t seed = 1;
};

struct SenderCounts {
  uint64_t data = 0, position = 0;  // capture packets sent (duplicates included)
  uint64_t lost = 0, reordered = 0, duplicated = 0;
  uint64_t junk_wrong_port = 0, junk_sensor_port = 0;
  uint64_t restarts = 0, loops = 0;
  uint64_t send_errors = 0;  // sendto failures (ENOBUFS...): not on the wire
  uint64_t bytes = 0;
  double seconds = 0;  // time actually spent sending
  // Datagrams that reached the sensor's ports: what the daemon must account for.
  uint64_t to_sensor_ports() const { return data + position + junk_sensor_port; }
};

// The capture's packets, cut to whole rotations (from the first to the last crossing of the
// 180 degree cut) so that it loops without a seam: the payload clock is shifted by the capture's
// span on every pass.
struct Capture {
  struct Packet {
    std::vector<uint8_t> payload;
    int64_t time_ns;
    bool position;
  };
  std::vector<Packet> packets;
  int64_t span_ns = 0;         // one pass, from the first packet to the first of the next pass
  uint32_t span_clock_us = 0;  // the same on the sensor's microsecond clock
  double data_rate_hz = 0;     // data packets per second at 1x
};
// Throws std::runtime_error when the file cannot be read or holds no data packets.
Capture load_capture(const std::string& path, uint16_t data_port = 2368,
                     uint16_t position_port = 8308);

// Sends until `options.seconds` passed or `stop` is set. Thread-safe counts are returned.
SenderCounts send(const Capture& capture, const SenderOptions& options,
                  const std::atomic<bool>& stop);

}  // namespace lidartag::load
