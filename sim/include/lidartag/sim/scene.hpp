// A simulated scene: the sensor, the world and the tags, as plain option structs with documented
// defaults and units. YAML loading lives in scene_yaml.cpp (one place); docs/simulator.md lists
// every key. Frames: world x/y horizontal, z up, the ground is the plane z = 0.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::sim {

// Setup error in a scene (unknown key, bad value, unknown family...): the message names the key.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Beam footprint, noise and the artefacts of the paper's Fig. 2. Probabilities are per beam.
struct NoiseOptions {
  double range_sigma_m = 0.015;     // Gaussian range noise, metres (per model: noise_defaults)
  double intensity_sigma = 2.0;     // Gaussian reflectivity noise, 0..255 reflectivity units
  double divergence_h_mrad = 3.0;   // full beam divergence, horizontal, milliradians
  double divergence_v_mrad = 1.5;   // full beam divergence, vertical, milliradians
  int footprint_samples = 5;        // rays per beam footprint: 1 (no footprint), 5 or 9
  double echo_separation_m = 0.5;   // sub-returns farther apart than this are separate echoes
  double depth_edge_m = 0.05;       // footprint depth spread that counts as a depth edge
  double depth_edge_missing = 0.3;  // probability that a beam on a depth edge returns nothing
  double depth_edge_mixed = 0.3;    // probability that its echoes merge into one mixed return
  double intensity_edge = 20.0;     // reflectivity spread in a footprint that counts as an edge
  double intensity_edge_missing = 0.15;  // probability of no return on a black/white edge
  double dropout = 0.002;                // probability that any beam returns nothing
  // Detection: an echo is reported when its apparent reflectivity (0..100 diffuse scale) is at
  // least detect_reflectivity_10m * (range / 10 m)^2 (inverse-square fall-off of the energy).
  double detect_reflectivity_10m = 0.05;
  double min_range_m = 0.0;  // returns closer than this are dropped; 0: the model's own limit
  double max_range_m = 0.0;  // returns farther than this are dropped; 0: the model's own limit

  // Everything off: exact ranges and reflectivities, one ray per beam, no artefacts.
  static NoiseOptions ideal();
};

// Documented per-model defaults (docs/simulator.md): range sigma chosen so that 2 sigma is about
// the datasheet accuracy (VLP-16/Puck Hi-Res/VLP-32C/VLS-128 +-3 cm: 0.015 m; HDL-32E +-2 cm but
// older electronics: 0.02 m).
NoiseOptions noise_defaults(velodyne::Model model);

// An Ouster sensor (docs/simulator.md, "Ouster sensors"): its model's beam table
// (driver::ouster::nominal_sensor_info: the OS1's nominal one, the OS0's and OS2's of real units).
struct OusterSensorOptions {
  driver::ouster::Model model = driver::ouster::Model::kOs1_64;
  int columns = 1024;  // lidar mode: columns per rotation (512, 1024, 2048)
  int rate_hz = 10;    // and rotations per second (10, 20; 2048 only at 10)
  driver::ouster::Profile profile = driver::ouster::Profile::kRng19Rfl8Sig16Nir16;
};

struct SensorOptions {
  velodyne::Model model = velodyne::Model::kVLP32C;
  // Set when `model` names an Ouster sensor: then `model`, `rpm`, `return_mode`,
  // `cut_azimuth_deg` and the position packets are unused (rotations are the sensor's frames).
  std::optional<OusterSensorOptions> ouster;
  double rpm = 600.0;  // 300..1200
  velodyne::ReturnMode return_mode = velodyne::ReturnMode::kStrongest;
  std::array<double, 2> position{0.0, 0.0};               // metres, world x, y
  double height = 1.0;                                    // metres above the ground (world z)
  double roll_deg = 0.0, pitch_deg = 0.0, yaw_deg = 0.0;  // R = Rz(yaw) Ry(pitch) Rx(roll)
  std::array<double, 3> velocity{0.0, 0.0, 0.0};          // m/s, world frame, constant
  std::array<double, 3> angular_velocity{0.0, 0.0, 0.0};  // deg/s, sensor (body) frame, constant
  double start_time_s = 1700000000.0;  // UTC seconds since the epoch of the first firing
  double cut_azimuth_deg = 180.0;      // where truth rotations start (the batcher's default cut)
  bool position_packets = false;       // also write position packets ($GPRMC, PPS locked)
  double position_rate_hz = 100.0;     // position packets per second
  NoiseOptions noise{};
};

