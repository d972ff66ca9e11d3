#pragma once
/// \file reference_hybrid.hpp
/// An independent reference for the hybrid simulator (header-only, tests only).
///
/// ReferenceHybrid integrates a vibro-impact system with a *fixed-step* Runge–Kutta method and
/// handles every event on its own. It shares nothing with vibro::Simulator but the input data
/// (the matrices, the forcing, and each stop's kind, mass, position, amplitude, phase and
/// restitution): no matrix exponential, no eigen-decomposition of the generator, no contact LCP,
/// no reduced flow, no certified bounds, no chatter jump inside the integration.
///
/// Scope: diagonal M and stops on single masses (Stop::upper / Stop::lower, fixed or moving) —
/// the setting of Wagg (2004). Stop j acts on mass i = i(j) with side σ = +1 (upper,
/// x_i ≤ P_j(t)) or σ = -1 (lower, x_i ≥ P_j(t)), where P_j(t) = p + a cos(Ωt + φ).
///
///  * Free flight: x' = v, v' = M⁻¹ (f(t) - C v - K x), f(t) = F0 + Fc cos Ωt + Fs sin Ωt plus any
///    extra harmonics Fc_h cos kΩt + Fs_h sin kΩt (their cos kΩt + i sin kΩt taken as the k-th
///    power of the clock's cos Ωt + i sin Ωt, de Moivre, not from the framework), integrated by the
///    11-stage, order-8 Cooper–Verner method (tableau in reference_integrator.hpp) in long double
///    with a fixed step h, h·ρ = step_rate (ρ = max(|λ(A)|, k_max Ω), A = [0 I; -M⁻¹K -M⁻¹C]). The
///    local error per step is ≈ (hρ)⁹/9! ≈ 5e-18 of the state at step_rate 0.05 (measured in
///    test_flow.cpp), so ~4e4 steps accumulate ≲ 2e-13. Measured on the paper's system over
///    50 periods (test_simulator.cpp): halving the step from 0.05 moves impact times by ≲ 7e-13
///    and release times by ≲ 3e-13.
///  * Sticking of mass i on stop j: x_i = P_j(t), x_i'' = P_j''(t); the other masses keep their
///    rows of the full equations (M diagonal, so the stop's force acts on row i only). The
///    contact force follows from row i of  M x'' = f - C v - K x - σ λ e_i:
///        λ_j = σ (F_i - m_i P_j''),   F = f(t) - C v - K x,
///    which for the paper is -F2 of eq. (12) (mass 1 on s1, σ = -1) and +F1 of eq. (15) (mass 2
///    on s2, σ = +1); it is positive while the stop holds.
///  * Events are guards crossing from ≤ 0 to > 0: the gap σ (x_i - P_j) of a free stop and -λ_j
///    of a held one. Each step compares the guards at both ends; if a guard's rate changes sign
///    from + to - inside a step with both ends ≤ 0, the interior maximum is located (bisection on
///    the rate) and tested too, so an excursion past a stop inside one step is not missed. The
///    crossing is located by safeguarded Newton on the sub-step length θ (one RK step of
///    length θ from the step start: same order of accuracy as a full step) down to a few units
///    of rounding in t (~1e-16 at t ~ 1e3 in long double), or to the gap's rounding over its rate
///    where that is coarser (bounces slower than ~1e-7); the state is taken on the far side of
///    the root (guard > 0 by at most that much).
///  * Impact (Newton's law on the relative velocity): v_i⁺ = P' - r (v_i⁻ - P'), x_i := P(t).
///    When the rebound speed |g'⁺| is below stick_velocity and the stop, if held, would push
///    (λ > 0), the mass sticks (v_i := P'). So chatter is resolved by integrating the bounces
///    themselves down to stick_velocity, default 1e-7 (bounce heights ~1e-14, ~1e6 ulps of a
///    position of order 0.3 in long double); the stick event's t_limit adds the accumulation
///    time of the remaining, unresolved bounces. Integrating on to 1e-9 (heights ~1e-18, ~50
///    ulps) was measured to make the accumulation time noisier (~1e-8), not better.
///  * Release where λ_j crosses zero (located like any other guard); after every event, stops
///    whose force is no longer positive (an impact of another mass can make it jump) are
///    released at once.
///
/// Usage:
///     vibro::test::ReferenceHybrid ref(scene);
///     ref.run(0.0L, x0, v0, t_end);           // long double vectors (VectorL)
///     for (const vibro::test::ReferenceEvent& e : ref.events) ...
#include "support/reference_integrator.hpp"
#include "vibro/stops.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace vibro::test {

