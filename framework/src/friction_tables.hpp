#pragma once
// Private to vibro_core: the algebra of friction.hpp's modes, shared by the friction engine
// without stops (friction.cpp) and with stops (friction_stops.cpp): the tangents, M⁻¹, the rows
// that map the augmented state z = [x; v; cos Ωt; sin Ωt; 1; …] to the relative velocities, the
// surfaces' accelerations and the right-hand side r, and each mode's force and acceleration rows.
//
// With stops (friction_stops.hpp) a table also carries the stops' part of a mode: the held
// rigid stops are equality constraints n_jᵀx'' = p_j''(t) solved together with the stuck
// frictional contacts (one Delassus system over both), and the engaged compliant stops add
// −n_j (k_s g_j + c_s g_j' + F_p) to r (stops.hpp). Without stops every operation is the one
// friction.cpp did before the stops were added, in the same order (the same bits).
#include "vibro/friction.hpp"
#include "vibro/flow.hpp"
#include "vibro/stops.hpp"

#include <map>
#include <vector>

namespace vibro::detail {

inline int sign_of(FrictionState s) { return static_cast<int>(s); }

/// The stops' part of a friction mode: every stop (its normal, motion p(t) = s0 + sc cos Ωt +
/// ss sin Ωt and compliant law) and which are held (rigid) and engaged (compliant).
struct FrictionStopPart {
  const std::vector<Stop>* stops = nullptr;
  ContactSet held, engaged;
};

struct FrictionTables {
  Eigen::Index n = 0, N = 0, off = 0;  // dof, augmented size, index of cos Ωt in z
  Eigen::MatrixXd W, minv, minv_W;     // n × m tangents; M⁻¹; M⁻¹W
  Eigen::MatrixXd u_rows, s2_rows;     // m × N: u_j = u_rows z, s_j'' = s2_rows z
  Eigen::MatrixXd r_rows;              // n × N: r = f(t) − C v − K x (− the engaged compliant stops), no friction
  Eigen::VectorXd limit_static, limit_kinetic;  // μ_s N, μ_k N
  /// Per contact j: Σ_k |(Wᵀ M⁻¹ W)_jk|, the largest relative acceleration u_j' that a force error
  /// of 1 on every contact can make (resolve_states' tolerance on u').
  Eigen::VectorXd accel_per_force;
  /// The held rigid stops (FrictionStopPart::held, in order): normals, M⁻¹ normals, and rows of
  /// their normal rates g' = nᵀv − p'(t) and of p''(t) (h × N). Empty without stops.
  Eigen::MatrixXd Wc, minv_Wc, uc_rows, s2c_rows;
  /// Per contact: its tangent lies in the span of the held stops' normals (in_span), so the
  /// stops fix its relative velocity. Such a contact, when stuck, is no constraint of its own:
  /// the held stops take the whole load and its friction force is 0 (the stuck constraint
  /// would repeat theirs, and the split of the force between them is not determined). When the
  /// stops let go it is decided again with its own holding force (friction_stops.hpp).
  std::vector<char> locked;

  FrictionTables(const LinearSystem& sys, const std::vector<FrictionContact>& contacts,
                 const FrictionStopPart* stops = nullptr)
      : FrictionTables(sys.mass(), sys.damping(), sys.stiffness(), sys.forcing(), contacts, stops) {}
  FrictionTables(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K,
                 const HarmonicForcing& f, const std::vector<FrictionContact>& contacts,
                 const FrictionStopPart* stops = nullptr) {
    n = M.rows();
    N = augmented_size(n, f);
    off = 2 * n;
    const auto m = static_cast<Eigen::Index>(contacts.size());
    const double omega = f.frequency;
    W.resize(n, m);
    u_rows = Eigen::MatrixXd::Zero(m, N);
    s2_rows = Eigen::MatrixXd::Zero(m, N);
    limit_static.resize(m);
    limit_kinetic.resize(m);
    for (Eigen::Index j = 0; j < m; ++j) {
      const FrictionContact& c = contacts[static_cast<std::size_t>(j)];
      W.col(j) = c.tangent(n);
      u_rows.row(j).segment(n, n) = W.col(j).transpose();
      // s = a cos(Ωt + φ) = a (cos φ cos Ωt − sin φ sin Ωt); u = wᵀv − s'.
      const double a = c.amplitude, cp = std::cos(c.phase), sp = std::sin(c.phase);
      u_rows(j, off) += a * omega * sp;
      u_rows(j, off + 1) += a * omega * cp;
      s2_rows(j, off) = -a * omega * omega * cp;
      s2_rows(j, off + 1) = a * omega * omega * sp;
      limit_static(j) = c.static_coefficient * c.normal_load;
      limit_kinetic(j) = c.kinetic_coefficient * c.normal_load;
    }
    minv = M.llt().solve(Eigen::MatrixXd::Identity(n, n));
    minv_W = minv * W;
    accel_per_force = (W.transpose() * minv_W).cwiseAbs().rowwise().sum();
    r_rows = Eigen::MatrixXd::Zero(n, N);
    r_rows.leftCols(n) = -K;
    r_rows.middleCols(n, n) = -C;
    r_rows.col(off) = f.cosine;
    r_rows.col(off + 1) = f.sine;
    r_rows.col(off + 2) = f.constant;
    for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
      r_rows.col(off + 3 + 2 * static_cast<Eigen::Index>(h)) = f.harmonics[h].cosine;
      r_rows.col(off + 4 + 2 * static_cast<Eigen::Index>(h)) = f.harmonics[h].sine;
    }
    Wc.resize(n, 0);
    minv_Wc.resize(n, 0);
    uc_rows.resize(0, N);
    s2c_rows.resize(0, N);
    if (stops) add_stops(*stops, omega, &f);
  }

