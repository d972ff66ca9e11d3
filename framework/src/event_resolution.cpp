#include "event_resolution.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numbers>

namespace vibro::detail {
namespace {

bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

/// out = a ∪ b (sorted; out's capacity suffices once reserved for every stop).
void merge_into(const ContactSet& a, const ContactSet& b, ContactSet& out) {
  out.clear();
  std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
}

Eigen::Index index_in(const ContactSet& s, int j) {
  return std::lower_bound(s.begin(), s.end(), j) - s.begin();
}

/// The second-order rule's tail after a rebound that lasts T0 by Budd–Dux, with the approach
/// acceleration a, its slope a' and the gap's damping α (simulator.hpp, ChatterRule):
/// T0 + T0² (α/6 − a'/(3a)).
double second_order_tail(double T0, double a, double a_slope, double alpha) {
  return T0 + T0 * T0 * (alpha / 6.0 - a_slope / (3.0 * a));
}

/// The third-order chatter rule's tail (simulator.hpp, ChatterRule::third_order): from the
/// rebound w0 at s = 0, the bounces of the gap's local model h'' = −a(s) + α h' + β h,
/// a(s) = A + A' s + ½ A'' s² (h ≥ 0 the height above the stop, s the time since the impact),
/// summed flight by flight until the second-order closed form (simulator.hpp) can take the rest:
/// until its error for the remaining tail T_k, estimated as T_k³ ρ² (ρ² the largest of |A''/a|,
/// (a'/a)², α², |β|: the next order's coefficients), is below `tolerance`, or the rebound below
/// w0/1000 (its O(T³) then ~1e-9 of the model's own O(T0⁴)). At thresholds where the
/// second-order rule is already within the tolerance no flight is summed at all. Each flight is
/// the root of its Taylor polynomial, h = Σ hₘ sᵐ/m! with h₀ = 0, h₁ = w,
/// hₘ₊₂ = −a⁽ᵐ⁾ + α hₘ₊₁ + β hₘ, of degree 8: a flight lasts ~2w/A, so the truncation is
/// O((ρ·2w/A)⁹) relative, far below the model's own O(w³) (ρ the largest of |α|, √|β| and the
/// drift rates of a); Newton from the flight's second-order length converges in one or two steps.
/// Returns the tail's duration, or NaN where the model has no accumulation within it (a(s) ≤ 0
/// reached, a rebound not decreasing, or more than 100 000 flights).
double local_tail(double w0, double r, double A, double A1, double A2, double alpha, double beta,
                  double tolerance) {
  constexpr int degree = 8;
  constexpr double inverse_factorial[degree + 1] = {1.0,       1.0,         1.0 / 2,     1.0 / 6,      1.0 / 24,
                                                    1.0 / 120, 1.0 / 720,   1.0 / 5040,  1.0 / 40320};
  double s = 0.0, w = w0;
  for (int flight = 0; flight < 100000; ++flight) {
    const double a0 = A + s * (A1 + 0.5 * A2 * s), a1 = A1 + A2 * s;
    if (!(a0 > 0.0)) break;
    const double T0 = 2.0 * w / (a0 * (1.0 - r));
    const double rho2 = std::max({std::abs(A2 / a0), (a1 / a0) * (a1 / a0), alpha * alpha, std::abs(beta)});
    if (w <= 1e-3 * w0 || T0 * T0 * T0 * rho2 <= tolerance) return s + second_order_tail(T0, a0, a1, alpha);
    // The derivatives hₘ at the take-off, then hₘ / m! (the polynomial's coefficients).
    double h[degree + 1] = {0.0, w};
    for (int m = 0; m + 2 <= degree; ++m) {
      const double am = m == 0 ? a0 : (m == 1 ? a1 : (m == 2 ? A2 : 0.0));
      h[m + 2] = -am + alpha * h[m + 1] + beta * h[m];
    }
    for (int m = 2; m <= degree; ++m) h[m] *= inverse_factorial[m];
    // The landing: the root of h(s)/s = Σ hₘ sᵐ⁻¹, by Newton from the second-order flight
    // 2w/a − (4/3) a' w²/a³ + (2/3) α w²/a² (simulator.hpp).
    double tau = 2.0 * w / a0 + (w * w / (a0 * a0)) * ((2.0 / 3.0) * alpha - (4.0 / 3.0) * a1 / a0);
    if (!(tau > 0.0)) break;
    for (int it = 0; it < 8; ++it) {
      double q = h[degree], dq = 0.0;
      for (int m = degree - 1; m >= 1; --m) {
        dq = dq * tau + q;
        q = q * tau + h[m];
      }
      const double step = q / dq;
      tau -= step;
      if (std::abs(step) <= 1e-14 * tau) break;
    }
    // The landing speed −h'(τ), the next rebound r times it.
    double slope = degree * h[degree];
    for (int m = degree - 1; m >= 1; --m) slope = slope * tau + m * h[m];
    const double next = -r * slope;
    if (!(tau > 0.0) || !(next < w)) break;
    s += tau;
    w = next;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

/// The second- and third-order chatter rules' state correction for stop j caught and held in
/// `held`, whose skipped bounces displace its gap by ∫ δg dt = `displacement` (simulator.hpp):
///     x -= (∫δg/G) d,   v += (∫δg/G) (M⁻¹ C d − M⁻¹ K M⁻¹ w_j),   d = P M⁻¹ C M⁻¹ w_j,
/// P removing the held stops' normal components (d -= M⁻¹ W (Wᵀ M⁻¹ W)⁻¹ Wᵀ d); v's normal part
/// is removed after, with the residual of every held stop (resolve_event). Uses w.G, w.gn,
/// w.impulse and w.factor as scratch (resolve_event fills them again after).
void chatter_correction(ContactAlgebra& algebra, const ContactSet& held, int j, double displacement,
                        Eigen::VectorXd& x, Eigen::VectorXd& v, EventWorkspace& w) {
  const double scale = displacement / algebra.delassus_diagonal(j);
  Eigen::VectorXd& d = w.chatter_d;
  algebra.damped_normal(j, d);
  const auto k = static_cast<Eigen::Index>(held.size());
  auto G = w.G.topLeftCorner(k, k);
  algebra.delassus(held, G);
  auto dn = w.gn.head(k);
  for (Eigen::Index a = 0; a < k; ++a) dn(a) = algebra.normal_dot(held[static_cast<std::size_t>(a)], d);
  auto mu = w.impulse.head(k);
  if (!spd_solve(G, dn, mu, w.factor.topLeftCorner(k, k)))
    mu = Eigen::MatrixXd(G).llt().solve(Eigen::VectorXd(dn));  // not reached for independent normals
  algebra.apply_impulse(held, mu, d);
  x -= scale * d;
  algebra.damped_response(j, d, w.chatter_e);
  v += scale * w.chatter_e;
}

}  // namespace

RunScales run_scales(const SimulatorOptions& o, double omega, double kmax, double mmax, double fmax,
                     const std::vector<Stop>& stops, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0) {
  if (!(omega > 0.0)) omega = 1.0;
  const double stiff = std::max(kmax, mmax * omega * omega);
  double L = o.length_scale;
  RunScales s;
  for (const Stop& st : stops) s.L_stops = std::max({s.L_stops, std::abs(st.position), st.motion_extent()});
  if (L == 0.0) {
    const double x_max = x0.size() > 0 ? x0.cwiseAbs().maxCoeff() : 0.0;
    const double v_term = (v0.size() > 0 ? v0.cwiseAbs().maxCoeff() : 0.0) / omega, f_term = fmax / stiff;
    L = stops_length_scale(stops, x_max);
    L = std::max({L, v_term, f_term});
    // What set L, for the messages of check_resolution (the largest term; ties go to the stops).
    const double top = std::max({s.L_stops, x_max, v_term, f_term});
    s.L_from = top == s.L_stops ? "the stops" : top == x_max ? "initial.x" : top == v_term ? "initial.v" : "the forcing";
  } else {
    s.L_from = "solver.length_scale";
  }
  s.L = L;
  s.V = L * omega;
  // A stop's higher harmonics move it faster than ω times its extent: k Ω per harmonic's amplitude.
  for (const Stop& st : stops)
    if (st.has_higher_harmonics()) s.V = std::max(s.V, st.motion_speed(omega));
  s.F = std::max(stiff * L, fmax);
  s.T = 2.0 * std::numbers::pi / omega;
  s.eps_gap = o.trigger * s.L;
  s.eps_force = o.trigger * s.F;
  s.dt_simultaneous = o.simultaneity * s.T;
  s.window = o.event_window > 0.0 ? o.event_window : s.T;
  s.rules = {o.chatter_velocity * s.V, o.chatter_height * s.L, o.contact_velocity * s.V, o.chatter_rule,
             o.trigger * s.T};
  return s;
}

void EventWorkspace::reserve(Eigen::Index m, Eigen::Index n) {
  const auto capacity = static_cast<std::size_t>(m);
  for (ContactSet* set : {&candidates, &chatter, &slow, &test, &held, &all, &next, &scratch_set})
    set->reserve(capacity);
  candidates.reserve(2 * capacity);  // appended to before its repeats are removed
  for (Eigen::VectorXd* vec : {&g_before, &g_after, &g_now, &hold_force, &forces, &q, &impulse, &gn, &rhs})
    vec->resize(m);
  chatter_d.resize(n);
  chatter_e.resize(n);
  G.resize(m, m);
  factor.resize(m, m);
  lcp.reserve(m);
  chatter_limits.reserve(capacity);
}

void check_resolution(const RunScales& s, const RunScales& automatic, const SimulatorOptions& options,
                      double t0, double t_end, std::vector<std::string>& warnings) {
  if (options.length_scale > 0.0 && automatic.L > 0.0) {
    const double eps = std::numeric_limits<double>::epsilon();
    if (s.eps_gap > 1e-3 * automatic.L || s.eps_gap < 10.0 * eps * automatic.L)
      throw InvalidInput("solver.length_scale = " + number_text(options.length_scale) + " puts the gap tolerance (trigger × L = " +
                         number_text(s.eps_gap) + ") outside [10 ulp, 1e-3] of the scene's own length scale " +
                         number_text(automatic.L) + " (stops, initial state, static response): " +
                         (s.eps_gap > 1e-3 * automatic.L ? "impacts would pass unseen" : "rounding would fire the guards") +
                         "; leave it 0 (automatic) or near " + number_text(automatic.L));
  }
  // A stop is located no better than its gap moves in one spacing of doubles near t: V·ulp(t).
  const double t_far = std::max(std::abs(t0), std::abs(t_end));
  const double t_named = std::abs(t0) > std::abs(t_end) ? t0 : t_end;  // the far end, with its sign
  const double ulp = std::nextafter(t_far, std::numeric_limits<double>::infinity()) - t_far;
  const double drift = s.V * ulp;  // ≈ |g'| ulp(t)
  if (drift > 1e-6 * s.L)
    throw InvalidInput("time " + number_text(t_named) + " is too large for this run: doubles near it are " +
                       number_text(ulp) + " apart, " + number_text(drift / s.L) +
                       " of the length scale per step at the run's speeds (1e-6 at most); start the run near "
                       "t = 0 (initial.time)");
  // The stops' own scale against the rounding of the run's positions and times: a run whose
  // motion (automatic.L, set by a large initial state or forcing) dwarfs its stops places events
  // no better than max(V·ulp(t), ε·L), and recorded states may lie that far past a stop.
  if (automatic.L_stops > 0.0) {
    const double eps = std::numeric_limits<double>::epsilon();
    const double place = std::max({automatic.V * ulp, eps * automatic.L, drift, eps * s.L});
    if (place > 1e-6 * automatic.L_stops)
      throw InvalidInput((std::string(automatic.L_from) == "the forcing"
                              ? "the forcing's static deflection fmax/k = " + number_text(automatic.L) + " sets the run's length scale"
                              : std::string(automatic.L_from) + " sets the run's length scale to " + number_text(automatic.L)) +
                         ", " + number_text(automatic.L / automatic.L_stops) + " × the stops' own scale " +
                         number_text(automatic.L_stops) + " (their largest offset or amplitude): near t = " +
                         number_text(t_named) + " doubles place an event only to " + number_text(place) + ", " +
                         number_text(place / automatic.L_stops) +
                         " of the stops' scale (1e-6 at most), so the stops would be crossed between two "
                         "representable times; bring " + automatic.L_from + " within about 1e6 × the stops' scale, "
                         "or scale the stops with it");
  }
  if (drift > 10.0 * s.eps_gap)
    warnings.push_back("time resolution: near t = " + number_text(t_named) + " doubles are " + number_text(ulp) +
                       " apart, so events are placed to " + number_text(drift) + " in the gaps (" +
                       number_text(drift / s.eps_gap) + " × the trigger tolerance " + number_text(s.eps_gap) + ")");
}

std::string stiff_warning(double steps_per_period, double periods) {
  return "stiff: the certified event search steps by 1/ρ, ρ the fastest rate of the motion (" +
         number_text(steps_per_period / (2.0 * std::numbers::pi)) + " × the forcing frequency): about " +
         number_text(std::round(steps_per_period)) + " search steps per forcing period, " +
         number_text(std::round(steps_per_period * periods)) + " for this run";
}

bool resolve_event(ContactAlgebra& algebra, const std::vector<Stop>& stops, const EventRules& rules,
                   double t, Eigen::VectorXd& x, Eigen::VectorXd& v, ContactSet& stuck,
                   const ContactSet& impacting, const ContactSet& releasing, const ContactSet& resting,
                   const std::function<void(const Event&)>& emit, RunSummary& summary, std::string* why,
                   EventWorkspace& w, const std::function<void(const ContactSet&)>& impact_set) {
  auto restitution = [&](int j) { return stops[static_cast<std::size_t>(j)].restitution; };
  ContactSet& candidates = w.candidates;
  w.scratch_set.clear();
  std::set_difference(stuck.begin(), stuck.end(), releasing.begin(), releasing.end(),
                      std::back_inserter(w.scratch_set));
  merge_into(w.scratch_set, resting, candidates);
  ContactSet& chatter = w.chatter;
  chatter.clear();
  const bool impacts = !impacting.empty();
  if (impacts) {
    algebra.gap_rates(t, v, w.g_before);
    // Chatter candidates: stops that would hold (acceleration LCP with them stuck) and whose
    // next bounce would be too small to resolve (or too slow).
    ContactSet& slow = w.slow;
    slow.clear();
    for (int j : impacting) {
      const double r = restitution(j);
      if (r > 0.0 && r < 1.0) slow.push_back(j);  // r = 0 sticks at once, r = 1 never chatters
    }
    if (!slow.empty()) {
      merge_into(candidates, slow, w.test);
      algebra.settle(t, x, v, w.test, w.held, w.hold_force.head(static_cast<Eigen::Index>(w.test.size())));
      for (int j : slow) {
        if (!contains(w.held, j)) continue;
        const double accel = algebra.delassus_diagonal(j) * w.hold_force(index_in(w.test, j));
        const double r = restitution(j);
        const double u = w.g_before(j);
        const double rise = (r * u) * (r * u) / (2.0 * accel);
        if (u <= rules.v_chatter || rise <= rules.h_chatter) chatter.push_back(j);
      }
    }
    ContactSet& all = w.all;
    merge_into(stuck, impacting, all);
    if (impact_set) impact_set(all);
    const auto m = static_cast<Eigen::Index>(all.size());
    auto G = w.G.topLeftCorner(m, m);
    algebra.delassus(all, G);
    auto q = w.q.head(m);
    auto g_now = w.g_now.head(m);
    for (Eigen::Index a = 0; a < m; ++a) {
      const int j = all[static_cast<std::size_t>(a)];
      const bool rest = contains(stuck, j) || contains(chatter, j);
      q(a) = (1.0 + (rest ? 0.0 : restitution(j))) * w.g_before(j);
      g_now(a) = algebra.gap(j, t, x);
    }
    auto impulse = w.impulse.head(m);
    solve_lcp(G, q, impulse, w.lcp);
    algebra.apply_impulse(all, impulse, v);
    // Place each impacting stop's gap exactly at zero: the located root leaves it within
    // rounding (≤ ε) of the surface, and without this a long run of tiny bounces could let
    // that rounding accumulate into the stop. The correction moves x along M⁻¹w by ≤ ε.
    for (Eigen::Index a = 0; a < m; ++a)
      if (g_now(a) > 0.0) algebra.shift(all, a, g_now(a) / G(a, a), x);
    algebra.gap_rates(t, v, w.g_after);
    for (int j : impacting) {
      emit({t, j, EventKind::impact, w.g_before(j), w.g_after(j), 0.0});
      ++summary.impacts;
    }
    // The stops that may hold after the impact: those of `all` not separating after it (rate
    // ≥ -v_contact), and the resting ones. A held stop that the impulse leaves separating (the
    // LCP gave it no impulse: keeping it shut would take a pull) opens at the impact and is
    // released. Until issue 13's stop 21 it stayed a candidate; held again, the residual-velocity
    // step below pulled it shut, which sent the impacting stop back into approach: a cascade of
    // a dozen impacts at one instant, each r × the last (a chain with a stop between two masses
    // held and an impact on one of them, tests/framework/test_modal.cpp), that amplified rounding.
    // (`all` is sorted, so the filtered list is; contains() is a binary search.)
    w.scratch_set.clear();
    for (int j : all)
      if (!contains(releasing, j) && w.g_after(j) >= -rules.v_contact) w.scratch_set.push_back(j);
    merge_into(w.scratch_set, resting, candidates);
  }
  ContactSet& next = w.next;
  auto forces = w.forces.head(static_cast<Eigen::Index>(candidates.size()));
  algebra.settle(t, x, v, candidates, next, forces);
  if (!algebra.accept(next, why)) return false;
  auto force_of = [&](int j) {
    for (std::size_t a = 0; a < candidates.size(); ++a)
      if (candidates[a] == j) return forces(static_cast<Eigen::Index>(a));
    return 0.0;
  };
  // Chatter limits (ChatterRule in simulator.hpp), computed before the residual normal
  // velocity is removed below (the second-order rule's kick has a normal part the stop takes).
  w.chatter_limits.clear();
  for (int j : chatter) {
    if (!contains(next, j)) continue;
    const double r = restitution(j);
    const double Gjj = algebra.delassus_diagonal(j);
    const double A = Gjj * force_of(j);
    const double w0 = r * w.g_before(j);
    double t_limit = t;
    if (A > 0.0) {
      // Budd & Dux (1994): rebounds r^k w0 under a constant approach acceleration A accumulate
      // after T0 = Σ 2 r^k w0 / A = 2 w0 / (A (1 - r)).
      const double T0 = 2.0 * w0 / (A * (1.0 - r));
      t_limit = t + T0;
      if (rules.chatter_rule != ChatterRule::first_order) {
        // A' = G λ_j', A'' = G λ_j'' along the sticking flow of `next` from the post-impact
        // state (exact).
        double slope = 0.0, curvature = 0.0;
        algebra.force_rates(next, j, t, x, v, &slope, &curvature);
        const double A_dot = Gjj * slope, alpha = algebra.chatter_alpha(j);
        double T;
        if (rules.chatter_rule == ChatterRule::second_order) {
          // Expansion (simulator.hpp, ChatterRule): with A_k = A + A'(t_k - t),
          // t_k - t = (2 w0 / A)(1 - r^k)/(1 - r) and w_k = r^k w0 (1 + κ w0 (1 - r^k)/(1 - r)),
          // κ = (2/3)(A'/A² + α/A) (from u_{k+1} = w_k (1 + κ w_k)), the sum of the flights
          // τ_k = 2 w_k / A_k + (-(4/3) A'/A³ + (2/3) α/A²) w_k² is, to O(w0²),
          //   T = T0 + w0² / (1 - r)² · (-(4/3) A'/A³ + (2/3) α/A²) = T0 + T0² (α/6 - A'/(3A)),
          // using Σ r^k (1 - r^k) = r / ((1 - r)(1 - r²)) and Σ r^{2k} = 1 / (1 - r²).
          T = second_order_tail(T0, A, A_dot, alpha);
        } else {
          T = local_tail(w0, r, A, A_dot, Gjj * curvature, alpha, algebra.chatter_beta(j), rules.t_tolerance);
        }
        if (std::isfinite(T) && std::abs(T - T0) <= 0.5 * T0) t_limit = t + T;
        // The bounces' mean displacement: ∫ δg dt = -(2/3) Σ w_k³ / A² over the tail, felt by
        // the rest of the system through C and K (chatter_correction above).
        const double r3 = r * r * r;
        const double displacement_integral = -(2.0 / 3.0) * w0 * w0 * w0 / (A * A * (1.0 - r3));
        chatter_correction(algebra, next, j, displacement_integral, x, v, w);
      }
    }
    w.chatter_limits.push_back({j, t_limit});
  }
  // Remove the residual normal velocity of the held stops (rounding, or < v_contact).
  if (!next.empty()) {
    const auto k = static_cast<Eigen::Index>(next.size());
    algebra.gap_rates(t, v, w.rhs);
    auto gn = w.gn.head(k);
    for (Eigen::Index a = 0; a < k; ++a) gn(a) = w.rhs(next[static_cast<std::size_t>(a)]);
    auto G = w.G.topLeftCorner(k, k);
    algebra.delassus(next, G);
    auto impulse = w.impulse.head(k);
    if (!spd_solve(G, gn, impulse, w.factor.topLeftCorner(k, k)))
      impulse = Eigen::MatrixXd(G).llt().solve(Eigen::VectorXd(gn));  // not reached for independent normals
    algebra.apply_impulse(next, impulse, v);
  }
  for (int j : next) {
    if (contains(stuck, j)) continue;
    if (contains(chatter, j)) {
      double t_limit = t;
      for (const EventWorkspace::ChatterLimit& c : w.chatter_limits)
        if (c.stop == j) t_limit = c.t;
      emit({t_limit, j, EventKind::chatter_limit, restitution(j) * w.g_before(j), 0.0, force_of(j)});
      ++summary.chatters;
    } else {
      emit({t, j, EventKind::stick, impacts ? w.g_before(j) : 0.0, 0.0, force_of(j)});
    }
    ++summary.sticks;
  }
  algebra.gap_rates(t, v, w.g_now);
  for (int j : stuck) {
    if (contains(next, j)) continue;
    emit({t, j, EventKind::release, 0.0, w.g_now(j), 0.0});
    ++summary.releases;
  }
  stuck.assign(next.begin(), next.end());
  return true;
}

bool compliant_switches(const ContactAlgebra& algebra, const std::vector<Stop>& stops, double t,
                        const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& impacting,
                        const ContactSet& releasing, ContactSet& engaged, ContactSet& rigid_impacts,
                        ContactSet& rigid_releases, Eigen::VectorXd& rates,
                        const std::function<void(const Event&)>& emit) {
  rigid_impacts.clear();
  rigid_releases.clear();
  bool switched = false;
  for (const auto* list : {&impacting, &releasing}) {
    const bool engage = list == &impacting;
    for (int j : *list) {
      const Stop& st = stops[static_cast<std::size_t>(j)];
      if (!st.is_compliant()) {
        (engage ? rigid_impacts : rigid_releases).push_back(j);
        continue;
      }
      const auto at = std::lower_bound(engaged.begin(), engaged.end(), j);
      const bool is_engaged = at != engaged.end() && *at == j;
      if (engage == is_engaged) continue;  // already in that state
      if (engage) engaged.insert(at, j);
      else engaged.erase(at);
      algebra.gap_rates(t, v, rates);
      const double rate = rates(j);
      emit({t, j, engage ? EventKind::engage : EventKind::disengage, rate, rate,
            engage ? st.stiffness * algebra.gap(j, t, x) + st.damping * rate + st.preload : 0.0});
      switched = true;
    }
  }
  return switched;
}

}  // namespace vibro::detail
