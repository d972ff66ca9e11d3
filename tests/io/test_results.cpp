// The HDF5 result file (docs/results.md): what a simulation records comes back bit for bit, only
// the recorded groups exist, nothing non-finite is written, and an interrupted sweep — destroyed
// writer, half-written point, killed process — resumes to a file identical to an uninterrupted one.
// The system is the two-mass chain of Wagg (2004), built by hand: m = k = 1, c = 0.1, a cosine
// force 0.5 on mass 1, a stop below mass 1 at -0.3 and above mass 2 at 0.1, r = 0.7. At
// Ω ≈ 0.25 it impacts, chatters and sticks, so every recorded group has content.
#include "vibro/io/result_file.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>
#include <hdf5.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace {

using namespace vibro;
using namespace vibro::io;
namespace fs = std::filesystem;

const char* kYaml = "# two masses between stops (test scene; the text is only stored)\n"
                    "model: {chain: {masses: [1, 1], springs: [1], left_spring: 1}}\n";

Scene make_scene(double frequency, RecordSpec record, RunSpec run) {
  Eigen::MatrixXd M = Eigen::MatrixXd::Identity(2, 2);
  Eigen::MatrixXd K(2, 2);
  K << 2, -1, -1, 1;
  const Eigen::MatrixXd C = 0.1 * K;
  HarmonicForcing f = HarmonicForcing::zero(2, frequency);
  f.cosine << 0.5, 0.0;
  std::vector<Stop> stops{Stop::lower(0, -0.3, 0.7), Stop::upper(1, 0.1, 0.7)};
  stops[0].name = "s1 (below mass 1)";
  return Scene{.file = "<test>",
               .yaml_text = kYaml,
               .name = "wagg2004 by hand",
               .dense = LinearSystem(M, C, K, f),
               .chain = std::nullopt,
               .stops = std::move(stops),
               .t0 = 0.0,
               .x0 = Eigen::Vector2d(0.0, 0.05),
               .v0 = Eigen::Vector2d::Zero(),
               .solver = {},
               .record = std::move(record),
               .run = std::move(run),
               .engine_reason = "a test scene made in code",
               .base = {},
               .forces = {},
               .friction = {},
               .restart = {}};
}

RecordSpec record_everything() {
  RecordSpec r;
  r.events = r.contacts = r.statistics = r.poincare = true;
  r.samples_per_period = 8;
  return r;
}

RunSpec simulate_run(double periods) {
  RunSpec run;
  run.transient_periods = 2.0;
  run.periods = periods;
  return run;
}

const std::vector<double> kFrequencies{0.24, 0.25, 0.255, 0.26, 0.27};

RunSpec sweep_run() {
  RunSpec run = simulate_run(6.0);
  run.kind = RunSpec::Kind::sweep;
  run.axes = {{"forcing.frequency", kFrequencies}};
  return run;
}

/// What the command does for one run: the transient unrecorded, then the recorded part.
Recording run(const Scene& scene) {
  const ImpactSystem system = scene.impact_system();
  Simulator simulator(system, scene.solver);
  const double t_start = scene.t0 + scene.run.transient_periods * scene.period();
  const RunSummary transient = simulator.run(scene.t0, scene.x0, scene.v0, t_start);
  Recording rec = Recording::for_scene(scene, t_start);
  rec.summary = simulator.run(t_start, transient.x, transient.v, rec.t_end, rec.observers());
  return rec;
}

/// Point p of the sweep: the base scene with forcing.frequency set (as the loader would).
Scene sweep_point(std::size_t p) {
  return make_scene(kFrequencies[p], record_everything(), sweep_run());
}

/// A file in this test process's own directory (ctest runs every test case in its own process).
std::string temp_file(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / (name + ".h5");
}

/// Removes a result file and its .partial when a test ends.
struct Cleanup {
  std::vector<std::string> paths;
  ~Cleanup() {
    for (const std::string& p : paths) {
      std::remove(p.c_str());
      std::remove(ResultFile::partial_path(p).c_str());
    }
  }
};

