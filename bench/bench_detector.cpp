// bench_detector: the detector's speed per rotation and per stage (the paper's Table II), on the
// rotations of pcaps/demo.pcap (lab, VLP-32C, two tags), pcaps/outdoor.pcap (parking lot,
// VLP-32C, three tags) and pcaps/boards.pcap (VLP-32C, 13 boards that are no tags: checkerboards,
// boards with holes, signs; many reach the pose fit and decoding), single-threaded; and on Ouster
// OS1-128 1024x10 frames (131,072 cells, 100 ms each): os1_128, the three whole frames of
// ../shared/captures/ouster/pcaps/OS-1-128_v2.3.0_1024x10_lb_n3.pcap (a street, no tag; skipped
// when ../shared is absent), with the default options as `lidartag detect` uses them; os1_128_sim,
// eight simulated frames of bench_accuracy's scene (a 1.2 m tag16h5 at 10 m, 45 deg), options as
// bench_accuracy's.
//
//   bench_detector [--benchmark_min_time=2]
//
// BM_Detect: one call of Detector::detect per iteration, cycling over the capture's rotations.
// Counters: the median over the iterations of each stage's time (ms, from ScanResult::timing_ms),
// the median total, and `period_pct`: the median total as a percentage of the 100 ms rotation
// period of a sensor at 600 rpm (the target is <= 2 %). The *_no_polish variants skip the pose's
// polish on every point, the *_no_family_check ones the decoding against the families not
// configured, the *_no_track_only ones the clusters fitted and decoded as tracker evidence only
// (validation.track_boundary_scale = boundary_scale), the *_no_retry ones the second pose fit of
// clusters whose fit stays poor (pose.retry_mean_cost_m = 0), the *_strict_track_bound ones the
// tracks' boundary bound as before 2026-12-05 (validation.track_testable_per_transition = 6,
// track_transitions_per_ring = 0). BM_EdgeFeatures and BM_Clustering time the first two stages
// alone.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "lidartag/detector/clustering.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/edge_features.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "sim_scans.hpp"

