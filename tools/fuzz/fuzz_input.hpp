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

/// A run over a grid of two axes (a basin, a two-parameter sweep) with more points than this is
/// skipped by fuzz_run: 256 × 256, experiments/chaos/basin_wagg.yaml's grid, so the seeds run
/// whole. Each axis is validated value by value when the scene loads (linear, bounded above),
/// but the run allocates, labels and writes every point of the product even when interrupted at
/// once: 1000 × 1000 points are seconds of that in release, tens of seconds under ASan.
inline constexpr std::size_t kMaxGridCells = 256 * 256;

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
    // Every run kind's grid (run_section.cpp's RunSection::axis callers), in each of its three
    // forms: a linspace or logspace count above the limit, or a values list with a number past
    // it. The basin grids were missing: a fuzzed basin_wagg.yaml with 8561 rows took 12–16 s per
    // input under ASan (35 µs per row in release, linear as designed), which libFuzzer reported
    // as slow units.
    const std::string past = "values[" + std::to_string(static_cast<long>(kMaxGridPoints)) + "]";
    for (const char* grid : {"run.sweep.parameters[0]", "run.sweep.parameters[1]", "run.basin.parameters[0]",
                             "run.basin.parameters[1]", "run.locate", "run.diagram", "run.lyapunov"}) {
      const std::string axis(grid);
      for (const char* spaced : {".linspace[2]", ".logspace[2]"}) {
        try {
          if (doc.get(axis + spaced) > kMaxGridPoints) return std::nullopt;
        } catch (const io::SceneError&) {
        }
      }
      try {
        (void)doc.get(axis + "." + past);  // a number there: more than kMaxGridPoints values
        return std::nullopt;
      } catch (const io::SceneError&) {
      }
    }
    return doc;
  } catch (const io::SceneError&) {
    return std::nullopt;
  }
}

}  // namespace vibro::fuzz