void append_points(ResultFile& file, std::size_t from, std::size_t to) {
  for (std::size_t p = from; p < to; ++p) file.append_point(p, {kFrequencies[p]}, run(sweep_point(p)));
}

void write_full_sweep(const std::string& path) {
  ResultFile file = ResultFile::create(path, sweep_point(0), current_meta(1));
  file.begin_sweep({"forcing.frequency"}, kFrequencies.size());
  append_points(file, 0, kFrequencies.size());
  file.finish(current_meta(1));
}

std::vector<double> column(const std::vector<Event>& events, double Event::*field) {
  std::vector<double> out;
  for (const Event& e : events) out.push_back(e.*field);
  return out;
}

Eigen::MatrixXd stacked(const std::vector<Eigen::VectorXd>& rows, Eigen::Index cols) {
  Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()), cols);
  for (std::size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
  return out;
}

/// Samples' layout: one column per sample.
Eigen::MatrixXd stacked(const Eigen::MatrixXd& columns, Eigen::Index cols) {
  REQUIRE(columns.rows() == cols);
  return columns.transpose();
}

/// The samples one after the other, as one row (how a point's block is flattened); Samples'
/// columns are already in that order (column-major).
Eigen::RowVectorXd flattened(const Eigen::MatrixXd& columns) {
  return Eigen::Map<const Eigen::RowVectorXd>(columns.data(), columns.size());
}

/// Equal bit for bit (so NaN fill equals NaN fill).
bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

/// Every object, dataset (type, shape, values) and attribute equal; /meta is left out (dates,
/// wall time and the resume count differ by nature).
void require_identical(const std::string& path_a, const std::string& path_b) {
  const ResultReader a(path_a), b(path_b);
  REQUIRE(a.objects() == b.objects());
  for (const std::string& object : a.objects()) {
    INFO(object);
    if (object == "/meta") continue;
    REQUIRE(a.attributes(object) == b.attributes(object));
    for (const std::string& name : a.attributes(object)) {
      INFO("attribute " << name);
      if (a.attribute_is_string(object, name))
        CHECK(a.attribute_strings(object, name) == b.attribute_strings(object, name));
      else
        CHECK(same_bits(a.attribute_numbers(object, name), b.attribute_numbers(object, name)));
    }
    if (!a.is_dataset(object)) continue;
    REQUIRE(a.type(object) == b.type(object));
    REQUIRE(a.shape(object) == b.shape(object));
    if (a.type(object) == "str")
      CHECK(a.read_strings(object) == b.read_strings(object));
    else
      CHECK(same_bits(a.read(object), b.read(object)));
  }
}

bool python_with_h5py() {
  return std::system("/usr/bin/python3 -c 'import h5py, numpy' >/dev/null 2>&1") == 0;
}

std::string read_back_script() {
  return (fs::path(__FILE__).parent_path() / "read_back.py").string();
}

}  // namespace

