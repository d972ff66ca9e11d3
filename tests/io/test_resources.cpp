// What a run will take, checked before it takes it (vibro/io/resources.hpp), and what the engines
// refuse or warn about before they start (Simulator::run in simulator.hpp): runs that cannot be
// resolved in doubles (t0 = 1e15, forcing 1e12 against k = 1, solver.length_scale 1e300).
#include "vibro/io/resources.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>
#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;
using Catch::Contains;

namespace {

/// One mass on a wall spring (k = 1, c = 0.1), a cosine force F at Ω = 0.8, a stop above at 0.5.
std::string one_mass(const std::string& force, const std::string& extra = "") {
  return "model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.1}}}\n"
         "forcing: {frequency: 0.8, cosine: [" + force + "]}\n"
         "stops: [{mass: 0, side: upper, position: 0.5, restitution: 0.5}]\n" + extra;
}

Scene build(const std::string& text) { return SceneDocument::parse(text, "test.yaml").build(); }

template <class F>
std::string what_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(nothing thrown)";
}

RunSummary run_for(const Scene& scene, double periods) {
  return make_engine(scene)->run(scene.t0, scene.x0, scene.v0, scene.t0 + periods * scene.period());
}

}  // namespace

TEST_CASE("a run too large for memory is refused before anything is allocated, with the numbers", "[resources]") {
  SECTION("a million-mass dense system: 800 bytes × n²") {
    Scene scene = build(one_mass("1"));
    const Eigen::Index n = 1'000'000;
    scene.dense = LazySystem(n, HarmonicForcing::zero(n, 0.8), []() -> LinearSystem {
      FAIL("the system must not be built");
      throw std::logic_error("unreachable");
    });
    scene.x0 = scene.v0 = Eigen::VectorXd::Zero(n);
    const std::string e = what_of([&] { check_run_resources(scene, 1); });
    CHECK_THAT(e, Contains("this run needs about 800 TB") && Contains("of memory is available") &&
                      Contains("the dense engine's set-up (1000000 degrees of freedom"));
  }
  SECTION("samples.per_period 1e6 × periods 1e9") {
    const Scene scene = build(one_mass("1", "record: {samples: {per_period: 1000000}}\nrun: {periods: 1e9}\n"));
    CHECK_THAT(what_of([&] { check_run_resources(scene, 1); }), Contains("the recording (1e+15 samples"));
  }
  SECTION("a scene file of a terabyte (sparse) is not read") {
    const vibro::test::TempDir dir;
    const std::string path = dir / "huge.yaml";
    const int fd = ::open(path.c_str(), O_CREAT | O_WRONLY, 0644);
    REQUIRE(fd >= 0);
    REQUIRE(::ftruncate(fd, 1'000'000'000'000) == 0);
    ::close(fd);
    CHECK_THAT(what_of([&] { (void)SceneDocument::load(path); }),
               Contains("huge.yaml: parsing the scene file (1 TB, about 400 bytes of YAML tree per byte) needs about "
                        "400 TB"));
  }
  SECTION("a filled list of 2·10⁷ masses: refused where the masses are read, before the chain is built") {
    // Every engine holds n × n modes or matrices (at least 25 bytes · n² = 10 PB here), so the
    // reader refuses the chain at its masses' line; building its links and walls first took ~200
    // bytes and ~1.7 µs per mass (a 10⁸-mass list: 21 GB and 3.7 minutes before any check).
    const std::string e = what_of([] {
      (void)SceneDocument::parse("model:\n  chain:\n    masses: {fill: 1, count: 2e7}\n", "big.yaml").build();
    });
    CHECK_THAT(e, Contains("big.yaml:3:") && Contains("model.chain.masses") &&
                      Contains("a chain of 20000000 masses (every engine holds n × n modes or matrices) needs about 1e+04 TB") &&
                      Contains("of memory is available"));
  }
  SECTION("an ordinary scene fits") {
    CHECK_NOTHROW(check_run_resources(build(one_mass("1")), 2));
  }
}

TEST_CASE("thread counts are capped by the work and refused beyond what the runtime can start", "[resources]") {
  CHECK(checked_threads(8, 3) == 3);
  CHECK(checked_threads(1, 100) == 1);
  CHECK(checked_threads(0, 1) == 1);
  CHECK_THAT(what_of([] { (void)checked_threads(100000, 100); }), Contains("--threads 100000: at most 1024 threads"));
}