struct RoomOptions {
  bool enabled = false;
  std::array<double, 2> center{0.0, 0.0};  // metres, world x, y of the floor's centre
  std::array<double, 2> size{10.0, 8.0};   // inner length (along the room's x) and width, metres
  double height = 3.0;                     // metres
  double yaw_deg = 0.0;
  double reflectivity = 50.0;  // walls and ceiling, 0..100 diffuse
  bool ceiling = true;
};

struct WallOptions {
  std::array<double, 2> from{0.0, 0.0};  // metres, world x, y of one end of the wall's centre line
  std::array<double, 2> to{1.0, 0.0};
  double height = 3.0;      // metres
  double thickness = 0.15;  // metres
  double reflectivity = 50.0;
};

struct BoxOptions {
  std::array<double, 3> center{0.0, 0.0, 0.5};  // metres, world
  std::array<double, 3> size{1.0, 1.0, 1.0};    // metres along the box's x, y, z
  double yaw_deg = 0.0;
  double reflectivity = 30.0;
};

// Vertical cylinder: poles, trees, people.
struct CylinderOptions {
  std::array<double, 3> base{0.0, 0.0, 0.0};  // metres, world centre of the bottom face
  double radius = 0.2;                        // metres
  double height = 1.7;                        // metres
  double reflectivity = 30.0;
};

enum class ClutterKind : uint8_t { kLab, kOutdoor, kParking };

// Random objects around the sensor, placed with a seeded generator; nothing is put on the
// sensor, on a tag (with its t*sqrt(2)/4 clearance) or between the sensor and a tag.
struct ClutterOptions {
  bool enabled = false;
  ClutterKind kind = ClutterKind::kLab;
  uint64_t seed = 1;
  int count = 20;                                          // objects (parking: cars) to place
  std::array<double, 4> region{-10.0, 10.0, -10.0, 10.0};  // xmin, xmax, ymin, ymax, metres
  double clearance = 0.5;                                  // metres kept free around sensor/tags
};

struct WorldOptions {
  bool ground = true;  // the plane z = 0
  double ground_reflectivity = 15.0;
  RoomOptions room{};
  std::vector<WallOptions> walls;
  std::vector<BoxOptions> boxes;
  std::vector<CylinderOptions> cylinders;
  ClutterOptions clutter{};
};

struct BoardOptions {
  double thickness = 0.02;     // metres, behind the printed face
  double margin = 0.05;        // metres of bare board around the marker
  double reflectivity = 60.0;  // the bare board (edges, margin, back)
};

// An easel-like stand: a post from the ground to the board's centre, behind the board.
struct StandOptions {
  bool enabled = false;
  double width = 0.05;  // metres, square section
  double reflectivity = 30.0;
};

struct TagOptions {
  std::string family = "tag16h5";  // built-in name or FILE.json[:NAME]
  int id = 0;
  double size = 0.8;  // t, full outer size of the printed marker (white ring included), metres
  std::array<double, 3> center{3.0, 0.0, 1.0};  // metres, world
  // Normal out of the printed face (tag +x). Unset (all zero): faces the sensor horizontally.
  std::array<double, 3> normal{0.0, 0.0, 0.0};
  // Rotation of the image about the normal, degrees, counter-clockwise seen from the front;
  // 0 ("square"): the image's top edge is up; 45 ("diamond"): a corner is up.
  double rotation_deg = 45.0;
  BoardOptions board{};
  StandOptions stand{};
  double white_reflectivity = 80.0;  // printed paper, 0..100 diffuse (retro-reflective: > 100)
  double black_reflectivity = 8.0;   // printed toner
};

// Boards that are not tags, the ones people put in front of LiDARs (false-positive torture).
enum class BoardKind : uint8_t {
  kCheckerboard,  // camera calibration checkerboard: dark and light squares
  kHoles,         // LiDAR-camera calibration target: a plain board with circular holes
  kStrips,        // a board with retro-reflective strips (tape)
  kSign,          // a sign: light face, dark border, lines of dark letter-like patches
};

