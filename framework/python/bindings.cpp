/// \file bindings.cpp
/// The compiled part of the Python module `vibro` (pybind11): scene documents, runs into memory,
/// result images, and one orbit at a time (tangent maps, multipliers, shooting). The public API, with its documentation, is vibro/__init__.py, which wraps
/// these; docs/python.md is its guide.
///
/// Runs release the GIL: the scene is built and run on a worker thread (sweeps then use their
/// OpenMP threads as `vibro run` does) while the calling thread waits, taking the GIL back every
/// 50 ms to let Python handle signals (PyErr_CheckSignals). If a handler raises — Ctrl-C's
/// KeyboardInterrupt — the run's stop flag is raised (SimulatorOptions::interrupt: the engine
/// stops at its next event), the worker finishes, and the partial result is returned marked
/// interrupted (vibro/__init__.py raises vibro.Interrupted carrying it); any other exception a
/// handler raises is re-raised once the worker is done. Signals reach Python's main thread
/// only, so a run in another thread is stopped by its own flag, never by Ctrl-C.
#include "vibro/bounded_wait.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/run_kinds.hpp"
#include "vibro/io/session.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/shooting.hpp"

#include <pybind11/complex.h>
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <complex>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

namespace py = pybind11;
using vibro::io::SceneDocument;

