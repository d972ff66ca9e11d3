// The rules every result file is written under (docs/results.md, "Writing, interruption,
// resume"; framework/io/src/output_lock.hpp): one writer at a time (OUT.lock), no existing file
// replaced without --force and never the scene, the partial created exclusively (never through
// a symbolic link), nothing left behind by a run that fails. Each case in its own directory.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>

using namespace vibro;
using namespace vibro::io;
using vibro::test::TempDir;
namespace fs = std::filesystem;

namespace {

const std::string kScene = R"(
model: {chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}}
forcing: {frequency: 0.255, cosine: [0.5, 0]}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7}
record: {events: true, samples: {per_period: 20}}
run: {kind: simulate, transient_periods: 1, periods: 2}
)";

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The names in a directory.
std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

/// The scene written to dir/scene.yaml and loaded from there (its file is a real path).
struct SceneOnDisk {
  std::string path;
  SceneDocument doc;
  Scene scene;
  explicit SceneOnDisk(const TempDir& dir, const std::string& text = kScene)
      : path((write_text(dir / "scene.yaml", text), dir / "scene.yaml")),
        doc(SceneDocument::load(path)),
        scene(doc.build()) {}
};

RunRequest request(const std::string& out, bool force = false) {
  RunRequest r{out, 1, false, false};
  r.force = force;
  return r;
}

template <class F>
std::string result_error(F&& f) {
  try {
    f();
  } catch (const ResultError& e) {
    return e.what();
  }
  FAIL("no ResultError was thrown");
  return {};
}

}  // namespace

TEST_CASE("a second writer to one output is refused and the first's file is whole", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  const std::string out = dir / "out.h5";
  ResultFile first = ResultFile::create(out, s.scene, current_meta(1));
  // The second writer, in the same process (open-file-description locks exclude it too), with
  // or without --force: refused before it touches anything.
  for (bool force : {false, true}) {
    INFO("force " << force);
    CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(out, force)); }),
               Catch::Contains("another run is writing it (process " + std::to_string(::getpid()) + " holds"));
  }
  CHECK(read_text(out + ".lock") == "vibro " + std::to_string(::getpid()) + "\n");
  // The first finishes as if alone.
  Recording rec = Recording::for_scene(s.scene, 0.0);
  rec.summary.x = s.scene.x0;
  rec.summary.v = s.scene.v0;
  first.write_simulation(rec);
  first.finish(current_meta(1));
  CHECK(ResultReader(out).attribute_string("/meta", "status") == "completed");
  CHECK(listing(dir.path()) == std::set<std::string>{"out.h5", "scene.yaml"});  // no lock left
}

TEST_CASE("an existing output is kept unless --force, and --force replaces it", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  const std::string out = dir / "out.h5";
  write_text(out, "an earlier result\n");
  fs::permissions(out, fs::perms::owner_read);  // read-only: still refused, not overwritten
  CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(out)); }),
             Catch::EndsWith("out.h5: exists: not overwritten (use --force to replace it)"));
  CHECK(read_text(out) == "an earlier result\n");
  CHECK(listing(dir.path()) == std::set<std::string>{"out.h5", "scene.yaml"});
  REQUIRE(run_scene(s.doc, s.scene, request(out, true)).exit_code == 0);
  CHECK(ResultReader(out).attribute_string("/meta", "status") == "completed");
  CHECK(listing(dir.path()) == std::set<std::string>{"out.h5", "scene.yaml"});
}

TEST_CASE("the scene file is never the output, even with --force", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  for (const std::string& out : {s.path, dir / "link.h5"}) {
    INFO(out);
    if (out != s.path) fs::create_symlink(s.path, out);
    CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(out, true)); }),
               Catch::Contains("is the scene file being run"));
    CHECK(read_text(s.path) == kScene);
  }
  // Nor may the partial or the lock be the scene (a scene named OUT.partial).
  const std::string partial_named = dir / "x.h5.partial";
  fs::copy_file(s.path, partial_named);
  SceneDocument doc = SceneDocument::load(partial_named);
  const Scene scene = doc.build();
  CHECK_THAT(result_error([&] { (void)run_scene(doc, scene, request(dir / "x.h5", true)); }),
             Catch::Contains("would be the scene file being run"));
  CHECK(read_text(partial_named) == kScene);
}

TEST_CASE("a directory as output is refused and nothing is left", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  fs::create_directory(dir / "results");
  CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(dir / "results", true)); }),
             Catch::EndsWith("results: is a directory: give a file name with -o"));
  CHECK(listing(dir.path()) == std::set<std::string>{"results", "scene.yaml"});
  CHECK(fs::is_empty(dir / "results"));
}

TEST_CASE("a symbolic link planted at OUT.partial or OUT.lock is never written through", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  const std::string out = dir / "out.h5", victim = dir / "victim";
  write_text(victim, "precious\n");
  SECTION("at OUT.partial: refused; with --force the link is removed, not its target") {
    fs::create_symlink(victim, out + ".partial");
    CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(out)); }),
               Catch::Contains("out.h5.partial: left by a run that was killed: delete it, or add --force"));
    CHECK(read_text(victim) == "precious\n");
    REQUIRE(run_scene(s.doc, s.scene, request(out, true)).exit_code == 0);
    CHECK(read_text(victim) == "precious\n");
    CHECK(listing(dir.path()) == std::set<std::string>{"out.h5", "scene.yaml", "victim"});
  }
  SECTION("at OUT.lock") {
    fs::create_symlink(victim, out + ".lock");
    CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(out, true)); }),
               Catch::Contains("out.h5.lock: is a symbolic link: refused"));
    CHECK(read_text(victim) == "precious\n");
    CHECK_FALSE(fs::exists(out));
  }
}

