// Reads every rotation of a CaptureReader and checks each (test/io/scan_invariants.hpp); returns
// the count and how many were complete. Where the reader assembles into scans the caller owns
// (CaptureReader::read(Scan&, timeout)), two scans live across inputs, so that their storage (up
// to 24 MB, zero-filled, for a VLS-128) is allocated once per process rather than once per input:
// a reader per input is what keeps inputs independent, and the scans' allocation is then most of
// a target's time. Otherwise next() and the reader's own scans. Chosen at compile time.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "io/scan_invariants.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::fuzz {

struct RotationCounts {
  uint64_t rotations = 0, complete = 0;
};

template <class Reader>
RotationCounts read_rotations(Reader& reader, size_t input_size) {
  RotationCounts n;
  auto check_one = [&](const Scan& scan) {
    ++n.rotations;
    n.complete += scan.complete ? 1 : 0;
    check(reader.model().has_value(), "a rotation without a model");
    const std::string problem = test::scan_problem(scan, *reader.model());
    check(problem.empty(), "rotation " + std::to_string(n.rotations) + ": " + problem);
    check(n.rotations <= input_size, "more rotations than input bytes");
  };
  if constexpr (requires(Reader & r, Scan & s) { r.read(s, std::chrono::milliseconds(0)); }) {
    static Scan scans[2];
    int k = 0;
    for (;;) {
      const auto result = reader.read(scans[k], std::chrono::milliseconds(0));
      if (result == Reader::ReadResult::kEnd) break;
      if (result != Reader::ReadResult::kRotation) continue;
      check_one(scans[k]);
      k ^= 1;
    }
  } else {
    while (const Scan* scan = reader.next()) check_one(*scan);
  }
  return n;
}

}  // namespace lidartag::fuzz
