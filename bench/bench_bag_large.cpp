// A large bag against the pcap of the same packets (issue 34: "reading a bag is at least as fast
// as reading the same packets from a pcap", shown on files large enough that opening costs
// nothing). From a real pair of ../shared/captures (a ROS 2 bag of VelodyneScan and the pcap it
// was recorded beside) it writes, into --work, the packets repeated --passes times (each pass's
// times moved on by the capture's length): a pcap, an MCAP of the same CDR messages (as rosbag2's
// MCAP storage holds them, chunks of 4 MiB, uncompressed, zstd and lz4) and a ROS 2 sqlite3 bag
// (the real bag's rows repeated). Then it reads each, alternating, --runs times on this thread: the
// packet source alone and the whole capture reader (decode + assembly into rotations); thread CPU
// time, medians, and the bag / pcap ratios. Beside them, the compressed MCAPs' chunks
// decompressed alone (libzstd, liblz4), the file already in memory: what decompression itself
// costs, the floor for reading compressed chunks.
//   build/bin/bench_bag_large [--pair vls128|vlp32c|vlp16_dual] [--passes 100] [--runs 5]
//                             [--work /tmp/lidartag_bag_large] [--keep]
#include <lz4frame.h>
#include <sqlite3.h>
#include <time.h>
#include <zstd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidartag/driver/bag/bag_packet_source.hpp"
#include "lidartag/driver/bag/mcap_writer.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace {

using namespace lidartag;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

struct Pair {
  std::string name, bag, pcap;
};
const std::vector<Pair> kPairs = {
    {"vls128", "bags/rosbag2/vls128", "vls128_nebula.pcap"},
    {"vlp32c", "bags/rosbag2/vlp32c", "vlp32c_nebula_fov.pcap"},
    {"vlp16_dual", "bags/rosbag2/vlp16_dual", "vlp16_dual_nebula.pcap"},
};

std::string shared(const std::string& name) {
  return std::string(LIDARTAG_SHARED_DIR) + "/captures/" + name;
}

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

struct Packet {
  std::vector<uint8_t> payload;
  int64_t time_ns;
  uint16_t port;
};

struct Message {
  std::vector<uint8_t> data;
  int64_t time_ns;
};

// The pcap's packets and the bag's VelodyneScan messages, in memory.
void load(const Pair& p, std::vector<Packet>& packets, std::vector<Message>& messages) {
  driver::PcapSource pcap(shared(p.pcap));
  driver::RawPacket raw;
  while (pcap.next(raw, 0ms) == driver::ReadStatus::kPacket)
    packets.push_back(
        {{raw.payload.begin(), raw.payload.end()}, raw.receive_time_ns, raw.destination_port});
  const auto reader = driver::bag::open_bag(shared(p.bag));
  driver::bag::BagMessage m;
  while (reader->next(m)) {
    if (reader->connections()[m.connection].type != "velodyne_msgs/msg/VelodyneScan") continue;
    messages.push_back({{m.data.begin(), m.data.end()}, m.time_ns});
  }
}