enum class ReferenceEventKind { impact, stick, release };

struct ReferenceEvent {
  long double t = 0.0L;
  int stop = -1;
  ReferenceEventKind kind = ReferenceEventKind::impact;
  long double v_before = 0.0L;  ///< g' before (> 0: approaching); impacts and sticks
  long double v_after = 0.0L;   ///< g' after; impacts
  /// Sticks only: where the bounces too slow to integrate would have accumulated. The last
  /// bounce left at |g'⁺| = r u < stick_velocity under the approach acceleration a = λ/m of the
  /// held stop; its remaining flights 2 r u/a, 2 r² u/a, … sum to Δ = 2 r u / (a (1 - r))
  /// (Budd & Dux 1994), exact for constant a; a drifting a moves the true accumulation point by
  /// O(Δ² |a'/a|): ≲ 1e-10 for u < 1e-7 and a ≳ 0.1 (Δ ≲ 5e-6).
  long double t_limit = 0.0L;
};

struct ReferenceHybridOptions {
  long double step_rate = 0.05L;       ///< h · ρ
  long double stick_velocity = 1e-7L;  ///< rebounds slower than this stick (if the stop holds)
  long max_events = 2000000;           ///< safety net against a runaway run
};

class ReferenceHybrid {
 public:
  /// Up to this many degrees of freedom the state lives on the stack (no allocation per stage).
  static constexpr int max_dof = 16;
  using Vec = Eigen::Matrix<long double, Eigen::Dynamic, 1, 0, max_dof, 1>;
  using Mat = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic, 0, max_dof, max_dof>;

