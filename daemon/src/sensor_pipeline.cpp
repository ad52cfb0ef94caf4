#include "lidartag/daemon/sensor_pipeline.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/flow_graph.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstring>

#include "lidartag/daemon/ego_motion_input.hpp"
#include "lidartag/daemon/lcm_log_source.hpp"
#include "lidartag/daemon/messages.hpp"
#include "lidartag/driver/io/live_source.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/io/udp_source.hpp"
#include "lidartag/driver/sources/open_reader.hpp"

namespace lidartag::daemon {

using namespace std::chrono_literals;

namespace {

bool is_replay(const SourceOptions& s) {
  return s.kind == SourceKind::kPcap || s.kind == SourceKind::kLcm;
}

std::optional<uint32_t> sender(const SourceOptions& s) {
  uint32_t address = 0;
  if (!s.sensor_address.empty() && driver::parse_ipv4_address(s.sensor_address, address)) {
    return address;
  }
  return std::nullopt;
}

// The senders of the sensors sharing this sensor's UDP ports (same bind address and ports, each
// with share_port and a sensor_address), in configuration order, which is the order their
// sockets are bound: each sensor's unicast datagrams are then steered to its own socket. Empty
// unless at least two share and every one of them names its sender.
std::vector<uint32_t> steer_senders(const SensorOptions& sensor, const DaemonOptions& options) {
  const SourceOptions& me = sensor.source;
  std::vector<uint32_t> senders;
  if (!me.share_port) return senders;
  for (const SensorOptions& other : options.sensors) {
    const SourceOptions& o = other.source;
    if (o.kind != SourceKind::kUdp || !o.share_port || o.bind_address != me.bind_address ||
        o.data_port != me.data_port || o.position_port != me.position_port) {
      continue;
    }
    const std::optional<uint32_t> address = sender(o);
    if (!address) return {};
    senders.push_back(*address);
  }
  if (senders.size() < 2) senders.clear();
  return senders;
}

// The driver's view of a sensor entry. A replay's ports left at Velodyne's defaults are the
// vendor's defaults (an Ouster capture, found so by its content, is read on 7502/7503).
driver::ScanSourceOptions scan_options(const SensorOptions& sensor) {
  const SourceOptions& s = sensor.source;
  driver::ScanSourceOptions o;
  const bool vendor_ports = s.kind == SourceKind::kPcap &&
                            s.data_port == velodyne::kDefaultDataPort &&
                            s.position_port == velodyne::kDefaultPositionPort;
  if (!vendor_ports) {
    o.data_port = s.data_port;
    o.aux_port = s.position_port;
  }
  o.replay.sensor_ipv4 = sender(s);
  o.replay.pacing =
      s.rate > 0 ? driver::ReplayPacing::kCaptureTime : driver::ReplayPacing::kAsFastAsPossible;
  o.replay.rate = s.rate > 0 ? s.rate : 1.0;
  o.replay.loop = s.loop;
  o.topic = s.topic;
  o.start_s = s.start;
  if (s.duration > 0) o.duration_s = s.duration;
  o.metadata = sensor.metadata;
  o.velodyne_model = sensor.model;
  o.ouster_model = sensor.ouster_model;
  o.calibration_file = sensor.calibration;
  o.velodyne_decoder = sensor.decoder;
  o.batcher = sensor.batcher;
  return o;
}

// A live source (UDP sockets, an interface's capture) or an LCM log of raw packets, on the
// configured ports (an Ouster entry's default to 7502/7503: config.cpp).
std::unique_ptr<driver::PacketSource> open_live_source(const SensorOptions& sensor,
                                                       const DaemonOptions& options) {
  const SourceOptions& s = sensor.source;
  switch (s.kind) {
    case SourceKind::kUdp: {
      driver::UdpSourceOptions o;
      o.bind_address = s.bind_address;
      o.data_port = s.data_port;
      o.position_port = s.position_port;
      o.sensor_ipv4 = sender(s);
      o.receive_buffer_bytes = s.receive_buffer_bytes;
      o.reuse_address = s.share_port;  // daemon-setup: exclusive unless the config shares
      o.steer_senders = steer_senders(sensor, options);
      return std::make_unique<driver::UdpSource>(o);
    }
    case SourceKind::kInterface: {
      driver::LiveSourceOptions o;
      o.interface = s.interface;
      o.data_port = s.data_port;
      o.position_port = s.position_port;
      o.sensor_ipv4 = sender(s);
      o.promiscuous = s.promiscuous;
      o.buffer_bytes = s.receive_buffer_bytes;
      return std::make_unique<driver::LiveSource>(o);
    }
    case SourceKind::kLcm: {
      LcmLogSourceOptions o;
      o.channel = s.channel.empty() ? channel_of(sensor, options.lcm.channels.raw) : s.channel;
      o.rate = s.rate;
      o.loop = s.loop;
      return std::make_unique<LcmLogSource>(s.file, o);
    }
    case SourceKind::kPcap:
      break;  // a file: driver::open_capture, by content
  }
  return nullptr;
}

}  // namespace

void LinePrinter::print(const std::string& line) {
  std::lock_guard lock(mutex_);
  if (failed_) return;
  if (std::fputs(line.c_str(), out_) >= 0 && std::fputc('\n', out_) != EOF &&
      std::fflush(out_) == 0) {
    return;
  }
  // daemon-setup: a failed write stops printing; a closed pipe stops the daemon.
  const int error = errno;
  failed_ = true;
  if (error == EPIPE) {
    spdlog::warn("--print-detections: standard output was closed (its reader went away)");
    closed_.store(true);
    ::kill(::getpid(), SIGPIPE);
  } else {
    spdlog::error("--print-detections: cannot write to standard output: {}; printing stops",
                  std::strerror(error));
  }
}

std::string detections_line(const std::string& sensor, const RotationResult& r) {
  const auto& detections = r.detection.detections;
  std::string line = fmt::format("{} rotation {}: {} tag{}", sensor, r.sequence, detections.size(),
                                 detections.size() == 1 ? "" : "s");
  for (size_t i = 0; i < detections.size(); ++i) {
    const auto& d = detections[i];
    line += fmt::format("{} {}:{} ({:.3f}, {:.3f}, {:.3f}) m score {:.2f}", i == 0 ? ":" : ";",
                        d.family, d.id, d.position.x(), d.position.y(), d.position.z(), d.score);
  }
  return line;
}

// The detection pipeline, a oneTBB flow graph in the shared arena. `take` (serial) is told by the
// receiver after each rotation it hands over, and by `publish` after each publication; it takes
// waiting rotations while fewer than tokens_ are in the pipeline, numbering them in taking order
// (which is rotation order: the buffer is FIFO). `detect` runs on up to `workers` arena threads;
// the sequencer restores the taking order, `publish` (serial) publishes and frees the slot.
struct SensorPipeline::Graph {
  using Take = tbb::flow::multifunction_node<tbb::flow::continue_msg, std::tuple<Rotation*>>;
  tbb::flow::graph graph;
  Take take;
  tbb::flow::function_node<Rotation*, Rotation*> detect;
  tbb::flow::sequencer_node<Rotation*> order;
  tbb::flow::function_node<Rotation*, tbb::flow::continue_msg> publish;

