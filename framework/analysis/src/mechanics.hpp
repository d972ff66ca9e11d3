#pragma once
// Private to vibro_analysis: the mechanics of an ImpactSystem written once for any scalar type
// (double for values, Dual for exact directional derivatives; dual.hpp).
//
// With n degrees of freedom and the stops in canonical form (stops.hpp) g_j = w_jᵀx − s_j(t):
//
//   forcing      f(t) = F0 + Fc cos Ωt + Fs sin Ωt + Σ_h (Fc_h cos k_hΩt + Fs_h sin k_hΩt)
//   stop motion  s_j(t) = s0_j + sc_j cos Ωt + ss_j sin Ωt + Σ_h (hc_jh cos k_hΩt + hs_jh sin k_hΩt)
//                (the stop's higher harmonics on the forcing's slots h, stops.hpp), and its time
//                derivatives
//   free         a_free = M⁻¹ (f − C v − K x)
//   held set S   W = [w_j]_{j∈S}, Q = M⁻¹ W, G = Wᵀ Q (Delassus), and from Wᵀ x'' = s''_S:
//                  λ_S = G⁻¹ (Wᵀ a_free − s''_S)                 (contact forces, contact.hpp)
//                  a_S = a_free − Q λ_S = Π a_free + Q G⁻¹ s''_S,   Π = I − Q G⁻¹ Wᵀ
//
// The constrained generator. With z = [x; v; cos Ωt; sin Ωt; 1; cos k_hΩt; sin k_hΩt …] the motion
// with S held is the linear system z' = Â_S z of size augmented_size(n, H) in the FULL coordinates, whose velocity rows are a_S
// written as a linear function of z (flow.hpp has Â_∅). It keeps the constraint manifold
// {Wᵀx = s(t), Wᵀv = s'(t)} invariant (Wᵀa_S = s''), so on the manifold it is the engine's
// reduced sticking flow (contact.hpp) in other coordinates, and its tangent map is the one of
// the engine's motion; off the manifold the normal coordinates drift linearly (g'' = 0), which
// the resets never feed (they leave tangent vectors on the manifold, see linearisation.hpp).
// Being written in full coordinates, its derivative along a parameter is one formula for every
// contact set and every kind of parameter, stop positions included.
//
// The event reset (the engine's rules, event_resolution.cpp, with its discrete decisions fixed:
// which stops impact, which the chatter rule catches, which take an impulse, which are held
// after):
//   1. impulse over `all` = S ∪ I with r_eff = 0 for held and caught stops, on its active set A:
//        v1 = v − Q_A G_AA⁻¹ ((1 + r_eff) ∘ (W_Aᵀ v − s'_A(t)))
//   2. second- and third-order chatter rules, for each caught stop j held after (simulator.hpp, ChatterRule):
//        x2 = x − (D_j / G_jj) d_j,   v2 = v1 + (D_j / G_jj) (M⁻¹ C d_j − M⁻¹ K M⁻¹ w_j),
//        d_j = P_N M⁻¹ C M⁻¹ w_j (P_N y = y − Q_N G_NN⁻¹ W_Nᵀ y),
//        D_j = −(2/3) w0³ / (A_j² (1 − r_j³)),
//        w0 = r_j (w_jᵀ v − s'_j(t)) (the rebound speed, from the velocity before the impact),
//        A_j = G_jj λ_j with λ = λ_N(x, v1, t) the forces of the held set N after the event
//        (with forces beyond M, C, K and the drive, those of set_chatter_forces);
//   3. the held set's residual normal velocity removed:
//        v3 = v2 − Q_N G_NN⁻¹ (W_Nᵀ v2 − s'_N(t)).
// Otherwise the position is not reset (the engine's placement of the gap exactly at zero
// corrects rounding only and is zero along the exact map).
//
// Compliant stops (stops.hpp). A contact set S is a mode's key, as in the engine (contact.hpp):
// the held rigid stops R = held_part(S) and the engaged compliant stops E = engaged_part(S).
// Each engaged stop j adds its Kelvin–Voigt force −w_j N_j, N_j = k_j g_j + c_j g'_j + F_p,j, to
// the free motion:
//   a_free,E = M⁻¹ (f − C v − K x − Σ_{j∈E} w_j N_j),
// linear in z again: k_j w_j w_jᵀ joins K, c_j w_j w_jᵀ joins C, and w_j (k_j s_j + c_j s'_j − F_p,j)
// joins f (the cos, sin and constant columns of B). Everything above then reads a_free,E for
// a_free and the rigid stops R for S: the constraint forces, the generator, the resets (an
// engagement or disengagement has no impulse: R_z is the identity up to the projection of
// step 3 onto the held rigid stops' manifold). With T = Dual the law's k_j, c_j, F_p,j carry
// their derivatives (StopDerivative::stiffness, damping, preload), so dÂ_S/dp holds
// dk_j w_j w_jᵀ, dc_j w_j w_jᵀ and dF_p,j for the engaged stops of S only.
#include "dual.hpp"
#include "vibro/contact.hpp"
#include "vibro/modal.hpp"
#include "vibro/parameter.hpp"
#include "vibro/simulator.hpp"
#include "vibro/stops.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iterator>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vibro::detail {

