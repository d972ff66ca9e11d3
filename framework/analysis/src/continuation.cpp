#include "vibro/continuation.hpp"

#include "section.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

namespace vibro {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kTwoPi = 2.0 * std::numbers::pi;
/// When the steps stall with an event within this fraction of T of the section (an impact drifting
/// through it with p makes the map over kT jump), continuation moves its section. Only then:
/// moving it whenever an event came near (tried at 1 % and 5 % of T) lost folds of the paper's
/// branch, since the guard against steps landing back on the branch cannot compare states across
/// sections and is reset at each move.
constexpr double kSectionMargin = 0.01;
/// An event within this fraction of T of the section is on it (shooting.cpp's test): the map over
/// kT jumps right there, whatever else the orbit is near.
constexpr double kSectionOnEvent = 1e-6;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

VectorXd stacked(const VectorXd& x, const VectorXd& v) {
  VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// Per stop, its events in order, with the impacts that belong to a chatter sequence told apart
/// from the free ones (a sequence's number of resolved bounces depends on the chatter rule's
/// threshold, not on the orbit; a free impact appearing or vanishing is a grazing).
/// A run of impacts of one stop ends at its next release, stick or chatter limit; a run ending in
/// a chatter limit holds its sequence from the impact after its longest flight on (the flights
/// measured from the event that opened the run: a sequence's flights shrink towards the limit, a
/// free bounce before it is separated from it by a longer flight); the impacts before that are
/// free. The orbit is closed: the events are taken cyclically, the run still open at the end of
/// the window continuing into the one that opens it, so the counts do not depend on where the
/// section cuts the orbit.
struct StopEvents {
  std::vector<ImpactRecord> free_impacts;  ///< impacts outside chatter sequences
  int chatters = 0, phases = 0;
};

std::vector<StopEvents> per_stop(const TangentMap& m, std::size_t stops) {
  struct Item {
    double t;
    EventKind kind;
    std::size_t impact;  ///< index into m.impacts (impacts only)
  };
  std::vector<std::vector<Item>> items(stops);
  std::size_t next_impact = 0;
  for (const Event& e : m.events) {
    const auto j = static_cast<std::size_t>(e.stop);
    const bool impact = e.kind == EventKind::impact;
    const std::size_t index = impact && next_impact < m.impacts.size() ? next_impact++ : m.impacts.size();
    if (j >= stops || (impact && index == m.impacts.size())) continue;
    items[j].push_back({e.t, e.kind, index});
  }
  const double span = m.t1 - m.t0;
  std::vector<StopEvents> out(stops);
  for (std::size_t j = 0; j < stops; ++j) {
    std::vector<Item>& it = items[j];
    // Rotate so that the events start just after the last closing event, one orbit earlier.
    std::size_t last_close = it.size();
    for (std::size_t i = 0; i < it.size(); ++i)
      if (it[i].kind != EventKind::impact) last_close = i;
    if (last_close < it.size()) {
      for (std::size_t i = last_close + 1; i < it.size(); ++i) it[i].t -= span;
      std::rotate(it.begin(), it.begin() + static_cast<std::ptrdiff_t>(last_close + 1), it.end());
    }
    double opened = it.empty() ? m.t0 : it.back().t - span;  // the closing event before the first
    std::vector<const Item*> run;
    for (const Item& e : it) {
      if (e.kind == EventKind::impact) {
        run.push_back(&e);
        continue;
      }
      std::size_t first_caught = run.size();  // stick, release: every impact of the run is free
      if (e.kind == EventKind::chatter_limit && !run.empty()) {
        double longest = -1.0, before = opened;
        for (std::size_t i = 0; i < run.size(); ++i) {
          if (run[i]->t - before > longest) longest = run[i]->t - before, first_caught = i;
          before = run[i]->t;
        }
      }
      for (std::size_t i = 0; i < first_caught; ++i) out[j].free_impacts.push_back(m.impacts[run[i]->impact]);
      run.clear();
      opened = e.t;
      if (e.kind == EventKind::chatter_limit) ++out[j].chatters;
      if (e.kind != EventKind::release) ++out[j].phases;
    }
    for (const Item* e : run) out[j].free_impacts.push_back(m.impacts[e->impact]);  // no closing event at all
  }
  return out;
}

/// The test functions of the non-structural multipliers.
double doubling_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  std::complex<double> p = 1.0;
  for (Index i = 0; i < d; ++i) p *= 1.0 + f.values(i);
  return p.real();
}
double torus_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  std::complex<double> p = 1.0;
  for (Index i = 0; i < d; ++i)
    for (Index j = i + 1; j < d; ++j) p *= f.values(i) * f.values(j) - 1.0;
  return p.real();
}
bool has_unit_pair(const FloquetMultipliers& f, double tol) {
  const Index d = f.values.size() - f.structural_zeros;
  for (Index i = 0; i < d; ++i)
    if (std::abs(f.values(i).imag()) > tol && std::abs(std::abs(f.values(i)) - 1.0) < tol) return true;
  return false;
}

/// One evaluated point (z, p): the map over kT at the branch's section phase.
struct Eval {
  bool ok = false;
  std::string why;
  double p = 0.0;
  VectorXd z;
  double t0 = 0.0, omega = 0.0;
  TangentMap map;
  VectorXd F, Pp;     ///< P(z) − z and ∂P/∂p (with the section and period moving with Ω)
  double residual = std::numeric_limits<double>::infinity();
};

/// The continuation of one branch family; holds the scales and the section.
class Continuer {
 public:
  Continuer(const ContinuationFamily& family, const ContinuationOptions& o, Index n, std::size_t stops,
            ContinuationResult& result)
      : family_(family), o_(o), n_(n), stops_(stops), result_(result) {}

  /// The engine at p: the last one made if it was made at this p (Newton at fixed p, shooting
  /// then evaluating, a section move: the modal engine's set-up and its contact sets' modes are
  /// paid once), else a new one. Valid until the next call with another p. Throws as the family.
  FamilyEngine& engine_at(double p) {
    if (!engine_ || !(engine_p_ == p)) {
      engine_.reset();
      engine_ = family_(p);
      engine_p_ = p;
    }
    return *engine_;
  }
  /// Takes `engine`, made at p, as the last one made.
  void adopt(double p, std::unique_ptr<FamilyEngine> engine) {
    engine_ = std::move(engine);
    engine_p_ = p;
  }

  double theta = 0.0;  ///< the section phase of the branch being followed
  int k = 1;
  double L = 1.0, V = 1.0, P = 1.0;

  VectorXd D() const {
    VectorXd d(2 * n_);
    d << VectorXd::Constant(n_, L), VectorXd::Constant(n_, V);
    return d;
  }
  VectorXd scaled(const Eval& e) const {
    VectorXd y(2 * n_ + 1);
    y << e.z.cwiseQuotient(D()), e.p / P;
    return y;
  }
  VectorXd scaled(const BranchPoint& b) const {
    VectorXd y(2 * n_ + 1);
    y << stacked(b.x, b.v).cwiseQuotient(D()), b.p / P;
    return y;
  }

