// vibro: the command-line front end. Scenes in (YAML), results out (HDF5).
//
//   vibro run SCENE [-o OUT.h5] [--set PATH=VALUE ...] [--threads N] [--resume] [--force]
//   vibro check SCENE [--set PATH=VALUE ...]
//   vibro info SCENE [--set PATH=VALUE ...]
//
// Exit codes: 0 success, 1 a run stopped early (event cap, numerical failure), 2 bad input (the
// scene, a --set, or the command's own arguments: a missing scene, an unknown option, a value
// that is not a number), 3 the result file could not be written (or exists: --force), 4 not
// enough memory or threads for this run, or too much work (the message gives the numbers), 5 an internal error
// (a bug: please report it), 130 interrupted (a sweep keeps OUT.partial). Every failure is one
// line on stderr, "error: …"; no exception ever leaves main().
#include "info.hpp"

#include "vibro/io/resources.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "vibro/io/signals.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <unistd.h>

#include <charconv>
#include <cstdio>
#include <exception>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

std::string resolved(const vibro::io::Scene& s) {
  std::string out = fmt::format("scene {} is valid\n", s.file);
  out += fmt::format("  degrees of freedom: {}, stops: {}\n", s.dof(), s.stops.size());
  out += fmt::format("  engine: {} ({})\n", to_string(s.engine), s.engine_reason);
  out += fmt::format("  forcing frequency: {:.12g} (period {:.12g})\n", s.forcing().frequency, s.period());
  out += fmt::format("  initial: t = {:.12g}\n", s.t0);
  const auto& o = s.solver;
  out += fmt::format("  solver: trigger {:g}, simultaneity {:g}, chatter_height {:g}, chatter_velocity {:g}, "
                     "contact_velocity {:g}, max_events {}, event_window {:g}, length_scale {:g}\n",
                     o.trigger, o.simultaneity, o.chatter_height, o.chatter_velocity, o.contact_velocity,
                     o.max_events, o.event_window, o.length_scale);
  const auto& r = s.record;
  out += fmt::format("  record: events {}, contacts {}, statistics {}, poincare {}, samples {}\n", r.events,
                     r.contacts, r.statistics, r.poincare,
                     r.samples_per_period ? fmt::format("{} per period", r.samples_per_period)
                                          : fmt::format("{} times", r.sample_times.size()));
  out += fmt::format("  run: {}, transient {:g} periods, recorded {:g} periods\n",
                     vibro::io::to_string(s.run.kind),
                     s.run.transient_periods, s.run.periods);
  for (const auto& a : s.run.axes)
    out += fmt::format("  sweep {}: {} values from {:.12g} to {:.12g}{}\n", a.path, a.values.size(),
                       a.values.front(), a.values.back(), s.run.follow ? " (following)" : "");
  return out;
}

/// Units of work a run can spread over threads: a sweep's points (a followed 1-D sweep is one
/// chain, a followed 2-D sweep one per row), a locate scan's grid steps; else one.
std::size_t sweep_units(const vibro::io::Scene& s) {
  const auto& axes = s.run.axes;
  if (axes.empty()) return 1;
  if (s.run.kind == vibro::io::RunSpec::Kind::locate) return axes[0].values.size();
  if (s.run.follow) return axes.size() == 1 ? 1 : axes[0].values.size();
  return axes[0].values.size() * (axes.size() > 1 ? axes[1].values.size() : 1);
}

/// The exit codes (the top of this file), for --help.
constexpr const char* kExitCodes =
    "Exit codes: 0 success, 1 the run stopped early (event cap, numerical failure), 2 bad input (scene, --set or\n"
    "arguments), 3 the result file cannot be written, 4 not enough memory or threads, or too much work, 5\n"
    "internal error, 130 interrupted. Every failure is one line on stderr starting with \"error:\".\n";

/// An error in the command's own arguments (exit code 2).
struct ArgumentError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// --threads N as typed: a whole number ≥ 0 (0: all cores). Throws ArgumentError for
/// anything else (a sign, a fraction, text) and ResourceError, with the number as typed, above
/// kMaxThreads (resources.hpp), so that a 20-digit count neither wraps nor prints a bound of
/// hundreds of digits.
int parse_threads(const std::string& text) {
  int value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  const bool digits = !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || (ec != std::errc() && ec != std::errc::result_out_of_range) || ptr != end)
    throw ArgumentError("--threads " + text + ": expected a whole number of threads ≥ 0 (0: all cores)");
  if (ec == std::errc::result_out_of_range || value > vibro::io::kMaxThreads)
    throw vibro::io::ResourceError(fmt::format("--threads {}: at most {} threads", text, vibro::io::kMaxThreads));
  return value;
}

/// One line for an argument error: CLI11's text without its own newlines.
std::string one_line(std::string text) {
  for (char& c : text)
    if (c == '\n' || c == '\r') c = ' ';
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

}  // namespace

int run_command(int argc, char** argv);

int main(int argc, char** argv) {
  // The one place where any failure becomes a message and an exit code (see the top).
  try {
    return run_command(argc, argv);
  } catch (const std::bad_alloc&) {
    std::fputs("error: out of memory (an allocation failed; the run's estimate did not foresee it: please report "
               "the scene)\n", stderr);
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: internal error (please report it with the scene): %s\n", e.what());
    return 5;
  } catch (...) {
    std::fputs("error: internal error (an unknown exception; please report it with the scene)\n", stderr);
    return 5;
  }
}