  explicit ReferenceHybrid(const ImpactSystem& scene, ReferenceHybridOptions options = {})
      : options_(options) {
    const LinearSystem& sys = scene.system();
    n_ = sys.dof();
    if (n_ > max_dof) throw std::invalid_argument("reference: at most max_dof masses");
    const Eigen::MatrixXd& M = sys.mass();
    for (Eigen::Index i = 0; i < n_; ++i)
      for (Eigen::Index k = 0; k < n_; ++k)
        if (i != k && M(i, k) != 0.0) throw std::invalid_argument("reference: M must be diagonal");
    mass_ = M.diagonal().cast<long double>();
    damping_ = sys.damping().cast<long double>();
    stiffness_ = sys.stiffness().cast<long double>();
    f0_ = sys.forcing().constant.cast<long double>();
    fc_ = sys.forcing().cosine.cast<long double>();
    fs_ = sys.forcing().sine.cast<long double>();
    omega_ = sys.forcing().frequency;
    int top_order = 1;
    for (const ForcingHarmonic& h : sys.forcing().harmonics) {
      orders_.push_back(h.order);
      hc_.push_back(h.cosine.cast<long double>());
      hs_.push_back(h.sine.cast<long double>());
      top_order = std::max(top_order, h.order);
    }
    for (const Stop& s : scene.stops()) {
      if (s.kind == Stop::Kind::between)
        throw std::invalid_argument("reference: only stops on single masses");
      const long double phi = s.phase;
      stops_.push_back({s.mass, s.kind == Stop::Kind::upper ? 1 : -1, s.position, s.amplitude,
                        std::cos(phi), std::sin(phi), s.restitution});
    }
    // ρ: spectral radius of the first-order matrix (double is plenty: it only sets h), and Ω.
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n_, 2 * n_);
    A.topRightCorner(n_, n_).setIdentity();
    for (Eigen::Index i = 0; i < n_; ++i) {
      A.row(n_ + i).head(n_) = -sys.stiffness().row(i) / M(i, i);
      A.row(n_ + i).tail(n_) = -sys.damping().row(i) / M(i, i);
    }
    const Eigen::EigenSolver<Eigen::MatrixXd> eig(A, false);
    rate_ = std::max(static_cast<long double>(eig.eigenvalues().cwiseAbs().maxCoeff()), omega_ * top_order);
    if (!(rate_ > 0.0L)) rate_ = 1.0L;
    held_by_.assign(static_cast<std::size_t>(n_), -1);
  }

  /// The fixed step h.
  long double step() const { return options_.step_rate / rate_; }

  /// Runs from (t0, x0, v0) to t_end, appending to `events`. Every stop is free at t0.
  void run(long double t0, const VectorL& x0, const VectorL& v0, long double t_end) {
    if (x0.size() != n_ || v0.size() != n_) throw std::invalid_argument("reference: state size");
    x = x0;
    v = v0;
    now_ = at(t0);
    std::fill(held_by_.begin(), held_by_.end(), -1);
    const long double h_nominal = step();
    while (now_.t < t_end) {
      if (static_cast<long>(events.size()) > options_.max_events)
        throw std::runtime_error("reference: event budget exhausted at t = " +
                                 std::to_string(static_cast<double>(now_.t)));
      const long double h = std::min(h_nominal, t_end - now_.t);
      Vec x1 = x, v1 = v;
      advance(now_, h, x1, v1);
      const Clock end = shifted(now_, h);
      ++steps;
      // Earliest crossing over all guards inside (t, t + h].
      long double best = std::numeric_limits<long double>::infinity();
      for (int j = 0; j < static_cast<int>(stops_.size()); ++j) {
        const long double g0 = guard(j, now_, x, v), g1 = guard(j, end, x1, v1);
        long double far = -1.0L;  // a sub-step length after which the guard is > 0, if any
        if (g0 <= 0.0L && g1 > 0.0L) {
          far = h;
        } else if (g0 <= 0.0L && g1 <= 0.0L && guard_rate(j, now_, x, v) > 0.0L &&
                   guard_rate(j, end, x1, v1) < 0.0L) {
          const long double peak = interior_maximum(j, h);
          Vec xp = x, vp = v;
          advance(now_, peak, xp, vp);
          if (guard(j, shifted(now_, peak), xp, vp) > 0.0L) far = peak;
        }
        if (far > 0.0L) best = std::min(best, locate(j, far));
      }
      if (best == std::numeric_limits<long double>::infinity()) {
        if (on_step) on_step(now_.t, x, v, h);
        x = x1;
        v = v1;
        now_ = at(now_.t + h);
        continue;
      }
      advance(now_, best, x, v);
      now_ = at(now_.t + best);
      pin_held();
      handle();
    }
    t = now_.t;
  }

  std::vector<ReferenceEvent> events;
  long double t = 0.0L;  ///< time reached
  Vec x, v;              ///< state reached
  long steps = 0;        ///< full steps taken (sub-steps of event location not counted)

  /// The stop holding mass i, or -1.
  int held_by(Eigen::Index i) const { return held_by_[static_cast<std::size_t>(i)]; }
  bool holds(int j) const { return held(j); }

  /// Called for every full step taken without an event, with the step's start (t, x, v) and its
  /// length h, before the step is applied: lets a test look inside steps (e.g. minimise a contact
  /// force with force_after) without changing the run.
  std::function<void(long double t, const Vec& x, const Vec& v, long double h)> on_step;

  /// Contact force of held stop j at t + tau, from (t, x, v) by one Runge–Kutta step of length
  /// tau (accurate like a full step for tau up to a few steps). Valid inside on_step.
  long double force_after(int j, long double t, const Vec& xs, const Vec& vs, long double tau) const {
    Vec xa = xs, va = vs;
    const Clock k = at(t);
    advance(k, tau, xa, va);
    return contact_force(j, shifted(k, tau), xa, va);
  }

 private:
  struct StopData {
    Eigen::Index mass;
    int side;  // +1 upper, -1 lower
    long double p, a, cos_phi, sin_phi, r;
  };

  /// A time with cos Ωt and sin Ωt (stage times are reached by rotation: only small arguments
  /// go through cosl/sinl inside a step, which keeps long double trigonometry cheap).
  struct Clock {
    long double t, c, s;
  };

  Clock at(long double time) const {
    return {time, std::cos(omega_ * time), std::sin(omega_ * time)};
  }
  Clock shifted(const Clock& k, long double dt) const {
    const long double cd = std::cos(omega_ * dt), sd = std::sin(omega_ * dt);
    return {k.t + dt, k.c * cd - k.s * sd, k.s * cd + k.c * sd};
  }

  /// d^derivative/dt^derivative of P_j.
  long double position(int j, const Clock& k, int derivative = 0) const {
    const StopData& s = stops_[static_cast<std::size_t>(j)];
    const long double c = k.c * s.cos_phi - k.s * s.sin_phi;   // cos(Ωt + φ)
    const long double sn = k.s * s.cos_phi + k.c * s.sin_phi;  // sin(Ωt + φ)
    const long double w = omega_;
    switch (derivative) {
      case 0:
        return s.p + s.a * c;
      case 1:
        return -s.a * w * sn;
      case 2:
        return -s.a * w * w * c;
      default:
        return s.a * w * w * w * sn;
    }
  }

  /// (cos kΩt, sin kΩt) = (c + i s)^k for the clock's (c, s) = (cos Ωt, sin Ωt).
  static std::pair<long double, long double> power(const Clock& k, int order) {
    long double c = 1.0L, s = 0.0L;
    for (int q = 0; q < order; ++q) {
      const long double c1 = c * k.c - s * k.s;
      s = s * k.c + c * k.s;
      c = c1;
    }
    return {c, s};
  }

  /// The extra harmonics' force on mass i (derivative 0) or its time derivative (1).
  long double harmonics_force(const Clock& k, Eigen::Index i, int derivative) const {
    long double sum = 0.0L;
    for (std::size_t h = 0; h < orders_.size(); ++h) {
      const auto [c, s] = power(k, orders_[h]);
      if (derivative == 0) sum += hc_[h](i) * c + hs_[h](i) * s;
      else sum += orders_[h] * omega_ * (hs_[h](i) * c - hc_[h](i) * s);
    }
    return sum;
  }

  /// F = f(t) - C v - K x, the force on each mass without the stops.
  Vec free_force(const Clock& k, const Vec& xs, const Vec& vs) const {
    Vec F(n_);
    for (Eigen::Index i = 0; i < n_; ++i) {  // plain loops: Eigen's GEMV is slow at n = 2
      long double sum = f0_(i) + fc_(i) * k.c + fs_(i) * k.s;
      if (!orders_.empty()) sum += harmonics_force(k, i, 0);
      for (Eigen::Index m = 0; m < n_; ++m)
        sum -= damping_(i, m) * vs(m) + stiffness_(i, m) * xs(m);
      F(i) = sum;
    }
    return F;
  }

  Vec acceleration(const Clock& k, const Vec& xs, const Vec& vs) const {
    Vec a = free_force(k, xs, vs).cwiseQuotient(mass_);
    for (Eigen::Index i = 0; i < n_; ++i)
      if (held_by_[static_cast<std::size_t>(i)] >= 0)
        a(i) = position(held_by_[static_cast<std::size_t>(i)], k, 2);
    return a;
  }

  /// λ_j = σ (F_i - m_i P''), for stop j holding its mass (x_i = P, v_i = P').
  long double contact_force(int j, const Clock& k, const Vec& xs, const Vec& vs) const {
    const StopData& s = stops_[static_cast<std::size_t>(j)];
    const long double F = free_force(k, xs, vs)(s.mass);
    return s.side * (F - mass_(s.mass) * position(j, k, 2));
  }

  bool held(int j) const {
    return held_by_[static_cast<std::size_t>(stops_[static_cast<std::size_t>(j)].mass)] == j;
  }

  long double guard(int j, const Clock& k, const Vec& xs, const Vec& vs) const {
    const StopData& s = stops_[static_cast<std::size_t>(j)];
    if (held(j)) return -contact_force(j, k, xs, vs);
    return s.side * (xs(s.mass) - position(j, k));
  }

  long double guard_rate(int j, const Clock& k, const Vec& xs, const Vec& vs) const {
    const StopData& s = stops_[static_cast<std::size_t>(j)];
    if (held(j)) {
      // -λ' = -σ (F_i' - m_i P'''),  F' = f' - C a - K v.
      const Vec a = acceleration(k, xs, vs);
      const long double df = omega_ * (fs_(s.mass) * k.c - fc_(s.mass) * k.s) + harmonics_force(k, s.mass, 1);
      const long double dF = df - damping_.row(s.mass).dot(a) - stiffness_.row(s.mass).dot(vs);
      return -s.side * (dF - mass_(s.mass) * position(j, k, 3));
    }
    return s.side * (vs(s.mass) - position(j, k, 1));
  }

  /// One Cooper–Verner step of length h from (k, xs, vs), in place.
  void advance(const Clock& k, long double h, Vec& xs, Vec& vs) const {
    std::array<Vec, CooperVerner8::stages> kx, kv;
    std::array<Clock, CooperVerner8::stages> clocks;
    for (int i = 0; i < CooperVerner8::stages; ++i) {
      const auto si = static_cast<std::size_t>(i);
      std::size_t same = si;  // the nodes repeat: rotate only once per distinct node
      for (std::size_t m = 0; m < si && same == si; ++m)
        if (tableau_.c[m] == tableau_.c[si]) same = m;
      clocks[si] = same < si ? clocks[same] : shifted(k, tableau_.c[si] * h);
      Vec xi = xs, vi = vs;
      for (int m = 0; m < i; ++m) {
        const auto sm = static_cast<std::size_t>(m);
        const long double w = h * tableau_.a[si][sm];
        if (w == 0.0L) continue;
        xi += w * kx[sm];
        vi += w * kv[sm];
      }
      kx[si] = vi;
      kv[si] = acceleration(clocks[si], xi, vi);
    }
    for (int i = 0; i < CooperVerner8::stages; ++i) {
      const auto si = static_cast<std::size_t>(i);
      const long double w = h * tableau_.b[si];
      if (w == 0.0L) continue;
      xs += w * kx[si];
      vs += w * kv[si];
    }
    // Held masses sit exactly on their stops (removes the O(h⁹) drift of the integration).
    const Clock end = shifted(k, h);
    for (Eigen::Index i = 0; i < n_; ++i) {
      const int j = held_by_[static_cast<std::size_t>(i)];
      if (j < 0) continue;
      xs(i) = position(j, end);
      vs(i) = position(j, end, 1);
    }
  }

  void pin_held() {
    for (Eigen::Index i = 0; i < n_; ++i) {
      const int j = held_by_[static_cast<std::size_t>(i)];
      if (j < 0) continue;
      x(i) = position(j, now_);
      v(i) = position(j, now_, 1);
    }
  }

  long double resolution() const {
    return 4.0L * std::numeric_limits<long double>::epsilon() * std::max(1.0L, std::fabs(now_.t));
  }

  /// Sub-step length of the maximum of guard j in (0, h), given guard' > 0 at 0 and < 0 at h.
  long double interior_maximum(int j, long double h) const {
    long double lo = 0.0L, hi = h;
    for (int it = 0; it < 200 && hi - lo > resolution(); ++it) {
      const long double mid = 0.5L * (lo + hi);
      Vec xm = x, vm = v;
      advance(now_, mid, xm, vm);
      (guard_rate(j, shifted(now_, mid), xm, vm) > 0.0L ? lo : hi) = mid;
    }
    return hi;
  }

  /// Smallest sub-step after which guard j is > 0 (to within resolution()), given it is ≤ 0 at
  /// 0 and > 0 at `far`: safeguarded Newton on the sub-step length (the guard's rate is known),
  /// a bisection every third iteration or when Newton leaves the bracket (so the bracket shrinks
  /// whatever the rounding); once Newton has converged, a probe half a resolution on the other
  /// side of the root closes the bracket.
  long double locate(int j, long double far) const {
    long double lo = 0.0L, hi = far;
    const long double flo = guard(j, now_, x, v);
    long double theta = far;
    {
      Vec xm = x, vm = v;
      advance(now_, far, xm, vm);
      const long double fhi = guard(j, shifted(now_, far), xm, vm);
      theta = lo - flo * (hi - lo) / (fhi - flo);  // regula falsi start
    }
    if (!held(j)) {
      // A gap: start from the root of its Taylor parabola at 0 when it has one inside, which is
      // nearly exact for the short flights of a chatter sequence (Newton from the far end
      // would only halve the distance per iteration there).
      const StopData& s = stops_[static_cast<std::size_t>(j)];
      const long double g1 = guard_rate(j, now_, x, v);
      const long double g2 = s.side * (acceleration(now_, x, v)(s.mass) - position(j, now_, 2));
      const long double disc = g1 * g1 - 2.0L * g2 * flo;
      if (g2 > 0.0L && disc >= 0.0L) {
        const long double root = (-g1 + std::sqrt(disc)) / g2;
        if (root > 0.0L && root < far) theta = root;
      }
    }
    // The root cannot be located better than the rounding of the guard over its rate: for the
    // gap of a bounce slower than ~1e-7 that is coarser than the time resolution.
    long double enough = resolution();
    for (int it = 0; it < 400 && hi - lo > enough; ++it) {
      if (!(theta > lo && theta < hi) || it % 3 == 2) theta = 0.5L * (lo + hi);
      Vec xm = x, vm = v;
      advance(now_, theta, xm, vm);
      const Clock k = shifted(now_, theta);
      const long double f = guard(j, k, xm, vm), d = guard_rate(j, k, xm, vm);
      (f > 0.0L ? hi : lo) = theta;
      if (!held(j) && d > 0.0L) {
        const StopData& s = stops_[static_cast<std::size_t>(j)];
        const long double noise = 16.0L * std::numeric_limits<long double>::epsilon() *
                                  (std::fabs(xm(s.mass)) + std::fabs(position(j, k)));
        enough = std::max(resolution(), noise / d);
      }
      long double next = d > 0.0L ? theta - f / d : 0.5L * (lo + hi);
      if (std::fabs(next - theta) < 0.5L * enough)  // converged: close the bracket
        next = f > 0.0L ? theta - 0.5L * enough : theta + 0.5L * enough;
      theta = next;
    }
    return hi;
  }

  void handle() {
    // Impacts: free stops at or past their surface and approaching.
    for (int j = 0; j < static_cast<int>(stops_.size()); ++j) {
      if (held(j)) continue;
      const StopData& s = stops_[static_cast<std::size_t>(j)];
      if (guard(j, now_, x, v) < 0.0L) continue;
      const long double before = guard_rate(j, now_, x, v);
      if (before <= 0.0L) continue;
      const long double after = -s.r * before;
      x(s.mass) = position(j, now_);
      v(s.mass) = position(j, now_, 1) + s.side * after;
      events.push_back({now_.t, j, ReferenceEventKind::impact, before, after, 0.0L});
      if (std::fabs(after) < options_.stick_velocity) {
        // Would the stop hold? λ with the mass on it, at rest relative to it.
        v(s.mass) = position(j, now_, 1);
        held_by_[static_cast<std::size_t>(s.mass)] = j;
        const long double force = contact_force(j, now_, x, v);
        if (force > 0.0L) {
          const long double approach = force / mass_(s.mass);
          const long double tail =
              s.r < 1.0L ? 2.0L * s.r * before / (approach * (1.0L - s.r)) : 0.0L;
          events.push_back({now_.t, j, ReferenceEventKind::stick, before, 0.0L, now_.t + tail});
        } else {
          held_by_[static_cast<std::size_t>(s.mass)] = -1;
          v(s.mass) = position(j, now_, 1) + s.side * after;
        }
      }
    }
    // Releases: held stops whose force is no longer positive (crossed, or jumped by an impact).
    for (int j = 0; j < static_cast<int>(stops_.size()); ++j) {
      if (!held(j) || contact_force(j, now_, x, v) > 0.0L) continue;
      held_by_[static_cast<std::size_t>(stops_[static_cast<std::size_t>(j)].mass)] = -1;
      events.push_back({now_.t, j, ReferenceEventKind::release, 0.0L, 0.0L, now_.t});
    }
  }

  ReferenceHybridOptions options_;
  Eigen::Index n_ = 0;
  Vec mass_;
  Mat damping_, stiffness_;
  Vec f0_, fc_, fs_;
  std::vector<int> orders_;   // extra harmonics: k, Fc_h, Fs_h
  std::vector<Vec> hc_, hs_;
  long double omega_ = 0.0L;
  long double rate_ = 1.0L;
  std::vector<StopData> stops_;
  std::vector<int> held_by_;  // per mass: the stop holding it, or -1
  Clock now_{0.0L, 1.0L, 0.0L};
  CooperVerner8 tableau_;
};

}  // namespace vibro::test
