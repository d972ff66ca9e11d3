#pragma once
// Shared by the fuzz targets: how a fuzzer's bytes become a scene document.
//
// An input is a scene's YAML text; lines at its top of the form "#set PATH=VALUE" are applied as
// `vibro --set` assignments first (YAML comments, so every scene is also a valid input). Only
// SceneError may come out: any other exception escapes the target and libFuzzer reports it as a
// crash, as it does for sanitizer findings.
#include "vibro/io/scene.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace vibro::fuzz {

/// Inputs above this size are skipped: the loader's cost is linear in the text (the scene size
/// limit against memory is tested in tests/io/test_cli.sh), so larger ones only slow the search.
inline constexpr std::size_t kMaxInput = 64 * 1024;

/// Grids above this many points are skipped: each point is a validated scene, so a sweep's cost
/// is linear in its points by design (a 10⁶-point linspace takes seconds, not a hang).
inline constexpr double kMaxGridPoints = 1000;

/// Every run kind's grid (run_section.cpp's RunSection::axis callers); each is given by a
/// `linspace` or `logspace` (a count) or a `values` list.
inline constexpr const char* kGrids[] = {"run.sweep.parameters[0]", "run.sweep.parameters[1]", "run.basin.parameters[0]",
                                         "run.basin.parameters[1]", "run.locate", "run.diagram", "run.lyapunov"};

/// The grids fuzz_run runs: at most this many points per axis. Each point of a grid is a scene,
/// validated when the scene is built and set up again when the run starts, linear in the points
/// by design: a basin of 256 × 256 points (experiments/chaos/basin_wagg.yaml) takes 1.1–1.9 s to
/// build under ASan, a diagram of 200 points 1.2 s, where fuzz_run can spend a few ms on an input.
/// fuzz_run lowers a larger count to this one (limit_grids, the same ends) and skips an input with
/// a longer values list.
inline constexpr double kRunGridPoints = 16;

/// Whether every grid of `doc` has at most `points` points. A `linspace` or `logspace` count above
/// it is lowered to it (the same ends) if `lower`, else makes the answer false; a `values` list
/// with more makes it false.
inline bool limit_grids(io::SceneDocument& doc, double points, bool lower) {
  const std::string past = "values[" + std::to_string(static_cast<long>(points)) + "]";
  for (const char* grid : kGrids) {
    const std::string axis(grid);
    for (const char* spaced : {".linspace[2]", ".logspace[2]"}) {
      try {
        if (doc.get(axis + spaced) <= points) continue;
        if (!lower) return false;
        doc.set(axis + spaced, points);
      } catch (const io::SceneError&) {
      }
    }
    try {
      (void)doc.get(axis + "." + past);  // a number there: more than `points` values
      return false;
    } catch (const io::SceneError&) {
    }
  }
  return true;
}

/// The document, with the "#set" lines applied; none if the input is skipped or refused.
inline std::optional<io::SceneDocument> document(const std::uint8_t* data, std::size_t size) {
  if (size > kMaxInput) return std::nullopt;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    io::SceneDocument doc = io::SceneDocument::parse(text, "fuzz.yaml");
    std::size_t at = 0;
    for (int k = 1; text.compare(at, 5, "#set ") == 0; ++k) {
      const std::size_t end = std::min(text.find('\n', at), text.size());
      doc.set_assignment(text.substr(at + 5, end - at - 5), k);
      at = end + 1;
      if (at >= text.size()) break;
    }
    // Every run kind's grid, in each of its three forms (a fuzzed basin_wagg.yaml with 8561 rows
    // takes 12–16 s under ASan: 35 µs per row in release, linear as designed).
    if (!limit_grids(doc, kMaxGridPoints, false)) return std::nullopt;
    return doc;
  } catch (const io::SceneError&) {
    return std::nullopt;
  }
}

}  // namespace vibro::fuzz