  Eval evaluate(const VectorXd& z, double p) {
    Eval e;
    e.p = p;
    e.z = z;
    ++result_.maps;
    try {
      FamilyEngine& engine = engine_at(p);
      e.omega = engine.frequency();
      if (!(e.omega > 0.0)) throw InvalidInput("the forcing frequency must be > 0 at p = " + number_text(p));
      const double T = kTwoPi / e.omega;
      e.t0 = theta / e.omega;
      const double t1 = e.t0 + k * T;
      LinearisationOptions lo;
      lo.parameter = engine.derivative;
      lo.features = true;
      e.map = engine.linearise(e.t0, z.head(n_), z.tail(n_), t1, lo);
      if (e.map.summary.status != RunStatus::completed) {
        e.why = std::string("run stopped early (") + to_string(e.map.summary.status) + "): " + e.map.summary.message;
        return e;
      }
      const double dw = engine.derivative.frequency;
      const double dt0 = -theta / (e.omega * e.omega) * dw;
      const double dt1 = dt0 - k * kTwoPi / (e.omega * e.omega) * dw;
      e.Pp = e.map.parameter + e.map.rate_end * dt1 - e.map.jacobian * (e.map.rate_start * dt0);
      e.F = stacked(e.map.x1, e.map.v1) - z;
      e.residual = e.F.cwiseQuotient(D()).cwiseAbs().maxCoeff();
      e.ok = true;
    } catch (const InvalidInput& err) {
      e.why = err.what();
    }
    return e;
  }

  /// DF in scaled variables: [D⁻¹ (J − I) D, D⁻¹ ∂P/∂p P].
  MatrixXd jacobian(const Eval& e) const {
    const VectorXd d = D();
    MatrixXd A(2 * n_, 2 * n_ + 1);
    A.leftCols(2 * n_) = d.cwiseInverse().asDiagonal() * (e.map.jacobian - MatrixXd::Identity(2 * n_, 2 * n_)) * d.asDiagonal();
    A.col(2 * n_) = e.Pp.cwiseQuotient(d) * P;
    return A;
  }

  /// The unit null vector of DF oriented along `along`.
  VectorXd tangent(const Eval& e, const VectorXd& along) const {
    const Index N = 2 * n_ + 1;
    MatrixXd B(N, N);
    B.topRows(N - 1) = jacobian(e);
    B.row(N - 1) = along.transpose();
    VectorXd rhs = VectorXd::Zero(N);
    rhs(N - 1) = 1.0;
    VectorXd t = B.fullPivLu().solve(rhs);
    if (!t.allFinite() || t.norm() == 0.0) {  // `along` ⟂ the null space: take it from the SVD
      Eigen::JacobiSVD<MatrixXd> svd(jacobian(e), Eigen::ComputeFullV);
      t = svd.matrixV().col(N - 1);
    }
    t.normalize();
    if (t.dot(along) < 0.0) t = -t;
    return t;
  }

  /// Newton on [F(y); nᵀ(y − y_pred)] = 0 from y_pred: a point on the branch in the hyperplane
  /// through y_pred normal to n. Returns a failed Eval when it does not converge.
  Eval correct(const VectorXd& y_pred, const VectorXd& n, int* iterations = nullptr) {
    const Index N = 2 * n_ + 1;
    const VectorXd d = D();
    VectorXd y = y_pred;
    Eval e;
    double last = std::numeric_limits<double>::infinity();
    for (int it = 0; it <= o_.max_corrector_iterations; ++it) {
      e = evaluate(d.cwiseProduct(y.head(2 * n_)), y(2 * n_) * P);
      if (!e.ok) return e;
      const double g = n.dot(y - y_pred);
      const double r = std::max(e.residual, std::abs(g));
      if (iterations) *iterations = it;
      // The map's own rounding, amplified by J, sets a floor under the residual: near grazing
      // (J ~ 1/u) it can exceed the tolerance, and the orbit is then as periodic as it can be.
      const MatrixXd A = jacobian(e);
      const double floor = 100.0 * std::numeric_limits<double>::epsilon() *
                           std::max(1.0, A.leftCols(2 * n_).cwiseAbs().rowwise().sum().maxCoeff());
      if (e.residual <= std::max(o_.tolerance, floor) && std::abs(g) <= 1e3 * o_.tolerance) return e;
      if (it >= 2 && r > 0.5 * last) {  // not converging (quadratically or at all): give up
        e.ok = false;
        e.why = "corrector stalled at residual " + number_text(r);
        return e;
      }
      last = r;
      MatrixXd B(N, N);
      B.topRows(N - 1) = A;
      B.row(N - 1) = n.transpose();
      VectorXd rhs(N);
      rhs << -e.F.cwiseQuotient(d), -g;
      const VectorXd delta = B.fullPivLu().solve(rhs);
      if (!delta.allFinite()) {
        e.ok = false;
        e.why = "singular corrector system";
        return e;
      }
      y += delta;
    }
    e.ok = false;
    e.why = "corrector did not converge in " + std::to_string(o_.max_corrector_iterations) + " iterations";
    return e;
  }

  /// Whether the orbit of e already closes after `periods` forcing periods (to 1e3 × tolerance).
  bool closes_after(const Eval& e, int periods) {
    const RunSummary r = engine_at(e.p).run(e.t0, e.z.head(n_), e.z.tail(n_), e.t0 + periods * kTwoPi / e.omega);
    if (r.status != RunStatus::completed) return false;
    const double res = std::max((r.x - e.z.head(n_)).cwiseAbs().maxCoeff() / L,
                                (r.v - e.z.tail(n_)).cwiseAbs().maxCoeff() / V);
    return res <= 1e3 * o_.tolerance;
  }

  BranchPoint point(const Eval& e, const VectorXd& t, int iterations) const {
    BranchPoint b;
    b.p = e.p;
    b.phase = theta;
    b.t0 = e.t0;
    b.x = e.z.head(n_);
    b.v = e.z.tail(n_);
    b.k = k;
    b.multipliers = floquet_multipliers(e.map, k);
    b.signature = orbit_signature(e.map, k, stops_);
    b.sticking = Eigen::VectorXd::Zero(static_cast<Index>(stops_));
    const double span = e.map.t1 - e.map.t0;
    for (const HeldPhase& h : e.map.phases)
      b.sticking(h.stop) += std::max(0.0, std::min(h.t_end, e.map.t1) - std::max(h.t_start, e.map.t0)) / span;
    b.tangent_p = t.size() ? t(2 * n_) : 0.0;
    b.residual = e.residual;
    b.corrector_iterations = iterations;
    return b;
  }

  const ContinuationFamily& family_;
  const ContinuationOptions& o_;
  Index n_;
  std::size_t stops_;
  ContinuationResult& result_;

 private:
  std::unique_ptr<FamilyEngine> engine_;
  double engine_p_ = kNaN;
};

/// A point of the branch as continuation keeps it: evaluated, with its tangent.
struct Node {
  Eval e;
  VectorXd t;
  BranchPoint b;
};

/// The scalar whose zero is located between two branch points (NaN: not defined at this point,
/// the location falls back to bisection on the event signature).
using TestFunction = std::function<double(const Node&)>;

class BranchRunner {
 public:
  BranchRunner(Continuer& c, const ContinuationOptions& o, ContinuationResult& result,
               const ContinuationProgress& progress)
      : c_(c), o_(o), result_(result), progress_(progress) {}