  /// The stops' part (friction_stops.hpp): engaged compliant stops into r, held rigid stops as
  /// constraint columns. A stop's motion p = s0 + sc cos Ωt + ss sin Ωt gives
  /// p' = Ω (ss cos Ωt − sc sin Ωt) and p'' = −Ω² (sc cos Ωt + ss sin Ωt); its higher harmonics
  /// (stops.hpp) the same at k_h Ω on the forcing's slot of their order.
  void add_stops(const FrictionStopPart& part, double omega, const HarmonicForcing* forcing) {
    const std::vector<Stop>& stops = *part.stops;
    for (int j : part.engaged) {
      const Stop& st = stops[static_cast<std::size_t>(j)];
      const Eigen::VectorXd w = st.normal(n);
      const double k = st.stiffness, c = st.damping, sc = st.s_cos(), ss = st.s_sin();
      // −w (k (wᵀx − p) + c (wᵀv − p') + F_p)
      r_rows.leftCols(n) -= k * w * w.transpose();
      r_rows.middleCols(n, n) -= c * w * w.transpose();
      r_rows.col(off) += w * (k * sc + c * omega * ss);
      r_rows.col(off + 1) += w * (k * ss - c * omega * sc);
      r_rows.col(off + 2) += w * (k * st.s0() - st.preload);
      for (std::size_t i = 0; i < st.harmonics.size(); ++i) {  // higher harmonics, ω_h = k_h Ω in place of Ω
        const std::size_t slot = forcing_slot(*forcing, st.harmonics[i].order);
        const Eigen::Index col = augmented_size(n, slot);
        const double wh = forcing->harmonics[slot].rate(omega), hc = st.h_cos(i), hs = st.h_sin(i);
        r_rows.col(col) += w * (k * hc + c * wh * hs);
        r_rows.col(col + 1) += w * (k * hs - c * wh * hc);
      }
    }
    const auto h = static_cast<Eigen::Index>(part.held.size());
    Wc.resize(n, h);
    uc_rows = Eigen::MatrixXd::Zero(h, N);
    s2c_rows = Eigen::MatrixXd::Zero(h, N);
    for (Eigen::Index a = 0; a < h; ++a) {
      const Stop& st = stops[static_cast<std::size_t>(part.held[static_cast<std::size_t>(a)])];
      Wc.col(a) = st.normal(n);
      uc_rows.row(a).segment(n, n) = Wc.col(a).transpose();
      uc_rows(a, off) = -omega * st.s_sin();
      uc_rows(a, off + 1) = omega * st.s_cos();
      s2c_rows(a, off) = -omega * omega * st.s_cos();
      s2c_rows(a, off + 1) = -omega * omega * st.s_sin();
      for (std::size_t i = 0; i < st.harmonics.size(); ++i) {
        const std::size_t slot = forcing_slot(*forcing, st.harmonics[i].order);
        const Eigen::Index col = augmented_size(n, slot);
        const double wh = forcing->harmonics[slot].rate(omega);
        uc_rows(a, col) = -wh * st.h_sin(i);
        uc_rows(a, col + 1) = wh * st.h_cos(i);
        s2c_rows(a, col) = -wh * wh * st.h_cos(i);
        s2c_rows(a, col + 1) = -wh * wh * st.h_sin(i);
      }
    }
    minv_Wc = minv * Wc;
    locked.assign(static_cast<std::size_t>(W.cols()), 0);
    for (Eigen::Index j = 0; j < W.cols(); ++j) locked[static_cast<std::size_t>(j)] = in_span(Wc, W.col(j));
  }

  /// Whether w lies in the column span of B (least-squares residual ≤ 1e-12 ‖w‖).
  static bool in_span(const Eigen::MatrixXd& B, const Eigen::VectorXd& w) {
    if (B.cols() == 0) return false;
    const Eigen::VectorXd c = B.colPivHouseholderQr().solve(w);
    return (w - B * c).norm() <= 1e-12 * w.norm();
  }
  bool is_locked(Eigen::Index j) const { return !locked.empty() && locked[static_cast<std::size_t>(j)]; }