namespace {

// --- Errors ---------------------------------------------------------------------------------

PyObject* scene_error_type = nullptr;   // vibro.SceneError(ValueError)
PyObject* result_error_type = nullptr;  // vibro.ResultError(OSError)

/// SceneError keeps the parts of its message as attributes (file, line, column, path, problem).
void raise_scene_error(const vibro::io::SceneError& e) {
  py::object error = py::reinterpret_borrow<py::object>(scene_error_type)(e.what());
  error.attr("file") = e.file();
  error.attr("line") = e.line();
  error.attr("column") = e.column();
  error.attr("path") = e.path();
  error.attr("problem") = e.problem();
  PyErr_SetObject(scene_error_type, error.ptr());
}

void translate(std::exception_ptr failure) {
  try {
    if (failure) std::rethrow_exception(failure);
  } catch (const vibro::io::SceneError& e) {
    raise_scene_error(e);
  } catch (const vibro::io::ResultError& e) {
    PyErr_SetString(result_error_type, e.what());
  } catch (const vibro::InvalidInput& e) {
    PyErr_SetString(PyExc_ValueError, e.what());
  }
}

// --- Scenes -----------------------------------------------------------------------------------

py::list to_list(const Eigen::VectorXd& v) {
  py::list out;
  for (Eigen::Index i = 0; i < v.size(); ++i) out.append(v(i));
  return out;
}

/// What a built scene resolved to, for the Python Scene's properties.
py::dict describe(const vibro::io::Scene& s) {
  py::dict d;
  d["file"] = s.file;
  d["name"] = s.name;
  d["dof"] = s.dof();
  d["frequency"] = s.forcing().frequency;
  d["period"] = s.period();
  d["t0"] = s.t0;
  d["x0"] = to_list(s.x0);
  d["v0"] = to_list(s.v0);
  py::list stops;
  for (const vibro::Stop& stop : vibro::validated_stops(s.stops, s.dof(), s.forcing().frequency)) stops.append(stop.name);
  d["stops"] = stops;
  d["engine"] = vibro::io::to_string(s.engine);
  d["engine_reason"] = s.engine_reason;
  if (s.base) d["frame"] = s.record.frame == vibro::BaseFrame::relative ? "relative" : "absolute";
  else d["frame"] = py::none();
  d["run_kind"] = vibro::io::to_string(s.run.kind);
  d["transient_periods"] = s.run.transient_periods;
  d["periods"] = s.run.periods;
  py::list axes;
  for (const vibro::io::SweepAxis& a : s.run.axes) axes.append(py::make_tuple(a.path, a.values));
  d["axes"] = axes;
  py::dict record;
  record["events"] = s.record.events;
  record["contacts"] = s.record.contacts;
  record["statistics"] = s.record.statistics;
  record["poincare"] = s.record.poincare;
  record["impact_map"] = s.record.impact_map;
  if (s.record.section) {
    const vibro::Hyperplane& plane = s.record.section->plane;
    py::dict section;
    section["normal"] = std::vector<double>(plane.normal.data(), plane.normal.data() + plane.normal.size());
    section["value"] = plane.value;
    section["direction"] = std::string(vibro::to_string(s.record.section->direction));
    record["section"] = section;
  } else {
    record["section"] = py::none();
  }
  record["samples_per_period"] = s.record.samples_per_period;
  record["sample_times"] = s.record.sample_times;
  d["record"] = record;
  return d;
}

// --- Runs -------------------------------------------------------------------------------------

/// A run on a worker thread, and what the waiting thread needs to know about it.
struct Work {
  std::atomic<bool> stop{false};
  std::mutex lock;
  std::condition_variable finished;
  bool done = false;
  vibro::io::MemoryRun run;
  /// The stop flag ended a set-up that nothing can poll (run_bounded, bounded_wait.hpp) before
  /// the run held anything: no image, an interrupted run all the same.
  bool set_up_interrupted = false;
  std::exception_ptr failure;
  std::atomic<double> progress_done{-1.0}, progress_total{0.0};  ///< RunRequest::on_progress
};

/// The runs in progress, so that the interpreter's exit can stop them (stop_all_runs).
std::mutex g_runs_lock;
std::vector<std::weak_ptr<Work>> g_runs;

/// Registered with Python's atexit: raises every running run's stop flag and waits (GIL
/// released) up to 10 s for their workers to end. Python runs it before it finalizes, while a
/// daemon thread may still wait in run_watched; once finalizing, such a thread is ended by the
/// interpreter where it next takes the GIL (Python ≤ 3.11: pthread_exit, an unwind through
/// run_watched), and the engine must not still be running then.
void stop_all_runs() {
  std::vector<std::shared_ptr<Work>> running;
  {
    const std::lock_guard<std::mutex> hold(g_runs_lock);
    for (const std::weak_ptr<Work>& w : g_runs)
      if (std::shared_ptr<Work> work = w.lock()) running.push_back(std::move(work));
  }
  py::gil_scoped_release release;
  for (const auto& work : running) work->stop.store(true);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  for (const auto& work : running) {
    std::unique_lock<std::mutex> hold(work->lock);
    work->finished.wait_until(hold, deadline, [&] { return work->done; });
  }
}

/// Keeps a run in g_runs while it runs.
class RunListed {
 public:
  explicit RunListed(const std::shared_ptr<Work>& work) : work_(work.get()) {
    const std::lock_guard<std::mutex> hold(g_runs_lock);
    g_runs.push_back(work);
  }
  ~RunListed() {
    const std::lock_guard<std::mutex> hold(g_runs_lock);
    g_runs.erase(std::remove_if(g_runs.begin(), g_runs.end(),
                                [this](const std::weak_ptr<Work>& w) {
                                  const std::shared_ptr<Work> p = w.lock();
                                  return !p || p.get() == work_;
                                }),
                 g_runs.end());
  }
  RunListed(const RunListed&) = delete;
  RunListed& operator=(const RunListed&) = delete;

 private:
  const Work* work_;
};

/// Joins the worker on every way out of run_watched, the stop flag raised first if it still
/// runs: also when the interpreter ends a daemon thread that waits here (an unwind; a joinable
/// std::thread destroyed then would call std::terminate).
class WorkerJoin {
 public:
  WorkerJoin(std::thread& worker, Work& work) : worker_(worker), work_(work) {}
  ~WorkerJoin() {
    if (!worker_.joinable()) return;
    work_.stop.store(true);
    worker_.join();
  }
  WorkerJoin(const WorkerJoin&) = delete;
  WorkerJoin& operator=(const WorkerJoin&) = delete;