  /// Follows the branch from `start` along `t` (unit, scaled), appending to `branch`.
  void follow(Node start, VectorXd t, Branch& branch, int branch_index, int depth,
              std::vector<std::pair<Node, int>>* doublings) {
    Node cur = std::move(start);
    cur.t = c_.tangent(cur.e, t);
    double h = std::min(std::max(o_.step, o_.min_step), o_.max_step);
    double last_dp = h * c_.P;
    bool jump_tried = false, resection_tried = false;
    std::vector<VectorXd> trail{c_.scaled(cur.e)};  // the points of this half, scaled
    while (static_cast<int>(branch.points.size()) < o_.max_points) {
      int iterations = 0;
      Node next;
      const VectorXd y_pred = c_.scaled(cur.e) + h * cur.t;
      next.e = c_.correct(y_pred, cur.t, &iterations);
      // A corrector that travels further than the step has found another branch crossing the
      // hyperplane (near corners and folds): not the continuation of this one.
      if (next.e.ok && (c_.scaled(next.e) - y_pred).norm() > h) {
        next.e.ok = false;
        next.e.why = "the corrector left the predictor by more than the step";
      }
      if (!next.e.ok) {
        h *= 0.5;
        // Across a grazing or a rising the branch has a corner and the map's derivative blows up
        // on one side: arclength steps shrink towards it. Past a few halvings near such a point,
        // step over it in p (the orbit on the far side is found by Newton at fixed p).
        // An event drifting into the section faster than the margin allows makes the map jump
        // within the step: move the section further from it (once per stall) and go on.
        // Near a grazing or a rising the jump comes first (it keeps the section, and with it the
        // guard against landing back on the branch); once it has failed, or landed on the part
        // already followed, an event on the section is the cause left. (The three-mass chain of
        // experiments/examples at Ω ≈ 0.18446: an impact of s3 reaches the section on the
        // unstable side of a fold, where every orbit found at fixed p is the stable one; and
        // near_nonsmooth holds all along that branch, whose chatter bounces are slow.)
        const bool on_event =
            detail::section_clearance(cur.e.map) < kSectionOnEvent * kTwoPi / cur.e.omega;
        if (h < 1e-2 * o_.max_step && !resection_tried && (!near_nonsmooth(cur) || (jump_tried && on_event))) {
          resection_tried = true;
          const double old_theta = c_.theta;
          if (std::optional<Node> moved = resection(cur, kSectionMargin)) {
            cur = std::move(*moved);
            carry(trail, old_theta);
            trail.push_back(c_.scaled(cur.e));
            continue;
          }
        }
        std::optional<Node> jumped;
        if (h < 1e-3 * o_.max_step && !jump_tried && near_nonsmooth(cur)) {
          jump_tried = true;
          jumped = jump(cur, last_dp);
        }
        if (!jumped) {
          if (h < o_.min_step) {
            branch.end = "step below min_step at p = " + number_text(cur.e.p) + " (" + next.e.why + ")";
            if (near_nonsmooth(cur)) locate_at_end(cur, last_dp, branch_index);
            return;
          }
          continue;
        }
        next = std::move(*jumped);
        h = std::clamp(std::abs(next.e.p - cur.e.p) / c_.P, o_.min_step, o_.max_step);
      } else {
        // Oriented along cur's tangent on a smooth stretch; where the step crossed a grazing or
        // a rising (the events changed) the branch may turn back in p at the corner: for now
        // along the step in p, and examine() turns it away from the point it locates there.
        next.b = c_.point(next.e, cur.t, iterations);
        VectorXd along = cur.t;
        if (!(next.b.signature == cur.b.signature)) {
          along.setZero();
          along(along.size() - 1) = next.e.p > cur.e.p ? 1.0 : -1.0;
        }
        next.t = c_.tangent(next.e, along);
        next.b.tangent_p = next.t(next.t.size() - 1);
      }
      // Near a fold beside a corner the two parts of the branch come close: a step (or a jump)
      // that lands back on a part already followed is not the continuation. Refused if the new
      // point is nearer to an earlier point than to the last one.
      // (The last few points are left out: at a sharp corner the new part starts beside them.)
      if (trail.size() >= 5) {
        const VectorXd y = c_.scaled(next.e);
        const double from_cur = (y - trail.back()).norm();
        bool back = false;
        for (std::size_t i = 0; i + 4 < trail.size(); ++i) back |= (y - trail[i]).norm() < 0.25 * from_cur;
        if (back) {
          h *= 0.5;
          if (h < o_.min_step) {
            branch.end = "step below min_step at p = " + number_text(cur.e.p) + " (steps land on the branch already followed)";
            return;
          }
          continue;
        }
      }
      // A doubled branch that closes after half its period has merged back into its parent
      // (at a period doubling of the parent: doubled branches often join two of them).
      if (c_.k > o_.period && c_.closes_after(next.e, c_.k / 2)) {
        branch.end = "merged into the period-" + std::to_string(c_.k / 2) + "T branch near p = " + number_text(next.e.p);
        return;
      }
      // Leaving the scan limits: place the last point on the limit.
      const bool out = next.e.p < o_.p_min || next.e.p > o_.p_max;
      if (out) {
        const double limit = next.e.p > o_.p_max ? o_.p_max : o_.p_min;
        if (auto last = on_limit(cur, next, limit)) {
          examine(cur, *last, branch_index, depth, doublings);
          append(branch, *last);
        }
        branch.end = std::string("reached p_") + (limit == o_.p_max ? "max" : "min") + " = " + number_text(limit);
        return;
      }
      examine(cur, next, branch_index, depth, doublings);
      append(branch, next);
      last_dp = std::max(std::abs(next.e.p - cur.e.p), 1e-9 * c_.P);
      trail.push_back(c_.scaled(next.e));
      cur = std::move(next);
      jump_tried = resection_tried = false;
      if (iterations <= 3) h = std::min(1.5 * h, o_.max_step);
      else if (iterations >= 6) h = std::max(0.6 * h, o_.min_step);
    }
    branch.end = "max_points (" + std::to_string(o_.max_points) + ") reached";
  }

  /// An orbit near a grazing (an impact slower than 1e-3 V, or a gap maximum within 1e-3 L of
  /// its stop) or a rising (an interior contact-force minimum within 1e-3 F of zero).
  static bool near_nonsmooth(const Node& n) {
    const TangentMap& m = n.e.map;
    const double L = m.summary.length_scale, F = m.summary.force_scale;
    if (m.least_guard_rate < 1e-3) return true;
    for (const GapPeak& g : m.gap_peaks)
      if (g.value > -1e-3 * L) return true;
    for (const ForceDip& d : m.force_dips)
      if (!d.past_release && d.value < 1e-3 * F) return true;
    return false;
  }

  /// The orbit a little further in p, by Newton at fixed p from cur's state: steps of 4, 8, 16 …
  /// times the last step in p, up to 2 % of the parameter scale, first onwards; then backwards,
  /// where only an orbit with other events counts (at a grazing corner the branch beyond the
  /// non-smooth point turns back in p; an orbit with cur's events there is the way we came).
  /// A doubled branch accepts no orbit that closes after half its period (its parent's).
  std::optional<Node> jump(const Node& cur, double last_dp) {
    const double dir = cur.t(cur.t.size() - 1);
    if (std::abs(dir) < 1e-6) return std::nullopt;  // at a fold p cannot be stepped
    for (const double sign : {1.0, -1.0}) {
      for (double dp = 4.0 * last_dp; dp <= 0.02 * c_.P; dp *= 2.0) {
        const double p = cur.e.p + sign * (dir > 0.0 ? dp : -dp);
        // The far side's tangent points away from the non-smooth point: along the jump in p.
        VectorXd away = VectorXd::Zero(cur.t.size());
        away(away.size() - 1) = p > cur.e.p ? 1.0 : -1.0;
        std::optional<Node> m = shoot_at(cur, p, away);
        if (!m) continue;
        if (sign < 0.0 && m->b.signature == cur.b.signature) continue;
        if (c_.k > o_.period && c_.closes_after(m->e, c_.k / 2)) continue;
        return m;
      }
    }
    return std::nullopt;
  }