TEST_CASE("A simulation's recording comes back bit for bit", "[results]") {
  const std::string path = temp_file("simulation");
  Cleanup cleanup{{path}};
  const Scene scene = make_scene(0.255, record_everything(), simulate_run(10.0));
  const Recording rec = run(scene);
  REQUIRE(rec.summary.status == RunStatus::completed);
  REQUIRE(rec.events->events.size() > 10);  // the data are not trivially empty
  REQUIRE(!rec.contacts->intervals.empty());
  REQUIRE(rec.samples->t.size() == 80);     // 8 per period, 10 periods
  REQUIRE(rec.poincare->t.size() >= 10);

  ResultFile file = ResultFile::create(path, scene, current_meta(1));
  CHECK(fs::exists(path + ".partial"));
  file.write_simulation(rec);
  RunMeta meta = current_meta(1);
  meta.wall_seconds = 1.5;
  file.finish(meta);
  CHECK_FALSE(fs::exists(path + ".partial"));
  REQUIRE(fs::exists(path));

  const ResultReader r(path);
  SECTION("events") {
    const std::vector<Event>& ev = rec.events->events;
    CHECK(r.read("/events/t") == column(ev, &Event::t));
    CHECK(r.read("/events/v_before") == column(ev, &Event::v_before));
    CHECK(r.read("/events/v_after") == column(ev, &Event::v_after));
    CHECK(r.read("/events/force") == column(ev, &Event::force));
    std::vector<std::int64_t> stop, kind;
    for (const Event& e : ev) {
      stop.push_back(e.stop);
      kind.push_back(static_cast<std::int64_t>(e.kind));
    }
    CHECK(r.read_integers("/events/stop") == stop);
    CHECK(r.read_integers("/events/kind") == kind);
    CHECK(r.type("/events/kind") == "i32");
    CHECK(r.attribute_strings("/events/kind", "names") ==
          std::vector<std::string>{"impact", "stick", "release", "chatter-limit"});
  }
  SECTION("contacts") {
    std::vector<double> t_start, t_end, force_min, t_force_min;
    std::vector<std::int64_t> stop, closed;
    for (const ContactInterval& c : rec.contacts->intervals) {
      stop.push_back(c.stop);
      t_start.push_back(c.t_start);
      t_end.push_back(c.t_end);
      force_min.push_back(c.force_min);
      t_force_min.push_back(c.t_force_min);
      closed.push_back(c.closed);
    }
    CHECK(r.read_integers("/contacts/stop") == stop);
    CHECK(r.read("/contacts/t_start") == t_start);
    CHECK(r.read("/contacts/t_end") == t_end);
    CHECK(r.read("/contacts/force_min") == force_min);
    CHECK(r.read("/contacts/t_force_min") == t_force_min);
    CHECK(r.read_integers("/contacts/closed") == closed);
  }
  SECTION("samples and Poincaré points") {
    CHECK(r.read("/samples/t") == rec.samples->t);
    CHECK(r.shape("/samples/x") == std::vector<std::size_t>{80, 2});
    CHECK(r.read_matrix("/samples/x") == stacked(rec.samples->x, 2));
    CHECK(r.read_matrix("/samples/v") == stacked(rec.samples->v, 2));
    CHECK(r.read("/poincare/t") == rec.poincare->t);
    CHECK(r.read_matrix("/poincare/x") == stacked(rec.poincare->x, 2));
    CHECK(r.read_matrix("/poincare/v") == stacked(rec.poincare->v, 2));
    // Sample i is at t_start + i T/8, exactly as Recording::for_scene scheduled it.
    CHECK(r.read("/samples/t")[3] == rec.t_start + 3.0 * scene.period() / 8.0);
  }
  SECTION("statistics: one row per recorded period, zero rows where nothing happened") {
    const PeriodStatistics& s = *rec.statistics;
    REQUIRE(r.shape("/stats/sticking_fraction") == std::vector<std::size_t>{10, 2});
    const Eigen::MatrixXd fraction = r.read_matrix("/stats/sticking_fraction");
    const Eigen::MatrixXd impacts = r.read_matrix("/stats/impacts");
    for (Eigen::Index k = 0; k < 10; ++k) {
      const auto kk = static_cast<std::size_t>(k);
      for (Eigen::Index j = 0; j < 2; ++j) {
        CHECK(fraction(k, j) == (kk < s.sticking_fraction.size() ? s.sticking_fraction[kk](j) : 0.0));
        CHECK(impacts(k, j) == (kk < s.impacts.size() ? s.impacts[kk](j) : 0));
      }
    }
    CHECK(r.attribute_strings("/stats/impacts", "stops") ==
          std::vector<std::string>{"s1 (below mass 1)", "upper x1"});
  }
  SECTION("scene") {
    CHECK(r.attribute_string("/scene", "yaml") == kYaml);
    CHECK(r.attribute_string("/scene", "file") == "<test>");
    CHECK(r.attribute_number("/scene", "frequency") == 0.255);
    CHECK(r.read_matrix("/scene/stiffness") == scene.system().stiffness());
    CHECK(r.read_matrix("/scene/damping") == scene.system().damping());
    CHECK(r.read_matrix("/scene/mass") == scene.system().mass());
    CHECK(r.read("/scene/forcing_cosine") == std::vector<double>{0.5, 0.0});
    CHECK(r.read_integers("/scene/stop_kind") == std::vector<std::int64_t>{1, 0});
    CHECK(r.read("/scene/stop_position") == std::vector<double>{-0.3, 0.1});
    CHECK(r.read_strings("/scene/stop_name") ==
          std::vector<std::string>{"s1 (below mass 1)", "upper x1"});
    CHECK(r.read("/scene/x0") == std::vector<double>{0.0, 0.05});
  }
  SECTION("meta") {
    CHECK(r.attribute_string("/meta", "status") == "completed");
    CHECK(r.attribute_string("/meta", "message").empty());
    CHECK(r.attribute_number("/meta", "wall_time") == 1.5);
    CHECK(r.attribute_number("/meta", "impacts") == rec.summary.impacts);
    CHECK(r.attribute_number("/meta", "sticks") == rec.summary.sticks);
    CHECK(r.attribute_number("/meta", "segments") == rec.summary.segments);
    CHECK(r.attribute_number("/meta", "contact_sets_built") ==
          static_cast<double>(rec.summary.contact_sets_built));
    CHECK(r.attribute_number("/meta", "trigger") == scene.solver.trigger);
    CHECK(r.attribute_number("/meta", "max_events") == scene.solver.max_events);
    CHECK(r.attribute_string("/meta", "version") == current_meta(1).version);
    CHECK(r.attribute_string("/meta", "date").size() == 20);  // 2024-01-02T03:04:05Z
    CHECK_FALSE(r.exists("/sweep"));
  }
}

