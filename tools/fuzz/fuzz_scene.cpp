// libFuzzer target: the scene loader (SceneDocument::parse, set_assignment, build). Any input
// must give a Scene or a SceneError; nothing else may escape, crash, hang or trip ASan/UBSan.
// Build and run: docs/fuzzing.md.
#include "fuzz_input.hpp"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto doc = vibro::fuzz::document(data, size);
  if (!doc) return 0;
  try {
    const vibro::io::Scene scene = doc->build();
    (void)scene.period();
  } catch (const vibro::io::SceneError&) {
  }
  return 0;
}