  /// The orbit at p by Newton shooting with its trust region (shooting.hpp) from `from`'s state:
  /// more patient than the corrector where the map is steep on one side (near grazing).
  std::optional<Node> shoot_at(const Node& from, double p, const VectorXd& along) {
    ShootingOptions so;
    so.period = c_.k;
    so.phase = c_.theta;
    so.free_section = false;
    so.tolerance = o_.tolerance;
    so.solver = o_.solver;
    const Index n = c_.n_;
    ShootingResult r;
    try {
      r = c_.engine_at(p).shoot(so, from.e.t0, from.e.z.head(n), from.e.z.tail(n));
    } catch (const InvalidInput&) {
      return std::nullopt;
    }
    if (!r.converged()) return std::nullopt;
    Node m;
    m.e = c_.evaluate(stacked(r.x, r.v), p);
    if (!m.e.ok) return std::nullopt;
    m.t = c_.tangent(m.e, along);
    m.b = c_.point(m.e, m.t, r.iterations);
    return m;
  }

  /// Where a branch cannot be continued past a grazing or a rising (its steps shrink to nothing
  /// against the non-smooth point), the point is still located, from this side: the orbit's
  /// nearest approach to a stop (or its least interior contact force) extrapolated to zero.
  void locate_at_end(const Node& cur, double last_dp, int branch_index) {
    const TangentMap& m = cur.e.map;
    const double L = m.summary.length_scale, F = m.summary.force_scale;
    int graze = -1, rise = -1;
    double best_gap = -1e-3 * L, best_force = 1e-3 * F;
    for (const GapPeak& g : m.gap_peaks)
      if (g.value > best_gap) best_gap = g.value, graze = g.stop;
    for (const ForceDip& d : m.force_dips)
      if (!d.past_release && d.value < best_force) best_force = d.value, rise = d.stop;
    const double dir = cur.t(cur.t.size() - 1) > 0.0 ? 1.0 : -1.0;
    Node beyond = cur;
    beyond.e.p = cur.e.p + dir * std::max(last_dp, 1e-9 * c_.P);
    const std::string note = "the branch could not be continued past it; located from this side";
    if (graze >= 0) {
      const auto j = static_cast<std::size_t>(graze);
      const int fewer = cur.b.signature.impacts[j];
      const TestFunction f = [this, j, fewer](const Node& n) { return grazing_function(n, j, fewer, fewer + 1); };
      record(BifurcationKind::grazing, graze, cur, beyond, branch_index, f, Mode::one_sided,
             same_counts(cur.b.signature, j, &Signature::impacts), note);
    }
    if (rise >= 0) {
      const auto j = static_cast<std::size_t>(rise);
      const int fewer = cur.b.signature.phases[j];
      const TestFunction f = [this, j, fewer](const Node& n) { return rising_function(n, j, fewer); };
      record(BifurcationKind::rising, rise, cur, beyond, branch_index, f, Mode::one_sided,
             same_counts(cur.b.signature, j, &Signature::phases), note);
    }
  }

  /// The branch's section moved into the middle of the longest stretch of cur's orbit free of
  /// events and held phases, if an event has come within margin·T of it (events drift with p; an
  /// impact crossing the section makes the map over kT jump, and a section on a held stop is not
  /// free). The state there is cur's orbit at the new time; the tangent is carried to it by the
  /// tangent map of the stretch between and the section's own motion with Ω, so the orientation
  /// along the branch survives a move at a fold. nullopt (the section unchanged) when no move is
  /// needed or none is better.
  std::optional<Node> resection(const Node& cur, double margin) {
    const TangentMap& g = cur.e.map;
    const double T = kTwoPi / cur.e.omega, clearance = detail::section_clearance(g);
    if (clearance >= margin * T) return std::nullopt;
    const auto [mid, half] = detail::free_section(g);
    if (half <= clearance || mid <= cur.e.t0) return std::nullopt;
    const Index n = c_.n_, N = 2 * n;
    FamilyEngine& engine = c_.engine_at(cur.e.p);
    LinearisationOptions lo;
    lo.parameter = engine.derivative;
    const TangentMap m = engine.linearise(cur.e.t0, cur.e.z.head(n), cur.e.z.tail(n), mid, lo);
    ++result_.maps;
    if (m.summary.status != RunStatus::completed) return std::nullopt;
    // z'(p) = φ(t'(p); t0(p), z(p), p) with t0 = θ/Ω and t' = θ'/Ω (θ' = Ω·mid, unwrapped).
    // (`engine` is not used after the corrector below, which may replace it.)
    const double w = cur.e.omega, dw = engine.derivative.frequency, theta_mid = w * mid;
    const double dt0 = -c_.theta / (w * w) * dw, dt1 = -theta_mid / (w * w) * dw;
    const VectorXd Pp = m.parameter + m.rate_end * dt1 - m.jacobian * (m.rate_start * dt0);
    const VectorXd d = c_.D();
    VectorXd along(N + 1);
    along.head(N) = (m.jacobian * d.cwiseProduct(cur.t.head(N)) + Pp * (c_.P * cur.t(N))).cwiseQuotient(d);
    along(N) = cur.t(N);
    along.normalize();
    const double old_theta = c_.theta;
    c_.theta = std::fmod(theta_mid, kTwoPi);
    VectorXd y(N + 1);
    y << stacked(m.x1, m.v1).cwiseQuotient(d), cur.e.p / c_.P;
    Node moved;
    int iterations = 0;
    moved.e = c_.correct(y, along, &iterations);  // a polish: it starts on the orbit
    if (!moved.e.ok || std::abs(moved.e.p - cur.e.p) > 1e-6 * c_.P) {
      c_.theta = old_theta;
      return std::nullopt;
    }
    moved.t = c_.tangent(moved.e, along);
    moved.b = c_.point(moved.e, moved.t, iterations);
    return moved;
  }

  /// The trail's points (scaled, at the section phase old_theta) carried to the branch's section
  /// now, each by a run of its own orbit from the old section time to the new one, so that the
  /// guard against steps landing back on the branch still sees the part followed before a move
  /// (reset instead, it let a jump from the unstable side of a fold land on the stable side
  /// already followed and retrace it). The last point (cur, in the old section) is dropped: the
  /// caller appends its moved state. A point whose run fails is dropped too.
  void carry(std::vector<VectorXd>& trail, double old_theta) const {
    const Index n = c_.n_, N = 2 * n;
    const VectorXd d = c_.D();
    double turn = std::fmod(c_.theta - old_theta, kTwoPi);
    if (turn < 0.0) turn += kTwoPi;
    std::vector<VectorXd> carried;
    for (std::size_t i = 0; i + 1 < trail.size(); ++i) {
      const double p = trail[i](N) * c_.P;
      FamilyEngine& engine = c_.engine_at(p);
      const double w = engine.frequency();
      const VectorXd z = trail[i].head(N).cwiseProduct(d);
      RunSummary r;
      try {
        r = engine.run(old_theta / w, z.head(n), z.tail(n), (old_theta + turn) / w);
      } catch (const InvalidInput&) {
        continue;
      }
      if (r.status != RunStatus::completed) continue;
      VectorXd y(N + 1);
      y << stacked(r.x, r.v).cwiseQuotient(d), trail[i](N);
      carried.push_back(std::move(y));
    }
    trail = std::move(carried);
  }

  void append(Branch& branch, const Node& n) {
    branch.points.push_back(n.b);
    if (progress_) progress_(branch, n.b);
  }

 private:
  /// The point between a and b (in the hyperplanes normal to a's tangent) where p = limit.
  std::optional<Node> on_limit(const Node& a, const Node& b, double limit) {
    auto f = [&](const Node& n) { return n.e.p - limit; };
    return illinois(a, b, f, true, nullptr);
  }