void sql(sqlite3* db, const std::string& statement) {
  char* error = nullptr;
  if (sqlite3_exec(db, statement.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string text = error != nullptr ? error : "?";
    sqlite3_free(error);
    throw std::runtime_error("sqlite: " + text + " in " + statement);
  }
}

struct Files {
  std::string pcap, mcap_none, mcap_zstd, mcap_lz4, rosbag2;
};

Files write_files(const Pair& p, const std::string& work, int passes) {
  std::vector<Packet> packets;
  std::vector<Message> messages;
  load(p, packets, messages);
  if (packets.empty() || messages.empty()) throw std::runtime_error("nothing read from " + p.name);
  const int64_t first = std::min(packets.front().time_ns, messages.front().time_ns);
  const int64_t last = std::max(packets.back().time_ns, messages.back().time_ns);
  const int64_t step = last - first + 100'000'000;  // each pass 0.1 s after the last

  fs::create_directories(work);
  Files f{work + "/" + p.name + ".pcap", work + "/" + p.name + "_none.mcap",
          work + "/" + p.name + "_zstd.mcap", work + "/" + p.name + "_lz4.mcap",
          work + "/" + p.name + "_rosbag2"};
  {
    driver::PcapWriter w(f.pcap);
    for (int k = 0; k < passes; ++k)
      for (const Packet& q : packets) w.write_udp(q.payload, q.time_ns + k * step, q.port);
    w.close();
  }
  for (const auto& [path, compression] :
       {std::pair{f.mcap_none, driver::bag::McapCompression::kNone},
        std::pair{f.mcap_zstd, driver::bag::McapCompression::kZstd},
        std::pair{f.mcap_lz4, driver::bag::McapCompression::kLz4}}) {
    driver::bag::McapWriterOptions o;
    o.compression = compression;
    o.profile = "ros2";
    driver::bag::McapWriter w(path, o);
    const uint16_t schema = w.add_schema("velodyne_msgs/msg/VelodyneScan", "ros2msg",
                                         "std_msgs/Header header\nVelodynePacket[] packets\n");
    const uint16_t channel = w.add_channel("/velodyne_packets", schema, "cdr");
    for (int k = 0; k < passes; ++k)
      for (const Message& m : messages) {
        const auto t = static_cast<uint64_t>(m.time_ns + k * step);
        if (!w.write(channel, t, t, m.data)) throw std::runtime_error(w.error());
      }
    w.close();
  }
  // The real bag's rows repeated (its metadata.yaml's counts and times are the real bag's: the
  // reader goes by the database).
  fs::remove_all(f.rosbag2);
  fs::copy(shared(p.bag), f.rosbag2);
  fs::path db;
  for (const auto& e : fs::directory_iterator(f.rosbag2))
    if (e.path().extension() == ".db3") db = e.path();
  sqlite3* handle = nullptr;
  if (sqlite3_open(db.c_str(), &handle) != SQLITE_OK) throw std::runtime_error("sqlite open");
  const std::unique_ptr<sqlite3, int (*)(sqlite3*)> closer(handle, sqlite3_close);
  sql(handle, "BEGIN");
  sql(handle, "CREATE TEMP TABLE one AS SELECT topic_id, timestamp, data FROM messages");
  for (int k = 1; k < passes; ++k)
    sql(handle, "INSERT INTO messages (topic_id, timestamp, data) SELECT topic_id, timestamp + " +
                    std::to_string(int64_t{k} * step) + ", data FROM one");
  sql(handle, "COMMIT");
  return f;
}

// One reading of `path`: packets (and rotations) seen; CPU seconds of this thread.
struct Reading {
  double cpu_s = 0;
  uint64_t items = 0;
};

Reading drain(const std::function<std::unique_ptr<driver::PacketSource>()>& open) {
  const double t0 = thread_cpu_s();
  const auto source = open();
  driver::RawPacket packet;
  Reading r;
  while (source->next(packet, 0ms) == driver::ReadStatus::kPacket) ++r.items;
  r.cpu_s = thread_cpu_s() - t0;
  return r;
}

Reading rotations(const std::string& path) {
  const double t0 = thread_cpu_s();
  velodyne::CaptureReader reader(path, velodyne::CaptureReaderOptions{});
  Reading r;
  while (reader.next() != nullptr) ++r.items;
  r.cpu_s = thread_cpu_s() - t0;
  return r;
}

std::vector<uint8_t> read_file(const std::string& path) {
  std::vector<uint8_t> bytes(fs::file_size(path));
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"),
                                                          std::fclose);
  if (!f || std::fread(bytes.data(), 1, bytes.size(), f.get()) != bytes.size())
    throw std::runtime_error("cannot read " + path);
  return bytes;
}

