// The `parameters` and `forces` sections of a scene (docs/scenes.md) and the Taylor engine's
// place in the engine choice. Kept apart from scene_sections.cpp: one concept, nonlinear forces.
//
//     parameters: {beta: 0.5, k3: 2}
//     forces:
//       - {coordinate: 0, expression: "-beta*x0^3 - 0.1*v0^2*tanh(v0)"}
//       - {cubic_spring: {mass: 1, coefficient: k3}}             # -k3*x1^3 on mass 1
//       - {cubic_spring: {between: [0, 1], coefficient: 0.2}}   # -0.2*(x0-x1)^3 on 0, + on 1
//
// Each entry's expression (vibro/taylor/expression.hpp) is parsed with its position in the file,
// so an error inside it points at the character (file:line:col); the entries of one coordinate
// are summed. The forces are evaluated at the initial state: a NaN or infinity there (log of a
// negative number, a division by zero) is refused at the entry.
#include "scene_sections.hpp"

#include "vibro/taylor/expression.hpp"
#include "vibro/taylor/taylor_step.hpp"
#include "vibro/taylor/taylor_system.hpp"

#include <cmath>
#include <stdexcept>

namespace vibro::io::detail {
namespace {

/// Where the text of scalar `node` starts in the file (1-based line and column of its first
/// character: after the quote of a quoted scalar).
taylor::ExpressionSource source_of(const YAML::Node& node) {
  const YAML::Mark m = node.Mark();
  if (m.is_null()) return {};
  const bool quoted = node.Tag() == "!";
  return {m.line + 1, m.column + 1 + (quoted ? 1 : 0)};
}

/// Parses an expression for its errors only, throwing SceneError at the offending character.
void check_expression(const std::string& file, const YAML::Node& node, const std::string& path, const std::string& text,
                      const taylor::Symbols& symbols) {
  taylor::ExpressionTree tree;
  try {
    taylor::parse_expression(text, symbols, tree, source_of(node));
  } catch (const taylor::ExpressionError& e) {
    if (e.line > 0) throw SceneError(file, e.line, e.column, path, e.message);
    throw SceneError(file, 0, 0, path, e.message);
  }
}

/// The value of one force F_i at the initial state (its own system: mass I, no linear part, so
/// v' = F); throws SceneError at `node` if it is not finite or leaves its domain there.
void check_initial_value(const std::string& file, const YAML::Node& node, const std::string& path,
                         const std::string& text, long coordinate, const SceneParts& p) {
  taylor::TaylorSystemSpec spec;
  spec.mass = Eigen::MatrixXd::Identity(p.n, p.n);
  spec.frequency = p.f.frequency;
  spec.parameters = p.forces.parameters;
  spec.forces.assign(static_cast<std::size_t>(p.n), "");
  spec.forces[static_cast<std::size_t>(coordinate)] = text;
  const taylor::TaylorSystem system(spec);
  taylor::TaylorStep step(system);
  Eigen::VectorXd z(2 * p.n), rate(2 * p.n);
  z << p.x0, p.v0;
  const taylor::StepStatus s = step.rate(p.t0, z, rate);
  const double value = rate(p.n + coordinate);
  const YAML::Mark m = node.Mark();
  const int line = m.is_null() ? 0 : m.line + 1, col = m.is_null() ? 0 : m.column + 1;
  if (s == taylor::StepStatus::domain_error)
    throw SceneError(file, line, col, path, "at the initial state (t = " + number_text(p.t0) + "): " + step.trouble());
  if (s != taylor::StepStatus::ok || !std::isfinite(value))
    throw SceneError(file, line, col, path,
                     "evaluates to " + number_text(value) + " at the initial state (t = " + number_text(p.t0) +
                         "): a force must be finite where the run starts");
}

}  // namespace

void read_forces(Reader& r, const YAML::Node& root, SceneParts& p) {
  const std::string& file = p.doc->file();
  NonlinearForces& out = p.forces;
  taylor::Symbols symbols{.coordinates = static_cast<int>(p.n), .parameters = {}};
  if (const YAML::Node pn = root["parameters"]) {
    r.note(pn);
    if (!pn.IsMap()) r.fail(pn, "parameters", "expected a mapping of names to numbers, found " + describe(pn));
    for (auto it = pn.begin(); it != pn.end(); ++it) {
      const std::string name = it->first.Scalar();
      const std::string path = "parameters." + name;
      out.parameters.emplace_back(name, r.number(it->second, path));
      try {  // the name's rules (an identifier, not a built-in symbol or a function, unique)
        taylor::TaylorSystemSpec spec;
        spec.mass = Eigen::MatrixXd::Identity(1, 1);
        spec.parameters = out.parameters;
        const taylor::TaylorSystem check(spec);
      } catch (const std::invalid_argument& e) {
        r.fail(it->first, path, e.what());
      }
      symbols.parameters.push_back(name);
    }
  }
  const YAML::Node fn = root["forces"];
  if (!fn) return;
  r.note(fn);
  if (!fn.IsSequence()) r.fail(fn, "forces", "expected a list of forces, found " + describe(fn));
  out.forces.assign(static_cast<std::size_t>(p.n), "");
  auto add = [&](long i, const std::string& text) {
    std::string& f = out.forces[static_cast<std::size_t>(i)];
    f += (f.empty() ? "(" : " + (") + text + ")";
  };
  for (std::size_t k = 0; k < fn.size(); ++k) {
    const YAML::Node e = fn[k];
    const std::string path = "forces[" + std::to_string(k) + "]";
    if (e.IsMap() && e["cubic_spring"]) {
      r.expect_map(e, path, {"cubic_spring"});
      const YAML::Node cs = e["cubic_spring"];
      const std::string cp = path + ".cubic_spring";
      r.expect_map(cs, cp, {"mass", "between", "coefficient"});
      if (!cs["coefficient"]) r.fail(cs, cp + ".coefficient", "missing: the cubic coefficient (a number or a parameter's name)");
      const YAML::Node cn = cs["coefficient"];
      const std::string coefficient = r.text(cn, cp + ".coefficient");
      check_expression(file, cn, cp + ".coefficient", coefficient, symbols);
      if (cs["mass"] && cs["between"]) r.fail(cs, cp, "give mass (a spring to the wall) or between (two masses), not both");
      if (cs["mass"]) {  // F_i = −c x_i³
        const long i = r.integer(cs["mass"], cp + ".mass", 0, p.n - 1);
        const std::string text = "-(" + coefficient + ")*x" + std::to_string(i) + "^3";
        check_initial_value(file, cn, cp + ".coefficient", text, i, p);
        add(i, text);
      } else if (cs["between"]) {  // F_i = −c (x_i − x_k)³, F_k = +c (x_i − x_k)³
        const YAML::Node bn = cs["between"];
        r.note(bn);
        if (!bn.IsSequence() || bn.size() != 2) r.fail(bn, cp + ".between", "expected two mass indices [i, k], found " + describe(bn));
        const long i = r.integer(bn[0], cp + ".between[0]", 0, p.n - 1);
        const long j = r.integer(bn[1], cp + ".between[1]", 0, p.n - 1);
        if (i == j) r.fail(bn, cp + ".between", "the two masses must differ");
        std::string cube = "(" + coefficient + ")*(x" + std::to_string(i) + " - x" + std::to_string(j) + ")^3";
        std::string negative = "-";
        negative += cube;
        check_initial_value(file, cn, cp + ".coefficient", negative, i, p);
        add(i, negative);
        add(j, cube);
      } else {
        r.fail(cs, cp, "missing: mass (a spring to the wall) or between (two masses)");
      }
      continue;
    }
    r.expect_map(e, path, {"coordinate", "expression"});
    if (!e["coordinate"]) r.fail(e, path + ".coordinate", "missing: the coordinate whose equation the force enters (0 … n-1)");
    if (!e["expression"]) r.fail(e, path + ".expression", "missing: the force, an expression in x0…, v0…, t, Omega and the parameters");
    const long i = r.integer(e["coordinate"], path + ".coordinate", 0, p.n - 1);
    const std::string text = r.text(e["expression"], path + ".expression");
    check_expression(file, e["expression"], path + ".expression", text, symbols);
    check_initial_value(file, e["expression"], path + ".expression", text, i, p);
    add(i, text);
  }
  if (fn.size() == 0) out.forces.clear();
}

bool resolve_taylor_engine(Reader& r, const YAML::Node& root, SceneParts& p) {
  const bool forces = !p.forces.forces.empty();
  const YAML::Node engine_node = root["solver"] ? root["solver"]["engine"] : YAML::Node();
  if (forces && (p.engine_choice == EngineChoice::dense || p.engine_choice == EngineChoice::modal))
    r.fail(engine_node, "solver.engine",
           std::string("the ") + to_string(p.engine_choice) +
               " engine integrates linear flows only; this scene has forces, which run on the Taylor engine "
               "(solver.engine: auto or taylor)");
  if (!forces && p.engine_choice != EngineChoice::taylor) return false;
  // Every run kind runs on the Taylor engine: the plain runs (simulate, sweep, diagram, basin,
  // locate) through engine.hpp's interface (make_engine), the analysis (orbit, continue,
  // lyapunov) through the variational equations (vibro/linearisation.hpp, nonlinear forces).
  p.engine = EngineKind::taylor;
  p.reason = forces ? (p.engine_choice == EngineChoice::taylor ? "solver.engine: taylor (the scene has forces)"
                                                               : "auto: the scene has forces (nonlinear)")
                    : "solver.engine: taylor";
  return true;
}

}  // namespace vibro::io::detail
