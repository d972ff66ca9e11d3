#include "vibro/io/kinds/basin.hpp"

#include "kinds.hpp"
#include "../run_section.hpp"

#include "../datasets.hpp"
#include "../mpi_world.hpp"
#include "../progress.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/io/result_file.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#ifdef VIBRO_WITH_MPI
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>

namespace vibro::io {
namespace {

using detail::integers;
using detail::reals;

constexpr std::int64_t kNotConverged = -1;
constexpr std::int64_t kStoppedEarly = -2;
constexpr std::int64_t kNotRun = -3;  ///< the run was interrupted before this point
constexpr std::int64_t kInadmissible = -4;  ///< the start lies outside a stop: not run
/// A period-k repeat counts only if no proper divisor q of k repeats to kDistinct × tolerance
/// (as in running_orbit.cpp: a period-1 orbit approached with a multiplier near −1 passes k = 2 first).
constexpr double kDistinct = 1e3;

/// A periodic attractor: its period k and its k stroboscopic states z = (x, v), in time order.
struct Attractor {
  int k = 0;
  std::vector<Eigen::VectorXd> z;
};

/// What one grid point's run ended on.
struct PointResult {
  enum class Outcome : std::int64_t { matched = 0, found = 1, not_converged = 2, stopped = 3, not_run = 4,
                                      inadmissible = 5 };
  Outcome outcome = Outcome::not_run;
  long periods = 0;
  int attractor = -1;  ///< matched: the catalogue index
  Attractor orbit;     ///< found: the new attractor
  RunStatus status = RunStatus::completed;
  std::string message;  ///< stopped: why
};

struct Scales {
  double L = 1.0, V = 1.0;
  Eigen::Index n = 0;
};

double distance(const Eigen::VectorXd& a, const Eigen::VectorXd& b, const Scales& s) {
  const Eigen::Index n = s.n;
  return std::max((a.head(n) - b.head(n)).cwiseAbs().maxCoeff() / s.L,
                  (a.tail(n) - b.tail(n)).cwiseAbs().maxCoeff() / s.V);
}

/// The index of the point of `a` within `match` of z, or −1.
int nearest_point(const Attractor& a, const Eigen::VectorXd& z, const Scales& s, double match) {
  for (int j = 0; j < a.k; ++j)
    if (distance(z, a.z[static_cast<std::size_t>(j)], s) <= match) return j;
  return -1;
}

/// Runs one start until it is on a known attractor, repeats (a new one), or the budget ends.
PointResult run_point(Engine& engine, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                      double T, long min_periods, const BasinSpec& spec, const std::vector<Attractor>& known,
                      const Scales& scales) {
  PointResult result;
  const Eigen::Index n = x0.size();
  std::deque<Eigen::VectorXd> history;  // the last max_period + 1 states
  Eigen::VectorXd z(2 * n);
  z << x0, v0;
  history.push_back(z);
  Eigen::VectorXd x = x0, v = v0;
  int streak = 0, on = -1, at = -1;  // consecutive matches of attractor `on`, last at its point `at`
  for (long p = 1; p <= spec.max_periods; ++p) {
    const RunSummary s = engine.run(t0 + static_cast<double>(p - 1) * T, x, v, t0 + static_cast<double>(p) * T);
    result.periods = p;
    if (s.status != RunStatus::completed) {
      result.outcome = PointResult::Outcome::stopped;
      result.status = s.status;
      result.message = s.message;
      return result;
    }
    x = s.x;
    v = s.v;
    z << x, v;
    history.push_back(z);
    if (history.size() > static_cast<std::size_t>(spec.max_period) + 1) history.pop_front();
    if (p < min_periods) continue;
    // On a known attractor: k + 1 consecutive points, each within `match` of the next point of it.
    bool matched = false;
    for (std::size_t a = 0; a < known.size() && !matched; ++a) {
      const int j = nearest_point(known[a], z, scales, spec.match);
      if (j < 0) continue;
      matched = true;
      const bool follows = streak > 0 && on == static_cast<int>(a) && j == (at + 1) % known[a].k;
      streak = follows ? streak + 1 : 1;
      on = static_cast<int>(a);
      at = j;
    }
    if (!matched) streak = 0;
    if (matched && streak > known[static_cast<std::size_t>(on)].k) {
      result.outcome = PointResult::Outcome::matched;
      result.attractor = on;
      return result;
    }
    // A repeat: a new attractor (or a known one not yet matched; the catalogue merges them).
    std::vector<double> d(history.size(), 0.0);  // d[k] = |z_p − z_{p−k}|
    for (std::size_t k = 1; k < history.size(); ++k) {
      d[k] = distance(z, history[history.size() - 1 - k], scales);
      if (d[k] > spec.tolerance) continue;
      bool distinct = true;
      for (std::size_t q = 1; q < k; ++q)
        if (k % q == 0 && d[q] <= kDistinct * spec.tolerance) distinct = false;
      if (!distinct) break;
      result.outcome = PointResult::Outcome::found;
      result.orbit.k = static_cast<int>(k);
      result.orbit.z.assign(history.end() - static_cast<std::ptrdiff_t>(k), history.end());
      return result;
    }
  }
  result.outcome = PointResult::Outcome::not_converged;
  return result;
}

/// The catalogue index of `a`: an attractor already there (same period, a point within `match`)
/// or `a` appended.
int catalogue_index(std::vector<Attractor>& catalogue, const Attractor& a, const Scales& s, double match) {
  for (std::size_t i = 0; i < catalogue.size(); ++i)
    if (catalogue[i].k == a.k && nearest_point(catalogue[i], a.z.front(), s, match) >= 0) return static_cast<int>(i);
  catalogue.push_back(a);
  return static_cast<int>(catalogue.size()) - 1;
}

/// A point's result as numbers (for MPI): outcome, periods, attractor, status, k, then k states.
[[maybe_unused]] std::vector<double> encode(const PointResult& r) {
  std::vector<double> out{static_cast<double>(r.outcome), static_cast<double>(r.periods),
                          static_cast<double>(r.attractor), static_cast<double>(r.status),
                          static_cast<double>(r.orbit.k)};
  for (const Eigen::VectorXd& z : r.orbit.z) out.insert(out.end(), z.data(), z.data() + z.size());
  return out;
}

[[maybe_unused]] PointResult decode(const double* in, Eigen::Index n, std::size_t& used) {
  PointResult r;
  r.outcome = static_cast<PointResult::Outcome>(static_cast<std::int64_t>(in[0]));
  r.periods = static_cast<long>(in[1]);
  r.attractor = static_cast<int>(in[2]);
  r.status = static_cast<RunStatus>(static_cast<int>(in[3]));
  r.orbit.k = static_cast<int>(in[4]);
  used = 5;
  for (int j = 0; j < r.orbit.k; ++j) {
    r.orbit.z.emplace_back(Eigen::Map<const Eigen::VectorXd>(in + used, 2 * n));
    used += static_cast<std::size_t>(2 * n);
  }
  if (r.outcome == PointResult::Outcome::stopped) r.message = to_string(r.status);
  return r;
}

/// Gathers every rank's results (point i computed on rank i mod size) on every rank, in grid order.
void gather(std::vector<PointResult>& results, const std::vector<std::size_t>& points, Eigen::Index n, int rank,
            int size) {
#ifdef VIBRO_WITH_MPI
  if (size == 1) return;
  std::vector<double> mine;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (static_cast<int>(i % static_cast<std::size_t>(size)) == rank) {
      const std::vector<double> e = encode(results[points[i]]);
      mine.insert(mine.end(), e.begin(), e.end());
    }
  int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(size)), offsets(static_cast<std::size_t>(size), 0);
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  for (int r = 1; r < size; ++r)
    offsets[static_cast<std::size_t>(r)] = offsets[static_cast<std::size_t>(r - 1)] + counts[static_cast<std::size_t>(r - 1)];
  std::vector<double> all(static_cast<std::size_t>(offsets.back() + counts.back()));
  MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  std::vector<std::size_t> cursor(offsets.begin(), offsets.end());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::size_t r = i % static_cast<std::size_t>(size);
    std::size_t used = 0;
    results[points[i]] = decode(all.data() + cursor[r], n, used);
    cursor[r] += used;
  }
#else
  (void)results, (void)points, (void)n, (void)rank, (void)size;
#endif
}

}  // namespace

