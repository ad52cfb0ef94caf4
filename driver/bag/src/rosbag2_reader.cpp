// ROS 2 bag with sqlite3 storage: a folder with metadata.yaml (the files, the storage, the
// compression) and .db3 files with tables topics(id, name, type, serialization_format, ...) and
// messages(id, topic_id, timestamp, data). Messages are delivered in timestamp order per file,
// each with its own recorded timestamp (metadata.yaml's times are not used: real bags disagree).
#include <sqlite3.h>
#include <yaml-cpp/yaml.h>
#include <zstd.h>

#include <algorithm>
#include <filesystem>
#include <map>

#include "internal.hpp"

namespace lidartag::driver::bag::detail {
namespace {

namespace fs = std::filesystem;

// A file URI for sqlite3_open_v2 with immutable=1: the bag is read in place, in a folder that
// may be read-only, without journal or lock files.
std::string sqlite_uri(const std::string& path) {
  std::string uri = "file:";
  static constexpr char kHex[] = "0123456789ABCDEF";
  for (const char ch : fs::absolute(path).string()) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '?' || c == '#' || c == '%' || c < 0x20) {
      uri += '%';
      uri += kHex[c >> 4];
      uri += kHex[c & 15];
    } else {
      uri += ch;
    }
  }
  return uri + "?immutable=1";
}

// The content size a zstd frame declares (0 when it declares none or is not a frame).
uint64_t zstd_content_size(std::span<const uint8_t> frame) {
  const unsigned long long n = ZSTD_getFrameContentSize(frame.data(), frame.size());
  return (n == ZSTD_CONTENTSIZE_ERROR || n == ZSTD_CONTENTSIZE_UNKNOWN) ? 0 : n;
}

struct CloseDb {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};

struct Statement {
  sqlite3_stmt* stmt = nullptr;
  ~Statement() { sqlite3_finalize(stmt); }
};

