// The `friction` section of a scene (docs/scenes.md): frictional contacts with stick-slip
// (friction.hpp; with stops friction_stops.hpp), and what the rest of the scene must be for them
// (no nonlinear forces, the dense engine; with stops no tangent-map run kinds).
#include "scene_sections.hpp"

#include "vibro/friction.hpp"

#include <string>

namespace vibro::io::detail {

void read_friction(Reader& r, const YAML::Node& root, SceneParts& p) {
  const YAML::Node fn = root["friction"];
  if (!fn) return;
  if (!fn.IsSequence()) r.fail(fn, "friction", "expected a list of frictional contacts, found " + describe(fn));
  const long n = p.n;
  for (std::size_t j = 0; j < fn.size(); ++j) {
    const YAML::Node c = fn[j];
    const std::string path = "friction[" + std::to_string(j) + "]";
    r.expect_map(c, path, {"mass", "between", "normal_load", "static", "kinetic", "surface", "name"});
    FrictionContact contact;
    if (c["between"]) {
      if (c["mass"]) r.fail(c["mass"], path + ".mass", "a contact between masses takes 'between', not 'mass'");
      if (c["surface"])
        r.fail(c["surface"], path + ".surface", "a contact between two masses has no surface: remove 'surface'");
      const auto pair = r.numbers(c["between"], path + ".between", 2, "the two masses i, k rubbing on each other", false);
      for (int q = 0; q < 2; ++q)
        r.integer(c["between"][static_cast<std::size_t>(q)], path + ".between[" + std::to_string(q) + "]", 0, n - 1);
      if (pair[0] == pair[1])
        r.fail(c["between"], path + ".between", "expected two different masses, found mass " + c["between"][0].Scalar() + " twice");
      contact.kind = FrictionContact::Kind::between;
      contact.mass = static_cast<Eigen::Index>(pair[0]);
      contact.other = static_cast<Eigen::Index>(pair[1]);
    } else {
      if (!c["mass"]) r.fail(c, path + ".mass", "missing: the mass that rubs on the surface (0-based), or 'between'");
      contact.mass = r.integer(c["mass"], path + ".mass", 0, n - 1);
      if (const YAML::Node s = c["surface"]) {
        r.expect_map(s, path + ".surface", {"amplitude", "phase"});
        if (s["amplitude"]) {
          contact.amplitude = r.number_in(s["amplitude"], path + ".surface.amplitude", 0, 1e300, "an amplitude ≥ 0");
          if (contact.amplitude > 0.0 && !(p.f.frequency > 0.0))
            r.fail(s["amplitude"], path + ".surface.amplitude",
                   "a moving surface moves at the forcing frequency: set forcing.frequency > 0");
        }
        if (s["phase"]) contact.phase = r.number(s["phase"], path + ".surface.phase");
      }
    }
    for (const char* key : {"normal_load", "static", "kinetic"})
      if (!c[key]) r.fail(c, path + "." + key, std::string("missing: the contact's ") +
                                                 (std::string(key) == "normal_load" ? "normal load N ≥ 0"
                                                  : std::string(key) == "static"     ? "static coefficient μ_s ≥ μ_k"
                                                                                     : "kinetic coefficient μ_k ≥ 0"));
    contact.normal_load = r.number_in(c["normal_load"], path + ".normal_load", 0, 1e300, "a normal load ≥ 0");
    contact.kinetic_coefficient = r.number_in(c["kinetic"], path + ".kinetic", 0, 1e300, "a kinetic coefficient ≥ 0");
    contact.static_coefficient = r.number_in(c["static"], path + ".static", 0, 1e300, "a static coefficient ≥ 0");
    if (contact.static_coefficient < contact.kinetic_coefficient)
      r.fail(c["static"], path + ".static",
             "the static coefficient " + c["static"].Scalar() + " is below the kinetic one " + c["kinetic"].Scalar() +
                 " (μ_s ≥ μ_k is required)");
    if (c["name"]) contact.name = r.text(c["name"], path + ".name");
    p.friction.push_back(contact);
  }
  try {
    p.friction = validated_friction(std::move(p.friction), n);
  } catch (const InvalidInput& e) {
    r.fail(fn, "friction", e.what());
  }
}

void check_friction(Reader& r, const YAML::Node& root, SceneParts& p) {
  if (p.friction.empty()) return;
  const YAML::Node fn = root["friction"];
  // Every run kind takes friction, with or without stops: the tangent-map kinds (orbit, continue,
  // lyapunov) through the friction saltations of the analysis layer (friction_tangent.hpp).
  if (p.engine == EngineKind::taylor)
    r.fail(root["forces"] ? root["forces"] : fn, root["forces"] ? "forces" : "friction",
           "friction and nonlinear forces cannot be combined: the friction engine's flows are exact and linear, the "
           "Taylor engine has no friction law (take the forces out, or the friction)");
  if (p.engine == EngineKind::modal) {
    if (p.engine_choice == EngineChoice::modal)
      r.fail(root["solver"]["engine"], "solver.engine",
             "the modal engine cannot run this scene: it has friction, which the dense engine handles (use solver.engine: "
             "dense or auto)");
    p.engine = EngineKind::dense;
  }
  if (p.engine_choice != EngineChoice::dense) p.reason = "auto: friction (the dense engine handles it)";
}

}  // namespace vibro::io::detail