// The chunks of an MCAP file in memory compressed as `compression` ("zstd", "lz4"), decompressed
// with one context into one buffer: CPU seconds of this thread (the walk over the records is not
// timed). Throws when a chunk does not decompress (the file is the one this program wrote).
double decompress_alone(const std::vector<uint8_t>& file, const std::string& compression) {
  auto u64 = [&](size_t at) {
    uint64_t v = 0;
    if (at + 8 > file.size()) throw std::runtime_error("MCAP cut short");
    std::memcpy(&v, file.data() + at, 8);
    return v;
  };
  struct Frame {
    size_t at, size, raw_size;
  };
  std::vector<Frame> frames;
  // Records after the 8-byte magic: opcode (1), length (8), body; a Chunk (0x06) body is
  // start time, end time, uncompressed size (8 each), CRC (4), compression (u32-prefixed string),
  // records length (8), records.
  for (size_t at = 8; at + 9 <= file.size();) {
    const uint8_t op = file[at];
    const size_t body = at + 9, length = u64(at + 1);
    if (op == 0x02 || op == 0x0F) break;  // Footer, Data End
    if (op == 0x06) {
      uint32_t name_length = 0;
      std::memcpy(&name_length, file.data() + body + 28, 4);
      const std::string name(file.begin() + static_cast<std::ptrdiff_t>(body + 32),
                             file.begin() + static_cast<std::ptrdiff_t>(body + 32 + name_length));
      const size_t records = body + 32 + name_length;
      if (name == compression) frames.push_back({records + 8, u64(records), u64(body + 16)});
    }
    at = body + length;
  }
  if (frames.empty()) throw std::runtime_error("no " + compression + " chunks");
  std::vector<uint8_t> out;
  const std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> zstd(ZSTD_createDCtx(), ZSTD_freeDCtx);
  LZ4F_dctx* lz4_context = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&lz4_context, LZ4F_VERSION)))
    throw std::runtime_error("no lz4 context");
  const std::unique_ptr<LZ4F_dctx, size_t (*)(LZ4F_dctx*)> lz4(lz4_context,
                                                               LZ4F_freeDecompressionContext);
  const double t0 = thread_cpu_s();
  for (const Frame& f : frames) {
    out.resize(f.raw_size);
    size_t n = 0;
    if (compression == "zstd") {
      n = ZSTD_decompressDCtx(zstd.get(), out.data(), out.size(), file.data() + f.at, f.size);
      if (ZSTD_isError(n)) n = 0;
    } else {
      // One call: the whole frame in, its whole size out.
      size_t out_size = out.size(), in_size = f.size;
      const size_t rc =
          LZ4F_decompress(lz4.get(), out.data(), &out_size, file.data() + f.at, &in_size, nullptr);
      n = rc == 0 ? out_size : 0;
    }
    if (n != f.raw_size) throw std::runtime_error(compression + " chunk not decompressed");
  }
  return thread_cpu_s() - t0;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::string pair_name = "vls128", work = "/tmp/lidartag_bag_large";
  int passes = 100, runs = 5;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--pair")
      pair_name = value();
    else if (a == "--passes")
      passes = std::stoi(value());
    else if (a == "--runs")
      runs = std::stoi(value());
    else if (a == "--work")
      work = value();
    else if (a == "--keep")
      keep = true;
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  const auto pair = std::find_if(kPairs.begin(), kPairs.end(),
                                 [&](const Pair& p) { return p.name == pair_name; });
  if (pair == kPairs.end() || passes < 1 || runs < 1) {
    std::fprintf(stderr, "--pair vls128|vlp32c|vlp16_dual, --passes >= 1, --runs >= 1\n");
    return 2;
  }
  if (!fs::exists(shared(pair->bag)) || !fs::exists(shared(pair->pcap))) {
    std::printf("skipped: %s or %s not found (../shared/captures)\n", pair->bag.c_str(),
                pair->pcap.c_str());
    return 0;
  }
  const Files files = write_files(*pair, work + "/" + std::to_string(::getpid()), passes);
  struct Input {
    std::string label, path;
    bool bag;
  };
  const std::vector<Input> inputs = {{"pcap", files.pcap, false},
                                     {"MCAP (uncompressed)", files.mcap_none, true},
                                     {"MCAP (zstd)", files.mcap_zstd, true},
                                     {"MCAP (lz4)", files.mcap_lz4, true},
                                     {"rosbag2 sqlite3", files.rosbag2, true}};
  std::map<std::string, std::vector<double>> source_s, reader_s;
  std::map<std::string, uint64_t> packets, scans;
  // The compressed files in memory, for their chunks decompressed alone.
  const std::vector<std::pair<std::string, std::string>> compressed = {{"zstd", files.mcap_zstd},
                                                                       {"lz4", files.mcap_lz4}};
  std::map<std::string, std::vector<uint8_t>> compressed_file;
  std::map<std::string, std::vector<double>> alone_s;
  for (const auto& [name, path] : compressed) compressed_file[name] = read_file(path);
  for (int run = 0; run < runs; ++run) {
    for (const auto& [name, path] : compressed)
      alone_s[name].push_back(decompress_alone(compressed_file[name], name));
    for (const Input& in : inputs) {
      const Reading s = drain([&]() -> std::unique_ptr<driver::PacketSource> {
        if (in.bag) return std::make_unique<driver::bag::BagPacketSource>(in.path);
        return std::make_unique<driver::PcapSource>(in.path);
      });
      const Reading r = rotations(in.path);
      source_s[in.label].push_back(s.cpu_s);
      reader_s[in.label].push_back(r.cpu_s);
      packets[in.label] = s.items;
      scans[in.label] = r.items;
    }
  }
  std::printf("pair %s, %d passes: file sizes", pair->name.c_str(), passes);
  for (const Input& in : inputs) {
    uintmax_t bytes = 0;
    if (fs::is_directory(in.path)) {
      for (const auto& e : fs::directory_iterator(in.path)) bytes += fs::file_size(e.path());
    } else {
      bytes = fs::file_size(in.path);
    }
    std::printf(" %s %.0f MB", in.label.c_str(), static_cast<double>(bytes) / 1e6);
  }
  std::printf("\nmedians of %d runs, thread CPU time\n", runs);
  std::printf("| source | packets | rotations | packets: s | / pcap | rotations: s | / pcap |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  const double pcap_source = median(source_s["pcap"]), pcap_reader = median(reader_s["pcap"]);
  int status = 0;
  for (const Input& in : inputs) {
    const double s = median(source_s[in.label]), r = median(reader_s[in.label]);
    std::printf("| %s | %llu | %llu | %.3f | %.2f | %.3f | %.2f |\n", in.label.c_str(),
                static_cast<unsigned long long>(packets[in.label]),
                static_cast<unsigned long long>(scans[in.label]), s, s / pcap_source, r,
                r / pcap_reader);
    // The same packets must give the same rotations whatever holds them.
    if (packets[in.label] != packets["pcap"] || scans[in.label] != scans["pcap"]) status = 1;
  }
  for (const auto& [name, path] : compressed) {
    const double z = median(alone_s[name]);
    std::printf("| %s chunks decompressed alone (file in memory) | | | %.3f | %.2f | | |\n",
                name.c_str(), z, z / pcap_source);
  }
  if (status != 0)
    std::printf("FAILED: a bag gave other packet or rotation counts than the pcap\n");
  if (!keep) fs::remove_all(work + "/" + std::to_string(::getpid()));
  return status;
}