struct CalibrationBoardOptions {
  BoardKind kind = BoardKind::kCheckerboard;
  std::array<double, 3> center{3.0, 0.0, 1.0};  // metres, world: centre of the front face
  // Out of the front face. Unset (all zero): faces the sensor horizontally.
  std::array<double, 3> normal{0.0, 0.0, 0.0};
  // About the normal, degrees counter-clockwise seen from the front; 0 ("square"): the width
  // horizontal; 45 ("diamond").
  double rotation_deg = 0.0;
  std::array<double, 2> size{0.85, 0.61};  // metres: width and height before the rotation
  double thickness = 0.01;                 // metres
  double reflectivity = 80.0;      // the board: light squares, sign face (retro-reflective > 100)
  double dark_reflectivity = 8.0;  // dark squares, sign border and letters
  StandOptions stand{};
  // checkerboard: inner corners across and up, side of a square (metres); the pattern is centred
  // on the board, its top-left square dark.
  std::array<int, 2> inner_corners{7, 5};
  double square_m = 0.095;
  // holes: circles through the board, each [y, z, radius] in metres in the board's frame (y to
  // the right, z up, origin at the centre, before the rotation).
  std::vector<std::array<double, 3>> holes;
  // strips: `strips` strips of retro-reflective tape strip_width_m wide, evenly spaced across
  // (horizontal) or up (vertical) the board.
  int strips = 3;
  double strip_width_m = 0.05;
  bool vertical_strips = false;
  double strip_reflectivity = 220.0;
  // sign: a dark border border_m wide and text_lines lines of letter-like dark patches (5 x 3
  // pixel glyphs drawn from text_seed).
  double border_m = 0.04;
  int text_lines = 2;
  uint64_t text_seed = 1;
};

// A camera beside the LiDAR (issue 30): renders the scene into an 8-bit grey image per run
// (camera_sim.hpp). Grey level = reflectivity (0..100 diffuse) * gain, clipped to 255.
struct CameraOptions {
  // Intrinsics, pixels, in lidartag's convention (pixel centres at integers). Defaults: 1280x720,
  // fx = fy = 900, the principal point at the image centre, no distortion.
  calib::CameraModel model = default_model();
  // lidar_to_camera: p_camera = R p_lidar + t (camera optical frame: x right, y down, z forward).
  // Default rotation: looking along the LiDAR's +x with its z up; translation 0.
  std::array<double, 4> rotation_wxyz = forward_wxyz();
  std::array<double, 3> translation_m{0.0, 0.0, 0.0};
  double noise_sigma = 2.0;   // Gaussian pixel noise, grey levels (0..255)
  double blur_sigma = 0.5;    // Gaussian blur (optics), pixels; 0: none
  int supersample = 4;        // samples per pixel along each axis (anti-aliasing), 1..8
  double gain = 2.55;         // grey levels per reflectivity unit
  double background = 200.0;  // grey level where a ray hits nothing (sky)

  static calib::CameraModel default_model();
  static std::array<double, 4> forward_wxyz();
};

// One pose of a calibration series: where the scene's first tag is put (TagOptions' meanings).
struct TagPose {
  std::array<double, 3> center{3.0, 0.0, 1.0};
  std::array<double, 3> normal{0.0, 0.0, 0.0};
  double rotation_deg = 45.0;
};

struct Scene {
  SensorOptions sensor{};
  std::optional<CameraOptions> camera;  // the `camera:` section; none: no image
  WorldOptions world{};
  std::vector<TagOptions> tags;
  std::vector<CalibrationBoardOptions> boards;
  // A calibration series: `lidartag sim` writes one capture, truth and image per pose, the first
  // tag moved there (the other keys of the tag kept). Empty: one capture of the scene as given.
  std::vector<TagPose> series;
  uint64_t seed = 1;   // noise seed (the --seed option overrides it)
  int rotations = 10;  // rotations written (the --rotations option overrides it)
};

// The scene of pose `index` of its series: the first tag moved to it.
Scene series_scene(const Scene& scene, size_t index);

// Parses a scene; `source` names the text in error messages. Throws SceneError.
Scene parse_scene(const std::string& yaml_text, const std::string& source = "scene");
// Reads and parses a scene file. Throws SceneError.
Scene load_scene(const std::string& path);

std::string_view clutter_kind_name(ClutterKind kind);
std::string_view board_kind_name(BoardKind kind);

}  // namespace lidartag::sim