TEST_CASE("a lock left by a killed run is taken over, and a file of that name that is not a lock is kept", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  const std::string out = dir / "out.h5";
  write_text(out + ".lock", "vibro 4000000\n");  // no such process holds it
  REQUIRE(run_scene(s.doc, s.scene, request(out)).exit_code == 0);
  CHECK(listing(dir.path()) == std::set<std::string>{"out.h5", "scene.yaml"});
  const std::string other = dir / "other.h5";
  write_text(other + ".lock", "my notes\n");
  CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(other, true)); }),
             Catch::Contains("other.h5.lock: exists and is not a vibro lock file: not touched"));
  CHECK(read_text(other + ".lock") == "my notes\n");
  CHECK_FALSE(fs::exists(other));
  // A lock-like file with another name (a hard link) is not written through.
  const std::string third = dir / "third.h5";
  const std::string elsewhere = dir / "elsewhere.txt";
  write_text(elsewhere, "vibro 4000000\n");
  fs::create_hard_link(elsewhere, third + ".lock");
  CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(third, true)); }),
             Catch::Contains("third.h5.lock: has other hard links: refused as a lock"));
  CHECK(read_text(elsewhere) == "vibro 4000000\n");
  CHECK(fs::hard_link_count(elsewhere) == 2);
  CHECK_FALSE(fs::exists(third));
}

TEST_CASE("an output made by another program during the run is not replaced, and nothing is left", "[output]") {
  const TempDir dir;
  const SceneOnDisk s(dir);
  const std::string out = dir / "out.h5";
  ResultFile file = ResultFile::create(out, s.scene, current_meta(1));
  Recording rec = Recording::for_scene(s.scene, 0.0);
  rec.summary.x = s.scene.x0;
  rec.summary.v = s.scene.v0;
  file.write_simulation(rec);
  write_text(out, "written meanwhile\n");
  CHECK_THAT(result_error([&] { file.finish(current_meta(1)); }),
             Catch::Contains("appeared while this run was writing"));
  CHECK(read_text(out) == "written meanwhile\n");
  CHECK_FALSE(fs::exists(out + ".partial"));
}

TEST_CASE("a full disk ends the run with a ResultError and leaves nothing behind", "[output]") {
  const TempDir dir;
  std::string text = kScene;
  text.replace(text.find("per_period: 20"), 14, "per_period: 20000");  // ≈ 1.3 MB of samples
  const SceneOnDisk s(dir, text);
  const std::string out = dir / "out.h5";
  // A file size limit of 256 kB stands for a full disk: writes past it fail with EFBIG.
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit old{};
  REQUIRE(getrlimit(RLIMIT_FSIZE, &old) == 0);
  rlimit small = old;
  small.rlim_cur = 256 * 1024;
  REQUIRE(setrlimit(RLIMIT_FSIZE, &small) == 0);
  std::string error;
  try {
    (void)run_scene(s.doc, s.scene, request(out));
  } catch (const ResultError& e) {
    error = e.what();
  }
  setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  CHECK_THAT(error, Catch::Contains("out.h5.partial: /samples/") && Catch::Contains("File too large"));
  CHECK(listing(dir.path()) == std::set<std::string>{"scene.yaml"});
}

TEST_CASE("resuming takes the lock and checks the target as a new run does", "[output]") {
  const TempDir dir;
  std::string text = kScene;
  text.replace(text.find("kind: simulate"), 14, "kind: sweep");
  text.replace(text.rfind('}'), 1, ", sweep: {parameters: [{path: forcing.frequency, linspace: [0.25, 0.26, 4]}]}}");
  const SceneOnDisk s(dir, text);
  const std::string out = dir / "out.h5";
  RunRequest first = request(out);
  first.interrupt_after = 2;
  REQUIRE(run_scene(s.doc, s.scene, first).exit_code == 130);
  CHECK(listing(dir.path()) == std::set<std::string>{"out.h5.partial", "scene.yaml"});
  // A new run does not start over an interrupted sweep.
  CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, request(out)); }),
             Catch::Contains("an interrupted sweep is kept there: finish it with --resume"));
  RunRequest resume = request(out);
  resume.resume = true;
  {
    ResultFile holder = ResultFile::open_partial(out, s.scene);  // another resumer holds the lock
    CHECK_THAT(result_error([&] { (void)run_scene(s.doc, s.scene, resume); }),
               Catch::Contains("another run is writing it"));
  }
  write_text(out + ".partial.resume", "a killed resume's scratch copy\n");  // taken over
  REQUIRE(run_scene(s.doc, s.scene, resume).exit_code == 0);
  CHECK(listing(dir.path()) == std::set<std::string>{"out.h5", "scene.yaml"});
  CHECK(ResultReader(out).attribute_number("/sweep", "completed") == 4);
}
