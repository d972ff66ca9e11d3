// initial.from (restart.hpp): a run started on an orbit saved in a result file.
#include "restart.hpp"

#include "scene_reader.hpp"

#include "vibro/io/result_file.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>

namespace vibro::io::detail {
namespace {

/// A saved number written as text (an orbit run's /orbit attributes): the shortest text that
/// reads back to the same double, so strtod restores it exactly.
std::optional<double> number_from_text(const std::string& s) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

/// The result file named by `from.file`: relative paths are relative to the scene file's folder
/// (as a scene's other files would be), or to the working folder for a scene given as text.
std::string resolve_file(const std::string& name, const std::string& scene_file) {
  const std::filesystem::path p(name);
  if (p.is_absolute() || scene_file.empty() || scene_file.front() == '<') return name;
  const std::filesystem::path folder = std::filesystem::path(scene_file).parent_path();
  return folder.empty() ? name : (folder / p).string();
}

Eigen::VectorXd row_of(const Eigen::MatrixXd& m, Eigen::Index row) { return m.row(row).transpose(); }

}  // namespace

RestartPoint read_restart(const YAML::Node& from, const std::string& scene_file) {
  Reader r(scene_file);
  r.expect_map(from, "initial.from", {"file", "branch", "point", "bifurcation"});
  if (!from["file"]) r.fail(from, "initial.from.file", "missing: the result file to start from");
  const std::string name = r.text(from["file"], "initial.from.file");
  const std::string path = resolve_file(name, scene_file);
  const bool branch = static_cast<bool>(from["branch"]), bifurcation = static_cast<bool>(from["bifurcation"]);
  if (branch && bifurcation)
    r.fail(from["bifurcation"], "initial.from.bifurcation",
           "give either `branch` and `point` (a branch point) or `bifurcation` (a located bifurcation), not both");
  if (from["point"] && !branch)
    r.fail(from["point"], "initial.from.point", "a point is counted along a branch: give `branch` too");

  std::optional<ResultReader> file;
  try {
    file.emplace(path);
  } catch (const std::exception& e) {
    r.fail(from["file"], "initial.from.file", "cannot read the result file " + path + ": " + e.what());
  }
  RestartPoint out;
  {
    const std::vector<std::string> meta = file->attributes("/meta");
    if (std::find(meta.begin(), meta.end(), "frame") != meta.end()) out.frame = file->attribute_string("/meta", "frame");
  }
  auto need = [&](const char* object, const YAML::Node& at, const std::string& key, const std::string& what) {
    if (!file->exists(object)) r.fail(at, key, path + " has no " + object + " (" + what + ")");
  };
  try {
    if (branch || bifurcation) {
      const char* group = branch ? "/branch" : "/bifurcations";
      need(group, branch ? from["branch"] : from["bifurcation"], branch ? "initial.from.branch" : "initial.from.bifurcation",
           "not a continuation result: an orbit run's file is read with `file` alone");
      long row = 0;
      if (branch) {
        const std::vector<std::int64_t> ids = file->read_integers("/branch/branch");
        const long b = r.integer(from["branch"], "initial.from.branch", 0, 1L << 40);
        std::vector<long> rows;
        for (std::size_t i = 0; i < ids.size(); ++i)
          if (ids[i] == b) rows.push_back(static_cast<long>(i));
        if (rows.empty())
          r.fail(from["branch"], "initial.from.branch",
                 fmt::format("{} has no branch {} (its /branches has {} rows)", path, b,
                             file->exists("/branches/k") ? file->read_integers("/branches/k").size() : 0));
        const long count = static_cast<long>(rows.size());
        if (!from["point"]) r.fail(from, "initial.from.point", "missing: which point of the branch (0 … count − 1, or −1 for the last)");
        const long i = r.integer(from["point"], "initial.from.point", -count, count - 1);
        row = rows[static_cast<std::size_t>(i < 0 ? count + i : i)];
        out.source = fmt::format("{}: branch {}, point {} (row {} of /branch)", name, b, i, row);
      } else {
        const long rows = static_cast<long>(file->read("/bifurcations/p").size());
        if (rows == 0) r.fail(from["bifurcation"], "initial.from.bifurcation", path + " has no located bifurcations");
        row = r.integer(from["bifurcation"], "initial.from.bifurcation", 0, rows - 1);
        const std::vector<std::string> names = file->attribute_strings("/bifurcations/kind", "names");
        const std::int64_t kind = file->read_integers("/bifurcations/kind")[static_cast<std::size_t>(row)];
        out.source = fmt::format("{}: bifurcation {} ({})", name, row,
                                 kind >= 0 && static_cast<std::size_t>(kind) < names.size() ? names[static_cast<std::size_t>(kind)] : "?");
      }
      const std::string g = group;
      const auto at = static_cast<std::size_t>(row);
      out.p = file->read(g + "/p")[at];
      out.t0 = file->read(g + "/t0")[at];
      out.phase = file->read(g + "/phase")[at];
      out.k = static_cast<int>(file->read_integers(g + "/k")[at]);
      out.x = row_of(file->read_matrix(g + "/x"), row);
      out.v = row_of(file->read_matrix(g + "/v"), row);
      out.path = file->attribute_string("/branch", "parameter");
    } else {
      need("/orbit", from["file"], "initial.from.file",
           "give `branch` and `point`, or `bifurcation`, to start from a continuation's orbit");
      const std::string status = file->attribute_string("/orbit", "status");
      if (status != "converged")
        r.fail(from["file"], "initial.from.file", path + ": the orbit run did not converge (/orbit status '" + status + "')");
      const std::optional<double> t0 = number_from_text(file->attribute_string("/orbit", "t0")),
                                  phase = number_from_text(file->attribute_string("/orbit", "phase")),
                                  period = number_from_text(file->attribute_string("/orbit", "period"));
      if (!t0 || !phase || !period)
        r.fail(from["file"], "initial.from.file", path + ": /orbit's t0, phase or period is not a number");
      out.t0 = *t0;
      out.phase = *phase;
      out.k = static_cast<int>(*period);
      out.x = file->read_matrix("/orbit/x").col(0);
      out.v = file->read_matrix("/orbit/v").col(0);
      out.source = name + ": the orbit";
    }
  } catch (const SceneError&) {
    throw;
  } catch (const std::exception& e) {
    r.fail(from["file"], "initial.from.file", "cannot read the saved orbit from " + path + ": " + e.what());
  }
  if (!out.x.allFinite() || !out.v.allFinite() || !std::isfinite(out.t0) || !std::isfinite(out.p) || out.k < 1)
    r.fail(from, "initial.from", out.source + ": the saved orbit is not finite");
  return out;
}

void apply_restart(SceneDocument& doc, const YAML::Node& root, const RestartPoint& point) {
  Reader r(doc.file());
  const YAML::Node initial = root["initial"];
  for (const char* key : {"x", "v", "time"})
    if (initial[key])
      r.fail(initial[key], std::string("initial.") + key,
             "initial.from sets the initial state (x, v and time from the saved orbit): give either `from` or the state");
  auto list = [](const Eigen::VectorXd& z) {
    std::string s = "[";
    for (Eigen::Index i = 0; i < z.size(); ++i) s += (i ? ", " : "") + fmt::format("{}", z(i));
    return s + "]";
  };
  // A base-excited orbit's state is in the frame its file was written in (record.frame): the
  // scene must compute in that frame (base.frame), as the state is not mapped.
  if (!point.frame.empty() && root["base"]) {
    const YAML::Node f = root["base"]["frame"];
    const std::string frame = f && f.IsScalar() ? f.Scalar() : "absolute";
    if (frame != point.frame)
      r.fail(root["initial"]["from"], "initial.from",
             point.source + ": the saved state is in the " + point.frame + " frame (its file's record.frame) and this "
                 "scene computes in the " + frame + " frame (base.frame): set base.frame: " + point.frame);
  }
  // The parameter first: the orbit exists at its value (a --set given afterwards still wins).
  if (!point.path.empty()) {
    try {
      doc.set(point.path, point.p);
    } catch (const SceneError& e) {
      r.fail(root["initial"]["from"], "initial.from",
             fmt::format("the saved orbit is at {} = {} (the parameter its file continued), which this scene cannot "
                         "set: {}",
                         point.path, point.p, e.problem()));
    }
  }
  doc.replace("initial", fmt::format("{{x: {}, v: {}, time: {}}}", list(point.x), list(point.v), point.t0));
  const YAML::Node run = root["run"];
  if (!run || !run["transient_periods"]) doc.replace("run.transient_periods", "0");
  const std::string kind = run && run["kind"] && run["kind"].IsScalar() ? run["kind"].Scalar() : "";
  if (kind == "continue" || kind == "orbit") {
    const std::string section = kind == "continue" ? "continue" : "orbit";
    const YAML::Node s = run[section];
    if (kind == "orbit" || s) {  // a continue run without its section is refused as usual
      if (!s || !s["period"]) doc.replace("run." + section + ".period", std::to_string(point.k));
      if (!s || !s["phase"]) doc.replace("run." + section + ".phase", fmt::format("{}", point.phase));
    }
  }
}

}  // namespace vibro::io::detail
