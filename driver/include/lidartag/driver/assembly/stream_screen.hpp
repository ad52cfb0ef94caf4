// Which packets belong to the stream (docs/scan-assembly.md, "Which packets belong to the
// stream"): duplicates, packets too late to be put in place, stray packets (spoofed, another
// sensor, garbage) and the candidates of a new stream (restart, clock jump, replay loop).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>

#include "lidartag/driver/assembly/reorder_window.hpp"
#include "lidartag/driver/columns.hpp"

namespace lidartag::driver {

class StreamScreen {
 public:
  // Consecutive packets that agree with each other but not with the stream, with no packet of
  // the stream in between, that make a new stream.
  static constexpr int kNewStreamPackets = 3;

  enum class Verdict : uint8_t { kAccept, kAcceptHeadWasStray, kDuplicate, kTooLate, kSuspect };
  // What became of a packet that does not fit the stream.
  enum class Candidate : uint8_t { kHeld, kReplacedStray, kDropped };

  // What screening needs of a stream's newest packet.
  struct Ref {
    int64_t stamp_ns = 0;  // first column
    float first_azimuth_deg = 0, last_azimuth_deg = 0;
    float rate_deg_per_us = 0;  // measured inside the packet
  };

  StreamScreen(const SensorLayout& layout, double flush_timeout_s);

  // `last_written_ns`: the time of the newest column already in the rotation, if any.
  Verdict screen(const ColumnPacket& packet, const ReorderWindow& window,
                 std::optional<int64_t> last_written_ns) const;
  // A packet went into the window; one left it for the rotation.
  void taken(const ColumnPacket& packet);
  void released(const ColumnPacket& packet);
  // The newest packet taken was a stray one: the one before it is the stream's newest again.
  void drop_head();
  // The stream ended: nothing is known of its packets any more.
  void forget_stream() { have_head_ = have_previous_head_ = false; }
  bool has_head() const { return have_head_; }
  const Ref& head() const { return head_; }

  // Candidates of a new stream: a packet that does not fit the stream is held if it continues
  // the candidates before it.
  Candidate add_candidate(const ColumnPacket& packet);
  // A packet that starts a new stream by itself (another return mode).
  void start_candidates(const ColumnPacket& packet);
  int candidates() const { return candidate_count_; }
  const ColumnPacket& candidate(int i) const { return candidates_[i].columns(); }
  // Forgets the candidates; returns how many there were.
  int clear_candidates();

 private:
  static constexpr int kHistory = 16;  // released packets remembered to recognise duplicates

  static Ref ref_of(const ColumnPacket& packet);
  // Whether `packet` continues a stream whose newest packet is `ref` (time and azimuth agree).
  bool fits(const Ref& ref, const ColumnPacket& packet) const;

  const SensorLayout& layout_;
  double flush_timeout_s_;
  bool have_head_ = false, have_previous_head_ = false;
  Ref head_{}, previous_head_{};
  std::array<int64_t, kHistory> released_stamp_{};
  std::array<float, kHistory> released_azimuth_{};
  int released_count_ = 0;
  HeldPackets candidates_;
  int candidate_count_ = 0;
};

}  // namespace lidartag::driver