TEST_CASE("Only the groups a scene records exist", "[results]") {
  const std::string path = temp_file("only");
  Cleanup cleanup{{path}};
  RecordSpec record;
  record.events = true;
  record.sample_times = {0.0, 1.0, 2.5};
  const Scene scene = make_scene(0.255, record, simulate_run(1.0));
  const Recording rec = run(scene);
  CHECK(rec.samples->t.size() == 3);
  ResultFile file = ResultFile::create(path, scene, current_meta(1));
  file.write_simulation(rec);
  file.finish(current_meta(1));

  const ResultReader r(path);
  CHECK(r.exists("/events/t"));
  CHECK(r.exists("/samples/x"));
  CHECK(r.shape("/samples/x") == std::vector<std::size_t>{3, 2});
  CHECK(r.read("/samples/t") == std::vector<double>{rec.t_start, rec.t_start + 1.0, rec.t_start + 2.5});
  for (const char* absent : {"/contacts", "/poincare", "/stats", "/sweep"}) {
    INFO(absent);
    CHECK_FALSE(r.exists(absent));
  }
  CHECK(r.objects() == std::vector<std::string>{
                           "/events", "/events/force", "/events/kind", "/events/stop", "/events/t",
                           "/events/v_after", "/events/v_before", "/meta", "/samples", "/samples/t",
                           "/samples/v", "/samples/x", "/scene", "/scene/damping",
                           "/scene/forcing_constant", "/scene/forcing_cosine",
                           "/scene/forcing_sine", "/scene/mass", "/scene/stiffness",
                           "/scene/stop_amplitude", "/scene/stop_kind", "/scene/stop_mass",
                           "/scene/stop_name", "/scene/stop_other", "/scene/stop_phase",
                           "/scene/stop_position", "/scene/stop_restitution", "/scene/v0",
                           "/scene/x0"});
}

TEST_CASE("A value that is not finite is never written", "[results]") {
  const std::string path = temp_file("nan");
  Cleanup cleanup{{path}};
  const Scene scene = make_scene(0.255, record_everything(), simulate_run(2.0));
  Recording rec = run(scene);
  rec.samples->x(1, 3) = std::nan("");
  {
    ResultFile file = ResultFile::create(path, scene, current_meta(1));
    CHECK_THROWS_WITH(file.write_simulation(rec),
                      Catch::Contains("/samples/x: entry [3, 1] is nan") &&
                          Catch::Contains("must be finite"));
  }  // a failed simulation leaves nothing behind
  CHECK_FALSE(fs::exists(path));
  CHECK_FALSE(fs::exists(path + ".partial"));
}

