// Seeded mutations of the bundled and the real captures (byte flips in payloads, record headers
// and IP/UDP headers; truncation; duplicated, reordered, dropped and zero-length records; huge
// lengths; time jumps) through CaptureReader and the Detector. Whatever the damage: the reader
// ends, every point of every rotation is finite and in its ring, damage that can be seen is
// counted, and the detector finds nothing that was not there.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "pcap_builder.hpp"
#include "scan_invariants.hpp"

namespace lidartag::velodyne {
namespace {

namespace fs = std::filesystem;
using test::Bytes;

const std::string kPcaps = LIDARTAG_SOURCE_DIR "/pcaps/";
const std::string kCaptures = LIDARTAG_SHARED_DIR "/captures/";

constexpr size_t kGlobalHeader = 24, kRecordHeader = 16;
constexpr size_t kNetHeaders = 42;  // Ethernet 14, IPv4 20, UDP 8

uint32_t le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
         static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
}
void set_le32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

// A classic little-endian pcap split into its records, each with its 16-byte header.
struct Capture {
  Bytes global;
  std::vector<Bytes> records;

  Bytes bytes() const {
    Bytes b = global;
    for (const Bytes& r : records) test::append(b, r);
    return b;
  }
};

Bytes read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  Bytes b(fs::file_size(path));
  in.read(reinterpret_cast<char*>(b.data()), static_cast<std::streamsize>(b.size()));
  return b;
}

Capture split(const Bytes& file) {
  Capture c;
  c.global.assign(file.begin(), file.begin() + kGlobalHeader);
  size_t off = kGlobalHeader;
  while (off + kRecordHeader <= file.size()) {
    const size_t end = off + kRecordHeader + le32(file.data() + off + 8);
    if (end > file.size()) break;
    c.records.emplace_back(file.begin() + static_cast<std::ptrdiff_t>(off),
                           file.begin() + static_cast<std::ptrdiff_t>(end));
    off = end;
  }
  return c;
}

// Records [first, first + n) of a capture.
Capture window(const Capture& c, size_t first, size_t n) {
  Capture w;
  w.global = c.global;
  const size_t end = std::min(c.records.size(), first + n);
  w.records.assign(c.records.begin() + static_cast<std::ptrdiff_t>(first),
                   c.records.begin() + static_cast<std::ptrdiff_t>(end));
  return w;
}

int64_t record_time_us(const Bytes& r) {
  return int64_t{le32(r.data())} * 1'000'000 + le32(r.data() + 4);
}
void set_record_time_us(Bytes& r, int64_t us) {
  set_le32(r.data(), static_cast<uint32_t>(us / 1'000'000));
  set_le32(r.data() + 4, static_cast<uint32_t>(us % 1'000'000));
}

struct Temp {
  std::string path;
  explicit Temp(const std::string& name)
      : path((fs::path(::testing::TempDir()) /
              ("lidartag_mutation_" + std::to_string(::getpid()) + "_" + name))
                 .string()) {}
  ~Temp() {
    std::error_code ec;
    fs::remove(path, ec);
  }
};

// What one pass of a capture through the reader and the detector gave.
struct Outcome {
  size_t rotations = 0, complete = 0, points = 0;
  std::vector<std::pair<std::string, int>> detections;  // (family, id), every rotation
  CaptureCounts counts;
  driver::SourceStats source;
  driver::BatcherStats batcher;
  bool opened = true;  // false: the file was refused at open (an IoError, also fine)
};

uint64_t decode_errors(const Outcome& o) {
  uint64_t n = 0;
  for (uint64_t e : o.counts.decode_errors) n += e;
  return n;
}

void check_detection(const detector::Detection& d, const std::string& what) {
  bool finite = d.position.allFinite() && d.orientation.coeffs().allFinite() &&
                std::isfinite(d.score) && std::isfinite(d.margin) && std::isfinite(d.size_m) &&
                std::isfinite(d.fit_cost);
  for (const auto& c : d.corners) finite = finite && c.allFinite();
  EXPECT_TRUE(finite) << what << ": detection with a non-finite value";
  EXPECT_GE(d.id, 0) << what;
}