namespace {

using namespace lidartag;

struct Capture {
  std::vector<Scan> rotations;
  detector::DetectorOptions options;
};

std::string pcap(const char* name) {
  return (std::filesystem::path(LIDARTAG_SOURCE_DIR) / "pcaps" / name).string();
}

// The whole frames of a real OS1-128 capture, destaggered as `lidartag detect` sees them; none when
// ../shared is absent.
void load_ouster_capture(Capture& c) {
  namespace ouster = driver::ouster;
  const auto dir = std::filesystem::path(LIDARTAG_SHARED_DIR) / "captures/ouster/pcaps";
  const auto pcap_path = dir / "OS-1-128_v2.3.0_1024x10_lb_n3.pcap";
  if (!std::filesystem::exists(pcap_path)) return;
  const ouster::SensorInfo info =
      ouster::load_metadata((dir / "OS-1-128_v2.3.0_1024x10.json").string());
  ouster::CaptureReader reader(pcap_path.string(), info);
  Scan scan;
  for (driver::ReadResult r;
       (r = reader.read(scan, std::chrono::seconds(10))) != driver::ReadResult::kEnd;)
    if (r == driver::ReadResult::kRotation && scan.complete) c.rotations.push_back(scan);
  c.options.cluster_diagnostics = false;
}

// Simulated OS1-128 1024x10 frames of bench_accuracy's scene: a 1.2 m tag16h5 at 10 m, 45 deg.
void load_ouster_sim(Capture& c) {
  sim::Scene scene = eval::accuracy_scene(velodyne::Model::kVLP32C, 10.0, 45, 0);
  scene.sensor.ouster = sim::OusterSensorOptions{driver::ouster::Model::kOs1_128, 1024, 10,
                                                 driver::ouster::Profile::kRng19Rfl8Sig16Nir16};
  scene.sensor.noise = sim::NoiseOptions{};
  const sim::Simulator simulator(std::move(scene));
  eval::SimScans scans(simulator);
  scans.run(8, 1, [&](const Scan& s, size_t) { c.rotations.push_back(s); });
  c.options.tag_sizes_m = {1.2};
  c.options.families = {"tag16h5", "tag25h9", "tag36h11"};
  c.options.cluster_diagnostics = false;
}

const Capture& capture(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Capture>> cache;
  auto& slot = cache[name];
  if (!slot && name == "os1_128") {
    slot = std::make_unique<Capture>();
    load_ouster_capture(*slot);
  } else if (!slot && name == "os1_128_sim") {
    slot = std::make_unique<Capture>();
    load_ouster_sim(*slot);
  } else if (!slot) {
    slot = std::make_unique<Capture>();
    velodyne::CaptureReader reader(pcap((name + ".pcap").c_str()), {});
    while (const Scan* s = reader.next())
      if (s->complete) slot->rotations.push_back(*s);
    // The tags each scene holds (pcaps/NAME.yaml).
    if (name == "demo") {
      slot->options.tag_sizes_m = {0.8, 0.6};
    } else {  // outdoor and boards: three sizes and three families at once
      slot->options.tag_sizes_m = {1.2, 0.8, 0.6};
      slot->options.families = {"tag16h5", "tag36h11", "tag25h9"};
    }
    slot->options.cluster_diagnostics = false;
  }
  return *slot;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// What a variant changes in the scene's options.
enum class Variant {
  kDefault,
  kNoPolish,
  kNoFamilyCheck,
  kNoTrackOnly,
  kNoRetry,
  kStrictTrackBound
};

void BM_Detect(benchmark::State& state, const std::string& name, Variant variant) {
  const Capture& c = capture(name);
  if (c.rotations.empty()) {
    state.SkipWithError("no complete rotations in the capture");
    return;
  }
  detector::DetectorOptions options = c.options;
  if (variant == Variant::kNoPolish) options.pose.polish_evaluations = 0;
  if (variant == Variant::kNoFamilyCheck) options.decode.reject_other_families = false;
  if (variant == Variant::kNoRetry) options.pose.retry_mean_cost_m = 0.0;
  if (variant == Variant::kNoTrackOnly)
    options.validation.track_boundary_scale = options.validation.boundary_scale;
  if (variant == Variant::kStrictTrackBound) {
    options.validation.track_testable_per_transition = 6.0f;
    options.validation.track_transitions_per_ring = 0.0f;
  }
  detector::Detector det(options);
  detector::ScanResult result;
  std::array<std::vector<double>, detector::kStageCount> stage_ms;
  std::vector<double> total_ms;
  size_t i = 0, found = 0;
  for (auto _ : state) {
    det.detect(c.rotations[i % c.rotations.size()], result);
    benchmark::DoNotOptimize(result.detections.data());
    for (size_t s = 0; s < stage_ms.size(); ++s) stage_ms[s].push_back(result.timing_ms[s]);
    total_ms.push_back(result.total_ms());
    found += result.detections.size();
    ++i;
  }
  for (int s = 0; s < detector::kStageCount; ++s)
    state.counters[std::string(detector::stage_name(static_cast<detector::Stage>(s))) + "_ms"] =
        median(stage_ms[static_cast<size_t>(s)]);
  state.counters["total_ms"] = median(total_ms);
  state.counters["period_pct"] = median(total_ms) / 100.0 * 100.0;
  state.counters["tags_per_rotation"] = static_cast<double>(found) / static_cast<double>(i);
}

void BM_EdgeFeatures(benchmark::State& state, const std::string& name) {
  const Capture& c = capture(name);
  detector::FeatureOptions fo;
  std::vector<detector::Feature> features;
  std::vector<float> gradient;
  size_t i = 0;
  for (auto _ : state) {
    detector::detect_edge_features(c.rotations[i++ % c.rotations.size()], fo, 0.0f, features,
                                   gradient);
    benchmark::DoNotOptimize(features.data());
  }
}

void BM_Clustering(benchmark::State& state, const std::string& name) {
  const Capture& c = capture(name);
  // The detector's derived limits for its largest tag, 1.2 m.
  detector::DetectorOptions options;
  options.tag_sizes_m = {1.2};
  const detector::Detector det(options);
  const detector::DetectorLimits& limits = det.limits();
  std::vector<std::vector<detector::Feature>> features(c.rotations.size());
  std::vector<float> gradient;
  for (size_t k = 0; k < c.rotations.size(); ++k)
    detector::detect_edge_features(c.rotations[k], options.features, limits.max_pair_chord_m,
                                   features[k], gradient);
  const detector::ClusterOptions co;
  std::vector<detector::Cluster> clusters;
  std::vector<int> labels;
  size_t i = 0;
  for (auto _ : state) {
    detector::cluster_features(features[i++ % features.size()], limits.tau_m, limits.max_extent_m,
                               co, clusters, labels);
    benchmark::DoNotOptimize(clusters.data());
  }
}

BENCHMARK_CAPTURE(BM_Detect, demo, std::string("demo"), Variant::kDefault)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, outdoor, std::string("outdoor"), Variant::kDefault)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, boards, std::string("boards"), Variant::kDefault)
    ->Unit(benchmark::kMillisecond);