template <class T>
using VecT = Eigen::Matrix<T, Eigen::Dynamic, 1>;
template <class T>
using MatT = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;

/// The decisions of one event resolution, fixed: the derivative is that of the map that makes
/// them (the engine makes the same ones for every state near the computed trajectory).
struct ResetRule {
  ContactSet held_before;  ///< S
  ContactSet impacting;    ///< I (empty: no impulse; a release or the start of a run)
  ContactSet caught;       ///< stops of I the chatter rule ended (r_eff = 0, kick)
  ContactSet impulse;      ///< A ⊂ S ∪ I: the stops whose impulse is > 0 (LCP active set)
  ContactSet held_after;   ///< N
  ChatterRule rule = ChatterRule::third_order;
};

/// A stop's normal: w = e_i (upper), −e_i (lower), e_i − e_k (between), or any dense n
/// (Stop::Kind::normal, then `dense` holds it and i, k, a, b are unused).
struct SparseNormal {
  Eigen::Index i = 0, k = -1;
  double a = 1.0, b = 0.0;  ///< w = a e_i + b e_k
  Eigen::VectorXd dense;    ///< w itself for a general stop; empty otherwise
  /// Writes w into `out` (length n, zero on entry): the sparse entries or the dense ones.
  template <class Out>
  void scatter(Out&& out) const {
    if (dense.size() > 0) {
      for (Eigen::Index l = 0; l < dense.size(); ++l) out(l) = dense(l);
      return;
    }
    out(i) = a;
    if (k >= 0) out(k) = b;
  }
};