RunReport run_basin(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  const auto wall_start = std::chrono::steady_clock::now();
  // Named variables, not a structured binding: lambdas below capture them, which clang 14 (the
  // sanitize preset's compiler) does not allow for bindings.
  const auto this_world = detail::world();
  const int rank = this_world.first, ranks = this_world.second;
  const SweepAxis& rows = scene.run.axes.at(0);
  const SweepAxis& cols = scene.run.axes.at(1);
  const BasinSpec& spec = scene.run.basin;
  const std::size_t n1 = rows.values.size(), n2 = cols.values.size(), total = n1 * n2;
  const double T = scene.period();
  const long min_periods = static_cast<long>(std::ceil(scene.run.transient_periods));
  const bool initial_only = rows.path.rfind("initial.", 0) == 0 && cols.path.rfind("initial.", 0) == 0;

  // Fixed scales for every distance: those of one period from the scene's own start.
  Scales scales;
  scales.n = scene.dof();
  {
    Scene base = scene;
    base.solver.interrupt = request.interrupt;
    const RunSummary s = make_engine(base)->run(scene.t0, scene.x0, scene.v0, scene.t0 + T);
    if (s.length_scale > 0.0) scales.L = s.length_scale;
    if (s.velocity_scale > 0.0) scales.V = s.velocity_scale;
  }

  std::optional<ResultFile> file;
  if (rank == 0) file.emplace(open_result_file(request, scene, current_meta(request.threads)));

  int threads = 1;
#ifdef _OPENMP
  if (request.threads > 0) omp_set_num_threads(request.threads);
  threads = omp_get_max_threads();
#endif
  std::vector<PointResult> results(total);
  std::vector<Attractor> catalogue;
  const int stride = spec.seed_stride;
  std::vector<std::size_t> seeds, rest;
  for (std::size_t i = 0; i < n1; ++i)
    for (std::size_t j = 0; j < n2; ++j)
      (i % static_cast<std::size_t>(stride) == 0 && j % static_cast<std::size_t>(stride) == 0 ? seeds : rest)
          .push_back(i * n2 + j);

  // Progress: rank 0 shows its own share of the points.
  std::size_t mine = 0;
  for (const std::vector<std::size_t>* list : {&seeds, &rest})
    for (std::size_t i = 0; i < list->size(); ++i)
      if (static_cast<int>(i % static_cast<std::size_t>(ranks)) == rank) ++mine;
  const RunRequest silent;
  detail::Progress progress(rank == 0 ? request : silent, "basin", "points", static_cast<double>(mine));

  // One pass over `points` (this rank's share), against the frozen catalogue `known`.
  auto pass = [&](const std::vector<std::size_t>& points, const std::vector<Attractor>& known) {
    std::exception_ptr failure;
    std::mutex lock;
#ifdef _OPENMP
#pragma omp parallel
#endif
    {
      SceneDocument point(doc);  // one copy per thread, its two values replaced per point
      std::unique_ptr<Engine> engine;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 4)
#endif
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (static_cast<int>(i % static_cast<std::size_t>(ranks)) != rank) continue;
        if (request.interrupt && request.interrupt->load()) continue;
        try {
          const std::size_t g = points[i];
          point.set(rows.path, rows.values[g / n2]);
          point.set(cols.path, cols.values[g % n2]);
          std::optional<Scene> made;
          try {
            made.emplace(point.build_point());
          } catch (const SceneError& e) {
            if (!detail::inadmissible_start(e)) throw;
            results[g].outcome = PointResult::Outcome::inadmissible;  // labelled, not run
            progress.add();
            continue;
          }
          Scene& built = *made;
          built.solver.interrupt = request.interrupt;
          if (!engine || !initial_only) engine = make_engine(built);
          results[g] = run_point(*engine, built.t0, built.x0, built.v0, T, min_periods, spec, known, scales);
          progress.add();
        } catch (const Interrupted&) {  // in the set-up of the point's engine (bounded_wait.hpp): not run (-3)
        } catch (...) {
          const std::lock_guard<std::mutex> hold(lock);
          if (!failure) failure = std::current_exception();
        }
      }
    }
    if (failure) std::rethrow_exception(failure);
    gather(results, points, scales.n, rank, ranks);
  };
  auto collect = [&](const std::vector<std::size_t>& points) {
    for (std::size_t g : points)
      if (results[g].outcome == PointResult::Outcome::found) {
        results[g].attractor = catalogue_index(catalogue, results[g].orbit, scales, spec.match);
        results[g].outcome = PointResult::Outcome::matched;
      }
  };
  pass(seeds, catalogue);
  collect(seeds);
  pass(rest, catalogue);
  collect(rest);
  if (rank != 0) return {};

  // The image and the attractors.
  std::vector<std::int64_t> label(total), periods(total), cells(catalogue.size(), 0);
  long not_converged = 0, stopped = 0, inadmissible = 0;
  long long periods_total = 0;
  std::string message;
  for (std::size_t g = 0; g < total; ++g) {
    const PointResult& r = results[g];
    periods[g] = r.periods;
    periods_total += r.periods;
    if (r.outcome == PointResult::Outcome::matched) {
      label[g] = r.attractor;
      ++cells[static_cast<std::size_t>(r.attractor)];
    } else if (r.outcome == PointResult::Outcome::not_converged) {
      label[g] = kNotConverged;
      ++not_converged;
    } else if (r.outcome == PointResult::Outcome::not_run) {
      label[g] = kNotRun;
    } else if (r.outcome == PointResult::Outcome::inadmissible) {
      label[g] = kInadmissible;
      ++inadmissible;
    } else {
      label[g] = kStoppedEarly;
      ++stopped;
      if (message.empty())
        message = fmt::format("at {} = {:.12g}, {} = {:.12g}: {}", rows.path, rows.values[g / n2], cols.path,
                              cols.values[g % n2], r.message);
    }
  }
  std::vector<std::int64_t> period, first;
  std::vector<double> ax, av;
  std::int64_t row = 0;
  const Eigen::Index n = scales.n;
  for (const Attractor& a : catalogue) {
    period.push_back(a.k);
    first.push_back(row);
    row += a.k;
    for (const Eigen::VectorXd& z : a.z) {
      ax.insert(ax.end(), z.data(), z.data() + n);
      av.insert(av.end(), z.data() + n, z.data() + 2 * n);
    }
  }
  Dataset labels = integers("label", label);
  labels.shape = {n1, n2};
  labels.labels.emplace_back("codes", std::vector<std::string>{
                                          "-1: not converged within run.basin.max_periods (chaotic, quasi-periodic or slow)",
                                          "-2: the run stopped early (/meta message)",
                                          "-3: not run (the basin was interrupted)",
                                          "-4: not run: the start lies outside a stop"});
  Dataset used = integers("periods_used", periods);
  used.shape = {n1, n2};
  const double mean_periods = static_cast<double>(periods_total) / static_cast<double>(total);
  file->write_group("basin",
                    {labels, used, reals("p1", rows.values, {n1}), reals("p2", cols.values, {n2})},
                    {{"p1", rows.path}, {"p2", cols.path}, {"mean_periods", fmt::format("{:.6g}", mean_periods)},
                     {"length_scale", fmt::format("{:.17g}", scales.L)},
                     {"velocity_scale", fmt::format("{:.17g}", scales.V)}});
  const std::size_t rows_out = static_cast<std::size_t>(row), dof = static_cast<std::size_t>(n);
  file->write_group("attractors", {integers("period", period), integers("first", first), integers("cells", cells),
                                   reals("x", ax, {rows_out, dof}), reals("v", av, {rows_out, dof})});

  const bool interrupted = request.interrupt && request.interrupt->load();
  file->set_outcome(interrupted ? "interrupted" : stopped ? "points_stopped_early" : "completed",
                    interrupted ? "interrupted: the points not run are labelled -3, those cut short -2" : message,
                    {{"points", static_cast<std::int64_t>(total)},
                     {"attractors", static_cast<std::int64_t>(catalogue.size())},
                     {"points_not_converged", not_converged},
                     {"points_stopped_early", stopped},
                     {"points_inadmissible", inadmissible},
                     {"periods_total", static_cast<std::int64_t>(periods_total)}});
  const double wall = detail::finish_run((*file), threads * ranks, wall_start);

  std::string text = fmt::format(
      "Basin of {} x {} = {} points ({} x {}) on {} threads x {} processes in {:.2f} s ({:.1f} points/s): "
      "{} attractors, mean {:.1f} periods per point\n",
      n1, n2, total, rows.path, cols.path, threads, ranks, wall, static_cast<double>(total) / wall, catalogue.size(),
      mean_periods);
  for (std::size_t a = 0; a < catalogue.size(); ++a)
    text += fmt::format("  attractor {}: period {}, {} points ({:.1f} %), x = [{}]\n", a, catalogue[a].k, cells[a],
                        100.0 * static_cast<double>(cells[a]) / static_cast<double>(total),
                        fmt::join(std::vector<double>(catalogue[a].z.front().data(), catalogue[a].z.front().data() + n), ", "));
  if (not_converged > 0)
    text += fmt::format("  {} points not converged within {} periods (label -1)\n", not_converged, spec.max_periods);
  if (stopped > 0) text += fmt::format("  {} points stopped early (label -2): {}\n", stopped, message);
  if (inadmissible > 0)
    text += fmt::format("  {} starts outside a stop, not run (label -4)\n", inadmissible);
  const auto not_run = std::count(label.begin(), label.end(), kNotRun);
  if (not_run > 0) text += fmt::format("  {} points not run: interrupted (label -3)\n", not_run);
  text += fmt::format("Results in {}.", file->path());
  return {interrupted ? 130 : stopped ? 1 : 0, text, request.in_memory ? file->image() : std::vector<char>{}};
}

}  // namespace vibro::io

