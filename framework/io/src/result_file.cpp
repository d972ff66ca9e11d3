// The result file's /scene and /meta, its life (create, create_in_memory, finish, the
// destructor), and the groups of run kinds other than simulate and sweep (write_group). The
// recorded groups are in kinds/simulate_layout.cpp, /sweep in kinds/sweep_layout.cpp, resuming in
// resume.cpp; the layout is docs/results.md: change both together, and only compatibly.
#include "datasets.hpp"
#include "result_file_impl.hpp"

#include <cstdio>
#include <stdexcept>

namespace vibro::io {

namespace detail {

namespace {

const char* flow_method_name(FlowMethod method) {
  switch (method) {
    case FlowMethod::automatic: return "automatic";
    case FlowMethod::spectral: return "spectral";
    case FlowMethod::exponential: return "exponential";
  }
  return "?";
}

std::vector<std::string> stop_names(const Scene& scene) {
  std::vector<std::string> names;
  // Names defaulted as in messages; O(m log m), no dense system.
  for (const Stop& stop : validated_stops(scene.stops, scene.dof(), scene.forcing().frequency))
    names.push_back(stop.name);
  return names;
}

}  // namespace

/// The resolved scene as datasets of /scene.
/// A scene run by the modal engine gives its chain in banded form (O(n)): its dense matrices are
/// never built (at n = 10 000 each would take 800 MB).
std::vector<Dataset> scene_datasets(const Scene& scene) {
  std::vector<Dataset> c;
  if (scene.engine == EngineKind::modal && scene.chain) {
    const BandedChain& chain = *scene.chain;
    c.push_back(vector_dataset("mass_diagonal", chain.mass));
    c.push_back(vector_dataset("stiffness_diagonal", chain.stiffness_diagonal));
    c.push_back(vector_dataset("stiffness_off_diagonal", chain.stiffness_off));
    c.push_back(vector_dataset("rayleigh", Eigen::Vector2d(chain.rayleigh_mass, chain.rayleigh_stiffness)));
  } else {
    const LinearSystem& s = scene.system();
    c.push_back(matrix_dataset("mass", s.mass()));
    c.push_back(matrix_dataset("damping", s.damping()));
    c.push_back(matrix_dataset("stiffness", s.stiffness()));
  }
  const HarmonicForcing& f = scene.forcing();
  c.push_back(vector_dataset("forcing_constant", f.constant));
  c.push_back(vector_dataset("forcing_cosine", f.cosine));
  c.push_back(vector_dataset("forcing_sine", f.sine));
  if (!f.harmonics.empty()) {  // extra harmonics (orders ≥ 2): one row each
    std::vector<std::int64_t> order;
    std::vector<Eigen::VectorXd> cosine, sine;
    for (const ForcingHarmonic& h : f.harmonics) {
      order.push_back(h.order);
      cosine.push_back(h.cosine);
      sine.push_back(h.sine);
    }
    const auto n = static_cast<std::size_t>(f.constant.size());
    c.push_back(integers("harmonic_order", std::move(order)));
    c.push_back(table("harmonic_cosine", cosine, n));
    c.push_back(table("harmonic_sine", sine, n));
  }

  // Stop names defaulted as in messages (a Scene made in code may leave them empty).
  const std::vector<Stop> stops = validated_stops(scene.stops, scene.dof(), f.frequency);
  const std::size_t m = stops.size();
  std::vector<std::int64_t> kind, mass, other;
  std::vector<double> position, restitution, amplitude, phase;
  std::vector<std::string> name;
  for (const Stop& stop : stops) {
    kind.push_back(static_cast<std::int64_t>(stop.kind));
    mass.push_back(stop.mass);
    other.push_back(stop.other);
    position.push_back(stop.position);
    restitution.push_back(stop.restitution);
    amplitude.push_back(stop.amplitude);
    phase.push_back(stop.phase);
    name.push_back(stop.name);
  }
  // Stops along general normals add the kind "normal" and the m × n matrix of every stop's
  // normal w_j (a scene without them keeps the three kinds and no matrix).
  bool general = false;
  for (const Stop& stop : stops) general = general || stop.kind == Stop::Kind::normal;
  std::vector<std::string> kind_names{"upper", "lower", "between"};
  if (general) kind_names.emplace_back("normal");
  c.push_back(integers("stop_kind", std::move(kind), {m}, Type::i32));
  c.back().labels.emplace_back("names", std::move(kind_names));
  c.push_back(integers("stop_mass", std::move(mass), {m}));
  c.push_back(integers("stop_other", std::move(other), {m}));
  c.push_back(reals("stop_position", std::move(position), {m}));
  c.push_back(reals("stop_restitution", std::move(restitution), {m}));
  c.push_back(reals("stop_amplitude", std::move(amplitude), {m}));
  c.push_back(reals("stop_phase", std::move(phase), {m}));
  c.push_back(texts("stop_name", std::move(name)));
  if (has_compliant(stops)) {  // the contact laws (docs/results.md); absent when every stop is rigid
    std::vector<std::int64_t> law;
    std::vector<double> stiffness, damping, preload;
    for (const Stop& stop : stops) {
      law.push_back(static_cast<std::int64_t>(stop.law));
      stiffness.push_back(stop.stiffness);
      damping.push_back(stop.damping);
      preload.push_back(stop.preload);
    }
    c.push_back(integers("stop_law", std::move(law), {m}, Type::i32));
    c.back().labels.emplace_back("names", std::vector<std::string>{"rigid", "compliant"});
    c.push_back(reals("stop_stiffness", std::move(stiffness), {m}));
    c.push_back(reals("stop_damping", std::move(damping), {m}));
    c.push_back(reals("stop_preload", std::move(preload), {m}));
  }
  if (general) {
    Eigen::MatrixXd normals(static_cast<Eigen::Index>(m), scene.dof());
    for (std::size_t j = 0; j < m; ++j) normals.row(static_cast<Eigen::Index>(j)) = stops[j].normal(scene.dof()).transpose();
    c.push_back(matrix_dataset("stop_normal", normals));
  }
  bool higher = false;
  for (const Stop& stop : stops) higher = higher || stop.has_higher_harmonics();
  if (higher) {  // stops' harmonics of order ≥ 2 (docs/results.md): one entry per stop and harmonic
    std::vector<std::int64_t> which, order;
    std::vector<double> cosine, sine;
    for (std::size_t j = 0; j < m; ++j)
      for (const StopHarmonic& h : stops[j].harmonics) {
        which.push_back(static_cast<std::int64_t>(j));
        order.push_back(h.order);
        cosine.push_back(h.cosine);
        sine.push_back(h.sine);
      }
    const std::size_t q = which.size();
    c.push_back(integers("stop_harmonic_stop", std::move(which), {q}));
    c.push_back(integers("stop_harmonic_order", std::move(order), {q}));
    c.push_back(reals("stop_harmonic_cosine", std::move(cosine), {q}));
    c.push_back(reals("stop_harmonic_sine", std::move(sine), {q}));
  }
  if (!scene.friction.empty()) {  // frictional contacts (docs/results.md); absent without friction
    const std::size_t q = scene.friction.size();
    std::vector<std::int64_t> fkind, fmass, fother;
    std::vector<double> load, mu_s, mu_k, famplitude, fphase;
    std::vector<std::string> fname;
    for (const FrictionContact& fc : scene.friction) {
      fkind.push_back(static_cast<std::int64_t>(fc.kind));
      fmass.push_back(fc.mass);
      fother.push_back(fc.other);
      load.push_back(fc.normal_load);
      mu_s.push_back(fc.static_coefficient);
      mu_k.push_back(fc.kinetic_coefficient);
      famplitude.push_back(fc.amplitude);
      fphase.push_back(fc.phase);
      fname.push_back(fc.name);
    }
    c.push_back(integers("friction_kind", std::move(fkind), {q}, Type::i32));
    c.back().labels.emplace_back("names", std::vector<std::string>{"surface", "between"});
    c.push_back(integers("friction_mass", std::move(fmass), {q}));
    c.push_back(integers("friction_other", std::move(fother), {q}));
    c.push_back(reals("friction_normal_load", std::move(load), {q}));
    c.push_back(reals("friction_static", std::move(mu_s), {q}));
    c.push_back(reals("friction_kinetic", std::move(mu_k), {q}));
    c.push_back(reals("friction_amplitude", std::move(famplitude), {q}));
    c.push_back(reals("friction_phase", std::move(fphase), {q}));
    c.push_back(texts("friction_name", std::move(fname)));
  }
  c.push_back(vector_dataset("x0", scene.x0));
  c.push_back(vector_dataset("v0", scene.v0));
  return c;
}

std::vector<std::pair<std::string, double>> scene_numbers(const Scene& scene) {
  return {{"frequency", scene.forcing().frequency},
          {"t0", scene.t0},
          {"transient_periods", scene.run.transient_periods},
          {"periods", scene.run.periods},
          {"follow", scene.run.follow ? 1.0 : 0.0},
          {"reverse", scene.run.reverse ? 1.0 : 0.0}};
}

/// The solver tolerances, written to /meta (and compared on resume); max_events is the one
/// integer among them (stored as i64, compared here as a double: exact below 2^53).
std::vector<std::pair<std::string, double>> tolerances(const SimulatorOptions& o) {
  return {{"trigger", o.trigger},
          {"simultaneity", o.simultaneity},
          {"chatter_height", o.chatter_height},
          {"chatter_velocity", o.chatter_velocity},
          {"contact_velocity", o.contact_velocity},
          {"max_events", static_cast<double>(o.max_events)},
          {"event_window", o.event_window},
          {"length_scale", o.length_scale},
          {"flow_max_condition", o.flow.max_condition}};
}

const char* status_name(RunStatus status) {
  switch (status) {
    case RunStatus::completed: return "completed";
    case RunStatus::event_cap: return "event_cap";
    case RunStatus::numerical_failure: return "numerical_failure";
    case RunStatus::unsupported: return "unsupported";
    case RunStatus::interrupted: return "interrupted";
  }
  return "?";
}

const std::vector<std::string>& count_names() {
  static const std::vector<std::string> names{"impacts",  "sticks",   "releases",
                                              "chatters", "segments", "contact_sets_built",
                                              "sticking_flows_built"};
  return names;
}

std::vector<std::int64_t> counts(const RunSummary& s) {
  return {s.impacts,
          s.sticks,
          s.releases,
          s.chatters,
          s.segments,
          static_cast<std::int64_t>(s.contact_sets_built),
          static_cast<std::int64_t>(s.sticking_flows_built)};
}

}  // namespace detail

ResultFile::Impl::Impl(std::unique_ptr<detail::OutputLock> output_lock, std::string final_path, std::string file,
     Store::Mode mode, const Scene& scene)
    : lock(std::move(output_lock)),
      path(std::move(final_path)),
      partial(partial_path(path)),
      file_name(std::move(file)),
      store(file_name, mode),
      record(scene.record),
      sweep_run(scene.run.kind == RunSpec::Kind::sweep),
      dof(scene.dof()),
      stops(detail::stop_names(scene)),
      compliant(has_compliant(scene.stops)),
      friction(!scene.friction.empty()) {}

void ResultFile::Impl::write_scene(const Scene& scene) const {
  store.create_group("/scene");
  store.set_text("/scene", "yaml", scene.yaml_text);
  store.set_text("/scene", "file", scene.file);
  store.set_text("/scene", "name", scene.name);
  store.set_text("/scene", "run_kind",
                 to_string(scene.run.kind));
  store.set_real("/scene", "period", scene.period());
  if (!scene.restart.empty()) store.set_text("/scene", "restart", scene.restart);  // only where used
  if (!scene.forces.forces.empty()) {  // only where present: linear scenes' files stay as they were
    for (std::size_t i = 0; i < scene.forces.forces.size(); ++i)
      if (!scene.forces.forces[i].empty()) store.set_text("/scene", "force_" + std::to_string(i), scene.forces.forces[i]);
    for (const auto& [name, value] : scene.forces.parameters) store.set_real("/scene", "parameter_" + name, value);
  }
  for (const auto& [name, value] : detail::scene_numbers(scene)) store.set_real("/scene", name, value);
  for (const Dataset& c : detail::scene_datasets(scene)) {
    detail::require_finite(store.name(), "/scene/" + c.name, c);
    store.write("/scene/" + c.name, c);
  }
}

void ResultFile::Impl::write_meta(const RunMeta& meta, const Scene& scene) const {
  store.create_group("/meta");
  store.set_text("/meta", "version", meta.version);
  store.set_text("/meta", "git_commit", meta.git_commit);
  store.set_text("/meta", "date", meta.date);
  store.set_text("/meta", "compiler", meta.compiler);
  store.set_integer("/meta", "threads", meta.threads);
  for (const auto& [name, value] : detail::tolerances(scene.solver))
    if (name == "max_events")
      store.set_integer("/meta", name, scene.solver.max_events);
    else
      store.set_real("/meta", name, value);
  store.set_text("/meta", "flow_method", detail::flow_method_name(scene.solver.flow.method));
  store.set_text("/meta", "chatter_rule", to_string(scene.solver.chatter_rule));
  store.set_text("/meta", "engine", to_string(scene.engine));
  if (scene.base) store.set_text("/meta", "frame", scene.record.frame == BaseFrame::relative ? "relative" : "absolute");
  store.set_text("/meta", "engine_choice", to_string(scene.engine_choice));
  store.set_text("/meta", "status", "running");
  store.set_text("/meta", "message", "");
  store.set_integer("/meta", "resumed", 0);
}

ResultFile::ResultFile(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ResultFile::ResultFile(ResultFile&&) noexcept = default;
ResultFile& ResultFile::operator=(ResultFile&&) noexcept = default;

ResultFile::~ResultFile() {
  if (!impl_ || impl_->finished) return;
  try {
    impl_->store.close();
  } catch (...) {
    // Nothing better to do in a destructor; the file is abandoned either way.
  }
  if (!impl_->keep_unfinished && !impl_->in_memory) std::remove(impl_->file_name.c_str());
}

ResultFile ResultFile::create(const std::string& path, const Scene& scene, const RunMeta& meta, bool overwrite) {
  const std::string partial = partial_path(path);
  auto lock = std::make_unique<detail::OutputLock>(path, scene.file, overwrite);
  lock->discard_stale_partial(scene.run.kind == RunSpec::Kind::sweep);
  ResultFile file(std::make_unique<Impl>(std::move(lock), path, partial, detail::Store::Mode::create, scene));
  Impl& f = *file.impl_;  // from here on, a failure removes the new file
  f.write_scene(scene);
  f.write_meta(meta, scene);
  f.commit();
  f.keep_unfinished = f.sweep_run;
  return file;
}

ResultFile ResultFile::create_in_memory(const Scene& scene, const RunMeta& meta) {
  const std::string name = detail::Store::memory_name("memory");
  ResultFile file(std::make_unique<Impl>(nullptr, name, name, detail::Store::Mode::memory, scene));
  Impl& f = *file.impl_;
  f.in_memory = true;
  f.write_scene(scene);
  f.write_meta(meta, scene);
  f.commit();
  return file;
}

std::vector<char> ResultFile::image() const {
  return impl_->finished ? impl_->final_image : impl_->store.image();
}

void ResultFile::write_group(const std::string& group, const std::vector<Dataset>& datasets,
                             const std::vector<std::pair<std::string, std::string>>& attributes) {
  Impl& f = *impl_;
  if (f.sweep_run) throw std::logic_error("results: write_group on a sweep");
  const std::string path = "/" + group;
  for (const Dataset& d : datasets) detail::require_finite(f.store.name(), path + "/" + d.name, d);
  f.store.create_group(path);
  for (const Dataset& d : datasets) f.store.write(path + "/" + d.name, d);
  for (const auto& [name, text] : attributes) f.store.set_text(path, name, text);
  f.store.flush();
}

void ResultFile::set_outcome(const std::string& status, const std::string& message,
                             const std::vector<std::pair<std::string, std::int64_t>>& counts) {
  Impl& f = *impl_;
  f.status = status;
  f.message = message;
  for (const auto& [name, value] : counts) f.store.set_integer("/meta", name, value);
  f.simulation_written = true;  // finish() may now complete the file
}

void ResultFile::finish(const RunMeta& meta) {
  Impl& f = *impl_;
  if (f.finished) throw std::logic_error("results: finish called twice");
  if (f.sweep_run) {
    if (!f.sweep_begun || f.completed != f.total)
      throw std::logic_error("results: finish: the sweep has " + std::to_string(f.completed) +
                             " of " + std::to_string(f.total) + " points");
    f.sum_sweep();
  } else if (!f.simulation_written) {
    throw std::logic_error("results: finish before write_simulation");
  }
  f.store.set_text("/meta", "status", f.status);
  f.store.set_text("/meta", "message", f.message);
  f.store.set_real("/meta", "wall_time", meta.wall_seconds);
  f.store.set_integer("/meta", "threads", meta.threads);
  f.store.flush();
  if (f.in_memory) f.final_image = f.store.image();
  f.store.close();
  f.finished = true;  // closed: from here on the destructor leaves the file alone
  if (f.in_memory) return;
  try {
    f.lock->publish(f.partial);
  } catch (const ResultError&) {
    if (!f.keep_unfinished) std::remove(f.partial.c_str());  // a sweep's stays, for --resume
    f.lock.reset();
    throw;
  }
  f.lock.reset();  // released and removed: the file is complete
}

const std::string& ResultFile::path() const { return impl_->path; }

}  // namespace vibro::io
