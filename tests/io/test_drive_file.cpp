// `forcing.file` (docs/scenes.md): a drive given by its harmonics in a CSV file runs bit for bit
// as the same harmonics written inline; a sampled period made of exactly H harmonics is reduced by
// the DFT to them to 1e-13; bad files are refused at file:line:col.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;
using Catch::Matchers::Contains;

namespace {

const std::string kHead = R"(name: drive-file
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
    right_wall: {spring: 0.5, damper: 0.05}
stops:
  - {mass: 1, side: upper, position: 0.3, restitution: 0.7}
initial: {x: [0, 0], v: [0, 0]}
record: {events: true, samples: {per_period: 8}}
run: {periods: 20, transient_periods: 5}
forcing:
  frequency: 0.4
)";

void write(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

std::string error_of(const std::string& text, const std::string& file) {
  try {
    SceneDocument::parse(text, file).build();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("forcing.file: harmonics from a file run bit for bit as written inline", "[scene][drive_file]") {
  const vibro::test::TempDir dir;
  const std::string inline_text = kHead + R"(  cosine: [0.5, 0]
  sine: [0, 0.1]
  harmonics:
    - {order: 3, cosine: [0.1, 0.02], sine: [0, 0.05]}
    - {order: 2, cosine: [0.2, 0], sine: [0.03, 0]}
)";
  write(dir / "drive.csv", "# k, cosine x0, cosine x1, sine x0, sine x1\n1, 0.5, 0, 0, 0.1\n\n3, 0.1, 0.02, 0, 0.05\n2,0.2,0,0.03,0\n");
  const std::string file_text = kHead + "  file: {path: drive.csv, format: harmonics}\n";
  std::vector<ResultReader> results;
  for (const auto& [text, name] : {std::pair{inline_text, std::string("inline")}, std::pair{file_text, std::string("file")}}) {
    const SceneDocument doc = SceneDocument::parse(text, dir / (name + ".yaml"));  // the CSV is beside it
    const Scene s = doc.build();
    REQUIRE(run_scene(doc, s, {dir / (name + ".h5"), 1, false, false, 0}).exit_code == 0);
    results.emplace_back(dir / (name + ".h5"));
  }
  REQUIRE(results[0].read("/events/t").size() >= 5);
  for (const char* d : {"/scene/forcing_cosine", "/scene/forcing_sine", "/scene/harmonic_cosine", "/scene/harmonic_sine",
                        "/events/t", "/events/v_before", "/samples/x", "/samples/v"}) {
    INFO(d);
    CHECK(results[0].read(d) == results[1].read(d));  // bit for bit
  }
  CHECK(results[0].read("/scene/harmonic_order") == results[1].read("/scene/harmonic_order"));
}

TEST_CASE("forcing.file: a sampled period of H harmonics is reduced to them", "[scene][drive_file]") {
  const vibro::test::TempDir dir;
  // f_q(t) = F0_q + Σ_{k=1..4} (c_kq cos kΩt + s_kq sin kΩt), sampled at N = 50 times t_j = jT/N
  // (computed in long double, written with 17 digits), reduced to H = 4 harmonics.
  const double F0[2] = {0.3, -0.1};
  const double c[4][2] = {{0.5, 0.0}, {0.2, -0.07}, {0.0, 0.01}, {-0.04, 0.3}};
  const double s[4][2] = {{0.0, 0.1}, {0.03, 0.0}, {0.11, -0.2}, {0.0, 0.06}};
  const int N = 50;
  std::string csv = "# one period of the drive, 50 samples\n";
  for (int j = 0; j < N; ++j) {
    for (int q = 0; q < 2; ++q) {
      long double f = F0[q];
      for (int k = 1; k <= 4; ++k) {
        const long double a = 2.0L * std::numbers::pi_v<long double> * static_cast<long double>(k * j % N) / N;
        f += c[k - 1][q] * std::cos(a) + s[k - 1][q] * std::sin(a);
      }
      char buf[40];
      std::snprintf(buf, sizeof buf, "%.17g", static_cast<double>(f));
      csv += (q ? ", " : "") + std::string(buf);
    }
    csv += "\n";
  }
  write(dir / "period.csv", csv);
  const Scene sc = SceneDocument::parse(kHead + "  file: {path: period.csv, format: samples, harmonics: 4}\n",
                                        dir / "s.yaml").build();
  const HarmonicForcing& f = sc.forcing();
  REQUIRE(f.harmonics.size() == 3);
  double worst = 0.0;
  for (int q = 0; q < 2; ++q) {
    worst = std::max({worst, std::abs(f.constant(q) - F0[q]), std::abs(f.cosine(q) - c[0][q]), std::abs(f.sine(q) - s[0][q])});
    for (int k = 2; k <= 4; ++k) {
      CHECK(f.harmonics[static_cast<std::size_t>(k - 2)].order == k);
      worst = std::max({worst, std::abs(f.harmonics[static_cast<std::size_t>(k - 2)].cosine(q) - c[k - 1][q]),
                        std::abs(f.harmonics[static_cast<std::size_t>(k - 2)].sine(q) - s[k - 1][q])});
    }
  }
  INFO("largest coefficient error " << worst);
  CHECK(worst <= 1e-13);
}

TEST_CASE("forcing.file: bad files and conflicts are refused at file:line:col", "[scene][drive_file]") {
  const vibro::test::TempDir dir;
  const std::string scene = dir / "s.yaml";
  const std::string harmonics = kHead + "  file: {path: d.csv, format: harmonics}\n";
  // line 16 of the scene is `  file: …`; its path value is at column 16.
  CHECK_THAT(error_of(harmonics, scene), Contains("s.yaml:16:16: forcing.file.path") && Contains("no such file"));
  write(dir / "d.csv", "1, 0.5, 0, 0, 0.1\n2, 0.2, x, 0, 0\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("forcing.file.path") && Contains("d.csv:2:9: expected a number, found 'x'"));
  write(dir / "d.csv", "1.5, 0.5, 0, 0, 0.1\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("d.csv:1:1: the order k must be a whole number") && Contains("1.5"));
  write(dir / "d.csv", "0, 0.5, 0, 0, 0.1\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("d.csv:1:1: the order k must be a whole number"));
  write(dir / "d.csv", "# c\n1, 0.5, 0, 0\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("d.csv:2:1: expected 5 numbers") && Contains("found 4"));
  write(dir / "d.csv", "1, 0.5, nan, 0, 0\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("d.csv:1:9: expected a finite number, found 'nan'"));
  write(dir / "d.csv", "2, 0.5, 0, 0, 0\n2, 0.5, 0, 0, 0\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("d.csv:2:1: order 2 is given twice"));
  write(dir / "d.csv", "\n# nothing\n");
  CHECK_THAT(error_of(harmonics, scene), Contains("no rows"));
  write(dir / "d.csv", "1, 0.5, 0, 0, 0.1\n");
  CHECK_THAT(error_of(kHead + "  cosine: [1, 0]\n  file: {path: d.csv, format: harmonics}\n", scene),
             Contains("s.yaml:16:") && Contains("forcing.cosine") && Contains("one place"));
  CHECK_THAT(error_of(kHead + "  file: {path: d.csv}\n", scene), Contains("forcing.file.format") && Contains("missing"));
  // Sampled: the row length, and H below N/2.
  const std::string samples = kHead + "  file: {path: p.csv, format: samples, harmonics: 2}\n";
  write(dir / "p.csv", "1, 0\n0, 1\n-1, 0\n0, -1\n");
  CHECK_THAT(error_of(samples, scene), Contains("p.csv: 4 samples resolve harmonics below N/2 = 2 only"));
  write(dir / "p.csv", "1, 0\n0, 1\n-1\n0, -1\n0, 0\n1, 1\n");
  CHECK_THAT(error_of(samples, scene), Contains("p.csv:3:1: expected 2 numbers"));
  write(dir / "p.csv", "1, 0\n0, 1\n-1, 0\n0, -1\n0, 0\n1, 1\n");
  CHECK_NOTHROW(SceneDocument::parse(samples, scene).build());
  CHECK_THAT(error_of(kHead + "  constant: [1, 0]\n  file: {path: p.csv, format: samples, harmonics: 2}\n", scene),
             Contains("forcing.constant") && Contains("mean"));
}
