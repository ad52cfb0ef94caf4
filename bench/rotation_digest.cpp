// `rotation_digest CAPTURE [CUT_DEG]`: every rotation of a capture (partial ones included) as one
// line (its fields and a hash of every cell of its points and columns), then every counter of the
// batcher and the reader. Two builds that print the same lines assemble the capture identically,
// bit for bit: bench/compare_rotations.sh runs it over the captures and their mutations.
#include <cstdint>
#include <cstdio>
#include <exception>
#include <span>
#include <string>

#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace {

using lidartag::Scan;

// FNV-1a over the bytes of `values`.
template <class T>
uint64_t mix(uint64_t h, std::span<const T> values) {
  for (const std::byte b : std::as_bytes(values)) {
    h ^= static_cast<uint64_t>(b);
    h *= 1099511628211ull;
  }
  return h;
}

uint64_t digest(const Scan& s) {
  uint64_t h = 1469598103934665603ull;
  const auto n = static_cast<size_t>(s.columns);
  for (int ret = 0; ret < s.returns; ++ret) {
    for (int ring = 0; ring < s.rings; ++ring) {
      const size_t c = s.at(ret, ring, 0);
      h = mix(h, std::span(s.x).subspan(c, n));
      h = mix(h, std::span(s.y).subspan(c, n));
      h = mix(h, std::span(s.z).subspan(c, n));
      h = mix(h, std::span(s.range).subspan(c, n));
      h = mix(h, std::span(s.azimuth_deg).subspan(c, n));
      h = mix(h, std::span(s.time_s).subspan(c, n));
      h = mix(h, std::span(s.intensity).subspan(c, n));
      h = mix(h, std::span(s.return_type).subspan(c, n));
    }
  }
  h = mix(h, std::span(s.column_azimuth_deg).first(n));
  return mix(h, std::span(s.column_time_s).first(n));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: rotation_digest CAPTURE [CUT_DEG]\n");
    return 2;
  }
  lidartag::velodyne::CaptureReaderOptions options;
  if (argc > 2) options.batcher.cut_azimuth_deg = std::stod(argv[2]);
  try {
    lidartag::velodyne::CaptureReader reader(argv[1], options);
    while (const Scan* s = reader.next()) {
      std::printf(
          "rotation %llu complete %d cut %d %d stamp %lld columns %d packets %d missing %u "
          "jumps %u rpm %.6f model %d mode %d rings %d returns %d hash %016llx\n",
          static_cast<unsigned long long>(s->sequence), s->complete, s->starts_at_cut,
          s->ends_at_cut, static_cast<long long>(s->stamp_ns), s->columns, s->packets,
          static_cast<unsigned>(s->missing_packets), static_cast<unsigned>(s->azimuth_jumps),
          static_cast<double>(s->rpm), s->model, s->return_mode, s->rings, s->returns,
          static_cast<unsigned long long>(digest(*s)));
    }
    const auto b = reader.batcher_stats();
    const auto& k = reader.counts();
    const uint64_t counts[] = {b.rotations,     b.complete,     b.incomplete,   b.missing_packets,
                               b.azimuth_jumps, b.fov_gaps,     b.overflows,    b.mode_changes,
                               b.duplicates,    b.reordered,    b.late_packets, b.inconsistent,
                               k.data_packets,  k.decoded,      k.undecodable,  k.model_mismatch,
                               k.model_changes, k.failed_probes};
    std::printf("counts");
    for (const uint64_t c : counts) std::printf(" %llu", static_cast<unsigned long long>(c));
    std::printf("\n");
  } catch (const std::exception& e) {
    std::printf("error %s\n", e.what());
  }
  return 0;
}
