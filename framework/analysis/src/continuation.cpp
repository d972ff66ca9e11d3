/// \file continuation.cpp
/// continue_orbits: the first branch through the orbit shot at p0, followed in both directions
/// from it (branch_runner.hpp) and joined in arclength order, then branch switching at the period
/// doublings located on it (branch_switching.hpp); and the options' checks and the names of the
/// bifurcation kinds. The method is described in continuation.hpp; its parts live in
/// corrector.cpp (evaluation, tangent, Newton corrector), branch_runner.cpp (stepping),
/// bifurcation_detection.cpp and bifurcation_location.cpp, test_functions.cpp,
/// event_signature.cpp, branch_switching.cpp and curves.cpp (two-parameter curves).
#include "vibro/continuation.hpp"

#include "branch_runner.hpp"
#include "branch_switching.hpp"
#include "vibro/bounded_wait.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace vibro {

using detail::BranchRunner;
using detail::Continuer;
using detail::Node;
using detail::stacked;
using Eigen::Index;
using Eigen::VectorXd;

const char* to_string(BifurcationKind kind) {
  switch (kind) {
    case BifurcationKind::fold: return "fold";
    case BifurcationKind::period_doubling: return "period_doubling";
    case BifurcationKind::neimark_sacker: return "neimark_sacker";
    case BifurcationKind::grazing: return "grazing";
    case BifurcationKind::rising: return "rising";
    case BifurcationKind::phase_change: return "phase_change";
    case BifurcationKind::chatter_change: return "chatter_change";
    case BifurcationKind::other: return "other";
    case BifurcationKind::branch_point: return "branch_point";
  }
  return "?";
}

std::vector<std::string> bifurcation_kind_names() {
  std::vector<std::string> out;
  for (int i = 0; i <= static_cast<int>(BifurcationKind::branch_point); ++i)
    out.emplace_back(to_string(static_cast<BifurcationKind>(i)));
  return out;
}

void ContinuationOptions::validate() const {
  auto bad = [](const std::string& field, double v, const std::string& rule) {
    throw InvalidInput("continue." + field + " = " + number_text(v) + ": " + rule);
  };
  if (!std::isfinite(p_min) || !std::isfinite(p_max) || !(p_min < p_max))
    throw InvalidInput("continue.range = [" + number_text(p_min) + ", " + number_text(p_max) +
                       "]: must be finite with p_min < p_max");
  if (direction != 1 && direction != -1) bad("direction", direction, "must be +1 (up) or −1 (down)");
  if (period < 1 || period > 1024) bad("period", period, "must be in [1, 1024]");
  if (!std::isfinite(phase)) bad("phase", phase, "must be finite");
  if (!(min_step > 0.0) || !(max_step >= min_step) || !std::isfinite(max_step))
    bad("max_step", max_step, "needs 0 < min_step ≤ max_step");
  if (!(step > 0.0) || !std::isfinite(step)) bad("step", step, "must be a finite number > 0");
  if (max_points < 2) bad("max_points", max_points, "must be ≥ 2");
  if (!(tolerance > 0.0) || !(tolerance < 1e-3)) bad("tolerance", tolerance, "must be in (0, 1e-3)");
  if (max_corrector_iterations < 2) bad("max_corrector_iterations", max_corrector_iterations, "must be ≥ 2");
  if (!(parameter_scale >= 0.0) || !std::isfinite(parameter_scale)) bad("parameter_scale", parameter_scale, "must be ≥ 0");
  if (!(locate_tolerance > 0.0) || !std::isfinite(locate_tolerance)) bad("locate_tolerance", locate_tolerance, "must be > 0");
  if (max_doublings < 0 || max_doublings > 8) bad("max_doublings", max_doublings, "must be in [0, 8]");
  if (max_branches < 1) bad("max_branches", max_branches, "must be ≥ 1");
  if (max_total_points < 2) bad("max_total_points", static_cast<double>(max_total_points), "must be ≥ 2");
  solver.validate();
}

