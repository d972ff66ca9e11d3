// Runs into memory (session.hpp): the file run_in_memory() holds is the one `vibro run` writes,
// dataset by dataset; save_image() and load_image() carry it to and from disk whole;
// SceneDocument::replace() edits sections and copies replay edits in order; a raised stop flag
// ends simulations and sweeps cleanly.
#include "vibro/io/result_file.hpp"
#include "vibro/io/session.hpp"

#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

using namespace vibro::io;

namespace {

const std::string kScene = R"(
model:
  chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}
forcing: {frequency: 0.255, cosine: [0.5, 0]}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7}
record: {events: true, contacts: true, statistics: true, poincare: true, samples: {per_period: 20}}
run:
  kind: sweep
  transient_periods: 5
  periods: 2
  sweep: {parameters: [{path: forcing.frequency, values: [0.25, 0.26, 0.27]}]}
)";

/// A folder of this test's own, removed at the end.
class Folder {
 public:
  Folder() {
    std::string pattern = (std::filesystem::temp_directory_path() / "vibro_test_session_XXXXXX").string();
    path_ = mkdtemp(pattern.data());
  }
  ~Folder() { std::filesystem::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

void require_same_datasets(const ResultReader& a, const ResultReader& b) {
  REQUIRE(a.objects() == b.objects());
  std::size_t datasets = 0;
  for (const std::string& o : a.objects()) {
    if (!a.is_dataset(o)) continue;
    INFO(o);
    ++datasets;
    REQUIRE(a.type(o) == b.type(o));
    REQUIRE(a.shape(o) == b.shape(o));
    if (a.type(o) == "str") {
      CHECK(a.read_strings(o) == b.read_strings(o));
    } else {
      CHECK(a.read(o) == b.read(o));  // bit for bit (these runs have no NaN padding)
    }
  }
  CHECK(datasets > 30);
}

}  // namespace

TEST_CASE("a run in memory holds the file vibro run writes", "[session]") {
  const Folder folder;
  for (const char* kind : {"sweep", "simulate"}) {
    INFO(kind);
    SceneDocument doc = SceneDocument::parse(kScene, "session.yaml");
    doc.replace("run.kind", kind);
    if (std::string(kind) == "simulate") doc.replace("run.sweep", "");
    const Scene scene = doc.build();
    const std::string out = folder / (std::string(kind) + ".h5");
    REQUIRE(run_scene(doc, scene, {out, 2}).exit_code == 0);
    const MemoryRun run = run_in_memory(doc, scene, {2, nullptr});
    REQUIRE(run.exit_code == 0);
    require_same_datasets(ResultReader(run.image), ResultReader(out));
    CHECK(ResultReader(run.image).attribute_string("/meta", "status") == "completed");
    CHECK_FALSE(std::filesystem::exists(out + ".partial"));
  }
}

TEST_CASE("save_image and load_image carry a result whole", "[session]") {
  const Folder folder;
  SceneDocument doc = SceneDocument::parse(kScene, "session.yaml");
  const MemoryRun run = run_in_memory(doc, doc.build(), {});
  const std::string path = folder / "saved.h5";
  save_image(run.image, path, false);
  CHECK(load_image(path) == run.image);
  require_same_datasets(ResultReader(path), ResultReader(run.image));
  CHECK_THROWS_WITH(save_image(run.image, path, false), Catch::Contains("exists; not replaced"));
  save_image(run.image, path, true);
  CHECK(std::distance(std::filesystem::directory_iterator(folder / ""), {}) == 1);  // no leftovers
  std::ofstream(folder / "text.h5") << "not HDF5";
  CHECK_THROWS_AS(load_image(folder / "text.h5"), ResultError);
  CHECK_THROWS_WITH(load_image(folder / "none.h5"), Catch::Contains("none.h5: cannot read the result file"));
}

TEST_CASE("replace edits sections and copies replay every edit in order", "[session][scene]") {
  SceneDocument doc = SceneDocument::parse(kScene, "session.yaml");
  doc.set("run.sweep.parameters[0].values[1]", 0.261);
  doc.replace("run.sweep", "");  // removes what was just set: a copy must not replay the set after it
  doc.replace("run.kind", "simulate");
  doc.replace("record", "{events: true}");
  doc.replace("solver.chatter_height", "1e-10");  // adds the missing section
  const SceneDocument copy(doc);
  const Scene scene = copy.build();
  CHECK(scene.run.kind == RunSpec::Kind::simulate);
  CHECK((scene.record.events && !scene.record.contacts && scene.record.samples_per_period == 0));
  CHECK(scene.solver.chatter_height == 1e-10);
  CHECK(copy.text() == kScene);  // like set(), the text stays as loaded
  CHECK_THROWS_WITH(doc.replace("stops[0].position", "1"), Catch::Contains("only mappings' keys can be replaced"));
  CHECK_THROWS_WITH(doc.replace("record", "{events: [}"), Catch::Contains("YAML syntax error in the value given"));
  doc.replace("record.events", "maybe");
  CHECK_THROWS_WITH(doc.build(), Catch::Contains("record.events: expected true or false, found 'maybe'"));
}

TEST_CASE("a raised stop flag ends runs in memory cleanly", "[session]") {
  std::atomic<bool> stop{true};
  SceneDocument doc = SceneDocument::parse(kScene, "session.yaml");
  const MemoryRun sweep = run_in_memory(doc, doc.build(), {2, &stop});
  CHECK(sweep.exit_code == 130);
  const ResultReader swept(sweep.image);
  CHECK(swept.attribute_number("/sweep", "completed") == 0);
  CHECK(swept.attribute_string("/meta", "status") == "running");  // not finished, as a .partial
  doc.replace("run.kind", "simulate");
  doc.replace("run.sweep", "");
  const MemoryRun simulation = run_in_memory(doc, doc.build(), {1, &stop});
  CHECK(simulation.exit_code == 130);
  const ResultReader simulated(simulation.image);
  CHECK(simulated.attribute_string("/meta", "status") == "interrupted");
  CHECK(simulated.attribute_number("/meta", "impacts") == 0);
}