namespace vibro::io::detail {
namespace {

/// run.basin (docs/scenes.md).
void parse_basin_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  const YAML::Node bs = s.node;
  if (bs && s.full) {
    BasinSpec& b = run.basin;
    r.expect_map(bs, "run.basin", {"parameters", "max_period", "max_periods", "tolerance", "match", "seed_stride"});
    const YAML::Node ps = bs["parameters"];
    if (!ps || !ps.IsSequence() || ps.size() != 2)
      r.fail(ps ? ps : bs, "run.basin.parameters",
             "expected a list of two parameters (the image's rows and columns), found " + (ps ? describe(ps) : std::string("nothing")));
    for (std::size_t a = 0; a < 2; ++a)
      run.axes.push_back(s.axis(ps[a], "run.basin.parameters[" + std::to_string(a) + "]", run.axes, {}));
    if (bs["max_period"]) b.max_period = static_cast<int>(r.integer(bs["max_period"], "run.basin.max_period", 1, 64));
    if (bs["max_periods"]) b.max_periods = r.integer(bs["max_periods"], "run.basin.max_periods", 2, 100000000);
    if (b.max_periods < b.max_period + 1)
      r.fail(bs["max_periods"] ? bs["max_periods"] : bs, "run.basin.max_periods",
             "expected at least max_period + 1 = " + std::to_string(b.max_period + 1) +
                 " periods (a period-k orbit is recognised after k + 1)");
    if (bs["tolerance"]) b.tolerance = r.number_in(bs["tolerance"], "run.basin.tolerance", 1e-15, 1e-2, "a relative tolerance in [1e-15, 1e-2]");
    if (bs["match"]) b.match = r.number_in(bs["match"], "run.basin.match", 1e-15, 1e-1, "a relative distance in [1e-15, 0.1]");
    if (b.match < b.tolerance)
      r.fail(bs["match"] ? bs["match"] : bs, "run.basin.match",
             "must not be below run.basin.tolerance (" +
                 (bs["tolerance"] ? bs["tolerance"].Scalar() : number_text(b.tolerance)) +
                 "): a run that repeats within the tolerance must also match its attractor");
    if (bs["seed_stride"]) b.seed_stride = static_cast<int>(r.integer(bs["seed_stride"], "run.basin.seed_stride", 1, 1000000));
    for (std::size_t a = 0; a < 2; ++a)
      s.check_values(run.axes[a], ps[a], "run.basin.parameters[" + std::to_string(a) + "]", true);
    if (!(s.frequency > 0.0))
      r.fail(s.run_node["kind"], "run.kind", "a basin compares stroboscopic points: it needs a forcing frequency > 0 (forcing.frequency)");
  }
}

}  // namespace

RunKindInfo basin_kind() {
  RunKindInfo k;
  k.name = "basin";
  k.kind = RunSpec::Kind::basin;
  k.summary = "basins of attraction over a 2-D grid of two scene values";
  k.section = "basin";
  k.missing = "missing: run.kind: basin needs run.basin.parameters (two scene values and their grids)";
  k.groups = {"basin", "attractors"};
  k.every_process = true;
  k.stoppable = true;
  k.parse = parse_basin_section;
  k.run = run_basin;
  return k;
}

}  // namespace vibro::io::detail