TEST_CASE("a run that doubles cannot resolve is refused, and one that misses the trigger warns", "[resources]") {
  SECTION("t0 = 1e15: doubles 0.125 apart") {
    const Scene scene = build(one_mass("1", "initial: {time: 1e15}\n"));
    CHECK_THAT(what_of([&] { (void)run_for(scene, 1); }),
               Contains("is too large for this run: doubles near it are 0.125 apart"));
  }
  SECTION("t0 = 1e6: runs, and says the time resolution is coarser than the trigger") {
    const RunSummary s = run_for(build(one_mass("1", "initial: {time: 1e6}\n")), 1);
    CHECK(s.status == RunStatus::completed);
    REQUIRE(s.warnings.size() == 1);
    CHECK_THAT(s.warnings[0], Contains("time resolution: near t = 1000007.85") && Contains("apart"));
  }
  SECTION("forcing 1e12 against k = 1 (measured 2.7e-3 relative error before) is refused; 1e6 warns") {
    CHECK_THAT(what_of([&] { (void)run_for(build(one_mass("1e12")), 1); }),
               Contains("static deflection fmax/k = 1000000000000") && Contains("(1e-6 at most)"));
    // (Without the stop: at F = 1e6 the mass would rattle against it for many events.)
    const RunSummary s = run_for(build("model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.1}}}\n"
                                       "forcing: {frequency: 0.8, cosine: [1e6]}\n"), 1);
    CHECK(s.status == RunStatus::completed);
    REQUIRE(s.warnings.size() == 1);
    CHECK_THAT(s.warnings[0], Contains("above the trigger"));
    CHECK(run_for(build(one_mass("1")), 1).warnings.empty());
  }
  SECTION("solver.length_scale far from the scene's own") {
    for (const char* L : {"1e300", "1e-300"}) {
      INFO(L);
      const Scene scene = build(one_mass("1", std::string("solver: {length_scale: ") + L + "}\n"));
      CHECK_THAT(what_of([&] { (void)run_for(scene, 1); }), Contains("puts the gap tolerance"));
    }
    CHECK(run_for(build(one_mass("1", "solver: {length_scale: 10}\n")), 1).status == RunStatus::completed);
  }
  SECTION("an initial velocity that dwarfs the stops: they would be crossed between representable times") {
    // v0 = 1e18 against a stop at 0.5: L = |v0|/Ω ≈ 1.25e18, and an event is placed to ε·L ≈ 280
    // at best (recorded states 400 … 1200 past the stops, exit 0, before this was refused).
    CHECK_THAT(what_of([&] { (void)run_for(build(one_mass("1", "initial: {v: [1e18]}\n")), 1); }),
               Contains("initial.v sets the run's length scale") && Contains("the stops' own scale 0.5"));
    CHECK_THAT(what_of([&] { (void)run_for(build(one_mass("1", "initial: {x: [-1e12]}\n")), 1); }),
               Contains("initial.x sets the run's length scale"));
    // 1e4 × the stops' scale is resolved (ε·L and V·ulp(t) ≈ 1e-12 of it).
    CHECK(run_for(build(one_mass("1", "initial: {v: [4000]}\n")), 1).status == RunStatus::completed);
  }
  SECTION("t0 = -1e15: the message keeps the sign") {
    CHECK_THAT(what_of([&] { (void)run_for(build(one_mass("1", "initial: {time: -1e15}\n")), 1); }),
               Contains("time -1000000000000000 is too large for this run"));
  }
  SECTION("the modal engine refuses alike") {
    std::string chain = "model: {chain: {masses: [1, 1], springs: [1], left_wall: {spring: 1}}}\n"
                        "forcing: {frequency: 0.8, cosine: [1, 0]}\nsolver: {engine: modal}\ninitial: {time: 1e15}\n";
    CHECK_THAT(what_of([&] { (void)run_for(build(chain), 1); }), Contains("is too large for this run"));
  }
}

TEST_CASE("a stiff run says so from its start, with the search steps per period", "[resources]") {
  // A damper of 1e7 on a unit mass: a decay rate of 1e7 against Ω = 0.8, ≈ 7.9e7 steps per period.
  const Scene scene = build("model: {chain: {masses: [1], left_wall: {spring: 1, damper: 1e7}}}\n"
                            "forcing: {frequency: 0.8, cosine: [1]}\n");
  const RunSummary s = run_for(scene, 1e-7);
  REQUIRE(s.warnings.size() == 1);
  CHECK_THAT(s.warnings[0], Contains("stiff: the certified event search steps by 1/ρ") &&
                                Contains("about 78539816 search steps per forcing period"));
  CHECK(run_for(build(one_mass("1")), 1).warnings.empty());
}