 private:
  std::thread& worker_;
  Work& work_;
};

/// Calls `callback(done, total)` (GIL held) if the run's progress moved since `shown`.
void report_progress(const py::object& callback, const Work& work, double& shown) {
  const double done = work.progress_done.load();
  if (callback.is_none() || done == shown) return;
  shown = done;
  callback(done, work.progress_total.load());
}

/// Runs `task(work)` on a worker thread with the GIL released; see the file's comment. Every
/// 50 ms the waiting thread also hands the run's progress to `progress` (a Python callable, or
/// None); an exception it raises stops the run and is re-raised, as a signal handler's is.
/// Returns whether a signal handler's KeyboardInterrupt stopped it.
template <class Task>
bool run_watched(const std::shared_ptr<Work>& work, Task task, const py::object& progress = py::none()) {
  const RunListed listed(work);
  std::thread worker([work, task]() mutable {
    try {
      task(*work);
    } catch (...) {
      work->failure = std::current_exception();
    }
    {
      const std::lock_guard<std::mutex> hold(work->lock);
      work->done = true;
    }
    work->finished.notify_all();
  });
  const WorkerJoin join(worker, *work);
  std::optional<py::error_already_set> raised;  // by a signal handler while the run went on
  double shown = -1.0;                          // the progress last handed to `progress`
  {
    // The GIL is released and taken back by hand, not by pybind11's scoped guards: a finalizing
    // interpreter ends a daemon thread inside PyEval_RestoreThread, and a guard's destructor
    // taking the GIL again during that unwind would abort the process.
    PyThreadState* state = PyEval_SaveThread();
    std::unique_lock<std::mutex> hold(work->lock);
    while (!work->finished.wait_for(hold, std::chrono::milliseconds(50), [&] { return work->done; })) {
      if (raised) continue;  // stopping: wait for the engine's next event
      hold.unlock();
      PyEval_RestoreThread(state);
      if (PyErr_CheckSignals() != 0) {
        raised.emplace();
        work->stop.store(true);
      } else {
        try {
          report_progress(progress, *work, shown);
        } catch (py::error_already_set& e) {
          raised.emplace(e);
          work->stop.store(true);
        }
      }
      state = PyEval_SaveThread();
      hold.lock();
    }
    hold.unlock();
    worker.join();  // before the GIL is taken back (where a finalizing interpreter ends the thread)
    PyEval_RestoreThread(state);
  }
  if (!raised && !work->failure) report_progress(progress, *work, shown);  // where it ended
  if (raised && !raised->matches(PyExc_KeyboardInterrupt)) throw *raised;
  if (work->failure && !raised) std::rethrow_exception(work->failure);
  return raised.has_value();
}

/// Builds and runs a copy of `doc` (its run.kind) into memory. `show`: progress on stderr, 0
/// none, 1 a redrawn line (a terminal), 2 a line at each tenth; `progress`: a callable given
/// (done, total) as the run goes on, or None.
py::tuple run(const SceneDocument& doc, int threads, int show, const py::object& progress) {
  auto work = std::make_shared<Work>();
  const SceneDocument copy(doc);  // the caller may edit its document meanwhile (another thread)
  const bool report = !progress.is_none();
  const bool interrupted = run_watched(
      work,
      [copy, threads, show, report](Work& w) {
        const vibro::io::Scene scene = copy.build();
        vibro::io::MemoryRunOptions options;
        options.threads = threads;
        options.interrupt = &w.stop;
        options.bar = show == 1;
        options.lines = show == 2;
        if (report)
          options.on_progress = [&w](double done, double total) {
            w.progress_total.store(total);
            w.progress_done.store(done);
          };
        try {
          w.run = vibro::io::run_in_memory(copy, scene, options);
        } catch (const vibro::Interrupted&) {  // a bounded set-up, before the kind held a result
          w.set_up_interrupted = true;
          w.run = {};
          w.run.exit_code = 130;
          w.run.summary = "Interrupted during a set-up computation: nothing was computed.";
        }
      },
      progress);
  if (work->failure) std::rethrow_exception(work->failure);  // interrupted before it ran
  py::bytes image(work->run.image.data(), work->run.image.size());
  return py::make_tuple(image, work->run.exit_code, work->run.summary, interrupted || work->set_up_interrupted);
}

/// Builds `doc` (validates it) with the GIL released: a sweep's check builds every point.
py::dict check(const SceneDocument& doc) {
  std::optional<vibro::io::Scene> scene;
  {
    py::gil_scoped_release release;
    scene = doc.build();
  }
  return describe(*scene);
}

// --- One orbit at a time: tangent maps, multipliers, shooting (framework/analysis) -----------

/// The scene's initial state, or the given one (sizes checked by the analysis layer).
Eigen::VectorXd state_or(const std::optional<Eigen::VectorXd>& given, const Eigen::VectorXd& scene_value) {
  return given ? *given : scene_value;
}

py::list complex_list(const Eigen::VectorXcd& values) {
  py::list out;
  for (Eigen::Index i = 0; i < values.size(); ++i) out.append(std::complex<double>(values(i)));
  return out;
}

py::dict describe_multipliers(const vibro::FloquetMultipliers& f) {
  py::dict d;
  d["values"] = complex_list(f.values);
  d["structural_zeros"] = f.structural_zeros;
  d["spectral_radius"] = f.spectral_radius;
  d["stable"] = f.stable;
  d["rate"] = f.rate;
  return d;
}

/// The tangent map of the dense engine (the Taylor engine for a scene with forces) over [t0, t1] from (x, v) (linearisation.hpp), and the
/// multipliers of that map read as a period-k map when k > 0.
py::dict tangent_map(const SceneDocument& doc, std::optional<double> t0, double t1, std::optional<Eigen::VectorXd> x,
                     std::optional<Eigen::VectorXd> v, int k) {
  std::optional<vibro::TangentMap> map;
  std::optional<vibro::FloquetMultipliers> multipliers;
  {
    py::gil_scoped_release release;
    const vibro::io::Scene scene = doc.build();
    if (scene.engine == vibro::io::EngineKind::taylor)  // nonlinear forces: the Taylor engine's map
      map = vibro::linearise(scene.impact_system(), scene.forces, scene.solver, t0.value_or(scene.t0),
                             state_or(x, scene.x0), state_or(v, scene.v0), t1);
    else
      map = vibro::linearise(scene.impact_system(), scene.solver, t0.value_or(scene.t0), state_or(x, scene.x0),
                             state_or(v, scene.v0), t1);
    if (k > 0 && map->summary.status == vibro::RunStatus::completed) multipliers = vibro::floquet_multipliers(*map, k);
  }
  py::dict d;
  d["status"] = vibro::to_string(map->summary.status);
  d["message"] = map->summary.message;
  d["t0"] = map->t0;
  d["t1"] = map->t1;
  d["x0"] = map->x0;
  d["v0"] = map->v0;
  d["x1"] = map->x1;
  d["v1"] = map->v1;
  d["jacobian"] = map->jacobian;
  d["free_dimension"] = static_cast<long>(map->free_dimension);
  d["events"] = map->events.size();
  if (multipliers) d["multipliers"] = describe_multipliers(*multipliers);
  return d;
}

/// Newton shooting on the dense engine (the Taylor engine for a scene with forces) from (t, x, v)
/// (shooting.hpp).
py::dict shoot(const SceneDocument& doc, int period, double phase, double tolerance, int max_iterations,
               std::optional<double> t, std::optional<Eigen::VectorXd> x, std::optional<Eigen::VectorXd> v) {
  std::optional<vibro::ShootingResult> r;
  {
    py::gil_scoped_release release;
    const vibro::io::Scene scene = doc.build();
    vibro::ShootingOptions o;
    o.period = period;
    o.phase = phase;
    o.tolerance = tolerance;
    o.max_iterations = max_iterations;
    o.solver = scene.solver;
    if (scene.engine == vibro::io::EngineKind::taylor)  // nonlinear forces: the Taylor engine
      r = vibro::shoot(scene.impact_system(), scene.forces, o, t.value_or(scene.t0), state_or(x, scene.x0),
                       state_or(v, scene.v0));
    else
      r = vibro::shoot(scene.impact_system(), o, t.value_or(scene.t0), state_or(x, scene.x0), state_or(v, scene.v0));
  }
  py::dict d;
  d["status"] = vibro::to_string(r->status);
  d["message"] = r->message;
  d["iterations"] = r->iterations;
  d["residuals"] = r->residuals;
  d["residual"] = r->residual;
  d["period"] = r->k;
  d["minimal_period"] = r->minimal_k;
  d["phase"] = r->phase;
  d["t0"] = r->t0;
  d["x"] = r->x;
  d["v"] = r->v;
  d["jacobian"] = r->map.jacobian;
  if (r->converged()) d["multipliers"] = describe_multipliers(r->multipliers);
  return d;
}

// --- Result images ----------------------------------------------------------------------------

/// A result file's bytes and a reader on them.
class Image {
 public:
  explicit Image(std::vector<char> bytes) : bytes_(std::move(bytes)), reader_(bytes_) {}
  static Image from_bytes(const py::bytes& data) {
    const std::string_view view(data);
    return Image(std::vector<char>(view.begin(), view.end()));
  }
  static Image load(const std::string& path) { return Image(vibro::io::load_image(path)); }

