// JSON Schema documents of the messages SceneRecorder writes. The foxglove.* ones describe the
// fields of Foxglove's message types of those names (docs.foxglove.dev, "Message schemas") as
// the JSON encoding carries them: times as {sec, nsec}, bytes as base64 strings
// ("contentEncoding": "base64", which is how Foxglove knows to decode them), enums as numbers.
#include <string_view>

#include "lidartag/foxglove/scene_recorder.hpp"

namespace lidartag::foxglove {
namespace {

#define LT_TIME                                                             \
  R"({"type":"object","properties":{"sec":{"type":"integer","minimum":0},)" \
  R"("nsec":{"type":"integer","minimum":0,"maximum":999999999}}})"
#define LT_VECTOR3                                                                 \
  R"({"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},)" \
  R"("z":{"type":"number"}}})"
#define LT_QUATERNION                                                              \
  R"({"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},)" \
  R"("z":{"type":"number"},"w":{"type":"number"}}})"
#define LT_POSE \
  R"({"type":"object","properties":{"position":)" LT_VECTOR3 R"(,"orientation":)" LT_QUATERNION "}}"
#define LT_COLOR                                                                   \
  R"({"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},)" \
  R"("b":{"type":"number"},"a":{"type":"number"}}})"
#define LT_ANY_ARRAY R"({"type":"array","items":{"type":"object"}})"

constexpr std::string_view kPointCloud =
    R"({"title":"foxglove.PointCloud","description":"A collection of N-dimensional points",)"
    R"("type":"object","properties":{"timestamp":)" LT_TIME R"(,"frame_id":{"type":"string"},)"
    R"("pose":)" LT_POSE R"(,"point_stride":{"type":"integer","minimum":0},)"
    R"("fields":{"type":"array","items":{"type":"object","properties":{)"
    R"("name":{"type":"string"},"offset":{"type":"integer","minimum":0},)"
    R"("type":{"type":"integer","description":"NumericType: 0 UNKNOWN, 1 UINT8, 2 INT8, )"
    R"(3 UINT16, 4 INT16, 5 UINT32, 6 INT32, 7 FLOAT32, 8 FLOAT64"}}}},)"
    R"("data":{"type":"string","contentEncoding":"base64"}}})";

constexpr std::string_view kSceneUpdate =
    R"({"title":"foxglove.SceneUpdate","description":"An update to the entities of a scene",)"
    R"("type":"object","properties":{"deletions":{"type":"array","items":{"type":"object",)"
    R"("properties":{"timestamp":)" LT_TIME R"(,"type":{"type":"integer",)"
    R"("description":"0 MATCHING_ID, 1 ALL"},"id":{"type":"string"}}}},)"
    R"("entities":{"type":"array","items":{"type":"object","properties":{)"
    R"("timestamp":)" LT_TIME R"(,"frame_id":{"type":"string"},"id":{"type":"string"},)"
    R"("lifetime":{"type":"object","properties":{"sec":{"type":"integer"},)"
    R"("nsec":{"type":"integer"}}},"frame_locked":{"type":"boolean"},)"
    R"("metadata":{"type":"array","items":{"type":"object","properties":{)"
    R"("key":{"type":"string"},"value":{"type":"string"}}}},)"
    R"("arrows":)" LT_ANY_ARRAY R"(,)"
    R"("cubes":{"type":"array","items":{"type":"object","properties":{"pose":)" LT_POSE
    R"(,"size":)" LT_VECTOR3 R"(,"color":)" LT_COLOR R"(}}},)"
    R"("spheres":)" LT_ANY_ARRAY R"(,"cylinders":)" LT_ANY_ARRAY R"(,"lines":)" LT_ANY_ARRAY
    R"(,"triangles":)" LT_ANY_ARRAY R"(,)"
    R"("texts":{"type":"array","items":{"type":"object","properties":{"pose":)" LT_POSE
    R"(,"billboard":{"type":"boolean"},"font_size":{"type":"number"},)"
    R"("scale_invariant":{"type":"boolean"},"color":)" LT_COLOR R"(,"text":{"type":"string"}}}},)"
    R"("models":{"type":"array","items":{"type":"object","properties":{)"
    R"("data":{"type":"string","contentEncoding":"base64"}}}}}}}}})";

constexpr std::string_view kFrameTransforms =
    R"({"title":"foxglove.FrameTransforms","description":"An array of FrameTransform messages",)"
    R"("type":"object","properties":{"transforms":{"type":"array","items":{"type":"object",)"
    R"("properties":{"timestamp":)" LT_TIME R"(,"parent_frame_id":{"type":"string"},)"
    R"("child_frame_id":{"type":"string"},"translation":)" LT_VECTOR3
    R"(,"rotation":)" LT_QUATERNION R"(}}}}})";

constexpr std::string_view kDetections =
    R"({"title":"lidartag.Detections","description":"The LiDARTags detected in one rotation: )"
    R"(positions in metres in the sensor frame, orientations as [w, x, y, z], tag frame to )"
    R"(sensor frame","type":"object","properties":{"sequence":{"type":"integer"},)"
    R"("stamp":{"type":"number","description":"seconds since the epoch"},)"
    R"("detections":{"type":"array","items":{"type":"object","properties":{)"
    R"("family":{"type":"string"},"id":{"type":"integer"},"size_m":{"type":"number"},)"
    R"("position":{"type":"array","items":{"type":"number"}},)"
    R"("orientation":{"type":"array","items":{"type":"number"}},)"
    R"("score":{"type":"number"},"margin":{"type":"number"},"points":{"type":"integer"}}}}}})";

constexpr std::string_view kStatus =
    R"({"title":"lidartag.Status","description":"A sensor's health as lidartagd publishes it",)"
    R"("type":"object","properties":{"sensor":{"type":"string"},"state":{"type":"string"},)"
    R"("reason":{"type":"string"}},"additionalProperties":true})";

#undef LT_TIME
#undef LT_VECTOR3
#undef LT_QUATERNION
#undef LT_POSE
#undef LT_COLOR
#undef LT_ANY_ARRAY

}  // namespace

std::string_view json_schema(std::string_view name) {
  if (name == "foxglove.PointCloud") return kPointCloud;
  if (name == "foxglove.SceneUpdate") return kSceneUpdate;
  if (name == "foxglove.FrameTransforms") return kFrameTransforms;
  if (name == "lidartag.Detections") return kDetections;
  if (name == "lidartag.Status") return kStatus;
  return {};
}

}  // namespace lidartag::foxglove