class Rosbag2Reader final : public MessageReader {
 public:
  Rosbag2Reader(const std::string& path, const ReaderOptions& options) : path_(path) {
    options_ = options;
    fs::path dir(path);
    std::error_code ec;
    std::vector<fs::path> files;
    if (fs::is_regular_file(dir, ec) && dir.filename() != "metadata.yaml") {
      files.push_back(dir);  // a .db3 named directly: that file alone
    } else {
      if (fs::is_regular_file(dir, ec)) dir = dir.parent_path();
      files = files_of(dir);
    }
    if (files.empty()) throw BagError(path + ": a ROS 2 bag folder without .db3 files");
    for (const auto& f : files) {
      sqlite3* db = nullptr;
      const int rc = sqlite3_open_v2(sqlite_uri(f.string()).c_str(), &db,
                                     SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
      dbs_.emplace_back(db);
      if (rc != SQLITE_OK) throw BagError(f.string() + ": " + sqlite3_errstr(rc));
      // Pages read through a memory map (of the file's first 256 MiB), not one read() each: a
      // message of 1 MB spans 250 pages.
      sqlite3_exec(db, "PRAGMA mmap_size=268435456", nullptr, nullptr, nullptr);
      read_topics(db, f.string());
    }
    // Per topic counts, all files (before any message is read).
    for (size_t i = 0; i < dbs_.size(); ++i) {
      Statement s;
      if (sqlite3_prepare_v2(dbs_[i].get(),
                             "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id", -1,
                             &s.stmt, nullptr) != SQLITE_OK)
        throw BagError(files[i].string() + ": no messages table (" + sqlite3_errmsg(dbs_[i].get()) +
                       ")");
      int rc = 0;
      while ((rc = sqlite3_step(s.stmt)) == SQLITE_ROW) {
        const auto it = ids_[i].find(sqlite3_column_int64(s.stmt, 0));
        if (it != ids_[i].end())
          connections_[it->second].count += static_cast<uint64_t>(sqlite3_column_int64(s.stmt, 1));
      }
      if (rc != SQLITE_DONE)
        throw BagError(files[i].string() + ": cannot read the messages table (" +
                       sqlite3_errmsg(dbs_[i].get()) + ")");
    }
    // The bag's start: its earliest message (metadata.yaml's starting_time may disagree).
    for (auto& db : dbs_) {
      Statement s;
      if (sqlite3_prepare_v2(db.get(), "SELECT MIN(timestamp) FROM messages", -1, &s.stmt,
                             nullptr) == SQLITE_OK &&
          sqlite3_step(s.stmt) == SQLITE_ROW && sqlite3_column_type(s.stmt, 0) != SQLITE_NULL) {
        const int64_t t = sqlite3_column_int64(s.stmt, 0);
        start_ns_ = std::min(start_ns_.value_or(t), t);
      }
    }
    names_ = files;
  }

  ~Rosbag2Reader() override { sqlite3_finalize(query_); }
  Rosbag2Reader(const Rosbag2Reader&) = delete;
  Rosbag2Reader& operator=(const Rosbag2Reader&) = delete;

  BagFormat format() const override { return BagFormat::kRosbag2; }

  bool next(BagMessage& out) override {
    for (;;) {
      if (!query_) {
        if (file_ >= dbs_.size()) return false;
        if (sqlite3_prepare_v2(dbs_[file_].get(),
                               "SELECT topic_id, timestamp, data FROM messages ORDER BY "
                               "timestamp, id",
                               -1, &query_, nullptr) != SQLITE_OK) {
          ++stats_.read_errors;
          note(names_[file_].string() + ": " + sqlite3_errmsg(dbs_[file_].get()));
          sqlite3_finalize(query_);
          query_ = nullptr;
          ++file_;
          continue;
        }
      }
      const int rc = sqlite3_step(query_);
      if (rc == SQLITE_ROW) {
        const auto it = ids_[file_].find(sqlite3_column_int64(query_, 0));
        if (it == ids_[file_].end()) {
          ++stats_.skipped_records;
          note(names_[file_].string() + ": a message of an unknown topic id skipped");
          continue;
        }
        if (!wanted(connections_[it->second].topic)) continue;
        if (!in_window(sqlite3_column_int64(query_, 1))) {
          ++stats_.outside_window;
          continue;
        }
        const void* blob = sqlite3_column_blob(query_, 2);
        const int bytes = sqlite3_column_bytes(query_, 2);
        out.connection = it->second;
        out.time_ns = sqlite3_column_int64(query_, 1);
        out.data = std::span<const uint8_t>(static_cast<const uint8_t*>(blob),
                                            static_cast<size_t>(std::max(bytes, 0)));
        if (message_zstd_) {
          const uint64_t size = zstd_content_size(out.data);
          const std::string problem = decompressor_.run("zstd", out.data, size, buffer_);
          if (!problem.empty()) {
            ++stats_.skipped_records;
            note(names_[file_].string() + ": a message skipped: " + problem);
            continue;
          }
          out.data = buffer_;
        }
        ++stats_.messages;
        stats_.bytes += out.data.size();
        return true;
      }
      if (rc != SQLITE_DONE) {
        ++stats_.read_errors;
        note(names_[file_].string() + ": reading stopped: " + sqlite3_errmsg(dbs_[file_].get()));
      }
      sqlite3_finalize(query_);
      query_ = nullptr;
      ++file_;
    }
  }

 private:
  std::vector<fs::path> files_of(const fs::path& dir) {
    std::vector<fs::path> files;
    std::error_code ec;
    const fs::path meta = dir / "metadata.yaml";
    if (fs::is_regular_file(meta, ec)) {
      YAML::Node info;
      try {
        info = YAML::LoadFile(meta.string())["rosbag2_bagfile_information"];
      } catch (const YAML::Exception& e) {
        throw BagError(meta.string() + ": " + e.what());
      }
      if (!info) throw BagError(meta.string() + ": no rosbag2_bagfile_information");
      const auto storage = info["storage_identifier"].as<std::string>("sqlite3");
      if (storage != "sqlite3")
        throw BagError(meta.string() + ": storage '" + storage +
                       "' (only sqlite3 bag folders are read; open an MCAP file directly)");
      const auto compression = info["compression_format"].as<std::string>("");
      const auto mode = info["compression_mode"].as<std::string>("");
      if (!compression.empty()) {
        if (compression != "zstd" || mode != "MESSAGE")
          throw BagError(meta.string() + ": compression " + compression + " (" + mode +
                         " mode) is not read (zstd per message is)");
        message_zstd_ = true;
      }
      for (const auto& f : info["relative_file_paths"]) files.push_back(dir / f.as<std::string>());
      for (const auto& f : files)
        if (!fs::is_regular_file(f, ec))
          throw BagError(meta.string() + ": lists " + f.string() + ", which is not there");
      if (!files.empty()) return files;
    }
    for (const auto& entry : fs::directory_iterator(dir, ec))
      if (entry.path().extension() == ".db3") files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    return files;
  }

  void read_topics(sqlite3* db, const std::string& name) {
    Statement s;
    if (sqlite3_prepare_v2(db, "SELECT id, name, type, serialization_format FROM topics", -1,
                           &s.stmt, nullptr) != SQLITE_OK)
      throw BagError(name + ": not a ROS 2 bag database (" + sqlite3_errmsg(db) + ")");
    std::map<int64_t, uint32_t> ids;
    int rc = 0;
    auto text = [&](int col) {
      const auto* t = sqlite3_column_text(s.stmt, col);
      return t ? std::string(reinterpret_cast<const char*>(t)) : std::string();
    };
    while ((rc = sqlite3_step(s.stmt)) == SQLITE_ROW) {
      Connection c;
      c.topic = text(1);
      c.type = text(2);
      const std::string format = text(3);
      // An empty serialization format: what some recorders wrote for CDR (a known quirk).
      c.encoding = (format == "cdr" || format.empty()) ? Encoding::kCdr : Encoding::kOther;
      // The same topic in several files is one connection.
      const auto same = std::find_if(connections_.begin(), connections_.end(),
                                     [&](const Connection& o) { return o.topic == c.topic; });
      if (same != connections_.end()) {
        ids[sqlite3_column_int64(s.stmt, 0)] = static_cast<uint32_t>(same - connections_.begin());
      } else {
        ids[sqlite3_column_int64(s.stmt, 0)] = static_cast<uint32_t>(connections_.size());
        connections_.push_back(std::move(c));
      }
    }
    if (rc != SQLITE_DONE) throw BagError(name + ": cannot read topics: " + sqlite3_errmsg(db));
    ids_.push_back(std::move(ids));
  }

  std::string path_;
  std::vector<std::unique_ptr<sqlite3, CloseDb>> dbs_;
  std::vector<fs::path> names_;
  std::vector<std::map<int64_t, uint32_t>> ids_;  // per file: topic id -> connection
  size_t file_ = 0;
  sqlite3_stmt* query_ = nullptr;
  bool message_zstd_ = false;
  std::vector<uint8_t> buffer_;
  Decompressor decompressor_;
};

}  // namespace

std::unique_ptr<MessageReader> open_rosbag2(const std::string& path, const ReaderOptions& options) {
  return std::make_unique<Rosbag2Reader>(path, options);
}

}  // namespace lidartag::driver::bag::detail