  /// mode_rows of `states`, computed on first use and kept for the run: the resolution at every
  /// event tries several assignments, mostly the same few, and each costs a factorisation. The
  /// cache stops growing at kMaxCached assignments (3^m of them exist); later ones are computed
  /// into a scratch pair each time.
  struct Rows {
    Eigen::MatrixXd force, accel, held;
  };
  const Rows& cached_rows(const std::vector<FrictionState>& states) const {
    const auto it = cache_.find(states);
    if (it != cache_.end()) return it->second;
    if (cache_.size() >= kMaxCached) {
      mode_rows(states, scratch_.force, scratch_.accel, &scratch_.held);
      return scratch_;
    }
    Rows& r = cache_[states];
    mode_rows(states, r.force, r.accel, &r.held);
    return r;
  }
  static constexpr std::size_t kMaxCached = 4096;
  mutable std::map<std::vector<FrictionState>, Rows> cache_;
  mutable Rows scratch_;

  /// In the given states: rows (m × N) of every contact's force F_j, and rows (n × N) of the
  /// acceleration x'' (both linear in z); with held stops, rows (h × N) of their forces along
  /// their normals into `held_rows` (the push on the masses is n_j F; the contact force of
  /// stops.hpp, λ_j = −F ≥ 0 while the stop holds).
  void mode_rows(const std::vector<FrictionState>& states, Eigen::MatrixXd& force_rows, Eigen::MatrixXd& accel_rows,
                 Eigen::MatrixXd* held_rows = nullptr) const {
    const auto m = static_cast<Eigen::Index>(states.size());
    const Eigen::Index hc = Wc.cols();
    force_rows = Eigen::MatrixXd::Zero(m, N);
    if (held_rows) held_rows->setZero(hc, N);
    std::vector<Eigen::Index> stuck;
    for (Eigen::Index j = 0; j < m; ++j) {
      const FrictionState s = states[static_cast<std::size_t>(j)];
      if (s == FrictionState::stuck) {
        if (!is_locked(j)) stuck.push_back(j);  // a locked stuck contact: force 0 (locked)
      } else {
        force_rows(j, off + 2) = -limit_kinetic(j) * sign_of(s);
      }
    }
    Eigen::MatrixXd r = r_rows;  // r with the slipping forces
    for (Eigen::Index j = 0; j < m; ++j)
      if (states[static_cast<std::size_t>(j)] != FrictionState::stuck) r.col(off + 2) += W.col(j) * force_rows(j, off + 2);
    accel_rows = minv * r;
    if (stuck.empty() && hc == 0) return;
    // The constraints: the held stops first, then the stuck contacts.
    const auto s = static_cast<Eigen::Index>(stuck.size()) + hc;
    Eigen::MatrixXd Ws(n, s), MWs(n, s), S2(s, N);
    for (Eigen::Index k = 0; k < hc; ++k) {
      Ws.col(k) = Wc.col(k);
      MWs.col(k) = minv_Wc.col(k);
      S2.row(k) = s2c_rows.row(k);
    }
    for (Eigen::Index k = hc; k < s; ++k) {
      Ws.col(k) = W.col(stuck[static_cast<std::size_t>(k - hc)]);
      MWs.col(k) = minv_W.col(stuck[static_cast<std::size_t>(k - hc)]);
      S2.row(k) = s2_rows.row(stuck[static_cast<std::size_t>(k - hc)]);
    }
    const Eigen::MatrixXd G = Ws.transpose() * MWs;
    const Eigen::MatrixXd hold = G.ldlt().solve(S2 - Ws.transpose() * accel_rows);  // F_S rows
    for (Eigen::Index k = hc; k < s; ++k) force_rows.row(stuck[static_cast<std::size_t>(k - hc)]) = hold.row(k);
    if (held_rows) *held_rows = hold.topRows(hc);
    accel_rows += MWs * hold;
  }
};

/// friction.hpp's resolution: the states of every contact at z, given the old states, the
/// contact whose guard fired (−1: none) and the tolerances; false when none is consistent.
/// With held stops in `tab` they are constraints of every assignment tried.
bool resolve_states(const FrictionTables& tab, const Eigen::VectorXd& z, std::vector<FrictionState>& states, int fired,
                    double eps_v, double eps_f, double eps_a);

/// Sets u_j = 0 exactly for every contact stuck before or after the switch, and g' = 0 for the
/// held stops of `tab`, by the smallest change of v in the metric of M (friction.cpp).
void settle_relative_velocities(const FrictionTables& tab, const std::vector<FrictionState>& before,
                                const std::vector<FrictionState>& after, Eigen::VectorXd& z);

/// z = [x; v; cos Ωt; sin Ωt; 1; cos k₁Ωt; sin k₁Ωt; …] (flow.hpp's layout) at time t: the
/// augmented state both friction engines evaluate their rows on (friction.cpp).
Eigen::VectorXd augmented_state(const LinearSystem& sys, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v);

}  // namespace vibro::detail

namespace vibro::detail {

/// A friction mode's guard rows (friction.hpp's order: per contact, −σ_j u_j while slipping,
/// F_j − μ_s N_j and −F_j − μ_s N_j while stuck), with each row's contact and whether it is a
/// force guard (friction.cpp).
Eigen::MatrixXd friction_guard_rows(const FrictionTables& tab, const std::vector<FrictionState>& states,
                                    const Eigen::MatrixXd& force_rows, std::vector<int>* contact,
                                    std::vector<char>* force_guard);

}  // namespace vibro::detail