namespace {

/// The dense engine at each p of `family` (which must outlive the result).
ContinuationFamily dense_engines(const ParameterFamily& family, const SimulatorOptions& solver) {
  return [&family, solver](double p) {
    FamilyPoint fp = family(p);
    return dense_family_engine(std::move(fp.system), std::move(fp.derivative), solver);
  };
}

}  // namespace

ContinuationResult continue_orbits(const ParameterFamily& family, double p0, double t_guess, const VectorXd& x,
                                   const VectorXd& v, const ContinuationOptions& options,
                                   const ContinuationProgress& progress) {
  return continue_orbits(dense_engines(family, options.solver), p0, t_guess, x, v, options, progress);
}

namespace {

/// Each point's state at the fixed phase θ (BranchPoint::x_fixed): its orbit run from its section
/// time t0 to the first t ≥ t0 with Ωt ≡ θ (mod 2π).
void carry_to_phase(const ContinuationFamily& family, BranchPoint& b, double theta, Index n) {
  b.x_fixed = VectorXd::Constant(n, detail::kNaN);
  b.v_fixed = VectorXd::Constant(n, detail::kNaN);
  try {
    std::unique_ptr<FamilyEngine> engine = family(b.p);
    const double w = engine->frequency();
    double t = (theta + detail::kTwoPi * std::ceil((w * b.t0 - theta) / detail::kTwoPi - 1e-12)) / w;
    if (t < b.t0) t += detail::kTwoPi / w;
    if (t == b.t0) {
      b.x_fixed = b.x;
      b.v_fixed = b.v;
      return;
    }
    const RunSummary r = engine->run(b.t0, b.x, b.v, t);
    if (r.status != RunStatus::completed) return;
    b.x_fixed = r.x;
    b.v_fixed = r.v;
  } catch (const InvalidInput&) {
  } catch (const Interrupted&) {  // the engine's set-up at p, bounded (bounded_wait.hpp): NaN, as a failed run
  }
}

}  // namespace