  /// Illinois iteration on σ ∈ [0, σ_b] for a zero of f between a and b (f(a) f(b) < 0), each
  /// evaluation the branch point in the hyperplane a + σ t_a (normal t_a). With bisect, or
  /// where f is NaN, it halves instead.
  std::optional<Node> illinois(const Node& a, const Node& b, const TestFunction& f, bool smooth, int* count,
                               const std::function<bool(const Node&)>& same_as_a = {}) {
    const VectorXd ya = c_.scaled(a.e);
    double s_lo = 0.0, s_hi = a.t.dot(c_.scaled(b.e) - ya);
    double f_lo = smooth ? f(a) : -1.0, f_hi = smooth ? f(b) : 1.0;
    if (smooth && (!std::isfinite(f_lo) || !std::isfinite(f_hi))) smooth = false, f_lo = -1.0, f_hi = 1.0;
    Node lo = a, hi = b;
    int side = 0;
    double s_last = std::numeric_limits<double>::infinity();
    for (int it = 0; it < 100; ++it) {
      double s = 0.5 * (s_lo + s_hi);
      if (smooth) s = s_hi - f_hi * (s_hi - s_lo) / (f_hi - f_lo);
      if (!(s > s_lo && s < s_hi)) s = 0.5 * (s_lo + s_hi);
      Node m;
      m.e = c_.correct(ya + s * a.t, a.t);
      if (count) ++*count;
      if (!m.e.ok) return std::nullopt;
      m.t = c_.tangent(m.e, a.t);
      m.b = c_.point(m.e, m.t, 0);
      m.b.located = true;
      double fm = smooth ? f(m) : kNaN;
      if (smooth && !std::isfinite(fm)) smooth = false;
      bool to_lo;
      if (smooth) {
        to_lo = (fm < 0.0) == (f_lo < 0.0);
      } else {
        to_lo = same_as_a ? same_as_a(m) : (m.e.p - a.e.p) * (b.e.p - a.e.p) < 0.0;
      }
      if (to_lo) {
        s_lo = s;
        f_lo = smooth ? fm : f_lo;
        lo = m;
        if (smooth && side == -1) f_hi *= 0.5;
        side = -1;
      } else {
        s_hi = s;
        f_hi = smooth ? fm : f_hi;
        hi = m;
        if (smooth && side == +1) f_lo *= 0.5;
        side = +1;
      }
      // In σ (scaled arclength): |Δp| ≤ |Δσ| P, and at a fold p is stationary in σ while the
      // test function (t_p) is not, so converging σ is what locates every kind.
      const double width = std::abs(s_hi - s_lo) * c_.P;
      const double s_step = std::abs(s - s_last) * c_.P;
      s_last = s;
      if (width <= o_.locate_tolerance || (smooth && (fm == 0.0 || s_step <= 0.1 * o_.locate_tolerance))) {
        Node best = smooth ? m : (same_as_a ? lo : m);
        best.b.p = best.e.p;
        bracket_low_ = std::min(lo.e.p, hi.e.p);
        bracket_high_ = std::max(lo.e.p, hi.e.p);
        located_smooth_ = smooth;
        return best;
      }
    }
    return std::nullopt;
  }

  /// How a bifurcation between two neighbours is located.
  enum class Mode {
    two_sided,   ///< Illinois on the arclength: f smooth through the zero (fold, PD, NS)
    one_sided,   ///< secant in p from the side where f is defined and smooth (grazing, rising)
    bisection    ///< on the event signature: the condition is not smooth in p
  };

  /// The branch point at p (the hyperplane p = const), Newton from `from`'s state.
  std::optional<Node> at_p(const Node& from, double p, const VectorXd& along) {
    VectorXd y = c_.scaled(from.e);
    y(y.size() - 1) = p / c_.P;
    VectorXd n = VectorXd::Zero(y.size());
    n(n.size() - 1) = 1.0;
    Node m;
    int it = 0;
    m.e = c_.correct(y, n, &it);
    if (!m.e.ok) return std::nullopt;
    m.t = c_.tangent(m.e, along);
    m.b = c_.point(m.e, m.t, it);
    m.b.located = true;
    return m;
  }

  /// A zero of f located from the side of `good` only, where f is defined and smooth (on_good
  /// says whether a point is on that side): secant steps in p through the two nearest good
  /// points (the first step goes half way towards `bad`). A trial point that has no orbit or
  /// lies on the other side halves the step back towards the last good point. The zero may lie
  /// beyond the good point, away from `bad`: at a grazing corner both branches reach the grazing
  /// from the same side in p. Ends when the secant's next step is below half the tolerance; the
  /// zero is that step's end, the orbit the last good point's.
  std::optional<Node> one_sided(const Node& good, const Node& bad, const TestFunction& f,
                                const std::function<bool(const Node&)>& on_good, int* count) {
    struct Good {
      double p, f;
      Node node;
    };
    std::vector<Good> g{{good.e.p, f(good), good}};
    double toward = bad.e.p;
    const VectorXd along = good.t;
    // The zero lies within the bracket or, at a corner, beyond one of its ends: after a jump from
    // the unstable side of a fold onto the branch without the impact, the corner lies below both
    // points by a few times their distance (the paper's system at A1 = 0.4939: 2.6 ×, where a
    // reach of 2 × left only a bisection between two branches). A secant that leads further has
    // left the orbit family.
    const double reach = 8.0 * std::abs(bad.e.p - good.e.p);
    const double lo = std::min(good.e.p, bad.e.p) - reach, hi = std::max(good.e.p, bad.e.p) + reach;
    const bool doubled = c_.k > o_.period;
    for (int it = 0; it < 60; ++it) {
      const Good& last = g.back();
      double p = 0.5 * (last.p + toward);
      if (g.size() >= 2) {
        const Good& prev = g[g.size() - 2];
        if (last.f == prev.f) break;
        const double root = last.p - last.f * (last.p - prev.p) / (last.f - prev.f);
        if (std::abs(root - last.p) <= 0.5 * o_.locate_tolerance) {
          located_p_ = root;
          bracket_low_ = std::min(last.p, root);
          bracket_high_ = std::max(last.p, root);
          return last.node;
        }
        if (!(root >= lo && root <= hi)) return std::nullopt;
        p = root;
      }
      bool stepped = false;
      for (int attempt = 0; attempt < 40 && !stepped; ++attempt) {
        if (std::abs(p - last.p) <= 0.5 * o_.locate_tolerance) break;
        std::optional<Node> m = at_p(last.node, p, along);
        if (count) ++*count;
        const double fm = m ? f(*m) : kNaN;
        if (m && on_good(*m) && std::isfinite(fm) && !(doubled && c_.closes_after(m->e, c_.k / 2))) {
          g.push_back({p, fm, *m});
          stepped = true;
        } else {
          p = last.p + 0.5 * (p - last.p);
        }
      }
      if (!stepped) {  // the good side ends within the tolerance of the last good point
        located_p_ = p;
        bracket_low_ = std::min(g.back().p, p);
        bracket_high_ = std::max(g.back().p, p);
        return g.back().node;
      }
    }
    return std::nullopt;
  }