int run_command(int argc, char** argv) {
  // Under `mpirun -np K` (a build with MPI) every process runs this; rank 0 alone prints.
  const vibro::io::ProcessGroup processes(argc, argv);
  const bool speaks = processes.rank() == 0;
  CLI::App app{"vibro — exact simulation of vibro-impact systems.\n"
               "Examples:\n"
               "  vibro run experiments/wagg2004/fig2_sticking_orbit.yaml -o fig2.h5\n"
               "  vibro run experiments/examples/three_mass_sweep.yaml -o sweep.h5 --threads 2\n"
               "  vibro run sweep.yaml -o sweep.h5 --resume       # finish an interrupted sweep\n"
               "  vibro info experiments/wagg2004/fig2_sticking_orbit.yaml\n"
               "  vibro check experiments/wagg2004/fig2_sticking_orbit.yaml --set forcing.frequency=0.26\n",
               "vibro"};
  app.require_subcommand(1);
  app.footer(kExitCodes);
  std::string scene_path;
  std::vector<std::string> sets;

  std::string output;
  int threads_requested = 0;
  std::string threads_text;
  bool resume = false;
  bool force = false;
  CLI::App* run = app.add_subcommand("run", "Simulate a scene (or sweep it) and write an HDF5 result file");
  run->add_option("scene", scene_path, "scene file (YAML)")->required();
  run->add_option("-o,--output", output, "result file (default: the scene's name with .h5, in the current folder)");
  run->add_option("--set", sets, "override a value: PATH=VALUE (repeatable)");
  run->add_option("--threads", threads_text, "threads for sweeps (default, or 0: all cores; at most 1024)");
  run->add_flag("--resume", resume, "finish an interrupted sweep from OUT.partial");
  run->add_flag("--force", force, "replace an existing OUT (and a stale OUT.partial); never the scene file");

  CLI::App* check = app.add_subcommand("check", "Validate a scene and print it resolved");
  check->add_option("scene", scene_path, "scene file (YAML)")->required();
  check->add_option("--set", sets, "override a value: PATH=VALUE (e.g. stops[1].position=0.12)");

  CLI::App* info = app.add_subcommand("info", "Natural frequencies, modal damping, stops, contact sets");
  info->add_option("scene", scene_path, "scene file (YAML)")->required();
  info->add_option("--set", sets, "override a value: PATH=VALUE");

  // Argument errors are bad input (exit code 2) in one "error:" line; --help prints the usage.
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    if (speaks) std::fprintf(stderr, "error: %s (vibro --help lists the arguments)\n", one_line(e.what()).c_str());
    return 2;
  }
  try {
    // `vibro run` answers SIGINT, SIGTERM and SIGHUP from here on, within a second in every phase
    // (vibro/io/signals.hpp): before the run kind starts, at once.
    std::optional<vibro::io::RunSignals> signals;
    if (run->parsed()) {
      if (output.empty()) {
        std::string base = scene_path.substr(scene_path.find_last_of('/') + 1);
        output = base.substr(0, base.find_last_of('.')) + ".h5";
      }
      signals.emplace(speaks ? "Interrupted before the run started: " + output + " was not written." : "");
    }
    if (!threads_text.empty()) threads_requested = parse_threads(threads_text);
    vibro::io::SceneDocument doc = vibro::io::SceneDocument::load(scene_path);
    for (std::size_t k = 0; k < sets.size(); ++k) doc.set_assignment(sets[k], static_cast<int>(k + 1));
    const vibro::io::Scene scene = doc.build();
    // Threads and memory are checked by `check` and `info` too: they say whether `run` can start.
    const int threads = vibro::io::checked_threads(threads_requested, sweep_units(scene));
    vibro::io::check_run_resources(scene, threads);
    if (const vibro::io::WorkEstimate work = vibro::io::estimate_run_work(scene);
        speaks && work.steps > vibro::io::kWarnSearchSteps)
      std::fprintf(stderr,
                   "warning: this run needs about %.3g steps of the certified event search (fastest rate up to %.3g per "
                   "time unit over %.3g time units): minutes to hours%s\n",
                   work.steps, work.rate, work.span, run->parsed() ? "; progress lines follow" : "");
    if (run->parsed()) {
      vibro::io::RunRequest request{output, threads, resume, isatty(STDERR_FILENO) == 1};
      request.progress_lines = speaks && !request.progress;  // a log: a line at each tenth of the run
      request.force = force;
      const vibro::io::RunReport report = vibro::io::run_scene(doc, scene, request);
      if (speaks) std::fprintf(stderr, "%s\n", report.summary.c_str());
      return report.exit_code;
    }
    if (!speaks) return 0;
    if (check->parsed()) std::fputs(resolved(scene).c_str(), stdout);
    if (info->parsed()) std::fputs(vibro::cli::describe_scene(scene).c_str(), stdout);
  } catch (const vibro::io::SceneError& e) {
    if (speaks) std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const vibro::InvalidInput& e) {
    if (speaks) std::fprintf(stderr, "error: %s: %s\n", scene_path.c_str(), e.what());
    return 2;
  } catch (const vibro::io::ResultError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());  // only rank 0 writes files
    return 3;
  } catch (const vibro::io::ResourceError& e) {
    if (speaks) std::fprintf(stderr, "error: %s: %s\n", scene_path.c_str(), e.what());
    return 4;
  } catch (const ArgumentError& e) {
    if (speaks) std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  return 0;
}