// Without the pose's polish on every point (pose.polish_evaluations = 0): faster, and about twice
// the rotation error (docs/detector.md).
BENCHMARK_CAPTURE(BM_Detect, demo_no_polish, std::string("demo"), Variant::kNoPolish)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, outdoor_no_polish, std::string("outdoor"), Variant::kNoPolish)
    ->Unit(benchmark::kMillisecond);
// Without decoding against the families that are not configured
// (decode.reject_other_families = false): what that check costs.
BENCHMARK_CAPTURE(BM_Detect, demo_no_family_check, std::string("demo"), Variant::kNoFamilyCheck)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, outdoor_no_family_check, std::string("outdoor"),
                  Variant::kNoFamilyCheck)
    ->Unit(benchmark::kMillisecond);
// Without the track-only candidates (validation.track_boundary_scale = boundary_scale): what
// looking at the clusters a little below eq. (6)'s bound costs.
BENCHMARK_CAPTURE(BM_Detect, demo_no_track_only, std::string("demo"), Variant::kNoTrackOnly)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, outdoor_no_track_only, std::string("outdoor"), Variant::kNoTrackOnly)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, boards_no_track_only, std::string("boards"), Variant::kNoTrackOnly)
    ->Unit(benchmark::kMillisecond);
// With the tracks' boundary bound as strict as before 2026-12-05 (one transition per 6 testable
// points, no cap per ring): what the far edge's looser bound costs.
BENCHMARK_CAPTURE(BM_Detect, demo_strict_track_bound, std::string("demo"),
                  Variant::kStrictTrackBound)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, outdoor_strict_track_bound, std::string("outdoor"),
                  Variant::kStrictTrackBound)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, boards_strict_track_bound, std::string("boards"),
                  Variant::kStrictTrackBound)
    ->Unit(benchmark::kMillisecond);
// Without the second pose fit, turned 45 degrees, of clusters whose fit stays above
// pose.retry_mean_cost_m: what it costs.
BENCHMARK_CAPTURE(BM_Detect, demo_no_retry, std::string("demo"), Variant::kNoRetry)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, outdoor_no_retry, std::string("outdoor"), Variant::kNoRetry)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, boards_no_retry, std::string("boards"), Variant::kNoRetry)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, os1_128, std::string("os1_128"), Variant::kDefault)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Detect, os1_128_sim, std::string("os1_128_sim"), Variant::kDefault)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_EdgeFeatures, os1_128, std::string("os1_128"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Clustering, os1_128, std::string("os1_128"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_EdgeFeatures, demo, std::string("demo"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_EdgeFeatures, outdoor, std::string("outdoor"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Clustering, demo, std::string("demo"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Clustering, outdoor, std::string("outdoor"))->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
