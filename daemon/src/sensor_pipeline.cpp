#include "lidartag/daemon/sensor_pipeline.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>

#include "lidartag/daemon/lcm_log_source.hpp"
#include "lidartag/daemon/messages.hpp"
#include "lidartag/daemon/scan_copy.hpp"
#include "lidartag/driver/io/live_source.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/io/udp_source.hpp"

namespace lidartag::daemon {

using namespace std::chrono_literals;

namespace {

enum FixedStage : size_t { kQueue, kDetect, kOrder, kPublish, kTotal, kFixedStages };

double ms(int64_t ns) {
  return static_cast<double>(ns) * 1e-6;
}

std::optional<uint32_t> sender(const SourceOptions& s) {
  uint32_t address = 0;
  if (!s.sensor_address.empty() && velodyne::parse_ipv4_address(s.sensor_address, address)) {
    return address;
  }
  return std::nullopt;
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
  std::string line = fmt::format("{} #{} {} tag{}", sensor, r.sequence, detections.size(),
                                 detections.size() == 1 ? "" : "s");
  for (size_t i = 0; i < detections.size(); ++i) {
    const auto& d = detections[i];
    line += fmt::format("{} {}:{} ({:.3f}, {:.3f}, {:.3f}) m score {:.2f}", i == 0 ? ":" : ";",
                        d.family, d.id, d.position.x(), d.position.y(), d.position.z(), d.score);
  }
  return line;
}

// What the receiving thread knows, copied once per rotation for the status thread.
struct SensorPipeline::Snapshot {
  velodyne::CaptureCounts counts;
  velodyne::SourceStats source;
  velodyne::BatcherStats batcher;
  std::optional<velodyne::Model> model;
  std::optional<velodyne::ReturnMode> mode;
  velodyne::TimeSource time_source = velodyne::TimeSource::kHost;
  float rpm = 0;
  std::string error;
};

SensorPipeline::SensorPipeline(const SensorOptions& sensor, const DaemonOptions& options,
                               LcmBus& bus, tbb::task_arena& arena, int workers,
                               PcapRecorder* recorder, LinePrinter* printer)
    : sensor_(sensor),
      options_(options),
      bus_(bus),
      arena_(arena),
      workers_(workers),
      printer_(printer),
      lossless_(options.pipeline.lossless_replay && (sensor.source.kind == SourceKind::kPcap ||
                                                     sensor.source.kind == SourceKind::kLcm)),
      detections_channel_(channel_of(sensor, options.lcm.channels.detections)),
      raw_channel_(channel_of(sensor, options.lcm.channels.raw)),
      tag_points_channel_(channel_of(sensor, options.lcm.channels.tag_points)),
      cloud_channel_(channel_of(sensor, options.lcm.channels.cloud)),
      ordered_(static_cast<size_t>(workers), static_cast<size_t>(options.pipeline.publish_queue)),
      snapshot_(std::make_unique<Snapshot>()) {
  for (int i = 0; i < workers_; ++i) {
    detectors_.push_back(std::make_unique<detector::Detector>(options.detector));
  }
  TapSource::RawTap raw_tap;
  if (options.lcm.publish_raw) {
    raw_tap = [this](const velodyne::RawPacket& p) {
      fill_raw_packet(p, sensor_.name, raw_message_);
      bus_.publish(raw_channel_, raw_message_);
    };
  }
  auto tap = std::make_unique<TapSource>(open_source(sensor, options), recorder, raw_tap);
  tap_ = tap.get();
  velodyne::CaptureReaderOptions reader;
  reader.source.data_port = sensor.source.data_port;
  reader.source.position_port = sensor.source.position_port;
  reader.model = sensor.model;
  reader.calibration_file = sensor.calibration;
  reader.decoder = sensor.decoder;
  reader.batcher = sensor.batcher;
  reader_ = std::make_unique<velodyne::CaptureReader>(std::move(tap), reader);

  stage_names_ = {"queue", "detect", "order", "publish", "total"};
  for (int s = 0; s < detector::kStageCount; ++s) {
    stage_names_.emplace_back(detector::stage_name(static_cast<detector::Stage>(s)));
  }
  for (size_t i = 0; i < stage_names_.size(); ++i) {
    windows_.push_back(std::make_unique<LatencyWindow>());
  }
}

SensorPipeline::~SensorPipeline() {
  stop();
  join();
}

void SensorPipeline::start() {
  publisher_beat_ns_.store(steady_ns());
  receiver_ = std::thread([this] { receive(); });
  publisher_ = std::thread([this] { publish_loop(); });
}

void SensorPipeline::stop() {
  stopping_.store(true);
  tap_->stop();
}

void SensorPipeline::join() {
  if (receiver_.joinable()) receiver_.join();
  if (publisher_.joinable()) publisher_.join();
  // Tasks still in the arena hold `this` until they decrement active_.
  while (active_.load(std::memory_order_acquire) > 0) std::this_thread::sleep_for(1ms);
}

std::string SensorPipeline::error() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_->error;
}

void SensorPipeline::take_snapshot(const Scan* last) {
  std::lock_guard lock(snapshot_mutex_);
  Snapshot& s = *snapshot_;
  const auto& counts = reader_->counts();
  s.counts.data_packets = counts.data_packets;
  s.counts.position_packets = counts.position_packets;
  s.counts.decoded = counts.decoded;
  s.counts.decode_errors = counts.decode_errors;
  s.counts.undecodable = counts.undecodable;
  s.counts.position_ok = counts.position_ok;
  s.counts.position_errors = counts.position_errors;
  s.counts.gprmc_valid = counts.gprmc_valid;
  s.counts.pps = counts.pps;
  s.source = reader_->source_stats();
  s.batcher = reader_->batcher_stats();
  s.model = reader_->model();
  s.mode = reader_->return_mode();
  s.time_source = reader_->clock().source();
  if (last != nullptr) s.rpm = last->rpm;
}

int64_t SensorPipeline::assembled_at(const Scan* scan) const {
  for (size_t i = 0; i < stamp_keys_.size(); ++i) {
    if (stamp_keys_[i] == scan) return stamp_times_[i].load(std::memory_order_relaxed);
  }
  return 0;
}

void SensorPipeline::receive() {
  try {
    while (const Scan* scan = reader_->next()) {
      take_snapshot(scan);
      assembled_.fetch_add(1, std::memory_order_relaxed);
      if (!buffer_) {
        // Sized for dual returns, so that a change of return mode still fits.
        buffer_ = std::make_unique<velodyne::ScanBuffer>(
            static_cast<size_t>(options_.pipeline.queue_depth), static_cast<size_t>(workers_),
            scan->rings, 2, scan->column_capacity);
        // Find the buffer's scans once, for the assembly-time table.
        std::vector<Scan*> all;
        while (Scan* s = buffer_->acquire()) all.push_back(s);
        for (Scan* s : all) buffer_->release(s);
        stamp_keys_.assign(all.begin(), all.end());
        stamp_times_ = std::make_unique<std::atomic<int64_t>[]>(stamp_keys_.size());
        buffer_ptr_.store(buffer_.get(), std::memory_order_release);
      }
      // Replays wait for the detector instead of dropping (the stop request ends the wait).
      while (lossless_ && buffer_->ready_count() >= buffer_->depth() && !stopping_.load()) {
        tap_->beat();
        spawn();
        std::this_thread::sleep_for(1ms);
      }
      Scan* slot = buffer_->acquire();
      if (slot == nullptr) {
        dropped_no_scan_.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      if (!copy_scan(*scan, *slot)) {
        buffer_->release(slot);
        dropped_no_scan_.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      for (size_t i = 0; i < stamp_keys_.size(); ++i) {
        if (stamp_keys_[i] == slot) stamp_times_[i].store(steady_ns(), std::memory_order_relaxed);
      }
      buffer_->publish(slot);
      spawn();
    }
  } catch (const std::exception& e) {
    // Only setup-like failures get here (the calibration file does not fit the model decided
    // from the packets): the pipeline stops, the daemon exits with an error.
    spdlog::error("sensor {}: {}", sensor_.name, e.what());
    std::lock_guard lock(snapshot_mutex_);
    snapshot_->error = e.what();
  }
  take_snapshot(nullptr);
  source_done_.store(true, std::memory_order_release);
  spawn();
}

void SensorPipeline::spawn() {
  velodyne::ScanBuffer* buffer = buffer_ptr_.load(std::memory_order_acquire);
  if (buffer == nullptr || buffer->ready_count() == 0) return;
  int active = active_.load(std::memory_order_relaxed);
  while (active < workers_) {
    if (active_.compare_exchange_weak(active, active + 1, std::memory_order_acq_rel)) {
      arena_.enqueue([this] { work(); });
      return;
    }
  }
}

void SensorPipeline::work() {
  velodyne::ScanBuffer* buffer = buffer_ptr_.load(std::memory_order_acquire);
  for (;;) {
    while (OrderedResults::Slot* slot =
               ordered_.take([buffer] { return buffer->pop(); }, steady_ns())) {
      process(slot);
    }
    // A rotation published after the last pop stays with this task; the publisher's periodic
    // spawn() covers the remaining race.
    if (buffer->ready_count() > 0 && ordered_.has_free_slot()) continue;
    active_.fetch_sub(1, std::memory_order_acq_rel);  // the task's last use of `this`
    return;
  }
}

void SensorPipeline::process(OrderedResults::Slot* slot) {
  const Scan& scan = *slot->scan;
  RotationResult& r = slot->result;
  r.sequence = scan.sequence;
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
  r.assembled_ns = assembled_at(&scan);
  detector::Detector& detector = *detectors_[static_cast<size_t>(slot->detector)];
  // Isolated: while this thread waits inside the detector's own parallel loops it must not pick
  // up another rotation, which would delay this one (and the publication order) behind it.
  tbb::this_task_arena::isolate([&] { detector.detect(scan, r.detection); });
  decimate_scan(scan, options_.lcm.cloud_decimation, r.cloud);
  r.detected_ns = steady_ns();
  buffer_ptr_.load(std::memory_order_relaxed)->release(slot->scan);
  processed_.fetch_add(1, std::memory_order_relaxed);
  ordered_.complete(slot);
}

uint64_t SensorPipeline::dropped_rotations() const {
  const velodyne::ScanBuffer* buffer = buffer_ptr_.load(std::memory_order_acquire);
  return (buffer ? buffer->dropped() : 0) + dropped_no_scan_.load();
}

void SensorPipeline::publish(OrderedResults::Slot* slot) {
  const RotationResult& r = slot->result;
  const int64_t before = steady_ns();
  const int64_t assembled = r.assembled_ns > 0 ? r.assembled_ns : r.taken_ns;
  fill_detections(r, sensor_.name, sensor_.frame_id, wall_utime(), ms(before - assembled),
                  static_cast<int64_t>(dropped_rotations()), message_);
  bus_.publish(detections_channel_, message_);
  // The visualisation messages follow their rotation's detections, in rotation order too.
  if (options_.detector.keep_tag_points && !r.detection.detections.empty()) {
    fill_tag_points(r, sensor_.name, sensor_.frame_id, tag_points_message_);
    bus_.publish(tag_points_channel_, tag_points_message_);
  }
  if (options_.lcm.cloud_decimation > 0) {
    fill_point_cloud(r, sensor_.name, sensor_.frame_id, cloud_message_);
    bus_.publish(cloud_channel_, cloud_message_);
  }
  const int64_t after = steady_ns();
  published_.fetch_add(1, std::memory_order_relaxed);
  detections_.fetch_add(r.detection.detections.size(), std::memory_order_relaxed);

  windows_[kQueue]->record(ms(r.taken_ns - assembled));
  windows_[kDetect]->record(ms(r.detected_ns - r.taken_ns));
  windows_[kOrder]->record(ms(before - r.detected_ns));
  windows_[kPublish]->record(ms(after - before));
  windows_[kTotal]->record(ms(after - assembled));
  for (size_t s = 0; s < r.detection.timing_ms.size(); ++s) {
    windows_[kFixedStages + s]->record(r.detection.timing_ms[s]);
  }
  if (printer_ != nullptr) printer_->print(detections_line(sensor_.name, r));
}

void SensorPipeline::publish_loop() {
  for (;;) {
    publisher_beat_ns_.store(steady_ns(), std::memory_order_relaxed);
    OrderedResults::Slot* slot = ordered_.next_ready(50ms);
    if (slot != nullptr) {
      publish(slot);
      ordered_.recycle(slot);
    }
    spawn();
    if (slot == nullptr && source_done_.load(std::memory_order_acquire)) {
      const velodyne::ScanBuffer* buffer = buffer_ptr_.load(std::memory_order_acquire);
      if ((buffer == nullptr || buffer->ready_count() == 0) &&
          active_.load(std::memory_order_acquire) == 0 && ordered_.in_use() == 0) {
        break;
      }
    }
  }
  publisher_done_.store(true, std::memory_order_release);
}

bool SensorPipeline::healthy(int64_t now_ns, int64_t stall_ns) const {
  if (!error().empty()) return false;
  if (!source_done_.load() && now_ns - tap_->heartbeat_ns() > stall_ns) return false;
  if (!publisher_done_.load() && now_ns - publisher_beat_ns_.load() > stall_ns) return false;
  const int64_t oldest = ordered_.oldest_in_detection_ns();
  return oldest == 0 || now_ns - oldest <= stall_ns;
}

SensorStatus SensorPipeline::status(int64_t now_ns, int64_t stall_ns) {
  SensorStatus st;
  st.sensor = sensor_.name;
  st.frame_id = sensor_.frame_id;
  st.healthy = healthy(now_ns, stall_ns);
  st.rotations_dropped = dropped_rotations();
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
    st.packets_dropped = s.source.kernel_drops + s.batcher.missing_packets;
    st.packets_malformed = s.source.truncated + s.source.malformed + decode_errors +
                           s.counts.undecodable + s.counts.position_errors;
    st.packets_ignored = s.source.ignored;
    st.error = s.error;
  }
  st.packets_received = tap_->packets();
  st.rotations_assembled = assembled_.load();
  st.rotations_processed = processed_.load();
  st.rotations_published = published_.load();
  st.detections = detections_.load();
  if (const velodyne::ScanBuffer* buffer = buffer_ptr_.load(std::memory_order_acquire)) {
    st.buffer_occupancy = buffer->ready_count();
    st.buffer_depth = buffer->depth();
  } else {
    st.buffer_depth = static_cast<uint64_t>(options_.pipeline.queue_depth);
  }
  st.stage_names = stage_names_;
  for (auto& w : windows_) st.stages.push_back(w->take());
  return st;
}

}  // namespace lidartag::daemon