  /// Bisection in p on a discrete property (same_as_a: whether a point is on a's side), each
  /// point by Newton at fixed p from the nearer bracket end's orbit (or the farther one's if
  /// that fails). Returns a's-side end of the final bracket; where no orbit can be found inside
  /// the bracket it stops there and reports the bracket reached.
  std::optional<Node> bisect(const Node& a, const Node& b, const std::function<bool(const Node&)>& same_as_a,
                             int* count) {
    Node lo = a, hi = b;
    for (int it = 0; it < 80 && std::abs(hi.e.p - lo.e.p) > o_.locate_tolerance; ++it) {
      const double p = 0.5 * (lo.e.p + hi.e.p);
      std::optional<Node> m = at_p(lo, p, lo.t);
      if (count) ++*count;
      if (!m) {
        m = at_p(hi, p, hi.t);
        if (count) ++*count;
      }
      if (!m) break;
      if (same_as_a(*m)) lo = *m;
      else hi = *m;
    }
    bracket_low_ = std::min(lo.e.p, hi.e.p);
    bracket_high_ = std::max(lo.e.p, hi.e.p);
    located_smooth_ = false;
    return lo;
  }

  void record(BifurcationKind kind, int stop, const Node& a, const Node& b, int branch_index,
              const TestFunction& f, Mode mode, const std::function<bool(const Node&)>& same_as_a,
              const std::string& note) {
    Bifurcation bif;
    bif.kind = kind;
    bif.stop = stop;
    bif.branch = branch_index;
    bif.note = note;
    bif.p_low = std::min(a.e.p, b.e.p);
    bif.p_high = std::max(a.e.p, b.e.p);
    bif.p = 0.5 * (a.e.p + b.e.p);
    bif.smooth = false;
    bif.value = kNaN;
    bif.point = b.b;
    if (!o_.locate) {
      result_.bifurcations.push_back(bif);
      return;
    }
    int count = 0;
    std::optional<Node> at;
    located_p_ = kNaN;
    if (mode == Mode::one_sided) {
      const bool a_good = same_as_a(a);  // same_as_a tells the good side here
      at = a_good ? one_sided(a, b, f, same_as_a, &count) : one_sided(b, a, f, same_as_a, &count);
      located_smooth_ = at.has_value();
      if (!at) {
        at = bisect(a, b, same_as_a, &count);
        bif.note += std::string(bif.note.empty() ? "" : "; ") + "the smooth location failed: bracketed by bisection";
      }
    } else if (mode == Mode::bisection) {
      at = bisect(a, b, same_as_a, &count);
    } else {
      at = illinois(a, b, f, true, &count, same_as_a);
    }
    bif.evaluations = count;
    if (!at) {
      bif.note += (bif.note.empty() ? "" : "; ") + std::string("not located (a corrector failed in the bracket)");
    } else {
      bif.p = std::isfinite(located_p_) ? located_p_ : at->e.p;
      bif.point = at->b;
      bif.smooth = located_smooth_;
      bif.p_low = bracket_low_;
      bif.p_high = bracket_high_;
      bif.value = located_smooth_ ? f(*at) : kNaN;
      if (!located_smooth_) bif.p = 0.5 * (bif.p_low + bif.p_high);
      last_located_ = *at;
    }
    result_.bifurcations.push_back(bif);
  }

  void examine(const Node& a, Node& b, int branch_index, int depth,
               std::vector<std::pair<Node, int>>* doublings) {
    const std::size_t stops = a.b.signature.impacts.size();
    // Fold: the tangent's p component changes sign on a smooth stretch. Across a change of the
    // event signature a sign change is the corner where two branches meet (at a grazing the
    // branches with and without the impact reach it from the same side in p).
    const bool turns = a.t(a.t.size() - 1) * b.t(b.t.size() - 1) < 0.0;
    if (turns && a.b.signature == b.b.signature) {
      const TestFunction f = [](const Node& n) { return n.t(n.t.size() - 1); };
      record(BifurcationKind::fold, -1, a, b, branch_index, f, Mode::two_sided, {}, "");
    }
    const FloquetMultipliers& ma = a.b.multipliers;
    const FloquetMultipliers& mb = b.b.multipliers;
    if (ma.structural_zeros == mb.structural_zeros && a.b.signature == b.b.signature) {
      // Period doubling and Neimark–Sacker need a smooth map between the points.
      if (doubling_test(ma) * doubling_test(mb) < 0.0) {
        const TestFunction f = [](const Node& n) { return doubling_test(n.b.multipliers); };
        record(BifurcationKind::period_doubling, -1, a, b, branch_index, f, Mode::two_sided, {}, "");
        if (doublings && depth < o_.max_doublings && result_.bifurcations.back().smooth)
          doublings->push_back({last_located_, branch_index});
      }
      if (torus_test(ma) * torus_test(mb) < 0.0) {
        const TestFunction f = [](const Node& n) { return torus_test(n.b.multipliers); };
        const std::size_t before = result_.bifurcations.size();
        record(BifurcationKind::neimark_sacker, -1, a, b, branch_index, f, Mode::two_sided, {}, "");
        if (result_.bifurcations.size() > before && !has_unit_pair(result_.bifurcations.back().point.multipliers, 1e-6))
          result_.bifurcations.pop_back();  // a neutral saddle (real μ_i μ_j = 1), not a torus
      }
    }
    const Signature& sa = a.b.signature;
    const Signature& sb = b.b.signature;
    if (sa == sb) return;
    const std::size_t first_new = result_.bifurcations.size();
    bool explained = false;
    for (std::size_t j = 0; j < stops; ++j) {
      const int stop = static_cast<int>(j);
      if (sa.impacts[j] != sb.impacts[j] && sa.chatters[j] == sb.chatters[j] && sa.phases[j] == sb.phases[j]) {
        explained = true;
        const int fewer = std::min(sa.impacts[j], sb.impacts[j]), more = std::max(sa.impacts[j], sb.impacts[j]);
        const TestFunction f = [this, j, fewer, more](const Node& n) { return grazing_function(n, j, fewer, more); };
        // Located from the side without the grazing impact, where the orbit's nearest approach
        // (its largest gap maximum) is smooth in p; the impacting side's map is not (its
        // Jacobian grows like 1/u as the impact speed u → 0).
        const auto fewer_side = [j, fewer](const Node& n) { return n.b.signature.impacts[j] == fewer; };
        const Node& good = fewer_side(a) ? a : b;
        const bool ok = std::isfinite(f(good)) && f(good) < 0.0;
        record(BifurcationKind::grazing, stop, a, b, branch_index, f, ok ? Mode::one_sided : Mode::bisection,
               ok ? fewer_side : same_counts(sa, j, &Signature::impacts),
               ok ? "" : "no gap maximum on the side without the impact: bracketed by bisection");
      }
      if (sa.phases[j] != sb.phases[j]) {
        explained = true;
        const int fewer = std::min(sa.phases[j], sb.phases[j]);
        const TestFunction f = [this, j, fewer](const Node& n) { return rising_function(n, j, fewer); };
        const auto fewer_side = [j, fewer](const Node& n) { return n.b.signature.phases[j] == fewer; };
        const Node& good = fewer_side(a) ? a : b;
        const Node& other = fewer_side(a) ? b : a;
        // Rising: on the unsplit side an interior force minimum falls to zero; on the split side
        // the held flow continued past the release needs a negative force. (The new part of the
        // split phase usually starts with a chatter, so the chatter count moves with it.)
        const bool rising = std::isfinite(f(good)) && f(good) > 0.0 && std::isfinite(f(other)) && f(other) < 0.0;
        const std::string how = sa.chatters[j] != sb.chatters[j] ? "entered by chatter" : "entered by an impact";
        record(rising ? BifurcationKind::rising : BifurcationKind::phase_change, stop, a, b, branch_index, f,
               rising ? Mode::one_sided : Mode::bisection, rising ? fewer_side : same_counts(sa, j, &Signature::phases),
               rising ? "" : "a contact phase (" + how + ") appears or vanishes; not smooth in p (it depends on the chatter rule): bracketed by bisection");
      } else if (sa.chatters[j] != sb.chatters[j]) {
        explained = true;
        record(BifurcationKind::chatter_change, stop, a, b, branch_index, {}, Mode::bisection,
               same_counts(sa, j, &Signature::chatters), "not smooth in p: bracketed by bisection");
      }
    }
    if (!explained) {
      const Signature sig = sa;
      record(BifurcationKind::other, -1, a, b, branch_index, {}, Mode::bisection,
             [sig](const Node& n) { return n.b.signature == sig; }, "event signature changed: " + sa.text() + " → " + sb.text());
    }
    point_away(a, b, first_new);
    if (a.t(a.t.size() - 1) * b.t(b.t.size() - 1) < 0.0)
      for (std::size_t i = first_new; i < result_.bifurcations.size(); ++i)
        result_.bifurcations[i].note += std::string(result_.bifurcations[i].note.empty() ? "" : "; ") +
                                        "the branch turns back in p here (a corner)";
  }

