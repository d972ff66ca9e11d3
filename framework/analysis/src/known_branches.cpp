/// \file known_branches.cpp
/// Recognising a branch already followed: an orbit compared with the orbits of a known branch of
/// the same period, through its shifted states and the known branch's own corrector
/// (known_branches.hpp).
#include "known_branches.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

namespace vibro::detail {
namespace {

/// Points at the end of a branch its own next point is not compared with (shift 0).
constexpr std::size_t kRecent = 10;

/// The scaled states of y's orbit at the section phase theta, one per forcing period, from the
/// first time ≥ t0 with Ωt ≡ theta (mod 2π); empty where a run fails.
std::vector<VectorXd> states_at(Continuer& c, const Node& y, double theta) {
  const Index n = c.n_;
  const double w = y.e.omega, T = kTwoPi / w;
  double turns = std::ceil((w * y.e.t0 - theta) / kTwoPi - 1e-12);
  double t = (theta + kTwoPi * turns) / w;
  if (t < y.e.t0) t += T;
  const VectorXd d = c.D();
  std::vector<VectorXd> out;
  VectorXd x = y.e.z.head(n), v = y.e.z.tail(n);
  double from = y.e.t0;
  try {
    FamilyEngine& engine = c.engine_at(y.e.p);
    for (int j = 0; j < c.k; ++j) {
      const double to = t + j * T;
      if (to > from) {
        const RunSummary r = engine.run(from, x, v, to);
        if (r.status != RunStatus::completed) return {};
        x = r.x;
        v = r.v;
        from = to;
      }
      VectorXd s(2 * n + 1);
      s << stacked(x, v).cwiseQuotient(d), y.e.p / c.P;
      out.push_back(std::move(s));
    }
  } catch (const InvalidInput&) {
    return {};
  }
  return out;
}

/// Against one branch; `shifted` caches y's states per section phase.
std::optional<KnownMatch> on_branch(Continuer& c, const Node& y, const Branch& branch, bool self,
                                    std::map<double, std::vector<VectorXd>>& shifted) {
  if (branch.k != c.k || branch.points.size() < 2) return std::nullopt;
  const double p = y.e.p, tolerance = 1e3 * c.o_.tolerance;
  const std::vector<BranchPoint>& q = branch.points;
  for (std::size_t i = 0; i + 1 < q.size(); ++i) {
    if (q[i].phase != q[i + 1].phase || q[i].k != c.k || q[i + 1].k != c.k) continue;
    // The bracket in p, widened by a quarter of its width (a fold between the two points).
    const double lo = std::min(q[i].p, q[i + 1].p), hi = std::max(q[i].p, q[i + 1].p), pad = 0.25 * (hi - lo);
    if (p < lo - pad || p > hi + pad) continue;
    auto found = shifted.find(q[i].phase);
    if (found == shifted.end()) found = shifted.emplace(q[i].phase, states_at(c, y, q[i].phase)).first;
    const VectorXd a = c.scaled(q[i]), b = c.scaled(q[i + 1]);
    const double chord = (b - a).norm();
    if (!(chord > 0.0)) continue;
    const VectorXd u = (b - a) / chord;
    // On its own branch the orbit itself (j = 0) counts only against points well behind it (a
    // branch come round to where it was); the last ones lie on its own continuation.
    const bool recent = self && i + kRecent >= q.size();
    for (std::size_t j = recent ? 1 : 0; j < found->second.size(); ++j) {
      const VectorXd& Y = found->second[j];
      const double s = u.dot(Y - a);
      if (s < -0.25 * chord || s > 1.25 * chord || (Y - a - s * u).norm() > 0.5 * chord + 10.0 * tolerance) continue;
      Continuer known(c.family_, c.o_, c.n_, c.stops_, c.result_);
      known.theta = q[i].phase;
      known.k = c.k;
      known.L = c.L;
      known.V = c.V;
      known.P = c.P;
      const Eval e = known.correct(a + s * u, u);
      if (!e.ok) continue;
      const double distance = (known.scaled(e) - Y).cwiseAbs().maxCoeff();
      if (distance <= tolerance) return KnownMatch{-1, static_cast<int>(j), distance, p};
    }
  }
  return std::nullopt;
}

}  // namespace

std::optional<KnownMatch> orbit_on_branch(Continuer& c, const Node& y, const Branch& branch, bool self) {
  std::map<double, std::vector<VectorXd>> shifted;
  return on_branch(c, y, branch, self, shifted);
}

std::optional<KnownMatch> on_known_branch(Continuer& c, const Node& y, const Branch* current, int current_index) {
  std::map<double, std::vector<VectorXd>> shifted;  // y's states per section phase
  for (std::size_t b = 0; b < c.result_.branches.size(); ++b)
    if (std::optional<KnownMatch> m = on_branch(c, y, c.result_.branches[b], false, shifted)) {
      m->branch = static_cast<int>(b);
      return m;
    }
  if (current)
    if (std::optional<KnownMatch> m = on_branch(c, y, *current, true, shifted)) {
      m->branch = current_index;
      return m;
    }
  return std::nullopt;
}

}  // namespace vibro::detail