  Graph(SensorPipeline& p, int workers)
      : take(graph, tbb::flow::serial,
             [&p](const tbb::flow::continue_msg&, Take::output_ports_type& out) { p.take(out); }),
        detect(graph, static_cast<size_t>(workers),
               [&p](Rotation* r) {
                 p.detect(*r);
                 return r;
               }),
        order(graph, [](Rotation* r) { return static_cast<size_t>(r->order); }),
        publish(graph, tbb::flow::serial, [&p](Rotation* r) {
          p.publish(*r);
          return tbb::flow::continue_msg();
        }) {
    tbb::flow::make_edge(tbb::flow::output_port<0>(take), detect);
    tbb::flow::make_edge(detect, order);
    tbb::flow::make_edge(order, publish);
    tbb::flow::make_edge(publish, take);
  }
};

SensorPipeline::SensorPipeline(const SensorOptions& sensor, const DaemonOptions& options,
                               LcmBus& bus, tbb::task_arena& arena, int workers,
                               PcapRecorder* recorder, LinePrinter* printer, DetectHook hook)
    : sensor_(sensor),
      options_(options),
      bus_(bus),
      arena_(arena),
      workers_(workers),
      lossless_(options.pipeline.lossless_replay && is_replay(sensor.source)),
      loop_(is_replay(sensor.source) && sensor.source.loop),
      hook_(std::move(hook)),
      raw_channel_(channel_of(sensor, options.lcm.channels.raw)),
      failures_(sensor.name, std::chrono::seconds(5)),
      monitor_(sensor_, options),
      buffer_(static_cast<size_t>(options.pipeline.queue_depth),
              static_cast<size_t>(workers + options.pipeline.publish_queue),
              lossless_ ? Overflow::kWait : Overflow::kDropOldest),
      publisher_(sensor_, options, bus, printer, failures_),
      tokens_(static_cast<size_t>(workers + options.pipeline.publish_queue)) {
  for (size_t i = 0; i < tokens_; ++i) {
    detectors_.push_back(std::make_unique<detector::Detector>(options.detector));
    if (options.detector.deskew.enabled && !options.ego_motion.channel.empty())
      ego_copies_.push_back(std::make_unique<detector::EgoMotion>(options.ego_motion.buffer));
  }
  // Every packet passes here on the receiving thread: senders are noted, raw packets published.
  TapSource::RawTap tap = [this](const driver::RawPacket& p) {
    monitor_.note_sender(p);
    if (options_.lcm.publish_raw) {
      fill_raw_packet(p, sensor_.name, raw_message_);
      if (!bus_.publish(raw_channel_, raw_message_)) failures_.failed(raw_channel_);
    }
  };
  // Every packet passes the tap (counted, recorded, published raw), whatever the source.
  const driver::SourceWrap wrap = [&](std::unique_ptr<driver::PacketSource> inner) {
    auto source = std::make_unique<TapSource>(std::move(inner), recorder, tap);
    tap_ = source.get();
    return std::unique_ptr<driver::PacketSource>(std::move(source));
  };
  const driver::ScanSourceOptions scan = scan_options(sensor);
  driver::OpenedReader opened =
      sensor.source.kind == SourceKind::kPcap
          ? driver::open_capture(sensor.source.file, scan, wrap)
          : driver::open_live(wrap(open_live_source(sensor, options)), scan);
  reader_ = std::move(opened.reader);
  monitor_.set_data_port(opened.data_port);
  spdlog::info("sensor {}: {} {} ({}), data port {}, {} port {}", sensor.name,
               opened.vendor == driver::Vendor::kOuster ? "Ouster" : "Velodyne",
               sensor.source.kind == SourceKind::kPcap
                   ? sensor.source.file
                   : std::string(source_kind_name(sensor.source.kind)),
               opened.what, opened.data_port,
               opened.vendor == driver::Vendor::kOuster ? "IMU" : "position", opened.aux_port);
  // Built inside the arena, so that its tasks run there.
  arena_.execute([&] { graph_ = std::make_unique<Graph>(*this, workers_); });
}

SensorPipeline::~SensorPipeline() {
  stop();
  join();
  graph_.reset();  // waits for the graph's tasks, which use `this`
}

void SensorPipeline::start() {
  monitor_.started(steady_ns());
  receiver_ = std::thread([this] { receive(); });
}

void SensorPipeline::stop() {
  stopping_.store(true);
  tap_->stop();
  buffer_.stop_waiting();
}

void SensorPipeline::join() {
  if (receiver_.joinable()) receiver_.join();
  // The receiver closed the buffer and told the graph: every rotation it handed over gets
  // published, then take() sees the buffer drained.
  graph_->graph.wait_for_all();
}

void SensorPipeline::wake_pipeline() {
  graph_->take.try_put(tbb::flow::continue_msg());
}

bool SensorPipeline::at_loop_seam(const Scan& scan) {
  // A looped replay starts over: the packets' clock jumps back, which ends the rotation in
  // progress (azimuth_jumps, not at the cut); the next one starts away from the cut. Neither is a
  // rotation the sensor made: both are counted, not published, so that the published rate stays
  // the capture's.
  if (after_seam_ && !scan.starts_at_cut) {
    after_seam_ = scan.azimuth_jumps > 0 && !scan.ends_at_cut;
    return true;
  }
  after_seam_ = scan.azimuth_jumps > 0 && !scan.ends_at_cut;
  return after_seam_;
}

void SensorPipeline::receive() {
  bool dropped = false;
  Rotation* slot = buffer_.acquire(dropped);  // a fresh buffer: a free slot
  try {
    for (;;) {
      const auto result = reader_->read(slot->scan, std::chrono::milliseconds(100));
      monitor_.beat(steady_ns());
      using Result = driver::ReadResult;
      monitor_.after_read(*reader_, result == Result::kRotation ? &slot->scan : nullptr);
      if (result == Result::kEnd) break;
      if (result == Result::kTimeout) continue;  // the rotation in progress stays in the slot
      const int64_t now = steady_ns();
      if (loop_ && at_loop_seam(slot->scan)) {
        monitor_.seam(now);  // counted, its number skipped, not published
        continue;            // the slot takes the next rotation
      }
      slot->assembled_ns = now;
      slot->sequence = monitor_.assembled(now);
      // The next slot first (a live source drops the oldest waiting rotation if it must, a replay
      // waits for the pipeline), then this rotation to the pipeline: at most queue_depth wait.
      monitor_.waiting(true);
      Rotation* next = buffer_.acquire(dropped);
      monitor_.waiting(false);
      monitor_.beat(steady_ns());
      if (dropped) monitor_.dropped_behind();
      buffer_.publish(slot);
      wake_pipeline();
      slot = next;
    }
  } catch (const std::exception& e) {
    // Only setup-like failures get here (the calibration file does not fit the model decided
    // from the packets): the pipeline stops, the daemon exits with an error.
    monitor_.fail(e.what());
  }
  monitor_.after_read(*reader_, nullptr);
  monitor_.receiver_done(reader_->source_error(), stopping_.load());  // else the source ended
  buffer_.close();
  wake_pipeline();  // take() finds the buffer drained once the rest is published
}

template <class Out>
void SensorPipeline::take(Out& out) {
  // Serial. Rotations in the pipeline: taken here, not yet released by publish().
  while (taken_ - released_.load(std::memory_order_acquire) < tokens_) {
    Rotation* r = buffer_.try_take();
    if (r == nullptr) break;
    r->result.taken_ns = steady_ns();
    r->order = taken_++;
    std::get<0>(out).try_put(r);
  }
  if (taken_ == released_.load(std::memory_order_acquire) && buffer_.drained()) {
    finished_.store(true, std::memory_order_release);
  }
}

void SensorPipeline::detect(Rotation& rotation) {
  const Scan& scan = rotation.scan;
  if (hook_) hook_(scan);
  RotationResult& r = rotation.result;
  r.sequence = rotation.sequence;
  r.stamp_ns = scan.stamp_ns;
  r.end_stamp_ns =
      scan.columns > 0
          ? scan.stamp_ns + static_cast<int64_t>(
                                scan.column_time_s[static_cast<size_t>(scan.columns - 1)] * 1e9)
          : scan.stamp_ns;
  r.complete = scan.complete;
  r.columns = scan.columns;
  r.points = static_cast<int>(scan.point_count());
  r.rpm = scan.rpm;
  r.assembled_ns = rotation.assembled_ns;
  // The rotations in the pipeline are consecutive in `order` (taken in order, released in order)
  // and at most tokens_ of them: order modulo tokens_ gives each its own detector.
  const size_t slot = rotation.order % tokens_;
  detector::Detector& detector = *detectors_[slot];
  // The deskew's motion: the sensor's poses (copied: the input's lock is held for the copy, not
  // the detection), else the tracker's model as of the latest published rotation.
  detector::SensorMotion motion;
  if (options_.detector.deskew.enabled) {
    motion.model = publisher_.motion();
    EgoMotionInput* ego = bus_.ego_motion();
    if (ego != nullptr && slot < ego_copies_.size()) {
      detector::EgoMotion& copy = *ego_copies_[slot];
      ego->read(publisher_.sensor_index(), [&](const detector::EgoMotion& e) { copy = e; });
      motion.ego = &copy;
    }
  }
  // Isolated: while this thread waits inside the detector's own parallel loops it must not pick
  // up another rotation, which would delay this one (and the publication order) behind it.
  tbb::this_task_arena::isolate([&] { detector.detect(scan, r.detection, motion); });
  if (options_.detector.deskew.enabled) {
    const auto add = [](std::atomic<uint64_t>& a, int v) {
      a.fetch_add(static_cast<uint64_t>(std::max(v, 0)), std::memory_order_relaxed);
    };
    add(deskewed_ego_, r.detection.deskewed_ego);
    add(deskewed_model_, r.detection.deskewed_model);
    add(deskew_without_motion_, r.detection.deskew_without_motion);
  }
  try {
    decimate_scan(scan, options_.lcm.cloud_decimation, r.cloud);
  } catch (const std::exception& e) {
    // The cloud could not grow (out of memory): this rotation's cloud is empty, nothing else.
    r.cloud.clear();
    spdlog::error("sensor {}: rotation {}: no cloud: {}", sensor_.name, r.sequence, e.what());
  }
  r.detected_ns = steady_ns();
}

void SensorPipeline::publish(Rotation& rotation) {
  const uint64_t dropped = monitor_.dropped();
  bool sent = false;
  try {
    sent = publisher_.publish(rotation.result, dropped);
  } catch (const std::exception& e) {
    // A message could not be allocated: this rotation is lost (counted as unsent), not the
    // pipeline.
    spdlog::error("sensor {}: rotation {} not published: {}", sensor_.name,
                  rotation.result.sequence, e.what());
  }
  monitor_.published(sent, rotation.result.detection.detections.size(), steady_ns());
  buffer_.release(&rotation);
  released_.fetch_add(1, std::memory_order_release);
}

SensorStatus SensorPipeline::status(int64_t now_ns) {
  PathGauges gauges;
  gauges.packets_received = tap_->packets();
  gauges.publish_failures = failures_.count();
  gauges.bus_failures = bus_.failures();
  gauges.buffer_waiting = buffer_.waiting();
  gauges.buffer_depth = buffer_.depth();
  gauges.finished = finished();
  gauges.size_warnings = publisher_.size_warnings();
  gauges.size_note = publisher_.size_note();
  SensorStatus st = monitor_.status(now_ns, gauges);
  st.ego_placed = publisher_.ego_placed();
  st.ego_missing = publisher_.ego_missing();
  st.deskewed_ego = deskewed_ego_.load(std::memory_order_relaxed);
  st.deskewed_model = deskewed_model_.load(std::memory_order_relaxed);
  st.deskew_without_motion = deskew_without_motion_.load(std::memory_order_relaxed);
  st.stage_names = publisher_.stage_names();
  st.stages = publisher_.take_latencies();
  failures_.report();
  return st;
}

}  // namespace lidartag::daemon