  /// The part of the branch beyond a grazing or a rising leaves the non-smooth point: b's tangent
  /// is turned to point away from the nearest of the points located between a and b (from
  /// result_.bifurcations[first] on) by solving their condition. The orientation b had, along
  /// the step in p, is right where the step crossed the point in p, but at a corner whose two
  /// parts lie on the same side in p, a step that lands between a and the point in p turns b
  /// back into it (the three-mass chain of experiments/examples at Ω ≈ 0.18063: the branch with
  /// one impact of s3 fewer was followed down into the grazing until the steps gave out).
  /// Unchanged where nothing was located smoothly (bisected changes, locate off), or where b
  /// lies on the point (within 1e-3 of the step: the chord's direction is then rounding).
  void point_away(const Node& a, Node& b, std::size_t first) const {
    const VectorXd yb = c_.scaled(b.e);
    VectorXd chord;
    for (std::size_t i = first; i < result_.bifurcations.size(); ++i) {
      const Bifurcation& f = result_.bifurcations[i];
      if (!f.smooth) continue;
      const VectorXd from_point = yb - c_.scaled(f.point);
      if (chord.size() == 0 || from_point.norm() < chord.norm()) chord = from_point;
    }
    if (chord.size() == 0 || chord.norm() <= 1e-3 * (yb - c_.scaled(a.e)).norm()) return;
    if (b.t.dot(chord) < 0.0) {
      b.t = -b.t;
      b.b.tangent_p = b.t(b.t.size() - 1);
    }
  }

  static std::function<bool(const Node&)> same_counts(const Signature& s, std::size_t j,
                                                     std::vector<int> Signature::*field) {
    const int count = (s.*field)[j];
    return [count, j, field](const Node& n) { return (n.b.signature.*field)[j] == count; };
  }

  /// Nearest approach of the orbit to stop j (see continuation.hpp): the largest interior gap
  /// maximum when j has `fewer` free impacts, the smallest u²/(2|g''|) of its free impacts when it
  /// has `more`; NaN otherwise.
  double grazing_function(const Node& n, std::size_t j, int fewer, int more) const {
    const int count = n.b.signature.impacts[j];
    if (count == fewer) {
      double best = -std::numeric_limits<double>::infinity();
      for (const GapPeak& g : n.e.map.gap_peaks)
        if (g.stop == static_cast<int>(j)) best = std::max(best, g.value);
      return std::isfinite(best) ? best : kNaN;
    }
    if (count == more) {
      const std::vector<StopEvents> ev = per_stop(n.e.map, c_.stops_);
      double best = std::numeric_limits<double>::infinity();
      for (const ImpactRecord& r : ev[j].free_impacts)
        if (r.acceleration < 0.0) best = std::min(best, r.speed * r.speed / (2.0 * -r.acceleration));
      return std::isfinite(best) ? best : kNaN;
    }
    return kNaN;
  }

  /// Rising of stop j: the least interior minimum of its contact force with `fewer` phases, the
  /// least force the held flow continued past a release would need with more.
  double rising_function(const Node& n, std::size_t j, int fewer) const {
    const int count = n.b.signature.phases[j];
    double best = std::numeric_limits<double>::infinity();
    for (const ForceDip& d : n.e.map.force_dips)
      if (d.stop == static_cast<int>(j) && d.past_release == (count != fewer)) best = std::min(best, d.value);
    return std::isfinite(best) ? best : kNaN;
  }

  Continuer& c_;
  const ContinuationOptions& o_;
  ContinuationResult& result_;
  const ContinuationProgress& progress_;
  Node last_located_;
  double located_p_ = kNaN;  ///< one-sided location: the extrapolated zero
  double bracket_low_ = 0.0, bracket_high_ = 0.0;
  bool located_smooth_ = true;
};

}  // namespace

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
  }
  return "?";
}

std::vector<std::string> bifurcation_kind_names() {
  std::vector<std::string> out;
  for (int i = 0; i <= static_cast<int>(BifurcationKind::other); ++i)
    out.emplace_back(to_string(static_cast<BifurcationKind>(i)));
  return out;
}

std::string Signature::text() const {
  std::ostringstream s;
  s << "k=" << k;
  for (std::size_t j = 0; j < impacts.size(); ++j)
    s << " s" << j << ":i" << impacts[j] << "c" << chatters[j] << "h" << phases[j];
  return s.str();
}