TEST_CASE("a run of more than 1e12 search steps is refused before it starts, with the estimate", "[resources]") {
  // Found by fuzzing: dampers of 1e15, springs of 1e308, a subnormal mass, Ω = 1e-300 ran for
  // minutes at ~0 % progress. The bound a + √b (a, b the largest row sums of M⁻¹|C|, M⁻¹|K|).
  const std::string chain = "model: {chain: {masses: [1, 2], springs: [1], dampers: [DAMPER], left_wall: {spring: 1}}}\n"
                            "forcing: {frequency: 0.8, cosine: [1, 0]}\nrun: {periods: 10}\n";
  auto with = [&](const std::string& damper) {
    std::string text = chain;
    return build(text.replace(text.find("DAMPER"), 6, damper));
  };
  const WorkEstimate w = estimate_run_work(with("0.1"));
  CHECK(w.rate == Approx(0.2 + std::sqrt(3.0)));  // row 0: |c| sums 0.1 + 0.1, |k| sums 2 + 1 (mass 1)
  CHECK(w.span == Approx(10 * 2 * std::numbers::pi / 0.8));
  CHECK_NOTHROW(check_run_resources(with("1e7"), 1));  // ≈ 2e9 steps: stiff, but it runs
  CHECK_THAT(what_of([&] { check_run_resources(with("1e15"), 1); }),
             Contains("this run needs about 1.57e+17 steps of the certified event search") &&
                 Contains("from the damping of mass 0") && Contains("refused above 1e+12"));
  const Scene tiny = build("model: {chain: {masses: [5e-324], left_wall: {spring: 1}}}\n"
                           "forcing: {frequency: 0.8, cosine: [1]}\n");
  CHECK_THAT(what_of([&] { check_run_resources(tiny, 1); }), Contains("stiffness over the mass of mass 0"));
  // A spring of 1e308 (its rate overflows to inf) and a forcing period of 6e300 time units.
  const Scene huge_spring = build("model: {chain: {masses: [1, 2], springs: [1e308], left_wall: {spring: 1}}}\n"
                                  "forcing: {frequency: 0.8, cosine: [1, 0]}\n");
  CHECK_THAT(what_of([&] { check_run_resources(huge_spring, 1); }),
             Contains("needs about inf steps") && Contains("lower the springs at mass"));
  const Scene slow_forcing = build("model: {chain: {masses: [1], left_wall: {spring: 1}}}\n"
                                   "forcing: {frequency: 1e-300, cosine: [0]}\n");
  CHECK_THAT(what_of([&] { check_run_resources(slow_forcing, 1); }),
             Contains("refused above 1e+12") && Contains("raise the forcing frequency"));
}

TEST_CASE("per-period statistics of a scene without stops are written (an empty stop axis)", "[resources]") {
  const vibro::test::TempDir dir;
  const std::string text = "model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.1}}}\n"
                           "forcing: {frequency: 0.8, cosine: [1]}\nrecord: {statistics: true}\nrun: {periods: 3}\n";
  const SceneDocument doc = SceneDocument::parse(text, "nostops.yaml");
  REQUIRE(run_scene(doc, doc.build(), {dir / "out.h5", 1, false, false}).exit_code == 0);
  const ResultReader file(dir / "out.h5");
  CHECK(file.shape("/stats/sticking_fraction") == std::vector<std::size_t>{3, 0});
  CHECK(file.attribute_strings("/stats/sticking_fraction", "stops").empty());
}

TEST_CASE("both engines report the time they reached for a progress line", "[resources]") {
  for (const char* engine : {"dense", "modal"}) {
    INFO(engine);
    Scene scene = build("model: {chain: {masses: [1, 1], springs: [1], left_wall: {spring: 1}}}\n"
                        "forcing: {frequency: 0.8, cosine: [0.3, 0]}\n"
                        "stops: [{mass: 1, side: upper, position: 0.2, restitution: 0.8}]\n"
                        "solver: {engine: " + std::string(engine) + "}\n");
    std::atomic<double> reached{-1.0};
    scene.solver.reached = &reached;
    const RunSummary s = run_for(scene, 3);
    REQUIRE(s.impacts > 0);
    CHECK(reached.load() > scene.t0);  // set during the run, at the last event or search step
    CHECK(reached.load() <= s.t);
  }
}

TEST_CASE("check and run agree on an initial state just inside a stop", "[resources]") {
  // The run's tolerance is trigger × L; L = 0.5 here (the stop), not the 0.0125 of the force.
  const std::string base = "model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.1}}}\n"
                           "forcing: {frequency: 0.8, cosine: [0.01]}\n"
                           "stops: [{mass: 0, side: upper, position: 0.5, restitution: 0.5}]\n";
  // 0.5 + 8e-14: beyond 1e-13 × 0.5 (and within the 1e-12 × 0.5 the loader allowed before). The loader (check and run alike) refuses it, at initial.x.
  const std::string beyond = base + "initial: {x: [0.50000000000008]}\n";
  try {
    (void)build(beyond);
    FAIL("accepted");
  } catch (const SceneError& e) {
    CHECK(e.path() == "initial.x");
    CHECK(e.line() == 4);
    CHECK_THAT(e.problem(), Contains("violates stops[0]"));
  }
  // 0.5 + 3e-14: within; the run starts.
  const Scene inside = build(base + "initial: {x: [0.50000000000003]}\n");
  CHECK(run_for(inside, 1).status == RunStatus::completed);
}
