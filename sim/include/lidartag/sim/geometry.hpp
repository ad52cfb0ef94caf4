// World primitives and ray casting: the ground plane, oriented boxes (walls, rooms, furniture,
// tag boards with their printed face) and vertical cylinders (poles, trees, people).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <vector>

namespace lidartag::sim {

// `dir` is a unit vector; distances along the ray are metres.
struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d dir = Eigen::Vector3d::UnitX();
};

struct Hit {
  double t = std::numeric_limits<double>::infinity();  // distance along the ray, metres
  double reflectivity = 0.0;                           // 0..100 diffuse, > 100 retro-reflective
  int tag = -1;  // index of the tag whose printed marker was hit, else -1
  bool hit() const { return t < std::numeric_limits<double>::infinity(); }
};

// The printed image on a box's +x face, centred on that face: rows x cols cells of `width` x
// `height` metres, row 0 at the top (+z), column 0 at the left (-y) seen from the front (+x).
struct PrintedPattern {
  int tag = -1;  // tag index reported in Hit::tag (-1: not a tag, e.g. a checkerboard)
  double width = 0, height = 0;  // metres across (y) and up (z)
  int cols = 0, rows = 0;
  std::vector<double> reflectivity;  // per cell, row-major
  // Reflectivity at (y, z) of the face; false when outside the printed area.
  bool reflectivity_at(double y, double z, double& reflectivity) const;
};

// A circular hole through a box, along its x axis: rays entering through the +x or -x face
// inside it pass through (the hole's wall is not modelled).
struct Hole {
  double y = 0, z = 0;  // centre in the box frame, metres
  double radius = 0;    // metres
};

struct OrientedBox {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // world <- box axes
  Eigen::Vector3d half = Eigen::Vector3d::Constant(0.5);   // half sizes along the box axes
  double reflectivity = 30.0;
  int pattern = -1;         // index of a PrintedPattern on the box's +x face, or -1
  std::vector<Hole> holes;  // through the box along x
};

struct VerticalCylinder {
  Eigen::Vector3d base = Eigen::Vector3d::Zero();  // centre of the bottom face
  double radius = 0.2;
  double height = 1.7;
  double reflectivity = 30.0;
};

// Box centred at `center` with full sizes `size`, rotated by `yaw_deg` about world z.
OrientedBox make_box(const Eigen::Vector3d& center, const Eigen::Vector3d& size, double yaw_deg,
                     double reflectivity);

// Ray-primitive tests: true and `t` (in (t_min, t_max)) for the nearest entry. `face_x` tells
// whether the box was entered through its +x face (local coordinates in `local`).
bool intersect_box(const OrientedBox& box, const Ray& ray, double t_max, double& t,
                   Eigen::Vector3d& local, bool& face_x);
bool intersect_cylinder(const VerticalCylinder& cyl, const Ray& ray, double t_max, double& t);

class World {
 public:
  void set_ground(bool enabled, double reflectivity);
  void add_box(const OrientedBox& box);
  void add_cylinder(const VerticalCylinder& cyl);
  int add_pattern(PrintedPattern pattern);  // returns its index for OrientedBox::pattern

  // Nearest surface along `ray` closer than t_max.
  Hit cast(const Ray& ray, double t_max) const;

  size_t boxes() const { return boxes_.size(); }
  size_t cylinders() const { return cylinders_.size(); }
  const std::vector<OrientedBox>& box_list() const { return boxes_; }
  const std::vector<VerticalCylinder>& cylinder_list() const { return cylinders_; }

 private:
  struct Bound {
    Eigen::Vector3d center;
    double radius;
  };
  bool ground_ = false;
  double ground_reflectivity_ = 15.0;
  std::vector<OrientedBox> boxes_;
  std::vector<Bound> box_bounds_;
  std::vector<VerticalCylinder> cylinders_;
  std::vector<Bound> cylinder_bounds_;
  std::vector<PrintedPattern> patterns_;
};

}  // namespace lidartag::sim
