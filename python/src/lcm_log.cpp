// lidartagd's LCM logs read through LCM's C++ log API (lcm::LogFile), each event decoded by its
// fingerprint with the project's generated C++ types (no python3-lcm needed). Events that do not
// decode are counted as malformed, events of other types as unknown; neither is fatal. A log that
// ends inside an event (cut short) counts as truncated.
#include <pybind11/stl.h>

#include <cstdio>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "lcm_types.hpp"
#include "lidartag/driver/io/errors.hpp"

namespace lidartag::python {
namespace {

struct LogEvent {
  int64_t eventnum = 0;
  int64_t utime = 0;  // the log's timestamp of the event, microseconds since the epoch
  std::string channel;
  std::string type;    // the message type's name; empty when unknown
  py::object message;  // the decoded message; None when unknown or malformed
  bool malformed = false;
  size_t size = 0;
};

class LcmLog {
 public:
  explicit LcmLog(const std::string& path) : path_(path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
      throw driver::IoError("no such LCM log: '" + path + "'");
    file_size_ = static_cast<long>(std::filesystem::file_size(path, ec));
    log_ = std::make_unique<lcm::LogFile>(path, "r");
    if (!log_->good()) throw driver::IoError("cannot open LCM log '" + path + "'");
  }

  LogEvent next() {
    struct Raw {
      int64_t eventnum, timestamp;
      std::string channel;
      std::vector<uint8_t> data;
    };
    std::optional<Raw> raw;
    {
      py::gil_scoped_release release;
      if (const lcm::LogEvent* e = log_ ? log_->readNextEvent() : nullptr) {
        end_of_events_ = std::ftell(log_->getFilePtr());
        const auto* bytes = static_cast<const uint8_t*>(e->data);
        const auto size = static_cast<size_t>(std::max<int32_t>(e->datalen, 0));
        raw = Raw{e->eventnum, e->timestamp, e->channel, {bytes, bytes + size}};
      } else if (log_) {
        // LCM stops at a cut or corrupt event header as at the end of the file: bytes left past
        // the last whole event mean the log was truncated.
        if (end_of_events_ < file_size_) truncated_ = true;
        log_.reset();
      }
    }
    if (!raw) throw py::stop_iteration();
    ++events_;
    LogEvent out;
    out.eventnum = raw->eventnum;
    out.utime = raw->timestamp;
    out.channel = std::move(raw->channel);
    out.size = raw->data.size();
    const uint8_t* p = raw->data.data();
    const size_t n = raw->data.size();
    const LcmType* type = nullptr;
    if (n >= 8) {
      const int64_t hash = read_be(p, 8);
      for (const LcmType& t : lcm_types())
        if (t.hash == hash) type = &t;
    }
    if (type == nullptr) {
      ++unknown_;
      return out;
    }
    out.type = type->name;
    size_t pos = 8;
    if (type->plausible(p, n, pos) && pos == n) out.message = type->decode(p, n);
    if (!out.message) {
      out.malformed = true;
      out.message = py::none();
      ++malformed_;
      return out;
    }
    ++decoded_[out.type];
    return out;
  }

  py::dict counts() const {
    py::dict d;
    d["events"] = events_;
    uint64_t decoded = 0;
    py::dict by_type;
    for (const auto& [name, count] : decoded_) {
      by_type[py::str(name)] = count;
      decoded += count;
    }
    d["decoded"] = decoded;
    d["by_type"] = by_type;
    d["malformed"] = malformed_;
    d["unknown"] = unknown_;
    d["truncated"] = truncated_;
    return d;
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::unique_ptr<lcm::LogFile> log_;
  long file_size_ = 0, end_of_events_ = 0;
  uint64_t events_ = 0, malformed_ = 0, unknown_ = 0;
  bool truncated_ = false;
  std::map<std::string, uint64_t> decoded_;
};

}  // namespace

void bind_lcm_log(py::module_& m) {
  py::class_<LogEvent>(m, "LogEvent", "One event of an LCM log.")
      .def_readonly("eventnum", &LogEvent::eventnum)
      .def_readonly("utime", &LogEvent::utime,
                    "The log's timestamp of the event, microseconds since the epoch.")
      .def_readonly("channel", &LogEvent::channel)
      .def_readonly("type", &LogEvent::type,
                    "The message type (e.g. 'tag_detections_t'), '' for other types.")
      .def_readonly("message", &LogEvent::message,
                    "The decoded message (lidartag.lcmtypes.*), None when unknown or malformed.")
      .def_readonly("malformed", &LogEvent::malformed)
      .def_readonly("size", &LogEvent::size, "Bytes of the encoded message.")
      .def("__repr__", [](const LogEvent& e) {
        return "<lidartag.LogEvent " + e.channel + " " +
               (e.type.empty() ? std::string("(unknown type)") : e.type) +
               (e.malformed ? " malformed" : "") + " at " + std::to_string(e.utime) + " us>";
      });

  py::class_<LcmLog>(m, "LcmLog", R"(The events of an LCM log (lidartagd's, lcm-logger's), read
lazily: `for event in lidartag.LcmLog(path): ...`. Each message is decoded by its type's
fingerprint, whatever its channel; `counts` tells what was read (events, decoded by type,
malformed, unknown, truncated).)")
      .def(py::init([](const py::object& path) {
             return std::make_unique<LcmLog>(
                 py::module_::import("os").attr("fspath")(path).cast<std::string>());
           }),
           py::arg("path"))
      .def("__iter__", [](LcmLog& l) -> LcmLog& { return l; })
      .def("__next__", &LcmLog::next)
      .def_property_readonly("counts", &LcmLog::counts)
      .def_property_readonly("path", &LcmLog::path);
}

}  // namespace lidartag::python