// Reads the capture at `path`, runs the detector on every rotation and checks every rotation.
// The number of rotations is bounded by the records (a reader that never ends fails here).
Outcome run(const std::string& path, size_t records, detector::Detector& det,
            const std::string& what) {
  Outcome o;
  std::unique_ptr<CaptureReader> reader;
  try {
    reader = std::make_unique<CaptureReader>(path, CaptureReaderOptions{});
  } catch (const driver::IoError&) {
    o.opened = false;  // a mangled global header: refused with a message, which is fine
    return o;
  }
  detector::ScanResult result;
  const size_t bound = 3 * records + 10;
  while (const Scan* scan = reader->next()) {
    if (++o.rotations > bound) {
      ADD_FAILURE() << what << ": more than " << bound << " rotations from " << records
                    << " records";
      break;
    }
    const auto model = reader->model();
    if (!model) {
      ADD_FAILURE() << what << ": a rotation without a model";
      break;
    }
    const std::string problem = test::scan_problem(*scan, *model);
    if (!problem.empty()) {
      [&] { FAIL() << what << ": " << problem; }();  // fatal: the caller stops
      return o;
    }
    o.complete += scan->complete ? 1 : 0;
    o.points += scan->point_count();
    det.detect(*scan, result);
    for (const auto& d : result.detections) {
      check_detection(d, what);
      o.detections.emplace_back(std::string(d.family), d.id);
    }
  }
  o.counts = reader->counts();
  o.source = reader->source_stats();
  o.batcher = reader->batcher_stats();
  // Every packet delivered is accounted for exactly once.
  const CaptureCounts& c = o.counts;
  EXPECT_EQ(c.data_packets + c.position_packets, o.source.packets) << what;
  EXPECT_EQ(c.decoded + decode_errors(o) + c.undecodable, c.data_packets) << what;
  EXPECT_EQ(c.position_ok + c.position_errors, c.position_packets) << what;
  return o;
}

// ---- Mutations. Each takes the records and the generator; the file is written afterwards. ----

using Rng = std::mt19937;

size_t pick(Rng& rng, size_t n) {
  return static_cast<size_t>(rng() % n);
}

// Flips 1..8 random bytes of record `r` in [from, size).
void flip_bytes(Bytes& r, size_t from, Rng& rng) {
  if (r.size() <= from) return;
  const int n = 1 + static_cast<int>(rng() % 8);
  for (int k = 0; k < n; ++k)
    r[from + pick(rng, r.size() - from)] ^= static_cast<uint8_t>(1 + rng() % 255);
}

enum class Mutation {
  kFlipPayload,
  kFlipRecordHeader,
  kFlipNetHeaders,
  kDuplicate,
  kReorder,
  kDrop,
  kZeroLength,
  kHugeLength,
  kShortCaplen,
  kTimeJump,
  kCount
};

