// Fuzz target: a simulator scene (YAML) through parse_scene, as `lidartag sim SCENE` reads it.
// Checks: bad scenes throw SceneError (never a YAML or standard exception of another kind).
#include <cstddef>
#include <cstdint>
#include <string>

#include "lidartag/sim/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)lidartag::sim::parse_scene(text, "fuzz");
  } catch (const lidartag::sim::SceneError&) {
  }
  return 0;
}
