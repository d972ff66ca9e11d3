// The sections of a scene file, each read by a function of its own (scene_sections.hpp); a new
// section copies one of them and adds one call to SceneDocument::build_checked (scene.cpp).
#include "scene_sections.hpp"

#include "vibro/io/resources.hpp"
#include "vibro/modal.hpp"

#include <algorithm>
#include <numbers>
#include <cmath>
#include <string>
#include <utility>

namespace vibro::io::detail {

/// `model`: model.chain (kept as links, assembled on demand) or model.matrices.
void read_model(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& M = p.M;
  auto& C = p.C;
  auto& K = p.K;
  auto& chain_links = p.chain_links;
  // --- model ---
  const YAML::Node model = root["model"];
  if (!model) r.fail(root, "model", "missing: a scene needs a model (model.chain or model.matrices)");
  r.expect_map(model, "model", {"chain", "matrices"});
  if (model["chain"] && model["matrices"])
    r.fail(model, "model", "give either model.chain or model.matrices, not both");
  if (const YAML::Node chain = model["chain"]) {
    r.expect_map(chain, "model.chain", {"masses", "springs", "dampers", "left_wall", "right_wall"});
    if (!chain["masses"]) r.fail(chain, "model.chain.masses", "missing: one mass per degree of freedom");
    models::Chain c;
    c.masses = r.numbers(chain["masses"], "model.chain.masses", -1, "one mass per degree of freedom");
    n = static_cast<long>(c.masses.size());
    if (n == 0) r.fail(chain["masses"], "model.chain.masses", "expected at least one mass, found an empty list");
    if (const double least = least_engine_bytes(static_cast<double>(n)); least > kEarlyCheckBytes) {
      try {
        require_memory(least, "a chain of " + std::to_string(n) + " masses (every engine holds n × n modes or matrices)");
      } catch (const ResourceError& e) {
        r.fail(chain["masses"], "model.chain.masses", e.what());
      }
    }
    for (long i = 0; i < n; ++i)
      if (!(c.masses[static_cast<std::size_t>(i)] > 0.0))
        r.fail(Reader::entry(chain["masses"], static_cast<std::size_t>(i)), "model.chain.masses[" + std::to_string(i) + "]",
               "expected a mass > 0, found " + number_text(c.masses[static_cast<std::size_t>(i)]));
    auto links = [&](const char* key, std::vector<double>& out) {
      const std::string path = std::string("model.chain.") + key;
      if (!chain[key]) return;
      out = r.numbers(chain[key], path, n - 1, "one per link between neighbouring masses");
      for (std::size_t i = 0; i < out.size(); ++i)
        if (out[i] < 0.0)
          r.fail(Reader::entry(chain[key], i), path + "[" + std::to_string(i) + "]", "expected a value ≥ 0, found " + number_text(out[i]));
    };
    links("springs", c.springs);
    links("dampers", c.dampers);
    if (c.springs.empty() && n > 1) c.springs.assign(static_cast<std::size_t>(n - 1), 0.0);
    auto wall = [&](const char* key, double& spring, double& damper) {
      const YAML::Node w = chain[key];
      if (!w) return;
      const std::string path = std::string("model.chain.") + key;
      r.expect_map(w, path, {"spring", "damper"});
      if (w["spring"]) spring = r.number_in(w["spring"], path + ".spring", 0, 1e300, "a value ≥ 0");
      if (w["damper"]) damper = r.number_in(w["damper"], path + ".damper", 0, 1e300, "a value ≥ 0");
    };
    wall("left_wall", c.left_spring, c.left_damper);
    wall("right_wall", c.right_spring, c.right_damper);
    // What LinearSystem would refuse in the assembled matrices, checked on the links in O(n):
    // every diagonal entry (a sum of two links and a wall) must be finite.
    for (long i = 0; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      double k = (i == 0 ? c.left_spring : 0.0) + (i == n - 1 ? c.right_spring : 0.0);
      double d = (i == 0 ? c.left_damper : 0.0) + (i == n - 1 ? c.right_damper : 0.0);
      if (i > 0) k += c.springs[u - 1], d += c.dampers.empty() ? 0.0 : c.dampers[u - 1];
      if (i < n - 1) k += c.springs[u], d += c.dampers.empty() ? 0.0 : c.dampers[u];
      if (!std::isfinite(k) || !std::isfinite(d))
        r.fail(chain, "model.chain", "the links of mass " + std::to_string(i) +
                                         " add up to an infinite stiffness or damping (values too large)");
    }
    chain_links = std::move(c);
  } else if (const YAML::Node mats = model["matrices"]) {
    r.expect_map(mats, "model.matrices", {"mass", "damping", "stiffness"});
    if (!mats["mass"]) r.fail(mats, "model.matrices.mass", "missing: the mass matrix");
    M = r.matrix(mats["mass"], "model.matrices.mass", -1);
    n = M.rows();
    C = mats["damping"] ? r.matrix(mats["damping"], "model.matrices.damping", n) : Eigen::MatrixXd::Zero(n, n);
    K = mats["stiffness"] ? r.matrix(mats["stiffness"], "model.matrices.stiffness", n) : Eigen::MatrixXd::Zero(n, n);
  } else {
    r.fail(model, "model", "expected model.chain or model.matrices");
  }
}

/// `forcing.harmonics` (docs/scenes.md): a list of {order: k, cosine: [...], sine: [...]}, k a
/// whole number ≥ 1, each order once. Order 1 is the drive's cosine and sine (given here or as
/// forcing.cosine/sine, not both: the same scene either way, bit for bit); orders ≥ 2 become
/// HarmonicForcing::harmonics in the order written.
void read_harmonics(Reader& r, const YAML::Node& fn, long n, HarmonicForcing& f) {
  const YAML::Node list = fn["harmonics"];
  r.note(list);
  if (!list.IsSequence())
    r.fail(list, "forcing.harmonics", "expected a list of {order, cosine, sine}, found " + describe(list));
  std::vector<std::pair<long, std::string>> seen;  // order, where
  for (std::size_t h = 0; h < list.size(); ++h) {
    const std::string path = "forcing.harmonics[" + std::to_string(h) + "]";
    const YAML::Node e = list[h];
    r.expect_map(e, path, {"order", "cosine", "sine"});
    if (!e["order"]) r.fail(e, path + ".order", "missing: each harmonic needs its order k (a whole number ≥ 1; frequency k × forcing.frequency)");
    const long order = r.integer(e["order"], path + ".order", 1, 1000000);
    for (const auto& [k, where] : seen)
      if (k == order) r.fail(e["order"], path + ".order", "order " + std::to_string(order) + " is given twice (also " + where + ")");
    Eigen::VectorXd c = Eigen::VectorXd::Zero(n), s = Eigen::VectorXd::Zero(n);
    if (e["cosine"]) c = to_vector(r.numbers(e["cosine"], path + ".cosine", n, "one amplitude per mass"));
    if (e["sine"]) s = to_vector(r.numbers(e["sine"], path + ".sine", n, "one amplitude per mass"));
    if (order == 1) {
      for (const char* key : {"cosine", "sine"})
        if (fn[key])
          r.fail(e["order"], path + ".order", std::string("order 1 is also given by forcing.") + key +
                                                  ": give the first harmonic in one place");
      f.cosine = c;
      f.sine = s;
      seen.emplace_back(order, path);
      continue;
    }
    seen.emplace_back(order, path);
    f.harmonics.push_back({static_cast<int>(order), std::move(c), std::move(s)});
  }
}

/// `forcing`, and the system it completes: the chain in banded form where its damping allows, the dense system built on demand (model.matrices: now, its errors pointed at the entry they name).
void read_forcing(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& M = p.M;
  auto& C = p.C;
  auto& K = p.K;
  auto& chain_links = p.chain_links;
  auto& f = p.f;
  auto& dense = p.dense;
  auto& banded = p.banded;
  auto& not_banded = p.not_banded;
  const YAML::Node model = root["model"];
  // --- forcing ---
  f = HarmonicForcing::zero(n);
  if (const YAML::Node fn = root["forcing"]) {
    r.expect_map(fn, "forcing", {"frequency", "constant", "cosine", "sine", "harmonics", "file"});
    if (fn["frequency"]) f.frequency = r.number_in(fn["frequency"], "forcing.frequency", 0, 1e300, "a frequency ≥ 0 (rad per unit time)");
    if (fn["constant"]) f.constant = to_vector(r.numbers(fn["constant"], "forcing.constant", n, "one force per mass"));
    if (fn["cosine"]) f.cosine = to_vector(r.numbers(fn["cosine"], "forcing.cosine", n, "one amplitude per mass"));
    if (fn["sine"]) f.sine = to_vector(r.numbers(fn["sine"], "forcing.sine", n, "one amplitude per mass"));
    if (fn["harmonics"]) read_harmonics(r, fn, n, f);
    if (fn["file"]) read_drive_file(r, fn, n, p.doc ? p.doc->file() : std::string(), f);
  }
  read_base(r, root, p);
  if (chain_links) {
    models::Chain& c = *chain_links;
    auto list = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
    c.force_constant = list(f.constant);
    c.force_cosine = list(f.cosine);
    c.force_sine = list(f.sine);
    c.frequency = f.frequency;
    try {
      banded = BandedChain::from_links(c.masses, c.springs, c.dampers, c.left_spring, c.left_damper,
                                       c.right_spring, c.right_damper, f);
      banded->validate();
    } catch (const InvalidInput& e) {
      banded.reset();
      not_banded = e.what();
    }
    if (!f.harmonics.empty()) {
      // The chain's links carry the first harmonic only: the dense system gets the extra ones
      // (the banded chain has them from f).
      dense = LazySystem(n, f, [c, extra = f.harmonics] {
        const LinearSystem s = models::build_chain(c);
        HarmonicForcing g = s.forcing();
        g.harmonics = extra;
        return LinearSystem(s.mass(), s.damping(), s.stiffness(), std::move(g));
      });
    } else
    dense = LazySystem(n, f, [c] { return models::build_chain(c); });
  } else try {
    dense = LazySystem(LinearSystem(M, C, K, f));
  } catch (const InvalidInput& e) {
    // Point at the matrix or forcing entry the message names.
    const std::string msg = e.what();
    const YAML::Node mats = model["matrices"];
    const YAML::Node fn = root["forcing"];
    const std::pair<const char*, const char*> where[] = {
        {"mass matrix", "mass"}, {"damping matrix", "damping"}, {"stiffness matrix", "stiffness"}};
    for (const auto& [prefix, key] : where)
      if (msg.rfind(prefix, 0) == 0 && mats && mats[key])
        r.fail(mats[key], std::string("model.matrices.") + key, msg.substr(msg.find(':') + 2));
    for (const char* key : {"constant", "cosine", "sine", "frequency"})
      if (msg.rfind(std::string("forcing.") + key, 0) == 0 && fn && fn[key])
        r.fail(fn[key], std::string("forcing.") + key, msg.substr(msg.find(':') + 2));
    if (msg.rfind("forcing.harmonics", 0) == 0 && fn && fn["harmonics"])
      r.fail(fn["harmonics"], "forcing.harmonics", msg.substr(msg.find(':') + 2));
    r.fail(model, "model", msg);
  }
}

/// A stop along a general normal, `{normal: [n_0, …, n_{n−1}], position: p}` (nᵀx ≤ p); the
/// restitution, motion and name are read by the caller.
Stop read_general_stop(Reader& r, const YAML::Node& s, const std::string& path, long n) {
  for (const char* key : {"mass", "side", "between", "gap"})
    if (s[key])
      r.fail(s[key], path + "." + key,
             "a stop along a normal takes 'normal' and 'position' (nᵀx ≤ position), not '" + std::string(key) + "'");
  const std::vector<double> normal = r.numbers(s["normal"], path + ".normal", n, "one coefficient per degree of freedom");
  bool zero = true;
  for (double c : normal) zero = zero && c == 0.0;
  if (zero)
    r.fail(s["normal"], path + ".normal", "expected a nonzero normal n of nᵀx ≤ position, found all zeros");
  if (!s["position"]) r.fail(s, path + ".position", "missing: the stop's offset p of nᵀx ≤ p");
  const double p = r.number(s["position"], path + ".position");
  return Stop::general(to_vector(normal), p, 1.0);
}

/// `stops[j].harmonics` (docs/scenes.md): a list of {order: k, cosine: c, sine: s}, k a whole
/// number ≥ 1, each order once, moving the stop's position by c cos kΩt + s sin kΩt. Order 1 is
/// the stop's amplitude and phase (given here or as amplitude/phase, not both: A = hypot(c, s),
/// φ = atan2(−s, c)); orders ≥ 2 become Stop::harmonics in the order written.
void read_stop_harmonics(Reader& r, const YAML::Node& s, const std::string& stop_path, const HarmonicForcing& f,
                         Stop& stop) {
  const YAML::Node list = s["harmonics"];
  r.note(list);
  const std::string at = stop_path + ".harmonics";
  if (!list.IsSequence()) r.fail(list, at, "expected a list of {order, cosine, sine}, found " + describe(list));
  if (!(f.frequency > 0.0))
    r.fail(list, at, "a moving stop moves at multiples of the forcing frequency: set forcing.frequency > 0");
  std::vector<std::pair<long, std::string>> seen;  // order, where
  for (std::size_t h = 0; h < list.size(); ++h) {
    const std::string path = at + "[" + std::to_string(h) + "]";
    const YAML::Node e = list[h];
    r.expect_map(e, path, {"order", "cosine", "sine"});
    if (!e["order"])
      r.fail(e, path + ".order", "missing: each harmonic needs its order k (a whole number ≥ 1; frequency k × forcing.frequency)");
    const long order = r.integer(e["order"], path + ".order", 1, 1000000);
    for (const auto& [k, where] : seen)
      if (k == order) r.fail(e["order"], path + ".order", "order " + std::to_string(order) + " is given twice (also " + where + ")");
    seen.emplace_back(order, path);
    const double c = e["cosine"] ? r.number(e["cosine"], path + ".cosine") : 0.0;
    const double sn = e["sine"] ? r.number(e["sine"], path + ".sine") : 0.0;
    if (order == 1) {
      for (const char* key : {"amplitude", "phase"})
        if (s[key])
          r.fail(e["order"], path + ".order", std::string("order 1 is also given by ") + stop_path + "." + key +
                                                  ": give the first harmonic in one place");
      // c cos Ωt + s sin Ωt = A cos(Ωt + φ): A cos φ = c, −A sin φ = s.
      stop.amplitude = std::hypot(c, sn);
      stop.phase = std::atan2(-sn, c);
      continue;
    }
    stop.harmonics.push_back({static_cast<int>(order), c, sn});
  }
}

/// `stops`, validated together (stops[j] errors point at that stop).
void read_stops(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& f = p.f;
  auto& stops = p.stops;
  std::vector<bool> attached;  // `attached: base` (scene_base.cpp)
  // --- stops ---
  if (const YAML::Node sn = root["stops"]) {
    if (!sn.IsSequence()) r.fail(sn, "stops", "expected a list of stops, found " + describe(sn));
    for (std::size_t j = 0; j < sn.size(); ++j) {
      const YAML::Node s = sn[j];
      const std::string path = "stops[" + std::to_string(j) + "]";
      r.expect_map(s, path, {"mass", "side", "between", "normal", "position", "gap", "restitution", "amplitude", "phase", "harmonics",
                                "name", "law", "stiffness", "damping", "preload", "attached"});
      Stop stop;
      if (s["normal"]) {
        stop = read_general_stop(r, s, path, n);
      } else if (s["between"]) {
        if (s["mass"] || s["side"] || s["position"])
          r.fail(s, path, "a stop between masses takes 'between' and 'gap', not 'mass', 'side' or 'position'");
        const auto pair = r.numbers(s["between"], path + ".between", 2, "the two masses i, k of x_i - x_k ≤ gap", false);
        for (int q = 0; q < 2; ++q)
          r.integer(s["between"][static_cast<std::size_t>(q)], path + ".between[" + std::to_string(q) + "]", 0, n - 1);
        if (pair[0] == pair[1])
          r.fail(s["between"], path + ".between", "expected two different masses, found mass " +
                                                      s["between"][0].Scalar() + " twice");
        if (!s["gap"]) r.fail(s, path + ".gap", "missing: the gap of x_i - x_k ≤ gap");
        stop = Stop::between(static_cast<Eigen::Index>(pair[0]), static_cast<Eigen::Index>(pair[1]),
                             r.number(s["gap"], path + ".gap"), 1.0);
      } else {
        if (!s["mass"]) r.fail(s, path + ".mass", "missing: the mass the stop limits (0-based)");
        if (!s["side"]) r.fail(s, path + ".side", "missing: 'upper' (x ≤ position) or 'lower' (x ≥ position)");
        if (!s["position"]) r.fail(s, path + ".position", "missing: where the stop is");
        if (s["gap"]) r.fail(s["gap"], path + ".gap", "'gap' is for stops between masses; use 'position'");
        const long i = r.integer(s["mass"], path + ".mass", 0, n - 1);
        const std::string side = r.choice(s["side"], path + ".side", {"upper", "lower"});
        const double p = r.number(s["position"], path + ".position");
        stop = side == "upper" ? Stop::upper(i, p, 1.0) : Stop::lower(i, p, 1.0);
      }
      const bool compliant = s["law"] && r.choice(s["law"], path + ".law", {"rigid", "compliant"}) == "compliant";
      if (compliant) {  // a Kelvin–Voigt stop (stops.hpp): k_s > 0, c_s ≥ 0, F_p ≥ 0
        if (s["restitution"])
          r.fail(s["restitution"], path + ".restitution",
                 "a compliant stop has no restitution coefficient (its energy loss is its damping); remove it");
        if (!s["stiffness"]) r.fail(s, path + ".stiffness", "missing: the compliant stop's stiffness k_s > 0");
        const double k = r.number(s["stiffness"], path + ".stiffness");
        if (!(k > 0.0)) r.fail(s["stiffness"], path + ".stiffness", "expected a stiffness > 0, found " + s["stiffness"].Scalar());
        const double c = s["damping"] ? r.number_in(s["damping"], path + ".damping", 0, 1e300, "a damping ≥ 0") : 0.0;
        const double fp = s["preload"] ? r.number_in(s["preload"], path + ".preload", 0, 1e300, "a preload ≥ 0") : 0.0;
        stop = stop.compliant(k, c, fp);
      } else {
        for (const char* key : {"stiffness", "damping", "preload"})
          if (s[key])
            r.fail(s[key], path + "." + key,
                   std::string("'") + key + "' belongs to a compliant stop: add law: compliant (the default law, rigid, takes restitution)");
        if (!s["restitution"]) r.fail(s, path + ".restitution", "missing: the restitution coefficient r ∈ [0, 1]");
        stop.restitution = r.number_in(s["restitution"], path + ".restitution", 0, 1, "a restitution coefficient in [0, 1]");
      }
      if (s["amplitude"]) {
        stop.amplitude = r.number_in(s["amplitude"], path + ".amplitude", 0, 1e300, "an amplitude ≥ 0");
        if (stop.amplitude > 0.0 && !(f.frequency > 0.0))
          r.fail(s["amplitude"], path + ".amplitude",
                 "a moving stop moves at the forcing frequency: set forcing.frequency > 0");
      }
      if (s["phase"]) stop.phase = r.number(s["phase"], path + ".phase");
      if (s["harmonics"]) read_stop_harmonics(r, s, path, f, stop);
      if (s["name"]) stop.name = r.text(s["name"], path + ".name");
      attached.push_back(s["attached"] && r.choice(s["attached"], path + ".attached", {"base", "laboratory"}) == "base");
      stops.push_back(stop);
    }
  }
  move_attached_stops(r, root, p, attached);
  try {
    stops = validated_stops(std::move(stops), n, f.frequency);  // O(m log m), no n × m normals
  } catch (const InvalidInput& e) {
    // The message starts with the stop ("stops[j] (name): ..."); point at that stop and do not
    // repeat its label.
    std::string msg = e.what();
    YAML::Node where = root["stops"];
    std::string path = "stops";
    if (msg.rfind("stops[", 0) == 0) {
      const std::size_t j = std::stoul(msg.substr(6));
      if (where && j < where.size()) {
        path = "stops[" + std::to_string(j) + "]";
        where = where[j];
        const std::size_t colon = msg.find("): ");
        if (colon != std::string::npos && msg.find(" and ") > colon) msg = msg.substr(colon + 3);
      }
    }
    r.fail(where ? where : root, path, msg);
  }
}

/// `initial`: time, x, v (rest at 0 by default).
void read_initial(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& t0 = p.t0;
  auto& x0 = p.x0;
  auto& v0 = p.v0;
  // --- initial state ---
  x0 = Eigen::VectorXd::Zero(n);
  v0 = Eigen::VectorXd::Zero(n);
  if (const YAML::Node in = root["initial"]) {
    r.expect_map(in, "initial", {"time", "x", "v"});
    if (in["time"]) t0 = r.number(in["time"], "initial.time");
    if (in["x"]) x0 = to_vector(r.numbers(in["x"], "initial.x", n, "one displacement per mass"));
    if (in["v"]) v0 = to_vector(r.numbers(in["v"], "initial.v", n, "one velocity per mass"));
  }
}

/// `solver`: the tolerances, the flow method, the chatter rule and `solver.engine` as asked for.
void read_solver(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& opt = p.opt;
  auto& engine_choice = p.engine_choice;
  // --- solver ---
  if (const YAML::Node sv = root["solver"]) {
    r.expect_map(sv, "solver", {"trigger", "simultaneity", "chatter_height", "chatter_velocity", "contact_velocity",
                                "max_events", "event_window", "length_scale", "flow_method", "max_condition", "engine",
                                "chatter_rule"});
    if (sv["trigger"]) opt.trigger = r.number_in(sv["trigger"], "solver.trigger", 1e-16, 1e-4, "a relative tolerance in [1e-16, 1e-4]");
    if (sv["simultaneity"]) opt.simultaneity = r.number_in(sv["simultaneity"], "solver.simultaneity", 0, 1e-2, "a relative time in [0, 1e-2]");
    if (sv["chatter_height"]) opt.chatter_height = r.number_in(sv["chatter_height"], "solver.chatter_height", 0, 1e-1, "a relative height in [0, 0.1]");
    if (sv["chatter_velocity"]) opt.chatter_velocity = r.number_in(sv["chatter_velocity"], "solver.chatter_velocity", 0, 1e-1, "a relative speed in [0, 0.1]");
    if (sv["contact_velocity"]) opt.contact_velocity = r.number_in(sv["contact_velocity"], "solver.contact_velocity", 0, 1e-3, "a relative speed in [0, 1e-3]");
    if (sv["max_events"]) opt.max_events = r.integer(sv["max_events"], "solver.max_events", 1, 1000000000L);
    if (sv["event_window"]) opt.event_window = r.number_in(sv["event_window"], "solver.event_window", 0, 1e300, "a time ≥ 0 (0: one forcing period)");
    if (sv["length_scale"]) opt.length_scale = r.number_in(sv["length_scale"], "solver.length_scale", 0, 1e300, "a length ≥ 0 (0: automatic)");
    if (sv["flow_method"]) {
      const std::string m = r.choice(sv["flow_method"], "solver.flow_method", {"automatic", "spectral", "exponential"});
      opt.flow.method = m == "spectral" ? FlowMethod::spectral : m == "exponential" ? FlowMethod::exponential : FlowMethod::automatic;
    }
    if (sv["max_condition"]) opt.flow.max_condition = r.number_in(sv["max_condition"], "solver.max_condition", 1, 1e16, "a condition number in [1, 1e16]");
    if (sv["chatter_rule"]) {
      const std::string c =
          r.choice(sv["chatter_rule"], "solver.chatter_rule", {"third_order", "second_order", "first_order"});
      opt.chatter_rule = c == "first_order"    ? ChatterRule::first_order
                         : c == "second_order" ? ChatterRule::second_order
                                               : ChatterRule::third_order;
    }
    if (sv["engine"]) {
      const std::string e = r.choice(sv["engine"], "solver.engine", {"auto", "dense", "modal", "taylor"});
      engine_choice = e == "dense"    ? EngineChoice::dense
                      : e == "modal"  ? EngineChoice::modal
                      : e == "taylor" ? EngineChoice::taylor
                                      : EngineChoice::automatic;
    }
  }
}

/// The initial state against the stops, with the tolerance the run will use.
void check_initial_state(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& M = p.M;
  auto& K = p.K;
  auto& chain_links = p.chain_links;
  auto& f = p.f;
  auto& stops = p.stops;
  auto& t0 = p.t0;
  auto& x0 = p.x0;
  auto& v0 = p.v0;
  auto& opt = p.opt;
  // The initial state, with the tolerance the run will use (trigger × L): what `check` accepts,
  // the run accepts. L is the engines' (run_length_scale); for an unforced scene the engines take
  // the fastest mode's frequency, unknown here, and the stops' and x0's part of L is used: a lower
  // bound, so the loader is never the more lenient.
  try {
    double kmax = 0.0, mmax = 0.0;
    if (chain_links) {
      const models::Chain& c = *chain_links;
      for (long i = 0; i < n; ++i) {
        const auto u = static_cast<std::size_t>(i);
        double k = (i == 0 ? c.left_spring : 0.0) + (i == n - 1 ? c.right_spring : 0.0);
        if (i > 0) k += c.springs[u - 1];
        if (i < n - 1) k += c.springs[u];
        kmax = std::max({kmax, k, i < n - 1 ? c.springs[u] : 0.0});
        mmax = std::max(mmax, c.masses[u]);
      }
    } else {
      kmax = K.cwiseAbs().maxCoeff();
      mmax = M.cwiseAbs().maxCoeff();
    }
    const bool forced = f.frequency > 0.0;
    double fmax = forced ? f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff() : 0.0;
    for (const ForcingHarmonic& h : f.harmonics)
      if (forced) fmax += h.cosine.cwiseAbs().maxCoeff() + h.sine.cwiseAbs().maxCoeff();
    const double L = run_length_scale(opt, forced ? f.frequency : 1.0, kmax, mmax, fmax, stops, x0,
                                      forced ? v0 : Eigen::VectorXd::Zero(n).eval());
    check_admissible(stops, f.frequency, t0, x0, opt.trigger * L);
  } catch (const InvalidInput& e) {
    const YAML::Node in = root["initial"];
    if (in && in["x"]) r.fail(in["x"], "initial.x", e.what());
    // The default initial state (rest at 0) violates a stop: point at that stop's position.
    const std::string msg = e.what();
    const std::size_t at = msg.find("stops[");
    const YAML::Node sn = root["stops"];
    if (at != std::string::npos && sn) {
      const std::size_t j = std::stoul(msg.substr(at + 6));
      if (j < sn.size()) {
        const char* key = sn[j]["between"] ? "gap" : "position";
        r.fail(sn[j][key], "stops[" + std::to_string(j) + "]." + key,
               msg + "; the initial state defaults to rest at x = 0 (set initial.x)");
      }
    }
    r.fail(root, "initial.x", msg);
  }
}

/// Sample times lie in the recorded span run.periods × period (Recording::for_scene): checked as
/// soon as run.periods is known — before the sweep values, so that times outside every point's
/// span are reported as such — and again for each sweep value (each is built on its own).
void check_sample_times(Reader& r, const YAML::Node& root, const SceneParts& p) {
  if (p.run.kind != RunSpec::Kind::simulate && p.run.kind != RunSpec::Kind::sweep) return;
  const YAML::Node rn = root["record"];
  const YAML::Node sm = rn ? rn["samples"] : YAML::Node();
  const YAML::Node times = sm ? sm["times"] : YAML::Node();
  if (!times) return;
  const double span = p.run.periods * (p.f.frequency > 0.0 ? 2.0 * std::numbers::pi / p.f.frequency : 1.0);
  for (std::size_t i = 0; i < p.rec.sample_times.size(); ++i)
    if (!(p.rec.sample_times[i] <= span))
      r.fail(times[i], "record.samples.times[" + std::to_string(i) + "]",
             "must lie in the recorded span [0, " + number_text(span) + "] (run.periods × the forcing period), found " +
                 number_text(p.rec.sample_times[i]));
}

/// `record.section`: {coordinate: i | normal: [n_0, …], value: c, direction: up | down | both}.
SectionSpec read_section(Reader& r, const YAML::Node& sn, Eigen::Index n) {
  const std::string path = "record.section";
  r.expect_map(sn, path, {"coordinate", "normal", "value", "direction"});
  if (sn["coordinate"] && sn["normal"])
    r.fail(sn, path, "give either coordinate (a coordinate's index) or normal (one weight per coordinate), not both");
  if (!sn["coordinate"] && !sn["normal"])
    r.fail(sn, path, "needs coordinate (the index of the coordinate crossing the value) or normal (one weight per "
                     "coordinate: the hyperplane normal·x = value)");
  SectionSpec spec;
  if (const YAML::Node c = sn["coordinate"]) {
    const long i = r.integer(c, path + ".coordinate", 0, static_cast<long>(n) - 1);
    spec.plane.normal = Eigen::VectorXd::Unit(n, static_cast<Eigen::Index>(i));
  } else {
    const std::vector<double> w = r.numbers(sn["normal"], path + ".normal", static_cast<long>(n), "one weight per coordinate");
    spec.plane.normal = Eigen::Map<const Eigen::VectorXd>(w.data(), static_cast<Eigen::Index>(w.size()));
    if (spec.plane.normal.norm() == 0.0) r.fail(sn["normal"], path + ".normal", "the normal is zero (no hyperplane)");
  }
  if (sn["value"]) spec.plane.value = r.number(sn["value"], path + ".value");
  if (sn["direction"]) {
    const std::string d = r.choice(sn["direction"], path + ".direction", {"up", "down", "both"});
    spec.direction = d == "up" ? Section::Direction::up : d == "down" ? Section::Direction::down : Section::Direction::both;
  }
  return spec;
}

/// `record`: the observers.
void read_record(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& f = p.f;
  auto& rec = p.rec;
  if (p.base) rec.frame = p.base->frame;  // the default: the frame the scene computes in
  // --- record ---
  if (const YAML::Node rn = root["record"]) {
    r.expect_map(rn, "record", {"events", "contacts", "statistics", "poincare", "impact_map", "section", "samples", "frame"});
    if (rn["events"]) rec.events = r.boolean(rn["events"], "record.events");
    if (rn["contacts"]) rec.contacts = r.boolean(rn["contacts"], "record.contacts");
    if (rn["statistics"]) rec.statistics = r.boolean(rn["statistics"], "record.statistics");
    if (rn["poincare"]) rec.poincare = r.boolean(rn["poincare"], "record.poincare");
    if (rn["impact_map"]) rec.impact_map = r.boolean(rn["impact_map"], "record.impact_map");
    if (const YAML::Node sn = rn["section"]) rec.section = read_section(r, sn, p.n);
    if (const YAML::Node sm = rn["samples"]) {
      r.expect_map(sm, "record.samples", {"per_period", "times"});
      if (sm["per_period"] && sm["times"]) r.fail(sm, "record.samples", "give either per_period or times, not both");
      if (sm["per_period"]) rec.samples_per_period = static_cast<int>(r.integer(sm["per_period"], "record.samples.per_period", 1, 1000000));
      if (sm["times"]) {
        rec.sample_times = r.numbers(sm["times"], "record.samples.times", -1, "times from the start of recording");
        for (std::size_t i = 0; i < rec.sample_times.size(); ++i)
          if (rec.sample_times[i] < 0.0)
            r.fail(Reader::entry(sm["times"], i), "record.samples.times[" + std::to_string(i) + "]",
                   "expected a time ≥ 0 (from the start of recording), found " + number_text(rec.sample_times[i]));
        if (!std::is_sorted(rec.sample_times.begin(), rec.sample_times.end()))
          r.fail(sm["times"], "record.samples.times", "expected times in increasing order");
      }
    }
    if (rn["frame"]) {
      const std::string frame = r.choice(rn["frame"], "record.frame", {"absolute", "relative"});
      if (!p.base)
        r.fail(rn["frame"], "record.frame",
               "the frame of the results is chosen for a base-excited scene: this scene has no base section "
               "(its coordinates are the laboratory's)");
      rec.frame = frame == "relative" ? BaseFrame::relative : BaseFrame::absolute;
    }
    for (const char* key : {"statistics", "poincare"})
      if (rn[key] && r.boolean(rn[key], std::string("record.") + key) && !(f.frequency > 0.0))
        r.fail(rn[key], std::string("record.") + key,
               "per-period statistics and Poincaré points need a forcing frequency > 0 (forcing.frequency)");
  }
}

/// The engine the scene runs on (docs/scenes.md, solver.engine), then the checks the run section asked to make on it.
void resolve_engine(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& chain_links = p.chain_links;
  auto& banded = p.banded;
  auto& not_banded = p.not_banded;
  auto& engine_choice = p.engine_choice;
  auto& point_engines = p.point_engines;
  auto& engine_checks = p.engine_checks;
  auto& engine = p.engine;
  auto& reason = p.reason;
  // --- engine (docs/scenes.md, solver.engine) ---
  // The modal engine also needs a stiffness matrix without rigid-body modes (ChainModes refuses
  // them): every mass tied to a wall through springs > 0. Checked on the links in O(n).
  std::string floating;  // a group of masses no spring ties to a wall, if any
  if (chain_links) {
    const models::Chain& c = *chain_links;
    long first = 0;
    bool walled = c.left_spring > 0.0;
    for (long i = 0; i < n; ++i) {
      const bool last = i == n - 1 || !(c.springs[static_cast<std::size_t>(i)] > 0.0);
      if (i == n - 1) walled = walled || c.right_spring > 0.0;
      if (!last) continue;
      if (!walled && floating.empty())
        floating = first == i ? "mass " + std::to_string(i) : "masses " + std::to_string(first) + "…" + std::to_string(i);
      first = i + 1;
      walled = false;
    }
  }
  const YAML::Node engine_node = root["solver"] ? root["solver"]["engine"] : YAML::Node();
  // The first compliant stop the modal engine cannot run (compliant_refusal: a non-neighbour
  // pair, or c_s ≠ β k_s), its reason and where it is written (its law: key).
  int refused_stop = -1;
  std::string refused_why;
  YAML::Node refused_at;
  if (banded)
    for (std::size_t j = 0; j < p.stops.size() && refused_stop < 0; ++j) {
      if (!p.stops[j].is_compliant()) continue;
      std::string why = compliant_refusal(p.stops[j], *banded);
      if (!why.empty()) {
        refused_stop = static_cast<int>(j);
        refused_why = std::move(why);
        const YAML::Node list = root["stops"];
        if (list && list.IsSequence() && j < list.size()) refused_at = list[j]["law"] ? list[j]["law"] : list[j];
      }
    }
  // The first stop along a general normal: the modal engine runs it (given explicitly) but does not
  // hold it, so auto leaves such scenes to the dense engine.
  int general_stop = -1;
  for (std::size_t j = 0; j < p.stops.size() && general_stop < 0; ++j)
    if (p.stops[j].kind == Stop::Kind::normal) general_stop = static_cast<int>(j);
  if (resolve_taylor_engine(r, root, p)) {
    // nonlinear forces (or solver.engine: taylor): the Taylor engine, scene_forces.cpp
  } else if (engine_choice == EngineChoice::modal) {
    auto refuse = [&](const std::string& why) {
      r.fail(engine_node, "solver.engine", "the modal engine cannot run this scene: " + why +
                                               " (use solver.engine: dense or auto)");
    };
    if (!chain_links) refuse("it needs model.chain (M diagonal, K tridiagonal), this scene gives model.matrices");
    if (!banded) refuse(not_banded);
    if (!floating.empty()) refuse(floating + " tied to no wall by springs: a rigid-body mode (give the chain a wall spring)");
    if (refused_stop >= 0) {
      const std::string path = "stops[" + std::to_string(refused_stop) + "]";
      r.fail(refused_at ? refused_at : engine_node, refused_at ? path + ".law" : std::string("solver.engine"),
             "the modal engine (solver.engine: modal) cannot run " + path + ": " + refused_why +
                 " (use solver.engine: dense or auto)");
    }
    engine = EngineKind::modal;
    reason = "solver.engine: modal";
  } else if (engine_choice == EngineChoice::dense) {
    reason = "solver.engine: dense";
  } else if (general_stop >= 0) {
    reason = "auto: stops[" + std::to_string(general_stop) + "] has a general normal (" + kModalStopsOnly + ")";
  } else if (!chain_links) {
    reason = "auto: model.matrices (the modal engine needs model.chain)";
  } else if (!banded) {
    reason = "auto: the chain's damping is not proportional (" + not_banded + ")";
  } else if (!floating.empty()) {
    reason = "auto: " + floating + " tied to no wall (a rigid-body mode; the modal engine needs none)";
  } else if (refused_stop >= 0) {
    reason = "auto: stops[" + std::to_string(refused_stop) + "]: " + refused_why;
  } else if (n < kModalAutomaticMinimumDof) {
    reason = "auto: " + std::to_string(n) + " masses (< " + std::to_string(kModalAutomaticMinimumDof) +
             ": the dense engine is cheap and handles every contact set)";
  } else {
    engine = EngineKind::modal;
    reason = "auto: a proportionally damped chain of " + std::to_string(n) + " masses (≥ " +
             std::to_string(kModalAutomaticMinimumDof) + ")";
  }

  // Sections are searched in the exact flows of the dense and the modal engine (vibro/section.hpp).
  if (const YAML::Node rn = root["record"]; rn && rn["section"]) {
    const YAML::Node sn = rn["section"];
    if (engine == EngineKind::taylor)
      r.fail(sn, "record.section", "the Taylor engine (nonlinear forces, or solver.engine: taylor) does not locate "
                                   "crossings of a hyperplane; the dense and the modal engine do");
    if (!p.friction.empty())
      r.fail(sn, "record.section", "the friction engine (friction:) does not locate crossings of a hyperplane; the "
                                   "dense and the modal engine do");
  }
  // What the run's section asked to check on the engine (e.g. what continuation differentiates).
  for (const auto& check : engine_checks) check(engine, reason);
  for (const PointEngine& point : point_engines)
    if (point.engine != engine)
      r.fail(point.at, point.path, point.what + " runs with the " + to_string(point.engine) + " engine, the base scene with the " +
                               to_string(engine) + " engine (" + reason + "): one run uses one engine; " +
                               "set solver.engine to dense or modal");
}

}  // namespace vibro::io::detail
