/// Tests of the table of run kinds (vibro/io/run_kinds.hpp): every kind the table holds is the
/// one the scene loader accepts, the one the runner runs, and is documented in docs/scenes.md and
/// docs/results.md.
#include "vibro/io/run_kinds.hpp"
#include "vibro/io/scene.hpp"

#include <catch2/catch.hpp>

#include <fstream>
#include <set>
#include <sstream>
#include <string>

using namespace vibro::io;

namespace {

std::string read_doc(const std::string& name) {
  std::ifstream in(std::string(VIBRO_DOCS) + "/" + name);
  REQUIRE(in.good());
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The line of a Markdown table whose first cell is `cell` (e.g. "`kind`"), or "" if none.
std::string table_row(const std::string& text, const std::string& cell) {
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    const std::string head = "| " + cell + " ";
    if (line.rfind(head, 0) == 0) return line;
  }
  return "";
}

}  // namespace

TEST_CASE("the table of run kinds is consistent", "[run_kinds]") {
  std::set<std::string> names, sections;
  std::set<int> kinds;
  for (const RunKindInfo& k : run_kinds()) {
    INFO(k.name);
    CHECK(names.insert(k.name).second);
    CHECK(kinds.insert(static_cast<int>(k.kind)).second);
    if (k.section) CHECK(sections.insert(k.section).second);
    CHECK(k.run != nullptr);
    CHECK(std::string(k.summary).size() > 10);
    CHECK(find_run_kind(k.name) == &k);
    CHECK(&run_kind(k.kind) == &k);
    CHECK(std::string(to_string(k.kind)) == k.name);
    if (k.missing) CHECK(k.section != nullptr);
  }
  CHECK(find_run_kind("nonsense") == nullptr);
  CHECK(run_kinds().front().name == std::string("simulate"));  // the default kind, first
}

TEST_CASE("the scene loader accepts exactly the run kinds of the table", "[run_kinds][scene]") {
  const std::string base = "model: {chain: {masses: [1], left_wall: {spring: 1}}}\nforcing: {frequency: 1}\n";
  std::string list;
  for (const RunKindInfo& k : run_kinds()) list += (list.empty() ? "" : ", ") + std::string(k.name);
  try {
    (void)SceneDocument::parse(base + "run: {kind: nonsense}\n").build();
    FAIL("run.kind: nonsense was accepted");
  } catch (const SceneError& e) {
    CHECK(e.problem() == "expected one of " + list + ", found 'nonsense'");
  }
  // A kind's own section under another kind is refused, naming the kind it belongs to.
  for (const RunKindInfo& k : run_kinds()) {
    if (!k.section) continue;
    INFO(k.name);
    try {
      (void)SceneDocument::parse(base + "run: {kind: simulate, " + k.section + ": {}}\n").build();
      FAIL("a stray run section was accepted");
    } catch (const SceneError& e) {
      CHECK(e.path() == std::string("run.") + k.section);
      CHECK(e.problem() == std::string("only for run.kind: ") + k.name);
    }
  }
}

TEST_CASE("docs/scenes.md and docs/results.md describe every run kind", "[run_kinds][docs]") {
  const std::string scenes = read_doc("scenes.md");
  const std::string results = read_doc("results.md");
  const std::string kind_row = table_row(scenes, "`kind`");
  const std::string run_kind_row = table_row(results, "`run_kind`");
  REQUIRE(!kind_row.empty());
  REQUIRE(!run_kind_row.empty());
  for (const RunKindInfo& k : run_kinds()) {
    INFO(k.name);
    const std::string name = std::string("`") + k.name + "`";
    CHECK(kind_row.find(name) != std::string::npos);      // scenes.md: `run.kind`'s values
    CHECK(run_kind_row.find(name) != std::string::npos);  // results.md: /scene's `run_kind`
    if (k.section) {
      const std::string key = std::string("`") + k.section + "`";
      CHECK(!table_row(scenes, key).empty());  // a row of the `run` table
      CHECK(scenes.find(std::string("### `run.") + k.section + "`") != std::string::npos);  // its own section
    }
    for (const std::string& group : k.groups) {
      INFO(group);
      CHECK(results.find("/" + group) != std::string::npos);
    }
  }
}