ContinuationResult continue_orbits(const ContinuationFamily& family, double p0, double t_guess, const VectorXd& x,
                                   const VectorXd& v, const ContinuationOptions& options_in,
                                   const ContinuationProgress& progress) {
  options_in.validate();
  // A copy: its max_points is lowered where the run's budget of points is nearer.
  ContinuationOptions options = options_in;
  if (!(p0 >= options.p_min && p0 <= options.p_max))
    throw InvalidInput("continuation: the start p = " + number_text(p0) + " is outside [" +
                       number_text(options.p_min) + ", " + number_text(options.p_max) + "]");
  std::unique_ptr<FamilyEngine> first = family(p0);
  const Index n = first->dof();
  const std::size_t stops = first->stop_count();
  ShootingOptions so;
  so.period = options.period;
  so.phase = options.phase;
  so.tolerance = options.tolerance;
  so.solver = options.solver;
  const ShootingResult start = first->shoot(so, t_guess, x, v);
  if (!start.converged())
    throw InvalidInput("continuation: no periodic orbit of period " + std::to_string(options.period) +
                       "T found at p = " + number_text(p0) + " from the guess: " + start.message);

  ContinuationResult result;
  Continuer c(family, options, n, stops, result);
  c.adopt(p0, std::move(first));
  c.theta = start.phase;
  c.k = options.period;
  c.L = start.length_scale;
  c.V = start.velocity_scale;
  c.P = options.parameter_scale > 0.0 ? options.parameter_scale : options.p_max - options.p_min;
  BranchRunner runner(c, options, result, progress);

  auto start_node = [&](const VectorXd& z, double p, const VectorXd& along) {
    Node s;
    s.e = c.evaluate(z, p);
    if (!s.e.ok) throw InvalidInput("continuation: the start orbit cannot be evaluated: " + s.e.why);
    s.t = c.tangent(s.e, along);
    s.b = c.point(s.e, s.t, 0);
    return s;
  };
  VectorXd up = VectorXd::Zero(2 * n + 1);
  up(2 * n) = options.direction;
  const Node s0 = start_node(stacked(start.x, start.v), p0, up);

  // Every point also at the fixed phase (the sections move along a branch).
  auto at_fixed_phase = [&] {
    result.fixed_phase = options.phase;
    for (Branch& b : result.branches)
      for (BranchPoint& q : b.points) carry_to_phase(family, q, options.phase, n);
    for (Bifurcation& b : result.bifurcations) carry_to_phase(family, b.point, options.phase, n);
  };
  std::vector<std::pair<Node, int>> doublings;
  detail::SwitchPoints branch_points;
  runner.branch_points = &branch_points;
  if (options.switch_at_start) {
    // Only the doubled branch from the start orbit, a period doubling (a restart at one).
    const FloquetMultipliers& mu = s0.b.multipliers;
    double nearest = std::numeric_limits<double>::infinity();
    for (Index j = 0; j < mu.values.size(); ++j) nearest = std::min(nearest, std::abs(mu.values(j) + 1.0));
    if (!(nearest <= 1e-3))
      throw InvalidInput("continuation: switch: period_doubling needs a start orbit at a period doubling, but the "
                         "start's multipliers are " + number_text(nearest) + " or more from −1");
    Branch start;
    start.k = c.k;
    start.points.push_back(s0.b);
    start.points.back().located = true;
    start.start = "the start orbit, a period doubling at p = " + number_text(p0);
    start.end = "not followed (switch: only the doubled branch is followed)";
    result.branches.push_back(std::move(start));
    doublings.emplace_back(s0, 0);
    detail::switch_at_doublings(family, options, c, doublings, 0, branch_points, result, progress);
    at_fixed_phase();
    return result;
  }

  // The first branch: one half in `direction`, the other from the start the other way.
  Branch forward, backward;
  forward.k = backward.k = c.k;
  const int max_points = options.max_points;
  options.max_points = static_cast<int>(std::min<long>(max_points, options.max_total_points));
  runner.append(forward, s0);
  // A factorisation interrupted (Interrupted, bounded_wait.hpp) ends a half where it is, as an
  // interrupted map does: the points so far are kept.
  const auto follow = [&](const VectorXd& along, Branch& half) {
    try {
      runner.follow(s0, along, half, 0, 0, &doublings);
    } catch (const Interrupted&) {
      half.end = "interrupted";
    }
  };
  follow(s0.t, forward);
  c.theta = s0.b.phase;  // the forward half may have moved the section
  const long left = options.max_total_points - static_cast<long>(forward.points.size());
  options.max_points = static_cast<int>(std::clamp<long>(left, 2, max_points));
  follow(-s0.t, backward);
  for (Branch* half : {&forward, &backward})
    if (options.max_points < max_points && static_cast<int>(half->points.size()) >= options.max_points) {
      half->end = "max_total_points (" + std::to_string(options.max_total_points) + ") reached: the run's budget of points";
      result.budget = "max_total_points (" + std::to_string(options.max_total_points) + ") reached (branch 0 cut short)";
    }
  options.max_points = max_points;
  Branch whole;
  whole.k = c.k;
  // The backward half was followed against the branch's orientation: reversed, its tangents too.
  for (auto it = backward.points.rbegin(); it != backward.points.rend(); ++it) {
    whole.points.push_back(*it);
    whole.points.back().tangent_p = -whole.points.back().tangent_p;
  }
  whole.points.insert(whole.points.end(), forward.points.begin(), forward.points.end());
  whole.start = "the orbit shot at p = " + number_text(p0);
  whole.end = "one end: " + backward.end + "; other end: " + forward.end;
  result.branches.push_back(std::move(whole));

  // Branch switching at period doublings (along the eigenvector of μ = −1, period 2k) and at
  // branch points (along the crossing branch), each new branch's own in turn.
  try {
    // Each call takes its list to the end, the entries its new branches add included (or stops
    // at the run's budget, saying what it left).
    std::size_t d = 0, b = 0;
    do {
      detail::switch_at_doublings(family, options, c, doublings, d, branch_points, result, progress);
      d = doublings.size();
      if (b < branch_points.size()) detail::switch_at_branch_points(family, options, c, branch_points, b, doublings, result, progress);
      b = branch_points.size();
    } while (d < doublings.size());
  } catch (const Interrupted&) {
  }

  at_fixed_phase();
  return result;
}

}  // namespace vibro