void mutate(Capture& c, Mutation m, Rng& rng) {
  auto& recs = c.records;
  if (recs.empty()) return;
  const size_t i = pick(rng, recs.size());
  switch (m) {
    case Mutation::kFlipPayload:
      flip_bytes(recs[i], kRecordHeader + kNetHeaders, rng);
      break;
    case Mutation::kFlipRecordHeader: {
      Bytes& r = recs[i];
      r[pick(rng, kRecordHeader)] ^= static_cast<uint8_t>(1 + rng() % 255);
      break;
    }
    case Mutation::kFlipNetHeaders: {
      Bytes& r = recs[i];
      r[kRecordHeader + pick(rng, std::min(kNetHeaders, r.size() - kRecordHeader))] ^=
          static_cast<uint8_t>(1 + rng() % 255);
      break;
    }
    case Mutation::kDuplicate:
      recs.insert(recs.begin() + static_cast<std::ptrdiff_t>(i), recs[i]);
      break;
    case Mutation::kReorder: {
      const size_t j = std::min(recs.size() - 1, i + 1 + pick(rng, 5));
      std::swap(recs[i], recs[j]);
      break;
    }
    case Mutation::kDrop: {
      const size_t n = std::min(recs.size() - i, 1 + pick(rng, 20));
      recs.erase(recs.begin() + static_cast<std::ptrdiff_t>(i),
                 recs.begin() + static_cast<std::ptrdiff_t>(i + n));
      break;
    }
    case Mutation::kZeroLength: {
      Bytes z(recs[i].begin(), recs[i].begin() + kRecordHeader);
      set_le32(z.data() + 8, 0);
      set_le32(z.data() + 12, 0);
      recs.insert(recs.begin() + static_cast<std::ptrdiff_t>(i), z);
      break;
    }
    case Mutation::kHugeLength: {
      // caplen and/or len far beyond the file (the data stay where they were).
      const uint32_t huge[] = {0xFFFFFFFFu, 0x80000000u, 0x00040001u, 65536u, 1u << 20};
      const uint32_t v = huge[pick(rng, std::size(huge))];
      set_le32(recs[i].data() + (rng() % 2 ? 8 : 12), v);
      break;
    }
    case Mutation::kShortCaplen: {
      // A consistent record whose captured data stop early (snap length), len unchanged.
      Bytes& r = recs[i];
      const size_t keep = pick(rng, r.size() - kRecordHeader);
      r.resize(kRecordHeader + keep);
      set_le32(r.data() + 8, static_cast<uint32_t>(keep));
      break;
    }
    case Mutation::kTimeJump: {
      static const int64_t jumps_us[] = {-3'600'000'000LL, -1'000'000,     -1, 1, 100,
                                         2'000'000,        3'600'000'000LL};
      const int64_t t = record_time_us(recs[i]) + jumps_us[pick(rng, std::size(jumps_us))];
      set_record_time_us(recs[i], std::max<int64_t>(0, t));
      break;
    }
    case Mutation::kCount:
      break;
  }
}

struct Source {
  std::string name;
  std::string path;
  detector::DetectorOptions options;
  std::set<std::pair<std::string, int>> tags;  // what may be found (the truth)
  int mutants;
  size_t window;  // records per mutant
};

detector::DetectorOptions options(std::vector<double> sizes, std::vector<std::string> families) {
  detector::DetectorOptions o;
  o.tag_sizes_m = std::move(sizes);
  o.families = std::move(families);
  o.cluster_diagnostics = false;
  return o;
}

std::vector<Source> bundled_sources() {
  return {{"demo",
           kPcaps + "demo.pcap",
           options({0.8, 0.6}, {"tag16h5"}),
           {{"tag16h5", 0}, {"tag16h5", 1}},
           150,
           200},
          {"outdoor",
           kPcaps + "outdoor.pcap",
           options({1.2, 0.8, 0.6}, {"tag16h5", "tag36h11", "tag25h9"}),
           {{"tag16h5", 2}, {"tag36h11", 7}, {"tag25h9", 4}},
           100,
           200}};
}

// Random mutants of `src`: 1-4 mutations of a window of records, sometimes the file cut short.
void fuzz(const Source& src) {
  if (!fs::exists(src.path)) GTEST_SKIP() << "capture not available: " << src.path;
  const Capture whole = split(read_bytes(src.path));
  ASSERT_FALSE(whole.records.empty()) << src.path;
  detector::Detector det(src.options);
  Rng rng(static_cast<uint32_t>(std::hash<std::string>{}(src.name) & 0xFFFFFFFF));
  Temp temp(src.name + ".pcap");
  for (int k = 0; k < src.mutants; ++k) {
    const size_t first =
        pick(rng, whole.records.size() - std::min(whole.records.size() - 1, src.window - 1));
    Capture c = window(whole, first, src.window);
    std::string what = src.name + " mutant " + std::to_string(k) + ":";
    const int n = 1 + static_cast<int>(rng() % 4);
    for (int m = 0; m < n; ++m) {
      const auto kind = static_cast<Mutation>(rng() % static_cast<int>(Mutation::kCount));
      mutate(c, kind, rng);
      what += ' ';  // appended piecewise: GCC 12 -O3 false -Wrestrict on " " + string
      what += std::to_string(static_cast<int>(kind));
    }
    Bytes bytes = c.bytes();
    if (rng() % 8 == 0) {
      bytes.resize(pick(rng, bytes.size()));
      what += " cut at " + std::to_string(bytes.size());
    }
    test::write_file(temp.path, bytes);
    const Outcome o = run(temp.path, c.records.size(), det, what);
    if (::testing::Test::HasFatalFailure()) return;
    for (const auto& d : o.detections)
      EXPECT_TRUE(src.tags.count(d)) << what << ": found " << d.first << " id " << d.second;
  }
}

TEST(CaptureMutation, BundledCapturesSurviveRandomMutations) {
  for (const Source& src : bundled_sources()) {
    SCOPED_TRACE(src.name);
    fuzz(src);
  }
}

TEST(CaptureMutation, RealCapturesSurviveRandomMutations) {
  if (!fs::exists(kCaptures)) GTEST_SKIP() << "real captures not available: " << kCaptures;
  // None of the real captures holds a tag: whatever is found is a false positive.
  for (const char* name : {"vlp16_mrpt_gps", "vlp16_dual_nebula", "vlp32c_nebula_fov",
                           "vls128_nebula", "hdl32e_rlu_gps"}) {
    SCOPED_TRACE(name);
    fuzz({name, kCaptures + name + ".pcap", options({1.2}, {"tag16h5"}), {}, 20, 300});
  }
}

// The mutations that can be recognised, one at a time, each where it must be counted.
TEST(CaptureMutation, EachRecognisableCorruptionIsCounted) {
  const std::string path = kPcaps + "demo.pcap";
  const Capture whole = split(read_bytes(path));
  ASSERT_GT(whole.records.size(), 400u);
  const Capture base = window(whole, 100, 300);
  detector::Detector det(options({0.8, 0.6}, {"tag16h5"}));
  Temp temp("counted.pcap");
  auto outcome = [&](const Capture& c, const std::string& what, size_t cut = 0) {
    Bytes bytes = c.bytes();
    if (cut > 0) bytes.resize(bytes.size() - cut);
    test::write_file(temp.path, bytes);
    return run(temp.path, c.records.size(), det, what);
  };
  const Outcome clean = outcome(base, "clean");
  ASSERT_TRUE(clean.opened);
  EXPECT_EQ(clean.counts.decoded, 300u);
  EXPECT_EQ(decode_errors(clean), 0u);
  EXPECT_EQ(clean.source.truncated + clean.source.malformed + clean.source.ignored, 0u);
  EXPECT_EQ(clean.batcher.missing_packets + clean.batcher.late_packets, 0u);

  struct Case {
    std::string name;
    std::function<void(Capture&)> mutate;
    std::function<bool(const Outcome&)> counted;
    size_t cut = 0;
  };
  auto packet = [](Capture& c, size_t i) { return c.records[i].data() + kRecordHeader; };
  const std::vector<Case> cases = {
      {"block flag", [&](Capture& c) { packet(c, 50)[kNetHeaders + 3 * kBlockSize] = 0x00; },
       [](const Outcome& o) {
         return o.counts.decode_errors[static_cast<size_t>(DecodeStatus::kBadBlockFlag)] == 1;
       }},
      {"azimuth", [&](Capture& c) { write_u16(packet(c, 50) + kNetHeaders + 2, 36000); },
       [](const Outcome& o) {
         return o.counts.decode_errors[static_cast<size_t>(DecodeStatus::kBadAzimuth)] == 1;
       }},
      {"return mode", [&](Capture& c) { packet(c, 50)[kNetHeaders + kReturnModeOffset] = 0x55; },
       [](const Outcome& o) {
         return o.counts.decode_errors[static_cast<size_t>(DecodeStatus::kBadReturnMode)] == 1;
       }},
      {"IP version", [&](Capture& c) { packet(c, 60)[14] = 0x65; },
       [](const Outcome& o) { return o.source.malformed == 1; }},
      {"IP total length", [&](Capture& c) { packet(c, 60)[16] = packet(c, 60)[17] = 0; },
       [](const Outcome& o) { return o.source.malformed == 1; }},
      {"UDP length", [&](Capture& c) { packet(c, 60)[38] = packet(c, 60)[39] = 0xFF; },
       [](const Outcome& o) { return o.source.malformed + o.source.truncated == 1; }},
      {"short payload",
       [&](Capture& c) {
         // One byte less in every length: a consistent datagram of 1205 bytes.
         Bytes& r = c.records[70];
         r.pop_back();
         for (size_t at : {size_t{8}, size_t{12}}) set_le32(r.data() + at, le32(r.data() + at) - 1);
         uint8_t* p = r.data() + kRecordHeader;
         const uint16_t ip_len = static_cast<uint16_t>(p[16] << 8 | p[17]) - 1;
         p[16] = static_cast<uint8_t>(ip_len >> 8);
         p[17] = static_cast<uint8_t>(ip_len);
         const uint16_t udp_len = static_cast<uint16_t>(p[38] << 8 | p[39]) - 1;
         p[38] = static_cast<uint8_t>(udp_len >> 8);
         p[39] = static_cast<uint8_t>(udp_len);
       },
       [](const Outcome& o) {
         return o.counts.decode_errors[static_cast<size_t>(DecodeStatus::kWrongSize)] == 1;
       }},
      {"snap length",
       [&](Capture& c) {
         Bytes& r = c.records[80];
         r.resize(kRecordHeader + 600);
         set_le32(r.data() + 8, 600);
       },
       [](const Outcome& o) { return o.source.truncated == 1; }},
      {"zero-length record",
       [&](Capture& c) {
         Bytes z(c.records[90].begin(), c.records[90].begin() + kRecordHeader);
         set_le32(z.data() + 8, 0);
         set_le32(z.data() + 12, 0);
         c.records.insert(c.records.begin() + 90, z);
       },
       [](const Outcome& o) { return o.source.truncated == 1 && o.counts.decoded == 300; }},
      {"duplicate", [&](Capture& c) { c.records.insert(c.records.begin() + 100, c.records[100]); },
       [](const Outcome& o) {
         return o.batcher.duplicates == 1 && o.batcher.late_packets == 1 && o.counts.decoded == 301;
       }},
      // Put back in place by the reorder window: counted, neither dropped nor missing.
      {"reorder", [&](Capture& c) { std::swap(c.records[110], c.records[111]); },
       [](const Outcome& o) {
         return o.batcher.reordered == 1 && o.batcher.late_packets == 0 &&
                o.batcher.missing_packets == 0;
       }},
      {"drop",
       [&](Capture& c) { c.records.erase(c.records.begin() + 120, c.records.begin() + 125); },
       [](const Outcome& o) { return o.batcher.missing_packets == 5 && o.counts.decoded == 295; }},
      {"huge caplen", [&](Capture& c) { set_le32(c.records[200].data() + 8, 0xFFFFFFF0u); },
       [](const Outcome& o) {
         return o.source.malformed + o.source.truncated == 1 && o.counts.decoded == 200;
       }},
      {"file cut mid-record", [](Capture&) {},
       [](const Outcome& o) { return o.source.truncated == 1 && o.counts.decoded == 299; }, 700},
  };
  for (const Case& k : cases) {
    Capture c = base;
    k.mutate(c);
    const Outcome o = outcome(c, k.name, k.cut);
    ASSERT_TRUE(o.opened) << k.name;
    EXPECT_TRUE(k.counted(o)) << k.name << ": decoded " << o.counts.decoded << ", decode errors "
                              << decode_errors(o) << ", source truncated " << o.source.truncated
                              << " malformed " << o.source.malformed << " ignored "
                              << o.source.ignored << ", batcher missing "
                              << o.batcher.missing_packets << " late " << o.batcher.late_packets;
    for (const auto& d : o.detections)
      EXPECT_TRUE(d.first == "tag16h5" && (d.second == 0 || d.second == 1)) << k.name;
  }
}

// The unmutated bundled capture, split and joined again by the mutator, still gives its normal
// result: every packet decoded, nothing counted, both tags in every complete rotation.
TEST(CaptureMutation, UnmutatedCaptureGivesItsNormalResult) {
  const std::string path = kPcaps + "demo.pcap";
  const Bytes original = read_bytes(path);
  const Capture c = split(original);
  ASSERT_EQ(c.bytes(), original);
  Temp temp("unmutated.pcap");
  test::write_file(temp.path, c.bytes());
  detector::Detector det(options({0.8, 0.6}, {"tag16h5"}));
  const Outcome o = run(temp.path, c.records.size(), det, "unmutated");
  EXPECT_EQ(o.counts.decoded, c.records.size());
  EXPECT_EQ(decode_errors(o), 0u);
  EXPECT_EQ(o.source.truncated + o.source.malformed + o.source.ignored, 0u);
  EXPECT_EQ(o.batcher.missing_packets + o.batcher.late_packets + o.batcher.azimuth_jumps, 0u);
  EXPECT_GE(o.complete, 10u);
  EXPECT_GE(o.detections.size(), 2 * o.complete);
}

// 20 % of the data packets are foreign: well-formed packets of the same sensor from elsewhere in
// the capture (random in-range azimuths), stamped like their neighbours. They are counted and
// dropped: no extra rotations, no jumps, the same complete rotations and both tags in each.
TEST(CaptureMutation, SpoofedPacketsDoNotMultiplyRotationsOrLoseTags) {
  const std::string path = kPcaps + "demo.pcap";
  const Capture c = split(read_bytes(path));
  detector::Detector det(options({0.8, 0.6}, {"tag16h5"}));
  Temp clean_file("spoof_clean.pcap");
  test::write_file(clean_file.path, c.bytes());
  const Outcome clean = run(clean_file.path, c.records.size(), det, "clean");
  Capture spoofed;
  spoofed.global = c.global;
  std::mt19937 rng(7);
  size_t added = 0;
  for (size_t i = 0; i < c.records.size(); ++i) {
    spoofed.records.push_back(c.records[i]);
    const Bytes& r = c.records[i];
    if (r.size() != kRecordHeader + kNetHeaders + kDataPacketSize || i % 4 != 1) continue;
    Bytes fake = c.records[std::uniform_int_distribution<size_t>(0, c.records.size() - 1)(rng)];
    if (fake.size() != r.size()) continue;
    // The neighbour's capture time and sensor time, a little later.
    const int64_t t = record_time_us(r) + 100;
    set_record_time_us(fake, t);
    uint8_t* payload = fake.data() + kRecordHeader + kNetHeaders;
    set_le32(payload + kTimestampOffset,
             le32(r.data() + kRecordHeader + kNetHeaders + kTimestampOffset) + 100);
    spoofed.records.push_back(fake);
    ++added;
  }
  Temp spoof_file("spoofed.pcap");
  test::write_file(spoof_file.path, spoofed.bytes());
  const Outcome o = run(spoof_file.path, spoofed.records.size(), det, "spoofed");
  EXPECT_GE(added * 4 + 8, c.records.size());  // a fifth of what arrives
  EXPECT_EQ(o.batcher.inconsistent, added);
  EXPECT_EQ(o.batcher.azimuth_jumps, 0u);
  EXPECT_EQ(o.batcher.missing_packets, 0u);
  EXPECT_EQ(o.rotations, clean.rotations);
  EXPECT_EQ(o.complete, clean.complete);
  EXPECT_GE(o.complete, 9u);
  EXPECT_EQ(o.detections, clean.detections);
  EXPECT_GE(o.detections.size(), 2 * o.complete);
}

// pcapng written from the demo's frames, then damaged: block lengths, option values and
// timestamps are libpcap's to parse, the timestamps it hands over are the source's to check.
TEST(CaptureMutation, MutatedPcapngEndsCleanly) {
  const Capture whole = split(read_bytes(kPcaps + "demo.pcap"));
  std::vector<test::Record> frames;
  for (size_t i = 300; i < 460 && i < whole.records.size(); ++i) {
    const Bytes& r = whole.records[i];
    frames.push_back({Bytes(r.begin() + kRecordHeader, r.end()), record_time_us(r) * 1000, 0});
  }
  detector::Detector det(options({0.8, 0.6}, {"tag16h5"}));
  Temp temp("mutant.pcapng");
  Rng rng(11);
  for (int k = 0; k < 60; ++k) {
    Bytes bytes = test::pcapng(1, frames, k % 3 == 0 ? uint8_t{9} : uint8_t{6});
    std::vector<size_t> blocks;  // where each block starts
    for (size_t at = 0; at + 8 <= bytes.size(); at += le32(bytes.data() + at + 4))
      blocks.push_back(at);
    const int flips = 1 + static_cast<int>(rng() % 6);
    for (int f = 0; f < flips; ++f) {
      // Mostly block headers (type, lengths, interface, timestamps, caplen), sometimes anywhere.
      const size_t at =
          rng() % 2 ? blocks[pick(rng, blocks.size())] + pick(rng, 28) : pick(rng, bytes.size());
      bytes[std::min(at, bytes.size() - 1)] ^= static_cast<uint8_t>(1 + rng() % 255);
    }
    if (rng() % 6 == 0) bytes.resize(pick(rng, bytes.size()));
    test::write_file(temp.path, bytes);
    (void)run(temp.path, frames.size(), det, "pcapng mutant " + std::to_string(k));
    if (::testing::Test::HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace lidartag::velodyne