  std::size_t size() const { return bytes_.size(); }
  py::bytes bytes() const { return py::bytes(bytes_.data(), bytes_.size()); }
  void save(const std::string& path, bool overwrite) const { vibro::io::save_image(bytes_, path, overwrite); }
  std::vector<std::string> objects() const { return reader_.objects(); }
  bool is_dataset(const std::string& path) const { return reader_.is_dataset(path); }

  /// The dataset as a numpy array of its stored type (f64, i32, i64; strings as str).
  py::object dataset(const std::string& path) const {
    const std::vector<std::size_t> shape = reader_.shape(path);
    const std::vector<py::ssize_t> dims(shape.begin(), shape.end());
    const std::string type = reader_.type(path);
    if (type == "f64") return copy_array<double>(reader_.read(path), dims);
    if (type == "i32") return copy_array<std::int32_t>(reader_.read_integers(path), dims);
    if (type == "i64") return copy_array<std::int64_t>(reader_.read_integers(path), dims);
    if (type == "str") return py::module_::import("numpy").attr("array")(reader_.read_strings(path), "str").attr("reshape")(dims);
    throw vibro::io::ResultError(path + ": a dataset of a type the result files do not use");
  }

  /// The attributes of a group or dataset: str, list of str, int or float.
  py::dict attributes(const std::string& object) const {
    py::dict out;
    for (const std::string& name : reader_.attributes(object)) {
      const std::string type = reader_.attribute_type(object, name);
      if (type == "str") out[name.c_str()] = reader_.attribute_string(object, name);
      else if (type == "str[]") out[name.c_str()] = reader_.attribute_strings(object, name);
      else if (type == "i64") out[name.c_str()] = static_cast<std::int64_t>(reader_.attribute_number(object, name));
      else out[name.c_str()] = reader_.attribute_number(object, name);
    }
    return out;
  }

