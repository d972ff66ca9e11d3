#include "run_section.hpp"

namespace vibro::io::detail {

SweepAxis RunSection::axis(const YAML::Node& p, const std::string& path, const std::vector<SweepAxis>& others,
                           std::vector<std::string> keys) {
  keys.insert(keys.end(), {"path", "linspace", "logspace", "values"});
  r.expect_map(p, path, keys);
  if (!p["path"]) r.fail(p, path + ".path", "missing: the scene value to vary, e.g. forcing.frequency");
  SweepAxis axis;
  axis.path = r.text(p["path"], path + ".path");
  for (const SweepAxis& other : others)
    if (other.path == axis.path) r.fail(p["path"], path + ".path", "'" + axis.path + "' is swept twice");
  if (axis.path.rfind("run.", 0) == 0) r.fail(p["path"], path + ".path", "the run section cannot be swept");
  try {
    (void)doc.get(axis.path);
  } catch (const SceneError& e) {
    r.fail(p["path"], path + ".path", "'" + axis.path + "' does not name a number in this scene: " + e.problem());
  }
  const int given = (p["linspace"] ? 1 : 0) + (p["logspace"] ? 1 : 0) + (p["values"] ? 1 : 0);
  if (given != 1) r.fail(p, path, "give exactly one of linspace, logspace, values");
  if (p["values"]) {
    axis.values = r.numbers(p["values"], path + ".values", -1, "the values to visit");
    if (axis.values.empty()) r.fail(p["values"], path + ".values", "expected at least one value");
  } else {
    const bool lg = static_cast<bool>(p["logspace"]);
    const std::string key = lg ? "logspace" : "linspace";
    const auto spec = r.numbers(p[key], path + "." + key, 3, "start, stop, count", false);
    axis.values = spaced(spec, lg, r, p[key], path + "." + key);
  }
  return axis;
}

bool inadmissible_start(const SceneError& e) { return e.problem().rfind("initial state violates ", 0) == 0; }

void RunSection::check_values(const SweepAxis& axis, const YAML::Node& p, const std::string& path,
                              bool starts_may_be_inadmissible) {
  SceneDocument point(doc);  // one copy, its value replaced per point: no re-parse per point
  for (std::size_t i = 0; i < axis.values.size(); ++i) {
    point.set(axis.path, axis.values[i]);
    const bool listed = static_cast<bool>(p["values"]);
    const YAML::Node at = listed ? p["values"][i] : p[p["linspace"] ? "linspace" : "logspace"];
    const std::string where = listed ? path + ".values[" + std::to_string(i) + "]" : path;
    try {
      const Scene built = point.build_point();
      point_engines.push_back({at, where, axis.path + " = " + number_text(axis.values[i]), built.engine});
    } catch (const SceneError& e) {
      if (starts_may_be_inadmissible && inadmissible_start(e)) continue;
      r.fail(at, where,
             axis.path + " = " + number_text(axis.values[i]) + " makes the scene invalid: " + e.problem() +
                 " (" + e.path() + ")");
    }
  }
}

void RunSection::monotonic(const YAML::Node& node, const std::string& path) {
  const auto& v = run.axes[0].values;
  if (v.size() < 2) r.fail(node, path, "expected at least two grid values");
  for (std::size_t i = 1; i < v.size(); ++i)
    if (!((v[i] - v[i - 1]) * (v[1] - v[0]) > 0.0))
      r.fail(node, path, "the grid must be strictly increasing or decreasing (value " + std::to_string(i) + ")");
}

}  // namespace vibro::io::detail