template <class T>
class Mechanics {
 public:
  /// The system's data as T; for T = Dual, `direction` (if given) seeds their derivatives.
  Mechanics(const ImpactSystem& system, const SystemDerivative* direction = nullptr)
      : n_(system.dof()), m_(system.stop_count()) {
    const LinearSystem& sys = system.system();
    const HarmonicForcing& f = sys.forcing();
    const SystemDerivative zero;
    const SystemDerivative& d = direction ? *direction : zero;
    M_ = seed(sys.mass(), d.mass);
    C_ = seed(sys.damping(), d.damping);
    K_ = seed(sys.stiffness(), d.stiffness);
    F0_ = seed(f.constant, d.constant);
    Fc_ = seed(f.cosine, d.cosine);
    Fs_ = seed(f.sine, d.sine);
    omega_ = make(f.frequency, d.frequency);
    for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
      const ForcingHarmonic& fh = f.harmonics[h];
      orders_.push_back(fh.order);
      Hc_.push_back(seed(fh.cosine, h < d.harmonic_cosine.size() ? d.harmonic_cosine[h] : Eigen::VectorXd()));
      Hs_.push_back(seed(fh.sine, h < d.harmonic_sine.size() ? d.harmonic_sine[h] : Eigen::VectorXd()));
    }
    llt_.compute(M_);
    add_stops(system.stops(), d);
  }

  /// A chain of the modal engine (modal.hpp) in its banded form: M diagonal, K tridiagonal,
  /// C = αM + βK, so that every operation the resets and the contact forces need is O(n) and
  /// nothing n × n is stored (chains of 10 000 masses); compliant stops as on the dense form
  /// (engaged sets' a_free,E, forces, resets). The generator and the force rows, which
  /// are dense by nature, are not available on this form (the modal tangent map does not use them).
  /// `direction` (T = Dual) seeds the forcing, Ω and the stops' data; it must not move M, C or K
  /// (their derivatives have no banded form here; the caller refuses them).
  Mechanics(const BandedChain& chain, const std::vector<Stop>& stops, const SystemDerivative* direction = nullptr)
      : n_(chain.dof()), m_(stops.size()), banded_(true) {
    const SystemDerivative zero;
    const SystemDerivative& d = direction ? *direction : zero;
    if (moves_matrices(d))
      throw std::logic_error("Mechanics: the banded form takes no derivative of M, C or K");
    mass_ = seed(chain.mass, Eigen::VectorXd());
    k_diagonal_ = seed(chain.stiffness_diagonal, Eigen::VectorXd());
    k_off_ = seed(chain.stiffness_off, Eigen::VectorXd());
    alpha_ = make(chain.rayleigh_mass, 0.0);
    beta_ = make(chain.rayleigh_stiffness, 0.0);
    F0_ = seed(chain.forcing.constant, d.constant);
    Fc_ = seed(chain.forcing.cosine, d.cosine);
    Fs_ = seed(chain.forcing.sine, d.sine);
    omega_ = make(chain.forcing.frequency, d.frequency);
    for (std::size_t h = 0; h < chain.forcing.harmonics.size(); ++h) {
      const ForcingHarmonic& fh = chain.forcing.harmonics[h];
      orders_.push_back(fh.order);
      Hc_.push_back(seed(fh.cosine, h < d.harmonic_cosine.size() ? d.harmonic_cosine[h] : Eigen::VectorXd()));
      Hs_.push_back(seed(fh.sine, h < d.harmonic_sine.size() ? d.harmonic_sine[h] : Eigen::VectorXd()));
    }
    add_stops(stops, d);
  }

  Eigen::Index dof() const { return n_; }
  std::size_t stops() const { return m_; }
  const T& frequency() const { return omega_; }
  const SparseNormal& normal(int j) const { return normals_[static_cast<std::size_t>(j)]; }
  const T& restitution(int j) const { return r_[static_cast<std::size_t>(j)]; }

  /// dᵏ/dtᵏ s_j(t), k = 0 … 3.
  T stop_position(int j, const T& t, int k = 0) const {
    const auto J = static_cast<std::size_t>(j);
    using std::cos;
    using std::sin;
    const T c = cos(omega_ * t), s = sin(omega_ * t);
    const T& a = sc_[J];
    const T& b = ss_[J];
    T out;
    switch (k) {
      case 0: out = s0_[J] + a * c + b * s; break;
      case 1: out = omega_ * (b * c - a * s); break;
      case 2: out = -omega_ * omega_ * (a * c + b * s); break;
      default: out = omega_ * omega_ * omega_ * (a * s - b * c); break;
    }
    if (stop_slots_.empty() || stop_slots_[J].empty()) return out;
    for (std::size_t i = 0; i < stop_slots_[J].size(); ++i) {
      const T w = harmonic_rate(stop_slots_[J][i]), ch = cos(w * t), sh = sin(w * t);
      const T& p = hc_[J][i];
      const T& q = hs_[J][i];
      switch (k) {
        case 0: out += p * ch + q * sh; break;
        case 1: out += w * (q * ch - p * sh); break;
        case 2: out -= w * w * (p * ch + q * sh); break;
        default: out += w * w * w * (p * sh - q * ch); break;
      }
    }
    return out;
  }

  /// The forcing's harmonic amplitudes: F0 (h = 0), Fc (h = 1), Fs (h = 2).
  const VecT<T>& forcing_amplitude(int h) const { return h == 0 ? F0_ : (h == 1 ? Fc_ : Fs_); }
  /// Stop j's: s0 (h = 0), sc (h = 1), ss (h = 2).
  const T& stop_amplitude(int j, int h) const {
    const auto J = static_cast<std::size_t>(j);
    return h == 0 ? s0_[J] : (h == 1 ? sc_[J] : ss_[J]);
  }

  /// f(t) (k = 0) or f'(t) (k = 1).
  VecT<T> forcing(const T& t, int k = 0) const {
    using std::cos;
    using std::sin;
    const T c = cos(omega_ * t), s = sin(omega_ * t);
    if (orders_.empty()) {
      if (k == 0) return F0_ + Fc_ * c + Fs_ * s;
      return omega_ * (Fs_ * c - Fc_ * s);
    }
    VecT<T> f = k == 0 ? VecT<T>(F0_ + Fc_ * c + Fs_ * s) : VecT<T>(omega_ * (Fs_ * c - Fc_ * s));
    for (std::size_t h = 0; h < orders_.size(); ++h) {
      const T w = harmonic_rate(h), ch = cos(w * t), sh = sin(w * t);
      f += k == 0 ? VecT<T>(Hc_[h] * ch + Hs_[h] * sh) : VecT<T>(w * (Hs_[h] * ch - Hc_[h] * sh));
    }
    return f;
  }
  /// Extra harmonics (system.hpp): their number and rates k_h Ω.
  std::size_t harmonics() const { return orders_.size(); }
  T harmonic_rate(std::size_t h) const { return static_cast<double>(orders_[h]) * omega_; }
  int harmonic_order(std::size_t h) const { return orders_[h]; }
  /// Extra harmonic h's amplitudes: its cosine (part 0) or sine (part 1) vector.
  const VecT<T>& harmonic_amplitude(std::size_t h, int part) const { return part == 0 ? Hc_[h] : Hs_[h]; }
  /// The augmented size 2n + 3 + 2H.
  Eigen::Index augmented() const { return augmented_size(n_, orders_.size()); }
  /// Stop j's part of extra harmonic h's amplitude in s_j(t): cosine (part 0) or sine (part 1);
  /// 0 when the stop does not move at that harmonic's order.
  T stop_harmonic_amplitude(int j, std::size_t h, int part) const {
    const auto J = static_cast<std::size_t>(j);
    T out = make(0.0, 0.0);
    if (stop_slots_.empty()) return out;
    for (std::size_t i = 0; i < stop_slots_[J].size(); ++i)
      if (stop_slots_[J][i] == h) out = out + (part == 0 ? hc_[J][i] : hs_[J][i]);
    return out;
  }

  /// w_jᵀ y.
  T normal_dot(int j, const VecT<T>& y) const {
    const SparseNormal& w = normal(j);
    if (w.dense.size() > 0) {
      T out = w.dense(0) * y(0);
      for (Eigen::Index l = 1; l < n_; ++l) out += w.dense(l) * y(l);
      return out;
    }
    T out = w.a * y(w.i);
    if (w.k >= 0) out += w.b * y(w.k);
    return out;
  }
  /// g_j = w_jᵀ x − s_j(t), and its rate w_jᵀ v − s_j'(t).
  T gap(int j, const VecT<T>& x, const T& t) const { return normal_dot(j, x) - stop_position(j, t); }
  T gap_rate(int j, const VecT<T>& v, const T& t) const { return normal_dot(j, v) - stop_position(j, t, 1); }

  /// W_set (n × |set|) and Q = M⁻¹ W_set.
  MatT<T> normals(const ContactSet& set) const {
    MatT<T> W = MatT<T>::Zero(n_, static_cast<Eigen::Index>(set.size()));
    for (std::size_t a = 0; a < set.size(); ++a) normal(set[a]).scatter(W.col(static_cast<Eigen::Index>(a)));
    return W;
  }
  MatT<T> mass_inverse(const MatT<T>& y) const {
    if (banded_) return MatT<T>(mass_.cwiseInverse().asDiagonal() * y);
    return llt_.solve(y);
  }
  VecT<T> mass_inverse(const VecT<T>& y) const {
    if (banded_) return y.cwiseQuotient(mass_);
    return llt_.solve(y);
  }
  /// K y.
  VecT<T> stiffness_times(const VecT<T>& y) const {
    if (!banded_) return K_ * y;
    VecT<T> out = k_diagonal_.cwiseProduct(y);
    for (Eigen::Index i = 0; i + 1 < n_; ++i) {
      out(i) += k_off_(i) * y(i + 1);
      out(i + 1) += k_off_(i) * y(i);
    }
    return out;
  }

  /// C y.
  VecT<T> damping_times(const VecT<T>& y) const {
    if (!banded_) return C_ * y;
    return alpha_ * mass_.cwiseProduct(y) + beta_ * stiffness_times(y);
  }

  /// M⁻¹ (f − C v − K x).
  VecT<T> free_acceleration(const VecT<T>& x, const VecT<T>& v, const T& t) const {
    return acceleration_under(forcing(t), x, v);
  }
  /// M⁻¹ (F − C v − K x) for a given force F.
  VecT<T> acceleration_under(const VecT<T>& F, const VecT<T>& x, const VecT<T>& v) const {
    if (banded_) {
      return mass_inverse(VecT<T>(F - damping_times(v) - stiffness_times(x)));
    }
    return llt_.solve(VecT<T>(F - C_ * v - K_ * x));
  }

  /// Whether stop j is compliant (stops.hpp), and the parts of a mode's key S: the held rigid
  /// stops and the engaged compliant ones (the whole key and nothing when no stop is compliant).
  bool compliant(int j) const { return !compliant_.empty() && compliant_[static_cast<std::size_t>(j)]; }
  bool any_compliant() const { return !compliant_.empty(); }
  ContactSet held_part(const ContactSet& S) const {
    if (compliant_.empty()) return S;
    ContactSet out;
    for (int j : S)
      if (!compliant(j)) out.push_back(j);
    return out;
  }
  ContactSet engaged_part(const ContactSet& S) const {
    ContactSet out;
    if (compliant_.empty()) return out;
    for (int j : S)
      if (compliant(j)) out.push_back(j);
    return out;
  }

  /// A compliant stop's law (stops.hpp): k_j, c_j, F_p,j (0 on a rigid stop).
  const T& compliant_stiffness(int j) const { return ks_[static_cast<std::size_t>(j)]; }
  const T& compliant_damping(int j) const { return cs_[static_cast<std::size_t>(j)]; }
  const T& preload(int j) const { return fp_[static_cast<std::size_t>(j)]; }

  /// a_free,E: the free acceleration with the compliant stops of S engaged (file comment).
  VecT<T> free_acceleration_in(const ContactSet& S, const VecT<T>& x, const VecT<T>& v, const T& t) const {
    VecT<T> a = free_acceleration(x, v, t);
    if (compliant_.empty()) return a;
    VecT<T> push = VecT<T>::Zero(n_);
    bool any = false;
    for (int j : S) {
      if (!compliant(j)) continue;
      const auto J = static_cast<std::size_t>(j);
      const T N = ks_[J] * gap(j, x, t) + cs_[J] * gap_rate(j, v, t) + fp_[J];
      VecT<T> w = VecT<T>::Zero(n_);
      normal(j).scatter(w);
      push += w * N;
      any = true;
    }
    if (any) a -= mass_inverse(push);
    return a;
  }

  /// λ_R = G⁻¹ (Wᵀ a_free,E − s''_R) at (x, v, t), for the held rigid stops R of S.
  VecT<T> forces(const ContactSet& S, const VecT<T>& x, const VecT<T>& v, const T& t) const {
    if (compliant_.empty()) return held_forces(S, free_acceleration(x, v, t), t);
    return held_forces(held_part(S), free_acceleration_in(S, x, v, t), t);
  }

  /// a_S = a_free,E − Q λ_R.
  VecT<T> acceleration(const ContactSet& S, const VecT<T>& x, const VecT<T>& v, const T& t) const {
    if (!compliant_.empty()) {
      const ContactSet R = held_part(S);
      const VecT<T> a = free_acceleration_in(S, x, v, t);
      if (R.empty()) return a;
      return a - mass_inverse(normals(R)) * held_forces(R, a, t);
    }
    const VecT<T> a = free_acceleration(x, v, t);
    if (S.empty()) return a;
    const MatT<T> Q = mass_inverse(normals(S));
    return a - Q * held_forces(S, a, t);
  }

  /// a_free = B z with B = M⁻¹ [−K, −C, Fc, Fs, F0, Fc_h, Fs_h …] (n × augmented(); columns x,
  /// v, cos, sin, 1, then cos, sin of each extra harmonic).
  MatT<T> free_rows() const {
    require_dense("free_rows");
    MatT<T> X(n_, augmented());
    X.leftCols(2 * n_ + 3) << -K_, -C_, Fc_, Fs_, F0_;
    for (std::size_t h = 0; h < orders_.size(); ++h) {
      X.col(augmented_size(n_, h)) = Hc_[h];
      X.col(augmented_size(n_, h) + 1) = Hs_[h];
    }
    return mass_inverse(X);
  }
  /// a_free,E = B_E z: free_rows() with the compliant stops of S engaged (file comment).
  MatT<T> free_rows(const ContactSet& S) const {
    if (compliant_.empty()) return free_rows();
    require_dense("free_rows");
    const Eigen::Index n = n_;
    MatT<T> X(n_, augmented());
    X.leftCols(2 * n_ + 3) << -K_, -C_, Fc_, Fs_, F0_;
    for (std::size_t h = 0; h < orders_.size(); ++h) {
      X.col(augmented_size(n_, h)) = Hc_[h];
      X.col(augmented_size(n_, h) + 1) = Hs_[h];
    }
    for (int j : S) {
      if (!compliant(j)) continue;
      const auto J = static_cast<std::size_t>(j);
      VecT<T> w = VecT<T>::Zero(n);
      normal(j).scatter(w);
      const MatT<T> wwT = w * w.transpose();
      X.leftCols(n) -= ks_[J] * wwT;
      X.middleCols(n, n) -= cs_[J] * wwT;
      X.col(2 * n) += w * (ks_[J] * sc_[J] + cs_[J] * omega_ * ss_[J]);
      X.col(2 * n + 1) += w * (ks_[J] * ss_[J] - cs_[J] * omega_ * sc_[J]);
      X.col(2 * n + 2) += w * (ks_[J] * s0_[J] - fp_[J]);
      for (std::size_t i = 0; !stop_slots_.empty() && i < stop_slots_[J].size(); ++i) {
        const std::size_t h = stop_slots_[J][i];
        const T wh = harmonic_rate(h);
        X.col(augmented_size(n, h)) += w * (ks_[J] * hc_[J][i] + cs_[J] * wh * hs_[J][i]);
        X.col(augmented_size(n, h) + 1) += w * (ks_[J] * hs_[J][i] - cs_[J] * wh * hc_[J][i]);
      }
    }
    return mass_inverse(X);
  }
  /// λ_R = L z with L = G⁻¹ (Wᵀ B_E − Z), Z z = s''_R(t) (|R| × augmented()), R the held rigid
  /// stops of S and E its engaged compliant ones.
  MatT<T> force_rows(const ContactSet& key) const {
    const ContactSet S = held_part(key);
    const Eigen::Index n = n_, N = augmented();
    const MatT<T> W = normals(S);
    const MatT<T> G = W.transpose() * mass_inverse(W);
    MatT<T> Z = MatT<T>::Zero(static_cast<Eigen::Index>(S.size()), N);
    for (std::size_t a = 0; a < S.size(); ++a) {
      const auto J = static_cast<std::size_t>(S[a]);
      Z(static_cast<Eigen::Index>(a), 2 * n) = -omega_ * omega_ * sc_[J];
      Z(static_cast<Eigen::Index>(a), 2 * n + 1) = -omega_ * omega_ * ss_[J];
      for (std::size_t i = 0; !stop_slots_.empty() && i < stop_slots_[J].size(); ++i) {
        const std::size_t h = stop_slots_[J][i];
        const T wh = harmonic_rate(h);
        Z(static_cast<Eigen::Index>(a), augmented_size(n, h)) = -wh * wh * hc_[J][i];
        Z(static_cast<Eigen::Index>(a), augmented_size(n, h) + 1) = -wh * wh * hs_[J][i];
      }
    }
    return G.partialPivLu().solve(MatT<T>(W.transpose() * free_rows(key) - Z));
  }
  /// g_j = ℓ_j z: w_j on x, −(sc_j, ss_j, s0_j) on (cos, sin, 1).
  VecT<T> gap_row(int j) const {
    const Eigen::Index n = n_;
    const auto J = static_cast<std::size_t>(j);
    VecT<T> row = VecT<T>::Zero(augmented());
    normal(j).scatter(row.head(n));
    row(2 * n) = -sc_[J];
    row(2 * n + 1) = -ss_[J];
    row(2 * n + 2) = -s0_[J];
    for (std::size_t i = 0; !stop_slots_.empty() && i < stop_slots_[J].size(); ++i) {
      row(augmented_size(n, stop_slots_[J][i])) = -hc_[J][i];
      row(augmented_size(n, stop_slots_[J][i]) + 1) = -hs_[J][i];
    }
    return row;
  }

  /// Â_S (augmented()): the motion with S held, in full coordinates (see the file comment).
  MatT<T> generator(const ContactSet& key) const {
    const Eigen::Index n = n_, N = augmented();
    const ContactSet S = held_part(key);
    MatT<T> g = MatT<T>::Zero(N, N);
    MatT<T> B = free_rows(key);
    if (!S.empty()) B -= mass_inverse(normals(S)) * force_rows(key);
    g.block(0, n, n, n).setIdentity();
    g.middleRows(n, n) = B;
    g(2 * n, 2 * n + 1) = -omega_;
    g(2 * n + 1, 2 * n) = omega_;
    for (std::size_t h = 0; h < orders_.size(); ++h) {
      const Eigen::Index c = augmented_size(n, h);
      g(c, c + 1) = -harmonic_rate(h);
      g(c + 1, c) = harmonic_rate(h);
    }
    return g;
  }

  /// [x; v] after an event resolved by `rule` at (x, v, t) (the file comment, steps 1–3).
  VecT<T> reset(const ResetRule& rule, const VecT<T>& x, const VecT<T>& v, const T& t) const {
    VecT<T> v1 = v;
    if (!rule.impacting.empty() && !rule.impulse.empty()) {
      const ContactSet& A = rule.impulse;
      const MatT<T> W = normals(A);
      const MatT<T> Q = mass_inverse(W);
      const MatT<T> G = W.transpose() * Q;
      VecT<T> q(static_cast<Eigen::Index>(A.size()));
      for (std::size_t a = 0; a < A.size(); ++a) {
        const int j = A[a];
        const bool rests = contains(rule.held_before, j) || contains(rule.caught, j);
        const T r = rests ? T(0.0) : restitution(j);
        q(static_cast<Eigen::Index>(a)) = (T(1.0) + r) * gap_rate(j, v, t);
      }
      v1 = v - Q * G.partialPivLu().solve(q);
    }
    VecT<T> out(2 * n_);
    out.head(n_) = x;
    VecT<T> v2 = v1;
    const ContactSet N = held_part(rule.held_after);
    if (rule.rule != ChatterRule::first_order && !rule.caught.empty() && !N.empty()) {
      const VecT<T> lambda = friction_.active() ? forces_with_friction(rule.held_after, x, v1, t)
                             : chatter_forces_  ? chatter_forces_(rule.held_after, x, v1, t)
                                                : forces(rule.held_after, x, v1, t);
      const MatT<T> WN = normals(N);
      const MatT<T> QN = mass_inverse(WN);
      const auto GN = (WN.transpose() * QN).eval().partialPivLu();
      for (int j : rule.caught) {
        if (!contains(N, j)) continue;
        const auto a = static_cast<Eigen::Index>(std::lower_bound(N.begin(), N.end(), j) - N.begin());
        const MatT<T> wj = normals({j});
        const VecT<T> qj = mass_inverse(VecT<T>(wj.col(0)));
        const T Gjj = normal_dot(j, qj);
        const T A = Gjj * lambda(a);
        if (!(value_of(A) > 0.0)) continue;
        const T r = restitution(j);
        const T w0 = r * gap_rate(j, v, t);
        const T D = -(2.0 / 3.0) * w0 * w0 * w0 / (A * A * (T(1.0) - r * r * r));
        VecT<T> d = mass_inverse(damping_times(qj));
        d -= QN * GN.solve(VecT<T>(WN.transpose() * d));
        out.head(n_) -= d * (D / Gjj);
        v2 += (mass_inverse(damping_times(d)) - mass_inverse(stiffness_times(qj))) * (D / Gjj);
      }
    }
    if (N.empty()) {
      out.tail(n_) = v2;
      return out;
    }
    const MatT<T> W = normals(N);
    const MatT<T> Q = mass_inverse(W);
    const MatT<T> G = W.transpose() * Q;
    VecT<T> g(static_cast<Eigen::Index>(N.size()));
    for (std::size_t a = 0; a < N.size(); ++a) g(static_cast<Eigen::Index>(a)) = gap_rate(N[a], v2, t);
    out.tail(n_) = v2 - Q * G.partialPivLu().solve(g);
    return out;
  }

  static bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

  /// The frictional contacts of a run with friction and stops (friction_stops.hpp), in the
  /// states they have while the stops' event is resolved: the slipping contacts' forces (one
  /// constant force) and the stuck contacts' constraints w_kᵀx'' = s_k''(t), s_k = a_k cos(Ωt + φ_k).
  /// The held stops' forces that the chatter rule reads (reset, step 2) are then those of the
  /// Delassus system over the held stops and the stuck contacts together, with the slipping
  /// forces in the free acceleration, as that engine computes them. Empty (the default): none.
  struct FrictionPart {
    VecT<T> slip_force;               ///< Σ_slipping w_k F_k (n), or empty
    MatT<T> stuck;                    ///< the stuck contacts' tangents (n × s)
    std::vector<T> amplitude, phase;  ///< their surfaces' a_k, φ_k
    bool active() const { return slip_force.size() > 0 || stuck.cols() > 0; }
  };
  void set_friction(FrictionPart part) { friction_ = std::move(part); }

  /// The held rigid stops' forces λ of the mode `key` at (x, v, t) of a system with forces beyond
  /// M, C, K and the drive (the nonlinear forces of the Taylor engine, nonlinear_part.hpp): the
  /// chatter rule (reset, step 2) reads them instead of forces(), as that engine's capture does.
  /// Empty (the default): forces().
  using ChatterForces = std::function<VecT<T>(const ContactSet& key, const VecT<T>& x, const VecT<T>& v, const T& t)>;
  void set_chatter_forces(ChatterForces forces) { chatter_forces_ = std::move(forces); }

  /// True when `d` moves M, C or K (a non-zero entry in one of them).
  static bool moves_matrices(const SystemDerivative& d) {
    for (const Eigen::MatrixXd* m : {&d.mass, &d.damping, &d.stiffness})
      if (m->size() > 0 && !m->isZero(0.0)) return true;
    return false;
  }

 private:
  static T make(double value, double derivative) {
    if constexpr (std::is_same_v<T, double>) {
      (void)derivative;
      return value;
    } else {
      return T(value, derivative);
    }
  }
  static MatT<T> seed(const Eigen::MatrixXd& value, const Eigen::MatrixXd& derivative) {
    MatT<T> out(value.rows(), value.cols());
    for (Eigen::Index i = 0; i < value.rows(); ++i)
      for (Eigen::Index k = 0; k < value.cols(); ++k)
        out(i, k) = make(value(i, k), derivative.size() ? derivative(i, k) : 0.0);
    return out;
  }
  static VecT<T> seed(const Eigen::VectorXd& value, const Eigen::VectorXd& derivative) {
    VecT<T> out(value.size());
    for (Eigen::Index i = 0; i < value.size(); ++i) out(i) = make(value(i), derivative.size() ? derivative(i) : 0.0);
    return out;
  }

  /// λ of the held rigid stops of `key` with the frictional contacts of friction_ (FrictionPart).
  VecT<T> forces_with_friction(const ContactSet& key, const VecT<T>& x, const VecT<T>& v, const T& t) const {
    using std::cos;
    const ContactSet R = held_part(key);
    VecT<T> a = free_acceleration_in(key, x, v, t);
    if (friction_.slip_force.size() > 0) a += mass_inverse(friction_.slip_force);
    const auto h = static_cast<Eigen::Index>(R.size()), s = friction_.stuck.cols();
    MatT<T> B(n_, h + s);
    B.leftCols(h) = normals(R);
    B.rightCols(s) = friction_.stuck;
    const MatT<T> G = B.transpose() * mass_inverse(B);
    VecT<T> q = B.transpose() * a;
    for (Eigen::Index k = 0; k < h; ++k) q(k) -= stop_position(R[static_cast<std::size_t>(k)], t, 2);
    for (Eigen::Index k = 0; k < s; ++k) {
      const auto K = static_cast<std::size_t>(k);
      q(h + k) += friction_.amplitude[K] * omega_ * omega_ * cos(omega_ * t + friction_.phase[K]);  // − s_k''
    }
    return VecT<T>(G.partialPivLu().solve(q)).head(h);
  }

  VecT<T> held_forces(const ContactSet& S, const VecT<T>& a_free, const T& t) const {
    if (S.empty()) return VecT<T>(0);
    const MatT<T> W = normals(S);
    const MatT<T> G = W.transpose() * mass_inverse(W);
    VecT<T> q = W.transpose() * a_free;
    for (std::size_t a = 0; a < S.size(); ++a) q(static_cast<Eigen::Index>(a)) -= stop_position(S[a], t, 2);
    return G.partialPivLu().solve(q);
  }

  void require_dense(const char* what) const {
    if (banded_) throw std::logic_error(std::string("Mechanics::") + what + " needs the dense form");
  }

  void add_stops(const std::vector<Stop>& stops, const SystemDerivative& d) {
    for (const FrictionDerivative& f : d.friction)
      if (!f.is_zero())
        throw InvalidInput("parameter derivative: it moves a frictional contact, and this system has none "
                           "(friction runs on the friction engine, friction_tangent.hpp)");
    for (std::size_t j = 0; j < m_; ++j) {
      const Stop& s = stops[j];
      const StopDerivative ds = d.stops.empty() ? StopDerivative{} : d.stops[j];
      SparseNormal w;
      w.i = s.mass;
      if (s.kind == Stop::Kind::normal) {  // (on the banded form too: O(N) per product with it)
        w.dense = s.direction;
        w.i = 0;
      } else if (s.kind == Stop::Kind::between) {
        w.k = s.other;
        w.b = -1.0;
      } else if (s.kind == Stop::Kind::lower) {
        w.a = -1.0;
      }
      normals_.push_back(w);
      s0_.push_back(make(s.s0(), ds.offset));
      sc_.push_back(make(s.s_cos(), ds.cosine));
      ss_.push_back(make(s.s_sin(), ds.sine));
      r_.push_back(make(s.restitution, ds.restitution));
      if (ds.moves_law() && !s.is_compliant())
        throw InvalidInput("parameter derivative: stop " + std::to_string(j) +
                           " is rigid; only a compliant stop's stiffness, damping and preload have derivatives");
      ks_.push_back(make(s.stiffness, ds.stiffness));
      cs_.push_back(make(s.damping, ds.damping));
      fp_.push_back(make(s.preload, ds.preload));
    }
    bool higher = false;
    for (const Stop& s : stops) higher = higher || s.has_higher_harmonics();
    if (higher) {  // each harmonic on the forcing's slot of its order (ImpactSystem adds it)
      stop_slots_.resize(m_);
      hc_.resize(m_);
      hs_.resize(m_);
      for (std::size_t j = 0; j < m_; ++j)
        for (std::size_t i = 0; i < stops[j].harmonics.size(); ++i) {
          const int order = stops[j].harmonics[i].order;
          std::size_t h = 0;
          while (h < orders_.size() && orders_[h] != order) ++h;
          if (h == orders_.size())
            throw std::logic_error("Mechanics: the forcing has no harmonic of order " + std::to_string(order) +
                                   " that a stop moves at");
          stop_slots_[j].push_back(h);
          auto derivative = [&](const std::vector<std::vector<double>>& list) {
            return j < list.size() && i < list[j].size() ? list[j][i] : 0.0;
          };
          hc_[j].push_back(make(stops[j].h_cos(i), derivative(d.stop_harmonic_cosine)));
          hs_[j].push_back(make(stops[j].h_sin(i), derivative(d.stop_harmonic_sine)));
        }
    }
    if (has_compliant(stops))  // on the banded form too: a_free,E needs only M⁻¹ and the normals
      for (const Stop& s : stops) compliant_.push_back(s.is_compliant());
  }

  Eigen::Index n_;
  std::size_t m_;
  bool banded_ = false;
  MatT<T> M_, C_, K_;          // dense form
  VecT<T> mass_, k_diagonal_, k_off_;  // banded form
  T alpha_ = T(0.0), beta_ = T(0.0);
  VecT<T> F0_, Fc_, Fs_;
  T omega_;
  std::vector<int> orders_;           // extra harmonics (both forms)
  std::vector<VecT<T>> Hc_, Hs_;
  Eigen::LLT<MatT<T>> llt_;
  std::vector<SparseNormal> normals_;
  std::vector<T> s0_, sc_, ss_, r_;
  // Higher harmonics of the stops (empty when no stop has any): stop j's harmonic i sits on the
  // forcing's slot stop_slots_[j][i] with canonical coefficients hc_[j][i], hs_[j][i].
  std::vector<std::vector<std::size_t>> stop_slots_;
  std::vector<std::vector<T>> hc_, hs_;
  std::vector<T> ks_, cs_, fp_;  // k_s, c_s, F_p of compliant stops (k_s, c_s, F_p: stops.hpp)
  std::vector<char> compliant_;  // per stop; empty when every stop is rigid
  FrictionPart friction_;        // friction with stops (set_friction); empty otherwise
  ChatterForces chatter_forces_;  // nonlinear forces (set_chatter_forces); empty otherwise
};