 private:
  template <class T, class From>
  static py::array copy_array(const std::vector<From>& values, const std::vector<py::ssize_t>& dims) {
    py::array_t<T> out(dims);
    T* data = out.mutable_data();
    for (std::size_t i = 0; i < values.size(); ++i) data[i] = static_cast<T>(values[i]);
    return out;
  }

  std::vector<char> bytes_;
  vibro::io::ResultReader reader_;
};

}  // namespace

PYBIND11_MODULE(_vibro, m) {
  m.doc() = "Compiled bindings of the vibro package (use `import vibro`; see help(vibro)).";
  m.attr("__version__") = VIBRO_VERSION;
  m.def(
      "run_kinds",
      [] {
        py::list kinds;
        for (const vibro::io::RunKindInfo& k : vibro::io::run_kinds())
          kinds.append(py::make_tuple(k.name, k.summary, k.section ? py::object(py::str(k.section)) : py::object(py::none()),
                                      k.missing ? py::object(py::str(k.missing)) : py::object(py::none())));
        return kinds;
      },
      "The run kinds (run.kind, docs/scenes.md), from the table `vibro run` dispatches on: a list of "
      "(name, summary, section, missing) with section the kind's own key under run (None: none) and "
      "missing the loader's message when that section is required and absent (None: optional).");

  scene_error_type = PyErr_NewExceptionWithDoc(
      "vibro.SceneError",
      "A malformed scene: the message is the command line's, 'file:line:column: key.path: problem'.\n"
      "Attributes: file, line, column (0 where there is no position), path, problem.",
      PyExc_ValueError, nullptr);
  result_error_type = PyErr_NewExceptionWithDoc(
      "vibro.ResultError", "A result file that cannot be written or read: 'FILE: /OBJECT: what'.", PyExc_OSError, nullptr);
  m.attr("SceneError") = py::reinterpret_borrow<py::object>(scene_error_type);
  m.attr("ResultError") = py::reinterpret_borrow<py::object>(result_error_type);
  py::register_exception_translator(translate);
  // Runs still going when the interpreter exits (in daemon threads) are stopped first.
  py::module_::import("atexit").attr("register")(py::cpp_function(&stop_all_runs));

  py::class_<SceneDocument>(m, "SceneDocument", "A scene's YAML tree, editable by path (vibro::io::SceneDocument).")
      .def_static("load", &SceneDocument::load, py::arg("path"), "Reads a scene file.")
      .def_static("parse", &SceneDocument::parse, py::arg("text"), py::arg("file") = "<string>",
                  "Parses scene text; `file` names it in messages.")
      .def("get", &SceneDocument::get, py::arg("path"), "The number at a path.")
      .def("set", &SceneDocument::set, py::arg("path"), py::arg("value"), "Sets the number at a path.")
      .def("set_assignment", &SceneDocument::set_assignment, py::arg("assignment"), py::arg("ordinal") = 1,
           "Applies 'PATH=VALUE' as `vibro run --set` does, with its messages.")
      .def("replace", &SceneDocument::replace, py::arg("path"), py::arg("yaml"),
           "Replaces (or adds, or with '' removes) the value at a key path by YAML text.")
      .def("copy", [](const SceneDocument& d) { return SceneDocument(d); })
      .def_property_readonly("text", &SceneDocument::text)
      .def_property_readonly("file", &SceneDocument::file)
      .def("check", &check, "Builds and validates the scene; returns what it resolved to.")
      .def("run", &run, py::arg("threads") = 0, py::arg("show") = 0, py::arg("progress") = py::none(),
           "Runs the scene's run.kind into memory: (image bytes, exit code, summary, interrupted). show: "
           "progress on stderr (0 none, 1 a redrawn line, 2 a line per tenth); progress: a callable given "
           "(done, total) as the run goes on.")
      .def("tangent_map", &tangent_map, py::arg("t0"), py::arg("t1"), py::arg("x"), py::arg("v"), py::arg("period"),
           "The dense engine's tangent map over [t0, t1] (None: the scene's start) and, with period k > 0, "
           "the multipliers of it as a k-period map.")
      .def("shoot", &shoot, py::arg("period"), py::arg("phase"), py::arg("tolerance"), py::arg("max_iterations"),
           py::arg("t"), py::arg("x"), py::arg("v"), "Newton shooting on the dense engine from a guess.");

  py::class_<Image>(m, "Image", "The bytes of a result file and a reader on them.")
      .def_static("from_bytes", &Image::from_bytes, py::arg("data"))
      .def_static("load", &Image::load, py::arg("path"), "Reads a result file.")
      .def("__len__", &Image::size)
      .def("bytes", &Image::bytes)
      .def("save", &Image::save, py::arg("path"), py::arg("overwrite") = false)
      .def("objects", &Image::objects)
      .def("is_dataset", &Image::is_dataset, py::arg("path"))
      .def("dataset", &Image::dataset, py::arg("path"))
      .def("attributes", &Image::attributes, py::arg("object"));
}
