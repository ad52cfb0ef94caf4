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

#include "lidartag/daemon/lcm_log_source.hpp"
#include "lidartag/daemon/messages.hpp"
#include "lidartag/driver/io/live_source.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/io/udp_source.hpp"

namespace lidartag::daemon {

using namespace std::chrono_literals;

namespace {

int64_t to_ns(double seconds) {
  return static_cast<int64_t>(seconds * 1e9);
}

double seconds(int64_t ns) {
  return static_cast<double>(ns) * 1e-9;
}

bool is_replay(const SourceOptions& s) {
  return s.kind == SourceKind::kPcap || s.kind == SourceKind::kLcm;
}

// Models that the packets' timing and layout cannot tell apart (VLP-16 and Puck Hi-Res).
bool same_timing(velodyne::Model a, velodyne::Model b, velodyne::ReturnMode mode) {
  const auto& sa = velodyne::model_spec(a);
  const auto& sb = velodyne::model_spec(b);
  return (sa.blocks_per_firing > 1) == (sb.blocks_per_firing > 1) &&
         std::abs(sa.packet_period_us(mode) - sb.packet_period_us(mode)) <
             0.01 * sa.packet_period_us(mode);
}

std::optional<uint32_t> sender(const SourceOptions& s) {
  uint32_t address = 0;
  if (!s.sensor_address.empty() && velodyne::parse_ipv4_address(s.sensor_address, address)) {
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

std::unique_ptr<velodyne::PacketSource> open_source(const SensorOptions& sensor,
                                                    const DaemonOptions& options) {
  const SourceOptions& s = sensor.source;
  switch (s.kind) {
    case SourceKind::kUdp: {
      velodyne::UdpSourceOptions o;
      o.bind_address = s.bind_address;
      o.data_port = s.data_port;
      o.position_port = s.position_port;
      o.sensor_ipv4 = sender(s);
      o.receive_buffer_bytes = s.receive_buffer_bytes;
      o.reuse_address = s.share_port;  // daemon-setup: exclusive unless the config shares
      o.steer_senders = steer_senders(sensor, options);
      return std::make_unique<velodyne::UdpSource>(o);
    }
    case SourceKind::kInterface: {
      velodyne::LiveSourceOptions o;
      o.interface = s.interface;
      o.data_port = s.data_port;
      o.position_port = s.position_port;
      o.sensor_ipv4 = sender(s);
      o.promiscuous = s.promiscuous;
      o.buffer_bytes = s.receive_buffer_bytes;
      return std::make_unique<velodyne::LiveSource>(o);
    }
    case SourceKind::kPcap: {
      velodyne::PcapSourceOptions o;
      o.data_port = s.data_port;
      o.position_port = s.position_port;
      o.sensor_ipv4 = sender(s);
      o.pacing = s.rate > 0 ? velodyne::ReplayPacing::kCaptureTime
                            : velodyne::ReplayPacing::kAsFastAsPossible;
      o.rate = s.rate > 0 ? s.rate : 1.0;
      o.loop = s.loop;
      return std::make_unique<velodyne::PcapSource>(s.file, o);
    }
    case SourceKind::kLcm: {
      LcmLogSourceOptions o;
      o.channel = s.channel.empty() ? channel_of(sensor, options.lcm.channels.raw) : s.channel;
      o.rate = s.rate;
      o.loop = s.loop;
      return std::make_unique<LcmLogSource>(s.file, o);
    }
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

// What the receiving thread knows, copied at every return of CaptureReader::read (each rotation,
// and at least every 100 ms) for the status.
struct SensorPipeline::Snapshot {
  velodyne::CaptureCounts counts;
  velodyne::SourceStats source;
  velodyne::BatcherStats batcher;
  std::optional<velodyne::Model> model;
  std::optional<velodyne::ReturnMode> mode;
  velodyne::TimeSource time_source = velodyne::TimeSource::kHost;
  float rpm = 0;
  int64_t sensor_ns = 0;          // first firing of the last rotation assembled
  uint64_t data_packets = 0;      // data-port packets received (also while the model is probed)
  int64_t last_data_ns = 0;       // steady clock, of the last read that saw new data packets
  std::string model_problem;      // the model decoded does not fit the packets' timing
  std::string model_note;         // CaptureReader::model_mismatch(), once packets contradict it
  std::vector<uint32_t> senders;  // seen within health.window_s
  std::string error;
  std::string source_error;  // why the source ended before its end (set once it ended)
};

// The rotation counters, changed together under counts_mutex_ so that every status sees
// assembled = published + behind + seam + unsent + in_flight.
struct SensorPipeline::Counts {
  uint64_t assembled = 0, published = 0, behind = 0, seam = 0, unsent = 0, in_flight = 0;
  uint64_t detections = 0;
  int64_t last_assembled_ns = 0;  // steady clock
  int64_t progress_ns = 0;        // last publication, or when the pipeline last became non-empty
  uint64_t dropped() const { return behind + seam + unsent; }
};

// The receiving thread's own: the distinct sender addresses of data packets (per packet one compare
// in the common case; the times are stamped when the snapshot is taken) and the model verdict.
struct SensorPipeline::ReceiverState {
  struct Entry {
    uint32_t address = 0;
    bool seen = false;    // since the last snapshot
    int64_t last_ns = 0;  // steady clock of the snapshot that last saw it
  };
  std::array<Entry, 8> entries{};
  size_t size = 0, last = 0;
  uint64_t data_packets = 0, seen_data = 0;  // data packets, and at the last snapshot
  // The model check's last verdict, and its text (empty: the model fits).
  std::optional<velodyne::Model> problem_model, problem_timing;
  std::string model_problem;
  uint64_t noted_mismatch = 0;  // CaptureCounts::model_mismatch when model_note was taken
};

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
      buffer_(static_cast<size_t>(options.pipeline.queue_depth),
              static_cast<size_t>(workers + options.pipeline.publish_queue),
              lossless_ ? Overflow::kWait : Overflow::kDropOldest),
      publisher_(sensor_, options, bus, printer, failures_),
      health_(options.health),
      tokens_(static_cast<size_t>(workers + options.pipeline.publish_queue)),
      receiver_state_(std::make_unique<ReceiverState>()),
      counts_(std::make_unique<Counts>()),
      snapshot_(std::make_unique<Snapshot>()) {
  snapshot_->senders.reserve(receiver_state_->entries.size());
  for (size_t i = 0; i < tokens_; ++i) {
    detectors_.push_back(std::make_unique<detector::Detector>(options.detector));
  }
  // Every packet passes here on the receiving thread: senders are noted, raw packets published.
  TapSource::RawTap tap = [this](const velodyne::RawPacket& p) {
    note_sender(p);
    if (options_.lcm.publish_raw) {
      fill_raw_packet(p, sensor_.name, raw_message_);
      if (!bus_.publish(raw_channel_, raw_message_)) failures_.failed(raw_channel_);
    }
  };
  auto source = std::make_unique<TapSource>(open_source(sensor, options), recorder, tap);
  tap_ = source.get();
  velodyne::CaptureReaderOptions reader;
  reader.source.data_port = sensor.source.data_port;
  reader.source.position_port = sensor.source.position_port;
  reader.model = sensor.model;
  reader.calibration_file = sensor.calibration;
  reader.decoder = sensor.decoder;
  reader.batcher = sensor.batcher;
  reader_ = std::make_unique<velodyne::CaptureReader>(std::move(source), reader);
  // Built inside the arena, so that its tasks run there.
  arena_.execute([&] { graph_ = std::make_unique<Graph>(*this, workers_); });
}

SensorPipeline::~SensorPipeline() {
  stop();
  join();
  graph_.reset();  // waits for the graph's tasks, which use `this`
}

void SensorPipeline::start() {
  const int64_t now = steady_ns();
  started_ns_.store(now);
  receiver_beat_ns_.store(now);
  {
    std::lock_guard lock(counts_mutex_);
    counts_->last_assembled_ns = now;
    counts_->progress_ns = now;
  }
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

std::string SensorPipeline::error() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_->error;
}

std::string SensorPipeline::source_error() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_->source_error;
}

void SensorPipeline::fail(const std::string& what) {
  spdlog::error("sensor {}: {}", sensor_.name, what);
  std::lock_guard lock(snapshot_mutex_);
  if (snapshot_->error.empty()) snapshot_->error = what;
}

void SensorPipeline::note_sender(const velodyne::RawPacket& p) {
  if (p.destination_port != sensor_.source.data_port) return;
  ReceiverState& s = *receiver_state_;
  ++s.data_packets;
  if (p.source_ipv4 == 0) return;  // unknown (some replays)
  if (s.size > 0 && s.entries[s.last].address == p.source_ipv4) {
    s.entries[s.last].seen = true;
    return;
  }
  for (size_t i = 0; i < s.size; ++i) {
    if (s.entries[i].address == p.source_ipv4) {
      s.entries[i].seen = true;
      s.last = i;
      return;
    }
  }
  // A new sender; with the table full, the one not seen for the longest time makes room.
  size_t slot = s.size;
  if (s.size == s.entries.size()) {
    slot = 0;
    for (size_t i = 1; i < s.size; ++i) {
      if (s.entries[i].last_ns < s.entries[slot].last_ns) slot = i;
    }
  } else {
    ++s.size;
  }
  s.entries[slot] = {p.source_ipv4, true, 0};
  s.last = slot;
}

void SensorPipeline::take_snapshot(const Scan* last) {
  const int64_t now = steady_ns();
  ReceiverState& mine = *receiver_state_;
  const auto& counts = reader_->counts();
  // The model decided (configured, or the product byte) against the packets' timing, which
  // follows the latest packets: a wrong configuration or a change mid-stream shows here. The
  // text is made when the verdict changes, not per rotation.
  const auto model = reader_->model();
  const auto timing = reader_->model_check().timing_model();
  const auto mode = reader_->return_mode().value_or(velodyne::ReturnMode::kStrongest);
  const bool mismatch = model && timing && !same_timing(*model, *timing, mode);
  if (!mismatch) {
    mine.model_problem.clear();
  } else if (mine.problem_model != model || mine.problem_timing != timing) {
    const std::string decided(velodyne::model_spec(*model).name);
    const std::string fits(velodyne::model_spec(*timing).name);
    mine.model_problem = sensor_.model
                             ? fmt::format(
                                   "configured model {} does not fit the packets (their "
                                   "timing is that of a {}): check sensors[].model",
                                   decided, fits)
                             : fmt::format(
                                   "decoding as {} (the product byte) but the packets' timing "
                                   "is that of a {}: set sensors[].model",
                                   decided, fits);
  }
  mine.problem_model = model;
  mine.problem_timing = timing;
  std::lock_guard lock(snapshot_mutex_);
  Snapshot& s = *snapshot_;
  s.counts.data_packets = counts.data_packets;
  s.counts.position_packets = counts.position_packets;
  s.counts.decoded = counts.decoded;
  s.counts.decode_errors = counts.decode_errors;
  s.counts.undecodable = counts.undecodable;
  s.counts.model_mismatch = counts.model_mismatch;
  s.counts.position_ok = counts.position_ok;
  s.counts.position_errors = counts.position_errors;
  s.counts.position_checksum = counts.position_checksum;
  s.counts.gprmc_valid = counts.gprmc_valid;
  s.counts.pps = counts.pps;
  if (mine.data_packets != mine.seen_data) s.last_data_ns = now;
  mine.seen_data = mine.data_packets;
  s.data_packets = mine.data_packets;
  s.source = reader_->source_stats();
  s.batcher = reader_->batcher_stats();
  s.model = model;
  s.mode = reader_->return_mode();
  s.time_source = reader_->clock().source();
  s.model_problem = mine.model_problem;  // copied into storage it keeps
  if (counts.model_mismatch != mine.noted_mismatch) {
    s.model_note = reader_->model_mismatch();
    mine.noted_mismatch = counts.model_mismatch;
  }
  s.senders.clear();
  for (size_t i = 0; i < mine.size; ++i) {
    auto& e = mine.entries[i];
    if (e.seen) e.last_ns = now;
    e.seen = false;
    if (now - e.last_ns <= to_ns(options_.health.window_s)) s.senders.push_back(e.address);
  }
  if (last != nullptr) {
    if (last->rpm > 0) s.rpm = last->rpm;
    s.sensor_ns = last->stamp_ns;
  }
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
      receiver_beat_ns_.store(steady_ns(), std::memory_order_relaxed);
      using Result = velodyne::CaptureReader::ReadResult;
      take_snapshot(result == Result::kRotation ? &slot->scan : nullptr);
      if (result == Result::kEnd) break;
      if (result == Result::kTimeout) continue;  // the rotation in progress stays in the slot
      const int64_t now = steady_ns();
      if (loop_ && at_loop_seam(slot->scan)) {
        std::lock_guard lock(counts_mutex_);
        ++counts_->assembled;  // its sequence number is skipped
        ++counts_->seam;
        counts_->last_assembled_ns = now;
        continue;  // the slot takes the next rotation
      }
      slot->assembled_ns = now;
      {
        std::lock_guard lock(counts_mutex_);
        Counts& c = *counts_;
        slot->sequence = c.assembled++;
        if (c.in_flight++ == 0) c.progress_ns = now;
        c.last_assembled_ns = now;
      }
      // The next slot first (a live source drops the oldest waiting rotation if it must, a replay
      // waits for the pipeline), then this rotation to the pipeline: at most queue_depth wait.
      receiver_waiting_.store(true, std::memory_order_relaxed);
      Rotation* next = buffer_.acquire(dropped);
      receiver_waiting_.store(false, std::memory_order_relaxed);
      receiver_beat_ns_.store(steady_ns(), std::memory_order_relaxed);
      if (dropped) {
        std::lock_guard lock(counts_mutex_);
        --counts_->in_flight;
        ++counts_->behind;
      }
      buffer_.publish(slot);
      wake_pipeline();
      slot = next;
    }
  } catch (const std::exception& e) {
    // Only setup-like failures get here (the calibration file does not fit the model decided
    // from the packets): the pipeline stops, the daemon exits with an error.
    fail(e.what());
  }
  take_snapshot(nullptr);
  {
    std::string why = reader_->source_error();
    std::lock_guard lock(snapshot_mutex_);
    snapshot_->source_error = std::move(why);
  }
  stopped_.store(stopping_.load());  // else the source itself ended
  receiver_done_.store(true, std::memory_order_release);
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
  detector::Detector& detector = *detectors_[rotation.order % tokens_];
  // Isolated: while this thread waits inside the detector's own parallel loops it must not pick
  // up another rotation, which would delay this one (and the publication order) behind it.
  tbb::this_task_arena::isolate([&] { detector.detect(scan, r.detection); });
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
  uint64_t dropped = 0;
  {
    std::lock_guard lock(counts_mutex_);
    dropped = counts_->dropped();
  }
  bool sent = false;
  try {
    sent = publisher_.publish(rotation.result, dropped);
  } catch (const std::exception& e) {
    // A message could not be allocated: this rotation is lost (counted as unsent), not the
    // pipeline.
    spdlog::error("sensor {}: rotation {} not published: {}", sensor_.name,
                  rotation.result.sequence, e.what());
  }
  {
    std::lock_guard lock(counts_mutex_);
    Counts& c = *counts_;
    --c.in_flight;
    if (sent) {
      ++c.published;
      c.detections += rotation.result.detection.detections.size();
    } else {
      ++c.unsent;
    }
    c.progress_ns = steady_ns();
  }
  buffer_.release(&rotation);
  released_.fetch_add(1, std::memory_order_release);
}

std::string SensorPipeline::stall(int64_t now) const {
  const int64_t limit = to_ns(options_.watchdog.stall_timeout_s);
  if (!receiver_done_.load(std::memory_order_acquire) &&
      !receiver_waiting_.load(std::memory_order_relaxed)) {
    const int64_t idle = now - receiver_beat_ns_.load(std::memory_order_relaxed);
    if (idle > limit) {
      return fmt::format("the receiving loop has not run for {:.1f} s", seconds(idle));
    }
  }
  std::lock_guard lock(counts_mutex_);
  const Counts& c = *counts_;
  if (c.in_flight > 0 && now - c.progress_ns > limit) {
    return fmt::format("no rotation published for {:.1f} s with {} in the pipeline",
                       seconds(now - c.progress_ns), c.in_flight);
  }
  return {};
}

bool SensorPipeline::progressing(int64_t now) const {
  if (finished()) return error().empty();
  if (!error().empty() || !stall(now).empty()) return false;
  const int64_t limit = to_ns(options_.watchdog.stall_timeout_s);
  {
    std::lock_guard lock(counts_mutex_);
    if (now - counts_->last_assembled_ns <= limit) return true;
  }
  std::lock_guard lock(snapshot_mutex_);
  const Snapshot& s = *snapshot_;
  // Waiting for the sensor to come up.
  if (s.data_packets == 0 && now - started_ns_.load() <= to_ns(options_.health.startup_grace_s)) {
    return true;
  }
  // Silent (never a packet past the grace, or none lately): a restart reopens the sockets,
  // unless the sensor is switched off on purpose. Packets without rotations (garbage): no.
  const bool silent =
      s.data_packets == 0 || now - s.last_data_ns > to_ns(options_.health.silence_s);
  return silent && options_.watchdog.while_silent;
}

SensorStatus SensorPipeline::status(int64_t now_ns) {
  SensorStatus st;
  st.sensor = sensor_.name;
  st.frame_id = sensor_.frame_id;
  HealthSample h;
  h.now_ns = now_ns;
  h.started_ns = started_ns_.load();
  h.ended = finished();
  h.stopped = stopped_.load();
  h.stall = stall(now_ns);
  h.data_port = sensor_.source.data_port;
  {
    std::lock_guard lock(snapshot_mutex_);
    const Snapshot& s = *snapshot_;
    if (s.model) st.model = std::string(velodyne::model_spec(*s.model).name);
    if (s.mode) st.return_mode = std::string(velodyne::return_mode_name(*s.mode));
    st.rpm = s.rpm;
    st.time_source = static_cast<int>(s.time_source);
    st.pps = static_cast<int>(s.counts.pps);
    st.position_packets = s.counts.position_packets;
    st.gprmc_valid = s.counts.gprmc_valid;
    uint64_t decode_errors = 0;
    for (uint64_t e : s.counts.decode_errors) decode_errors += e;
    st.packets_data = s.counts.data_packets;
    st.packets_decoded = s.counts.decoded;
    st.packets_kernel_dropped = s.source.kernel_drops;
    st.packets_missing = s.batcher.missing_packets;
    // `reordered` counts every packet that came after a later one (put in place or dropped);
    // late_packets = duplicates + the reordered ones dropped. (A batcher that does not tell them
    // apart counts every late packet in late_packets only: the difference is then the reorders.)
    st.packets_duplicate = s.batcher.duplicates;
    st.packets_reordered =
        std::max(s.batcher.reordered, s.batcher.late_packets - s.batcher.duplicates);
    st.packets_malformed = s.source.truncated + s.source.malformed + decode_errors +
                           s.counts.undecodable + s.counts.position_errors +
                           s.counts.position_checksum;
    st.packets_foreign = s.source.foreign_source;
    st.packets_inconsistent = s.batcher.inconsistent;
    st.packets_model_mismatch = s.counts.model_mismatch;
    st.packets_ignored = s.source.ignored;
    st.senders = s.senders;
    st.error = s.error;
    h.error = s.error;
    h.data_packets = s.data_packets;
    h.last_data_ns = s.last_data_ns;
    h.decoded = s.counts.decoded;
    h.malformed = st.packets_malformed;
    h.ignored = s.source.ignored;
    h.foreign = s.source.foreign_source;
    if (h.ended) h.source_error = s.source_error;
    h.missing = s.batcher.missing_packets;
    h.model_mismatch = s.counts.model_mismatch;
    h.rpm = s.rpm;
    h.sensor_ns = s.sensor_ns;
    h.inconsistent = s.batcher.inconsistent;
    h.model_problem = s.model_problem;
    h.model_note = s.model_note;
    h.senders = s.senders;
  }
  st.packets_received = tap_->packets();
  {
    std::lock_guard lock(counts_mutex_);
    const Counts& c = *counts_;
    st.rotations_assembled = c.assembled;
    st.rotations_published = c.published;
    st.rotations_behind = c.behind;
    st.rotations_seam = c.seam;
    st.rotations_unsent = c.unsent;
    st.rotations_dropped = c.dropped();
    st.rotations_in_flight = c.in_flight;
    st.detections = c.detections;
    h.rotations = c.assembled;
    h.dropped_behind = c.behind;
  }
  st.publish_failures = failures_.count();
  // Any LCM failure of the bus (the status messages too) means publishing fails now.
  h.publish_failures = std::max<uint64_t>(bus_.failures(), st.publish_failures);
  st.health = health_.update(h);
  st.progressing = progressing(now_ns);
  st.buffer_occupancy = buffer_.waiting();
  st.buffer_depth = buffer_.depth();
  st.stage_names = publisher_.stage_names();
  st.stages = publisher_.take_latencies();
  failures_.report();
  return st;
}

}  // namespace lidartag::daemon