inline ContactSet set_union(const ContactSet& a, const ContactSet& b) {
  ContactSet out;
  std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
  return out;
}

/// w_j and −(1 + r_j) M⁻¹w_j / (w_jᵀM⁻¹w_j) from the engine's own mechanics; for a compliant
/// stop (no impulse) w_j and an empty jump.
inline std::pair<Eigen::VectorXd, Eigen::VectorXd> lone_impact(const detail::Mechanics<double>& mech, int j) {
  const Eigen::VectorXd w = mech.normals(ContactSet{j}).col(0);
  if (mech.compliant(j)) return {w, Eigen::VectorXd()};
  const Eigen::VectorXd q = mech.mass_inverse(w);
  return {w, -(1.0 + mech.restitution(j)) / w.dot(q) * q};
}

/// The impulse LCP's active set A ⊂ S ∪ I at (v, t), as the engine solves it (the ResetRule's
/// `impulse`): restitution 0 for held and caught stops.
inline ContactSet impulse_set(const Mechanics<double>& mech, const ContactSet& held, const ContactSet& impacting,
                              const ContactSet& caught, const Eigen::VectorXd& v, double t) {
  const ContactSet all = set_union(mech.held_part(held), impacting);
  if (impacting.empty() || all.empty()) return {};
  const Eigen::MatrixXd W = mech.normals(all);
  const Eigen::MatrixXd G = W.transpose() * mech.mass_inverse(W);
  Eigen::VectorXd q(static_cast<Eigen::Index>(all.size()));
  for (std::size_t a = 0; a < all.size(); ++a) {
    const int j = all[a];
    const bool rests = Mechanics<double>::contains(held, j) || Mechanics<double>::contains(caught, j);
    q(static_cast<Eigen::Index>(a)) = (1.0 + (rests ? 0.0 : mech.restitution(j))) * mech.gap_rate(j, v, t);
  }
  const Eigen::VectorXd impulse = solve_lcp(G, q);
  ContactSet A;
  for (std::size_t a = 0; a < all.size(); ++a)
    if (impulse(static_cast<Eigen::Index>(a)) > 0.0) A.push_back(all[a]);
  return A;
}

}  // namespace vibro::detail
