// vibro: the command-line front end. Scenes in (YAML), results out (HDF5).
//
//   vibro run SCENE [-o OUT.h5] [--set PATH=VALUE ...] [--threads N] [--resume]
//   vibro check SCENE [--set PATH=VALUE ...]
//   vibro info SCENE [--set PATH=VALUE ...]
//
// Exit codes: 0 success, 1 the run stopped early (event cap, numerical failure), 2 bad input.
#include "info.hpp"

#include "vibro/io/scene.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <string>
#include <vector>

namespace {

vibro::io::Scene load(const std::string& path, const std::vector<std::string>& sets) {
  vibro::io::SceneDocument doc = vibro::io::SceneDocument::load(path);
  for (const std::string& s : sets) doc.set_assignment(s);
  return doc.build();
}

std::string resolved(const vibro::io::Scene& s) {
  std::string out = fmt::format("scene {} is valid\n", s.file);
  out += fmt::format("  degrees of freedom: {}, stops: {}\n", s.system.dof(), s.stops.size());
  out += fmt::format("  forcing frequency: {:.12g} (period {:.12g})\n", s.system.forcing().frequency, s.period());
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
                     s.run.kind == vibro::io::RunSpec::Kind::sweep ? "sweep" : "simulate",
                     s.run.transient_periods, s.run.periods);
  for (const auto& a : s.run.axes)
    out += fmt::format("  sweep {}: {} values from {:.12g} to {:.12g}{}\n", a.path, a.values.size(),
                       a.values.front(), a.values.back(), s.run.follow ? " (following)" : "");
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"vibro — exact simulation of vibro-impact systems.\n"
               "Examples:\n"
               "  vibro info experiments/wagg2004/fig2_sticking_orbit.yaml\n"
               "  vibro check experiments/wagg2004/fig2_sticking_orbit.yaml --set forcing.frequency=0.26\n",
               "vibro"};
  app.require_subcommand(1);
  std::string scene_path;
  std::vector<std::string> sets;

  CLI::App* check = app.add_subcommand("check", "Validate a scene and print it resolved");
  check->add_option("scene", scene_path, "scene file (YAML)")->required();
  check->add_option("--set", sets, "override a value: PATH=VALUE (e.g. stops[1].position=0.12)");

  CLI::App* info = app.add_subcommand("info", "Natural frequencies, modal damping, stops, contact sets");
  info->add_option("scene", scene_path, "scene file (YAML)")->required();
  info->add_option("--set", sets, "override a value: PATH=VALUE");

  CLI11_PARSE(app, argc, argv);
  try {
    const vibro::io::Scene scene = load(scene_path, sets);
    if (check->parsed()) std::fputs(resolved(scene).c_str(), stdout);
    if (info->parsed()) std::fputs(vibro::cli::describe_scene(scene).c_str(), stdout);
  } catch (const vibro::io::SceneError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const vibro::InvalidInput& e) {
    std::fprintf(stderr, "error: %s: %s\n", scene_path.c_str(), e.what());
    return 2;
  }
  return 0;
}
