// `base` (docs/scenes.md): the support motion x_b(t) that moves a chain's walls (or, for
// model.matrices, the coordinates along a given influence vector ι), turned into the equivalent
// harmonic forcing of the frame chosen (base_motion.hpp); `stops[j].attached: base`.
#include "scene_sections.hpp"

#include "vibro/base_motion.hpp"

#include <string>

namespace vibro::io::detail {

void read_base(Reader& r, const YAML::Node& root, SceneParts& p) {
  const YAML::Node bn = root["base"];
  if (!bn) return;
  const long n = p.n;
  r.expect_map(bn, "base", {"displacement", "influence", "frame"});
  BaseExcitation b;
  if (bn["frame"]) b.frame = r.choice(bn["frame"], "base.frame", {"absolute", "relative"}) == "relative"
                                 ? BaseFrame::relative
                                 : BaseFrame::absolute;
  if (!bn["displacement"])
    r.fail(bn, "base.displacement", "missing: the base motion x_b(t) as {cosine, sine, harmonics}");
  const YAML::Node dn = bn["displacement"];
  r.expect_map(dn, "base.displacement", {"cosine", "sine", "harmonics"});
  if (dn["cosine"] || dn["sine"])
    b.displacement.push_back({1, dn["cosine"] ? r.number(dn["cosine"], "base.displacement.cosine") : 0.0,
                              dn["sine"] ? r.number(dn["sine"], "base.displacement.sine") : 0.0});
  if (const YAML::Node list = dn["harmonics"]) {
    r.note(list);
    if (!list.IsSequence())
      r.fail(list, "base.displacement.harmonics", "expected a list of {order, cosine, sine}, found " + describe(list));
    for (std::size_t h = 0; h < list.size(); ++h) {
      const std::string path = "base.displacement.harmonics[" + std::to_string(h) + "]";
      const YAML::Node e = list[h];
      r.expect_map(e, path, {"order", "cosine", "sine"});
      if (!e["order"])
        r.fail(e, path + ".order", "missing: each harmonic needs its order k (a whole number ≥ 1; frequency k × forcing.frequency)");
      const long order = r.integer(e["order"], path + ".order", 1, 1000000);
      for (const BaseHarmonic& seen : b.displacement)
        if (seen.order == order)
          r.fail(e["order"], path + ".order",
                 "order " + std::to_string(order) + " is given twice" +
                     (order == 1 ? std::string(" (also as base.displacement.cosine/sine): give the first harmonic in one place")
                                 : std::string()));
      b.displacement.push_back({static_cast<int>(order), e["cosine"] ? r.number(e["cosine"], path + ".cosine") : 0.0,
                                e["sine"] ? r.number(e["sine"], path + ".sine") : 0.0});
    }
  }
  if (b.displacement.empty())
    r.fail(dn, "base.displacement", "expected at least one of cosine, sine, harmonics (the base motion x_b(t))");
  if (!(p.f.frequency > 0.0))
    r.fail(bn, "base", "a base motion moves at the forcing frequency: set forcing.frequency > 0");

  if (p.chain_links) {
    if (bn["influence"])
      r.fail(bn["influence"], "base.influence",
             "a chain's base is its walls, and every mass moves with them in a rigid motion of the rig (ι = 1): "
             "influence is for model.matrices");
    const models::Chain& c = *p.chain_links;
    if (c.left_spring == 0.0 && c.left_damper == 0.0 && c.right_spring == 0.0 && c.right_damper == 0.0)
      r.fail(bn, "base",
             "model.chain has no spring or dashpot to a wall (left_wall, right_wall): the base motion moves the walls, "
             "and without them it reaches no mass (a free chain on a shaken base feels the base only through the "
             "stops on the base: give those stops their own amplitude and phase instead)");
    b.influence = Eigen::VectorXd::Ones(n);
    b.stiffness = Eigen::VectorXd::Zero(n);
    b.damping = Eigen::VectorXd::Zero(n);
    b.stiffness(0) += c.left_spring;
    b.damping(0) += c.left_damper;
    b.stiffness(n - 1) += c.right_spring;
    b.damping(n - 1) += c.right_damper;
    b.inertia = Eigen::Map<const Eigen::VectorXd>(c.masses.data(), n);
  } else {
    if (!bn["influence"])
      r.fail(bn, "base.influence",
             "missing: for model.matrices, the influence vector ι (the coordinates' displacement when the whole rig "
             "moves rigidly by one unit; one entry per degree of freedom)");
    b.influence = to_vector(r.numbers(bn["influence"], "base.influence", n, "one entry per degree of freedom"));
    b.stiffness = p.K * b.influence;
    b.damping = p.C * b.influence;
    b.inertia = p.M * b.influence;
    if (b.frame == BaseFrame::absolute && b.stiffness.isZero(0.0) && b.damping.isZero(0.0))
      r.fail(bn["influence"], "base.influence",
             "K ι and C ι are zero: in absolute coordinates the base motion reaches no mass through springs or "
             "dashpots (ι is a rigid-body mode of the free structure)");
  }
  try {
    b.validate(n);
  } catch (const InvalidInput& e) {
    r.fail(bn, "base", e.what());
  }
  add_base_forcing(p.f, b);
  p.base = std::move(b);
}

void move_attached_stops(Reader& r, const YAML::Node& root, SceneParts& p, const std::vector<bool>& attached) {
  bool any = false;
  for (bool a : attached) any = any || a;
  if (!p.base) {
    if (any)
      for (std::size_t j = 0; j < attached.size(); ++j)
        if (attached[j])
          r.fail(root["stops"][j]["attached"], "stops[" + std::to_string(j) + "].attached",
                 "a stop attached to the base needs a base section (base.displacement)");
    return;
  }
  try {
    move_stops_with_base(p.stops, attached, *p.base);
  } catch (const InvalidInput& e) {
    const std::string msg = e.what();
    std::string path = "stops";
    YAML::Node where = root["stops"];
    if (msg.rfind("stops[", 0) == 0) {
      const std::size_t j = std::stoul(msg.substr(6));
      path = "stops[" + std::to_string(j) + "]";
      where = where[j];
      if (where["attached"]) where = where["attached"];
      r.fail(where, path, msg.substr(msg.find(": ") + 2));
    }
    r.fail(where ? where : root, path, msg);
  }
}

}  // namespace vibro::io::detail

namespace vibro::io::detail {

void check_result_frame(Reader& r, const YAML::Node& root, const SceneParts& p) {
  if (!p.base || p.rec.frame == p.base->frame) return;
  const YAML::Node run = root["run"];
  const std::string kind = run && run.IsMap() && run["kind"] && run["kind"].IsScalar() ? run["kind"].Scalar() : "";
  if (kind != "continue" && kind != "locate" && kind != "basin") return;
  r.fail(root["record"]["frame"], "record.frame",
         "run.kind " + kind + " writes its states in the frame the scene computes in (base.frame: " +
             (p.base->frame == BaseFrame::absolute ? "absolute" : "relative") +
             "): run the scene with base.frame set to the frame wanted (the two agree to rounding)");
}

}  // namespace vibro::io::detail