Signature orbit_signature(const TangentMap& m, int k, std::size_t stops) {
  Signature s;
  s.k = k;
  const std::vector<StopEvents> ev = per_stop(m, stops);
  for (const StopEvents& e : ev) {
    s.impacts.push_back(static_cast<int>(e.free_impacts.size()));
    s.chatters.push_back(e.chatters);
    s.phases.push_back(e.phases);
  }
  return s;
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

ContinuationResult continue_orbits(const ContinuationFamily& family, double p0, double t_guess, const VectorXd& x,
                                   const VectorXd& v, const ContinuationOptions& options,
                                   const ContinuationProgress& progress) {
  options.validate();
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

  // The first branch: one half in `direction`, the other from the start the other way.
  std::vector<std::pair<Node, int>> doublings;
  Branch forward, backward;
  forward.k = backward.k = c.k;
  runner.append(forward, s0);
  runner.follow(s0, s0.t, forward, 0, 0, &doublings);
  c.theta = s0.b.phase;  // the forward half may have moved the section
  runner.follow(s0, -s0.t, backward, 0, 0, &doublings);
  Branch whole;
  whole.k = c.k;
  // The backward half was followed against the branch's orientation: reversed, its tangents too.
  for (auto it = backward.points.rbegin(); it != backward.points.rend(); ++it) {
    whole.points.push_back(*it);
    whole.points.back().tangent_p = -whole.points.back().tangent_p;
  }
  whole.points.insert(whole.points.end(), forward.points.begin(), forward.points.end());
  whole.end = "one end: " + backward.end + "; other end: " + forward.end;
  result.branches.push_back(std::move(whole));

  // Branch switching at period doublings: along the eigenvector of μ = −1, period 2k.
  for (std::size_t i = 0; i < doublings.size(); ++i) {
    const auto [at, parent] = doublings[i];
    const TangentMap& m = at.e.map;
    Eigen::EigenSolver<MatrixXd> es(m.reduced);
    Index best = -1;
    for (Index j = 0; j < es.eigenvalues().size(); ++j)
      if (best < 0 || std::abs(es.eigenvalues()(j) + 1.0) < std::abs(es.eigenvalues()(best) + 1.0)) best = j;
    if (best < 0) continue;
    const VectorXd e = m.lift * es.eigenvectors().col(best).real();
    const int depth = static_cast<int>(std::log2(static_cast<double>(result.branches[static_cast<std::size_t>(parent)].k) /
                                                 options.period)) + 1;
    Continuer child(family, options, n, stops, result);
    child.theta = at.b.phase;  // the section where the doubling was found
    child.k = 2 * result.branches[static_cast<std::size_t>(parent)].k;
    child.L = c.L;
    child.V = c.V;
    child.P = c.P;
    BranchRunner child_runner(child, options, result, progress);
    Node s;
    s.e = child.evaluate(at.e.z, at.e.p);
    if (!s.e.ok) continue;
    VectorXd dir = VectorXd::Zero(2 * n + 1);
    dir.head(2 * n) = e.cwiseQuotient(child.D());
    dir.normalize();
    s.t = dir;
    s.b = child.point(s.e, dir, 0);
    s.b.located = true;
    // The doubled branch leaves the PD point along the eigenvector with p stationary
    // (p − p* ~ a², a the amplitude along e), while the old branch — also 2k-periodic — crosses
    // the same hyperplanes at p − p* ~ h: with h small enough the corrector lands on the new
    // branch. A point whose k-map already closes is the old one: retry with a smaller step.
    const int parent_k = result.branches[static_cast<std::size_t>(parent)].k;
    std::optional<Node> first;
    for (double h : {1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5}) {
      Node m;
      m.e = child.correct(child.scaled(s.e) + h * dir, dir);
      if (!m.e.ok) continue;
      if (c.closes_after(m.e, parent_k)) continue;
      m.t = child.tangent(m.e, dir);
      m.b = child.point(m.e, m.t, 0);
      first = std::move(m);
      break;
    }
    Branch b;
    b.k = child.k;
    b.parent = parent;
    const int index = static_cast<int>(result.branches.size());
    child_runner.append(b, s);
    if (!first) {
      b.end = "branch switching failed: every step along the eigenvector of μ = −1 fell back onto the period-" +
              std::to_string(parent_k) + "T branch";
      result.branches.push_back(std::move(b));
      continue;
    }
    child_runner.append(b, *first);
    child_runner.follow(*first, first->t, b, index, depth, depth < options.max_doublings ? &doublings : nullptr);
    result.branches.push_back(std::move(b));
  }
  return result;
}

void CurveOptions::validate() const {
  if (!(p2_min < p2_max) || !std::isfinite(p2_min) || !std::isfinite(p2_max))
    throw InvalidInput("curve.range: p2_min < p2_max required");
  if (!(p1_min < p1_max) || !std::isfinite(p1_min) || !std::isfinite(p1_max))
    throw InvalidInput("curve: p1 limits: p1_min < p1_max required");
  if (!(step > 0.0) || !std::isfinite(step)) throw InvalidInput("curve.step = " + number_text(step) + ": must be > 0");
  if (max_points < 2) throw InvalidInput("curve.max_points must be ≥ 2");
  if (direction != 1 && direction != -1) throw InvalidInput("curve.direction must be +1 or −1");
}

Curve follow_curve(const PlaneFamily& family, const Bifurcation& start, double p2_start, const CurveOptions& options) {
  const SimulatorOptions solver = options.branch.solver;
  const PlaneContinuationFamily engines = [&family, solver](double p1, double p2) {
    PlanePoint pp = family(p1, p2);
    std::unique_ptr<FamilyEngine> engine = dense_family_engine(std::move(pp.system), pp.d1, solver);
    return PlaneEngine{std::move(engine), std::move(pp.d1), std::move(pp.d2)};
  };
  return follow_curve(engines, start, p2_start, options);
}

Curve follow_curve(const PlaneContinuationFamily& family, const Bifurcation& start, double p2_start,
                   const CurveOptions& options) {
  options.validate();
  if (start.kind != BifurcationKind::grazing && start.kind != BifurcationKind::rising)
    throw InvalidInput(std::string("curve: only grazing and rising points can be followed, not ") + to_string(start.kind));
  Curve curve;
  curve.kind = start.kind;
  curve.stop = start.stop;
  const double P1 = options.scale1 > 0.0 ? options.scale1 : options.p1_max - options.p1_min;
  const double P2 = options.scale2 > 0.0 ? options.scale2 : options.p2_max - options.p2_min;
  CurvePoint c0;
  c0.p1 = start.p;
  c0.p2 = p2_start;
  c0.value = start.value;
  c0.point = start.point;
  curve.points.push_back(c0);
  // Direction along the curve in scaled (p1/P1, p2/P2): first p2, then the secant.
  Eigen::Vector2d dir(0.0, options.direction);
  double h = options.step;
  while (static_cast<int>(curve.points.size()) < options.max_points) {
    const CurvePoint& last = curve.points.back();
    if (curve.points.size() >= 2) {
      const CurvePoint& prev = curve.points[curve.points.size() - 2];
      Eigen::Vector2d s((last.p1 - prev.p1) / P1, (last.p2 - prev.p2) / P2);
      if (s.norm() > 0.0) dir = s.normalized();
    }
    const Eigen::Vector2d normal(-dir(1), dir(0));
    const double a1 = last.p1 + h * dir(0) * P1, a2 = last.p2 + h * dir(1) * P2;
    if (a2 < options.p2_min || a2 > options.p2_max || a1 < options.p1_min || a1 > options.p1_max) {
      curve.end = "left the parameter limits";
      return curve;
    }
    // The family along the normal line through the predictor: σ in scaled units.
    const ContinuationFamily line = [&](double sigma) {
      const double q1 = a1 + sigma * normal(0) * P1, q2 = a2 + sigma * normal(1) * P2;
      PlaneEngine pe = family(q1, q2);
      pe.engine->derivative = pe.d1.combined(normal(0) * P1, pe.d2, normal(1) * P2);
      return std::move(pe.engine);
    };
    ContinuationOptions lo = options.branch;
    lo.period = last.point.k;
    lo.phase = last.point.phase;
    lo.p_min = -4.0 * h;
    lo.p_max = 4.0 * h;
    lo.parameter_scale = 1.0;
    lo.step = std::min(h, lo.max_step);
    lo.max_points = 60;
    lo.max_doublings = 0;
    // Continue along the line from the previous curve point's orbit until the kind is found.
    bool found = false;
    ContinuationResult r;
    try {
      r = continue_orbits(line, 0.0, last.point.t0, last.point.x, last.point.v, lo);
    } catch (const InvalidInput& e) {
      curve.end = std::string("no orbit near the predictor: ") + e.what();
      return curve;
    }
    // The located point of the kind nearest to the predictor.
    const Bifurcation* best = nullptr;
    for (const Bifurcation& b : r.bifurcations)
      if (b.kind == start.kind && b.stop == start.stop && b.smooth && (!best || std::abs(b.p) < std::abs(best->p)))
        best = &b;
    if (best) {
      CurvePoint cp;
      cp.p1 = a1 + best->p * normal(0) * P1;
      cp.p2 = a2 + best->p * normal(1) * P2;
      cp.value = best->value;
      cp.point = best->point;
      curve.points.push_back(cp);
      found = true;
    }
    if (!found) {
      h *= 0.5;
      if (h < 1e-6) {
        curve.end = "the curve was lost (no located point on the line across it)";
        return curve;
      }
    } else {
      h = std::min(1.5 * h, 4.0 * options.step);
    }
  }
  curve.end = "max_points reached";
  return curve;
}

}  // namespace vibro