TEST_CASE("HDF5 failures name the file and the object", "[results]") {
  const Scene scene = make_scene(0.255, record_everything(), simulate_run(1.0));
  CHECK_THROWS_WITH(ResultFile::create("/nonexistent-dir/x.h5", scene, current_meta(1)),
                    Catch::StartsWith("/nonexistent-dir/x.h5.lock: cannot create the lock file: No such file"));
  CHECK_THROWS_AS(ResultReader("/nonexistent-dir/x.h5"), ResultError);
  const std::string path = temp_file("errors");
  Cleanup cleanup{{path}};
  ResultFile file = ResultFile::create(path, scene, current_meta(1));
  file.write_simulation(run(scene));
  file.finish(current_meta(1));
  const ResultReader r(path);
  CHECK_THROWS_WITH(r.read("/events/nothing"),
                    Catch::StartsWith(path + ": /events/nothing: cannot open the dataset"));
}

TEST_CASE("An interrupted sweep resumes to the same file as an uninterrupted one", "[results]") {
  const std::string whole = temp_file("sweep_whole"), resumed = temp_file("sweep_resumed");
  Cleanup cleanup{{whole, resumed}};
  write_full_sweep(whole);

  SECTION("writer destroyed after 3 points") {
    {
      ResultFile file = ResultFile::create(resumed, sweep_point(0), current_meta(1));
      file.begin_sweep({"forcing.frequency"}, 5);
      append_points(file, 0, 3);
      CHECK_THROWS_AS(file.append_point(4, {kFrequencies[4]}, run(sweep_point(4))), std::logic_error);
      Recording bad = run(sweep_point(3));
      bad.events->events.back().force = INFINITY;
      CHECK_THROWS_WITH(file.append_point(3, {kFrequencies[3]}, bad),
                        Catch::Contains("/events/force: entry [") && Catch::Contains("(point 3) is inf"));
      CHECK(file.completed_points() == 3);
    }  // no finish: a sweep keeps its .partial
    CHECK_FALSE(fs::exists(resumed));
    REQUIRE(fs::exists(resumed + ".partial"));
    {
      const ResultReader partial(resumed + ".partial");
      CHECK(partial.attribute_string("/meta", "status") == "running");
      CHECK(partial.shape("/sweep/values") == std::vector<std::size_t>{3, 1});
      CHECK(partial.shape("/samples/x")[0] == 3);
    }
    ResultFile file = ResultFile::open_partial(resumed, sweep_point(0));
    CHECK(file.completed_points() == 3);
    double t = 0.0;
    Eigen::VectorXd x, v;
    REQUIRE(file.last_state(t, x, v));
    CHECK(t == run(sweep_point(2)).summary.t);
    file.begin_sweep({"forcing.frequency"}, 5);  // resumed: checks only
    append_points(file, 3, 5);
    file.finish(current_meta(1));
    CHECK_FALSE(fs::exists(resumed + ".partial"));
    require_identical(whole, resumed);
    CHECK(ResultReader(resumed).attribute_number("/meta", "resumed") == 1);
  }

  SECTION("a point half-written when the run stopped is dropped") {
    {
      ResultFile file = ResultFile::create(resumed, sweep_point(0), current_meta(1));
      file.begin_sweep({"forcing.frequency"}, 5);
      append_points(file, 0, 4);
    }
    {  // Point 3's data are on disk but not counted: what a kill inside append_point leaves.
      const std::string partial = resumed + ".partial";
      const hid_t f = H5Fopen(partial.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
      REQUIRE(f >= 0);
      const hid_t g = H5Gopen2(f, "/sweep", H5P_DEFAULT);  // (H5Aopen_by_name cannot write)
      const hid_t a = H5Aopen(g, "completed", H5P_DEFAULT);
      const std::int64_t three = 3;
      CHECK(H5Awrite(a, H5T_NATIVE_INT64, &three) >= 0);
      H5Aclose(a);
      H5Gclose(g);
      H5Fclose(f);
    }
    ResultFile file = ResultFile::open_partial(resumed, sweep_point(0));
    CHECK(file.completed_points() == 3);
    append_points(file, 3, 5);
    file.finish(current_meta(1));
    require_identical(whole, resumed);
  }

  SECTION("a counted point whose data were lost is computed again") {
    {
      ResultFile file = ResultFile::create(resumed, sweep_point(0), current_meta(1));
      file.begin_sweep({"forcing.frequency"}, 5);
      append_points(file, 0, 4);
    }
    {  // Point 3's second sample reads as the fill value, as if its chunk never reached the disk.
      const std::string partial = resumed + ".partial";
      const hid_t f = H5Fopen(partial.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
      const hid_t d = H5Dopen2(f, "/samples/x", H5P_DEFAULT);
      const hid_t space = H5Dget_space(d);
      const hsize_t start[] = {3, 1, 0}, count[] = {1, 1, 1};
      H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
      const hid_t one = H5Screate_simple(3, count, nullptr);
      const double nan = std::nan("");
      CHECK(H5Dwrite(d, H5T_NATIVE_DOUBLE, one, space, H5P_DEFAULT, &nan) >= 0);
      H5Sclose(one);
      H5Sclose(space);
      H5Dclose(d);
      H5Fclose(f);
    }
    ResultFile file = ResultFile::open_partial(resumed, sweep_point(0));
    CHECK(file.completed_points() == 3);
    append_points(file, 3, 5);
    file.finish(current_meta(1));
    require_identical(whole, resumed);
  }

  SECTION("a partial file with damaged bytes is refused, naming what is damaged") {
    {
      ResultFile file = ResultFile::create(resumed, sweep_point(0), current_meta(1));
      file.begin_sweep({"forcing.frequency"}, 5);
      append_points(file, 0, 3);
    }
    // Flip the lowest byte of every stored copy of point 1's end time (it is in /sweep/t_end
    // and in the recorded samples): damage inside the data, the file's structure left intact.
    const std::string partial = resumed + ".partial";
    const double t_end = run(sweep_point(1)).summary.t;
    char pattern[sizeof t_end];
    std::memcpy(pattern, &t_end, sizeof t_end);
    std::string bytes;
    {
      std::ifstream in(partial, std::ios::binary);
      bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    int flipped = 0;
    for (std::size_t at = bytes.find(pattern, 0, sizeof t_end); at != std::string::npos;
         at = bytes.find(pattern, at + 1, sizeof t_end), ++flipped)
      bytes[at] = static_cast<char>(bytes[at] ^ 0x01);
    REQUIRE(flipped > 0);
    std::ofstream(partial, std::ios::binary | std::ios::trunc) << bytes;

    CHECK_THROWS_WITH(ResultFile::open_partial(resumed, sweep_point(0)),
                      Catch::StartsWith(partial + ": /") && Catch::Contains("damaged") &&
                          Catch::Contains("checksum") && Catch::Contains("remove " + partial));
    CHECK(fs::exists(partial));  // left as it was, for the user to inspect or remove
    CHECK_FALSE(fs::exists(partial + ".resume"));
    CHECK_FALSE(fs::exists(resumed));
  }

  SECTION("a killed process keeps the points it flushed") {
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) {  // the child must never return into Catch
      try {
        ResultFile file = ResultFile::create(resumed, sweep_point(0), current_meta(1));
        file.begin_sweep({"forcing.frequency"}, 5);
        append_points(file, 0, 2);
        ::raise(SIGKILL);  // no destructor, no close: as `kill -9`
      } catch (...) {
      }
      ::_exit(1);
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    REQUIRE(WIFSIGNALED(status));
    REQUIRE(WTERMSIG(status) == SIGKILL);
    ResultFile file = ResultFile::open_partial(resumed, sweep_point(0));
    CHECK(file.completed_points() == 2);
    append_points(file, 2, 5);
    file.finish(current_meta(1));
    require_identical(whole, resumed);
  }

  SECTION("the layout of the stacked and concatenated data") {
    const ResultReader r(whole);
    CHECK(r.shape("/sweep/values") == std::vector<std::size_t>{5, 1});
    CHECK(r.read("/sweep/values") == kFrequencies);
    CHECK(r.attribute_strings("/sweep/values", "parameters") ==
          std::vector<std::string>{"forcing.frequency"});
    CHECK(r.read_integers("/sweep/status") == std::vector<std::int64_t>(5, 0));
    CHECK(r.shape("/samples/x") == std::vector<std::size_t>{5, 48, 2});
    CHECK(r.shape("/stats/impacts") == std::vector<std::size_t>{5, 6, 2});
    const std::vector<std::int64_t> rows = r.read_integers("/events/rows");
    const std::vector<std::int64_t> point = r.read_integers("/events/point");
    REQUIRE(rows.size() == 5);
    std::size_t offset = 0;
    for (std::size_t p = 0; p < 5; ++p) {
      const Recording rec = run(sweep_point(p));
      REQUIRE(rows[p] == static_cast<std::int64_t>(rec.events->events.size()));
      const std::vector<double> t = r.read("/events/t");
      for (std::size_t i = 0; i < rec.events->events.size(); ++i) {
        CHECK(point[offset + i] == static_cast<std::int64_t>(p));
        CHECK(t[offset + i] == rec.events->events[i].t);
      }
      offset += rec.events->events.size();
      const Eigen::MatrixXd x = r.read_matrix("/samples/x");  // 5 × (48·2)
      CHECK(Eigen::RowVectorXd(x.row(static_cast<Eigen::Index>(p))) == flattened(rec.samples->x));
    }
    CHECK(offset == point.size());
    CHECK(r.attribute_string("/meta", "status") == "completed");
  }
}

TEST_CASE("Resuming refuses another scene and keeps the partial file", "[results]") {
  const std::string path = temp_file("refuse");
  Cleanup cleanup{{path}};
  {
    ResultFile file = ResultFile::create(path, sweep_point(0), current_meta(1));
    file.begin_sweep({"forcing.frequency"}, 5);
    append_points(file, 0, 1);
  }
  Scene edited = sweep_point(0);
  edited.yaml_text += "# edited\n";
  CHECK_THROWS_WITH(ResultFile::open_partial(path, edited),
                    Catch::Contains("/scene attribute yaml: differs"));
  Scene other_set = sweep_point(0);  // same text, another --set stops[1].position=0.12
  other_set.stops[1].position = 0.12;
  CHECK_THROWS_WITH(ResultFile::open_partial(path, other_set),
                    Catch::Contains("/scene/stop_position: differs"));
  CHECK_THROWS_WITH(ResultFile::open_partial(temp_file("nothing"), sweep_point(0)),
                    Catch::Contains("no interrupted run to resume"));
  const Scene simulation = make_scene(0.255, record_everything(), simulate_run(6.0));
  CHECK_THROWS_WITH(ResultFile::open_partial(path, simulation),
                    Catch::Contains("only a sweep can be resumed"));
  REQUIRE(fs::exists(path + ".partial"));
  ResultFile file = ResultFile::open_partial(path, sweep_point(0));
  CHECK(file.completed_points() == 1);
  CHECK_THROWS_WITH(file.begin_sweep({"stops[1].position"}, 5),
                    Catch::Contains("sweeps other parameters"));
}

TEST_CASE("h5py reads the files (tests/io/read_back.py)", "[results]") {
  if (!fs::exists("/usr/bin/python3") || !python_with_h5py() || !fs::exists(read_back_script())) {
    WARN("skipped: needs /usr/bin/python3 with h5py and numpy, and " << read_back_script());
    return;
  }
  const std::string simulation = temp_file("py_simulation"), sweep = temp_file("py_sweep");
  Cleanup cleanup{{simulation, sweep}};
  const Scene scene = make_scene(0.255, record_everything(), simulate_run(4.0));
  ResultFile file = ResultFile::create(simulation, scene, current_meta(2));
  file.write_simulation(run(scene));
  file.finish(current_meta(2));
  write_full_sweep(sweep);

  const std::string script = "/usr/bin/python3 " + read_back_script();
  CHECK(std::system((script + " --quiet " + simulation + " --dof 2 --stops 2 --samples 32 --periods 4")
                        .c_str()) == 0);
  CHECK(std::system((script + " --quiet " + sweep + " --dof 2 --stops 2 --samples 48 --periods 6"
                              " --points 5")
                        .c_str()) == 0);
}
