#include "vibro/modal_tangent.hpp"

#include "mechanics.hpp"
#include "transition.hpp"

#include "vibro/bounded_wait.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>

namespace vibro {
namespace {

using detail::Dual;
using detail::Mechanics;
using detail::ResetRule;
using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using VecD = detail::VecT<Dual>;
using MatD = detail::MatT<Dual>;


VecD seeded(const Eigen::Ref<const VectorXd>& value, const Eigen::Ref<const VectorXd>& direction) {
  VecD out(value.size());
  for (Index i = 0; i < value.size(); ++i) out(i) = Dual(value(i), direction(i));
  return out;
}
VectorXd derivative(const VecD& a) {
  VectorXd out(a.size());
  for (Index i = 0; i < a.size(); ++i) out(i) = a(i).d;
  return out;
}
VecD constant(const VectorXd& value) { return value.cast<Dual>(); }

/// Throws InvalidInput for a parameter derivative of the wrong size or one that moves M, C or K,
/// or a compliant stop's spring or dashpot: those move the chain's modes (or an engaged set's),
/// i.e. the homogeneous flow itself, which the modal map keeps fixed. A preload is a force only.
void check_derivative(const SystemDerivative& d, Index n, const std::vector<Stop>& stops) {
  d.validate(n, stops.size());
  if (Mechanics<double>::moves_matrices(d))
    throw InvalidInput("linearisation: derivatives of the mass, damping or stiffness matrices are not available on "
                       "the modal engine (they move its modes): use the dense engine");
  for (std::size_t j = 0; j < d.stops.size(); ++j)
    if (d.stops[j].stiffness != 0.0 || d.stops[j].damping != 0.0)
      throw InvalidInput("linearisation: derivatives of stops[" + std::to_string(j) +
                         "]'s stiffness or damping are not available on the modal engine (they move the modes of "
                         "the sets where it is engaged): use the dense engine");
}

/// A segment: the homogeneous flow of one contact set over τ = t_end − t_begin.
struct Flight {
  const ModalContactMode* mode = nullptr;
  double tau = 0.0, t_begin = 0.0, t_end = 0.0;
};

/// One guard's saltation at (x, v⁻, t), applied to vectors (see the header):
///     δx⁺ = δx + jump_x s,   δv⁺ = R_z(δx, δv) + jump_v s,   s = (h_z·δz) / ḣ⁻.
struct Salt {
  ResetRule rule;
  int guard = -1;        // -1: no guard (a reset without a crossing)
  bool impact = false;   // the guard is a gap (else −λ of a held stop)
  double t = 0.0, rate = 0.0;
  VectorXd x, vm;
  VectorXd jump;         // f⁺ − R_z f⁻ − R_t (2n)
};

/// The event at one instant: its guards in sequence.
struct Jump {
  std::vector<Salt> salts;
};

/// An impact in free flight after which the stop leaves (no stop held before or after, no
/// chatter): applied in the free chain's modal coordinates (u, u'), O(N) per column, as the
/// engine applies the impact itself. With φ = Φᵀw_j (Φ⁻¹M⁻¹w_j = Φᵀw_j, G = wᵀM⁻¹w = |φ|²), the
/// impulse Λ = (1 + r) g'⁻/G, g'⁻ = ḣ⁻ the approach speed and g''⁻ the gap's acceleration
/// before, the saltation of the header becomes
///     δu'  ← δu' − φ (1 + r)/G · φᵀδu'                     (R_z: the Newton law)
///     s = φᵀδu / g'⁻,   δu ← δu − φ Λ s,   δu' ← δu' + (2σ∘φ Λ + φ (1 + r) g''⁻/G) s,
/// since v⁺ − v⁻ = −M⁻¹wΛ, a⁺ − a⁻ = M⁻¹CM⁻¹wΛ (Φ⁻¹M⁻¹CM⁻¹w = (α + βω²)∘φ = 2σ∘φ for
/// C = αM + βK) and R_z a⁻ + R_t = a⁻ − M⁻¹w (1 + r) g''⁻/G. (Without an impulse, Λ = 0 and the
/// map is the identity.) The general path gives the same to rounding (test_modal_tangent.cpp).
struct FreeImpact {
  VectorXd phi;            // Φᵀw_j
  double newton = 0.0;     // (1 + r)/G, 0 without an impulse
  double rate = 0.0;       // g'⁻
  double impulse = 0.0;    // Λ
  double curvature = 0.0;  // (1 + r) g''⁻ / G (0 without an impulse)
  double acceleration = 0.0;  // g''⁻
  int stop = -1;           // j
  double t = 0.0, delassus = 0.0;  // the impact's time, G = w_jᵀM⁻¹w_j
};

using Op = std::variant<Flight, Jump, FreeImpact>;

/// The periodic particular solution of one contact set's motion (the held stops' motion plus the
/// reduced chain's periodic response, modal.hpp) as harmonic amplitudes, p(t) = a0 + ac cos Ωt +
/// as sin Ωt + Σ_h (hc_h cos r_h t + hs_h sin r_h t) (the drive's extra harmonics, r_h = k_h Ω),
/// in dual numbers (value, derivative along dD): in the free chain's modal coordinates for the
/// free set (where the record's columns are modal), in physical ones otherwise.
struct Particular {
  VecD a0, ac, as;
  std::vector<VecD> hc, hs;
  std::vector<Dual> rates;
};

}  // namespace

/// A parameter column carried through the record (ModalTangent::parameter): the system's data
/// seeded along dD, the column of D that holds ζ = ∂z/∂p, each contact set's particular solution.
struct ModalTangent::Sensitivity {
  Sensitivity(const BandedChain& chain, const std::vector<Stop>& stops, const SystemDerivative& d, Index col)
      : data(chain, stops, &d), column(col) {}
  Mechanics<Dual> data;
  Index column;
  std::map<const ModalContactMode*, Particular> particular;
};

struct ModalTangent::Record {
  Record(const BandedChain& chain, const std::vector<Stop>& stops) : mech(chain, stops), dual(chain, stops) {}
  Mechanics<double> mech;
  Mechanics<Dual> dual;
  std::vector<Op> ops;
  const ChainModes* free = nullptr;      // the free chain's modes (the modal coordinates of FreeImpact)
  bool modal_events = true;              // free-flight impacts as FreeImpact (else the general path)
  /// Whether the columns of `md`'s flights stay in the free chain's modal coordinates: the free
  /// set (no stop held or engaged), whose modes are the free chain's.
  bool free_set(const ModalContactMode& md) const { return md.modes == free && md.stuck.empty(); }
  std::size_t split = 0;                 // ops [0, split) and [split, end): J = J₂ J₁ (see fill_jacobian)
  const ModalContactMode* split_mode = nullptr;
  mutable ChainModes::Workspace work;

  /// The contact force of held stop `guard` along (δx, δv, δt) at (x, v, t): −h_z·δz (release guard).
  double force_derivative(const ContactSet& held, int guard, const VectorXd& x, const VectorXd& v, double t,
                          const Eigen::Ref<const VectorXd>& dx, const Eigen::Ref<const VectorXd>& dv, double dt) const {
    return force_of(dual, held, guard, seeded(x, dx), seeded(v, dv), Dual(t, dt)).d;
  }
  static Dual force_of(const Mechanics<Dual>& m, const ContactSet& held, int guard, const VecD& x, const VecD& v,
                       const Dual& t) {
    const ContactSet R = m.held_part(held);  // the forces are the held rigid stops' (not the engaged ones')
    const auto a = static_cast<Index>(std::lower_bound(R.begin(), R.end(), guard) - R.begin());
    return m.forces(held, x, v, t)(a);
  }

  /// h_z·δz of a salt.
  double guard_derivative(const Salt& s, const Eigen::Ref<const VectorXd>& dx, const Eigen::Ref<const VectorXd>& dv) const {
    if (s.guard < 0) return 0.0;
    if (s.impact) {
      const detail::SparseNormal& w = mech.normal(s.guard);
      if (w.dense.size() > 0) return w.dense.dot(dx);  // a general normal
      return w.a * dx(w.i) + (w.k >= 0 ? w.b * dx(w.k) : 0.0);
    }
    return -force_derivative(s.rule.held_before, s.guard, s.x, s.vm, s.t, dx, dv, 0.0);
  }

  /// The saltation on the columns of D; with `p`, its column ζ also gets the parameter term
  /// s_p = R_p + jump h_p / ḣ⁻ (linearisation.hpp), h_p and R_p the guard's and the reset's
  /// derivatives along dD at the event's (x, v⁻, t).
  void apply(const Salt& s, Eigen::Ref<MatrixXd> D, const Sensitivity* p) const {
    const Index n = mech.dof();
    for (Index c = 0; c < D.cols(); ++c) {
      const VectorXd dx = D.col(c).head(n), dv = D.col(c).tail(n);
      const double sc = s.guard >= 0 && s.rate != 0.0 ? guard_derivative(s, dx, dv) / s.rate : 0.0;
      D.col(c) = derivative(dual.reset(s.rule, seeded(s.x, dx), seeded(s.vm, dv), Dual(s.t))) + s.jump * sc;
    }
    if (!p) return;
    auto zeta = D.col(p->column);
    const VecD x = constant(s.x), vm = constant(s.vm);
    if (s.guard >= 0 && s.rate != 0.0) {
      // A gap g = wᵀx − s_j(t) moves by −∂s_j/∂p at fixed x; a release guard −λ_j by −∂λ_j/∂p.
      const double hp = s.impact ? -p->data.stop_position(s.guard, Dual(s.t)).d
                                 : -force_of(p->data, s.rule.held_before, s.guard, x, vm, Dual(s.t)).d;
      zeta += s.jump * (hp / s.rate);
    }
    zeta += derivative(p->data.reset(s.rule, x, vm, Dual(s.t)));
  }

  void apply(const Jump& j, Eigen::Ref<MatrixXd> D, const Sensitivity* p) const {
    for (const Salt& s : j.salts) apply(s, D, p);
  }

  /// A free-flight impact on modal columns [δu; δu'] (see FreeImpact). With `p`, ζ also gets
  /// s_p: with h_p = −∂s_j(t)/∂p and κ = ∂Λ/∂p = ∂((1 + r) g'⁻)/∂p / G at fixed (x, v⁻),
  ///     δu ← δu − φ Λ h_p/g'⁻,   δu' ← δu' + (2σ∘φ Λ + φ (1 + r) g''⁻/G) h_p/g'⁻ − φ κ
  /// (v⁺ = v⁻ − M⁻¹wΛ, so R_p = −M⁻¹w κ, whose modal coordinates are −φ κ).
  void apply_modal(const FreeImpact& f, Eigen::Ref<MatrixXd> U, const Sensitivity* p) const {
    const Index n = f.phi.size();
    const VectorXd two_sigma_phi = 2.0 * free->decay().cwiseProduct(f.phi);
    const VectorXd moved = two_sigma_phi * f.impulse + f.phi * f.curvature;  // a⁺ − R_z a⁻ − R_t
    for (Index c = 0; c < U.cols(); ++c) {
      auto u = U.col(c).head(n);
      auto ud = U.col(c).tail(n);
      const double s = f.phi.dot(u) / f.rate;
      if (f.newton != 0.0) ud -= f.phi * (f.newton * f.phi.dot(ud));
      u -= f.phi * (f.impulse * s);
      ud += moved * s;
    }
    if (!p || f.newton == 0.0) return;  // without an impulse the map is the identity
    const double hp = -p->data.stop_position(f.stop, Dual(f.t)).d;
    const Dual rate(f.rate, -p->data.stop_position(f.stop, Dual(f.t), 1).d);  // g'⁻ = wᵀv⁻ − s_j'(t)
    const double kappa = ((1.0 + p->data.restitution(f.stop)) * rate).d / f.delassus;
    auto zeta = U.col(p->column);
    zeta.head(n) -= f.phi * (f.impulse * hp / f.rate);
    zeta.tail(n) += moved * (hp / f.rate) - f.phi * kappa;
  }

  /// Mass-weighted means of the masses of each reduced coordinate of `md` (rows of `physical`,
  /// n × p → n_r × p): the M-orthogonal projection onto the set's constraint manifold, as the
  /// engine projects states. `lift` is its right inverse x = T y (prescribed masses 0).
  MatrixXd project(const ModalContactMode& md, const Eigen::Ref<const MatrixXd>& physical) const {
    const Index nr = md.size();
    MatrixXd Y = MatrixXd::Zero(nr, physical.cols());
    for (Index r = 0; r < nr; ++r) {
      double sm = 0.0;
      for (Index l = md.first[static_cast<std::size_t>(r)]; l <= md.last[static_cast<std::size_t>(r)]; ++l) {
        Y.row(r) += mass_of_chain(l) * physical.row(l);
        sm += mass_of_chain(l);
      }
      Y.row(r) /= sm;
    }
    return Y;
  }
  static void lift(const ModalContactMode& md, const Eigen::Ref<const MatrixXd>& Y, Eigen::Ref<MatrixXd> physical) {
    for (Index l = 0; l < physical.rows(); ++l) {
      const Index r = md.coordinate[static_cast<std::size_t>(l)];
      if (r >= 0) physical.row(l) = Y.row(r);
      else physical.row(l).setZero();
    }
  }

  /// The particular solution of `md` (see Particular), built on first use: O(N n_r) for a set.
  /// The held stops' motion is taken as o = M⁻¹W G⁻¹ s_S(t), one solution of W_Sᵀ o = s_S(t):
  /// x = T y + o covers the same constraint manifold as the engine's o (any such o does, since
  /// range T = null W_Sᵀ), and the periodic solution x_p it gives is the same motion. With
  /// o' = Ω(o_s cos − o_c sin), o'' = −Ω²(o_c cos + o_s sin), the reduced chain is forced by
  /// Tᵀ(f − M o'' − C o' − K o); its modal amplitudes are Φ_Sᵀ Tᵀ M a = Φ_S⁻¹ (projected a) for
  /// the harmonic amplitudes a of M⁻¹(f − M o'' − C o' − K o), and each mode answers by
  /// harmonic_response (modal.hpp) in dual numbers: Ω's derivative enters there and in cos Ωt.
  const Particular& particular(Sensitivity& p, const ModalContactMode& md) const {
    const auto found = p.particular.find(&md);
    if (found != p.particular.end()) return found->second;
    const Mechanics<Dual>& m = p.data;
    const Index n = mech.dof(), nr = md.size(), k = static_cast<Index>(md.stuck.size());
    const Dual W = m.frequency();
    std::array<VecD, 3> o{VecD::Zero(n), VecD::Zero(n), VecD::Zero(n)};
    if (k > 0) {
      const MatD normals = m.normals(md.stuck);
      const MatD Q = m.mass_inverse(normals);
      const Eigen::PartialPivLU<MatD> G(MatD(normals.transpose() * Q));
      for (int h = 0; h < 3; ++h) {
        VecD s(k);
        for (Index a = 0; a < k; ++a) s(a) = m.stop_amplitude(md.stuck[static_cast<std::size_t>(a)], h);
        o[h] = Q * G.solve(s);
      }
    }
    const VecD zero = VecD::Zero(n);
    // Amplitudes: constant, cosine, sine, then each extra harmonic's cosine and sine: M⁻¹ F_h, and
    // for held stops moving at that harmonic's rate r the first harmonic's terms with Ω → r.
    const auto H = static_cast<Index>(m.harmonics());
    const Index K = 3 + 2 * H;
    std::vector<VecD> a{m.acceleration_under(m.forcing_amplitude(0), o[0], zero),
                        VecD(m.acceleration_under(m.forcing_amplitude(1), o[1], VecD(W * o[2])) + W * W * o[1]),
                        VecD(m.acceleration_under(m.forcing_amplitude(2), o[2], VecD(-W * o[1])) + W * W * o[2])};
    std::vector<VecD> oh(static_cast<std::size_t>(2 * H), zero);  // o_h's cosine (h), sine (H + h)
    if (k > 0) {
      const MatD normals = m.normals(md.stuck);
      const MatD Q = m.mass_inverse(normals);
      const Eigen::PartialPivLU<MatD> G(MatD(normals.transpose() * Q));
      for (Index h = 0; h < H; ++h)
        for (int part = 0; part < 2; ++part) {
          VecD s(k);
          bool moving = false;
          for (Index b = 0; b < k; ++b) {
            s(b) = m.stop_harmonic_amplitude(md.stuck[static_cast<std::size_t>(b)], static_cast<std::size_t>(h), part);
            moving = moving || s(b).v != 0.0 || s(b).d != 0.0;
          }
          if (moving) oh[static_cast<std::size_t>(part * H + h)] = Q * G.solve(s);
        }
    }
    for (int part = 0; part < 2; ++part)
      for (Index h = 0; h < H; ++h) {
        const Dual r = m.harmonic_rate(static_cast<std::size_t>(h));
        const VecD& mine = oh[static_cast<std::size_t>(part * H + h)];
        const VecD& other = oh[static_cast<std::size_t>((1 - part) * H + h)];
        // cosine: M⁻¹(F_hc − C r o_hs − K o_hc) + r² o_hc; sine: M⁻¹(F_hs + C r o_hc − K o_hs) + r² o_hs.
        a.push_back(VecD(m.acceleration_under(m.harmonic_amplitude(static_cast<std::size_t>(h), part), mine,
                                              VecD((part == 0 ? r : -r) * other)) +
                         r * r * mine));
      }
    // The engaged compliant stops' forces −M⁻¹w_j N_j along x = o(t), N_j = k_j g_j + c_j g_j' + F_p,j
    // with g_j = w_jᵀo − s_j(t) (mechanics.hpp): on harmonic (cos, sin) amplitudes (g_c, g_s) at
    // rate r, N's are (k g_c + c r g_s, k g_s − c r g_c); the constant one is k g_0 + F_p.
    for (int j : md.engaged) {
      VecD w = VecD::Zero(n);
      m.normal(j).scatter(w);
      const VecD Mw = m.mass_inverse(w);
      const Dual k = m.compliant_stiffness(j), c = m.compliant_damping(j);
      auto gap = [&](const VecD& offset, const Dual& s) { return Dual(m.normal_dot(j, offset) - s); };
      auto push = [&](std::size_t cos_slot, std::size_t sin_slot, const Dual& rate, const Dual& gc, const Dual& gs) {
        a[cos_slot] -= Mw * Dual(k * gc + c * rate * gs);
        a[sin_slot] -= Mw * Dual(k * gs - c * rate * gc);
      };
      a[0] -= Mw * Dual(k * gap(o[0], m.stop_amplitude(j, 0)) + m.preload(j));
      push(1, 2, W, gap(o[1], m.stop_amplitude(j, 1)), gap(o[2], m.stop_amplitude(j, 2)));
      for (Index h = 0; h < H; ++h) {
        const auto hs = static_cast<std::size_t>(h);
        push(static_cast<std::size_t>(3 + h), static_cast<std::size_t>(3 + H + h), m.harmonic_rate(hs),
             gap(oh[hs], m.stop_harmonic_amplitude(j, hs, 0)),
             gap(oh[static_cast<std::size_t>(H + h)], m.stop_harmonic_amplitude(j, hs, 1)));
      }
    }
    Particular out;
    out.hc.assign(oh.begin(), oh.begin() + H);
    out.hs.assign(oh.begin() + H, oh.end());
    for (Index h = 0; h < H; ++h) out.rates.push_back(m.harmonic_rate(static_cast<std::size_t>(h)));
    std::vector<VecD*> amplitude{&out.a0, &out.ac, &out.as};
    for (auto* list : {&out.hc, &out.hs})
      for (VecD& v : *list) amplitude.push_back(&v);
    MatrixXd A(n, 2 * K);  // values, then derivatives
    for (Index h = 0; h < K; ++h) {
      for (Index i = 0; i < n; ++i) {
        A(i, h) = a[static_cast<std::size_t>(h)](i).v;
        A(i, K + h) = a[static_cast<std::size_t>(h)](i).d;
      }
      if (h < 3) *amplitude[static_cast<std::size_t>(h)] = o[static_cast<std::size_t>(h)];
    }
    if (nr > 0) {
      const ChainModes& modes = *md.modes;
      MatrixXd U(nr, 2 * K), C(nr, 2 * K);
      const MatrixXd Y = md.stuck.empty() ? A : project(md, A);
      modes.tangent_to_modal(Y, U, work);
      auto put = [&](Index i, Index col, const Dual& c) {
        C(i, col) = c.v;
        C(i, K + col) = c.d;
      };
      for (Index i = 0; i < nr; ++i) {
        const HarmonicResponse<Dual> r =
            harmonic_response(modes.omega_squared()(i), modes.decay()(i), W, Dual(U(i, 0), U(i, K)),
                              Dual(U(i, 1), U(i, K + 1)), Dual(U(i, 2), U(i, K + 2)));
        put(i, 0, r.c0);
        put(i, 1, r.cc);
        put(i, 2, r.cs);
        for (Index h = 0; h < H; ++h) {
          const Index cc = 3 + h, cs = 3 + H + h;
          const HarmonicResponse<Dual> rh =
              harmonic_response(modes.omega_squared()(i), modes.decay()(i), out.rates[static_cast<std::size_t>(h)],
                                Dual(0.0), Dual(U(i, cc), U(i, K + cc)), Dual(U(i, cs), U(i, K + cs)));
          put(i, cc, rh.cc);
          put(i, cs, rh.cs);
        }
      }
      MatrixXd X = C;  // the free set stays in modal coordinates (o = 0 there)
      if (!free_set(md)) {
        MatrixXd Yp(nr, 2 * K);
        modes.tangent_to_physical(C, Yp, work);
        X.resize(n, 2 * K);
        lift(md, Yp, X);
      }
      for (Index h = 0; h < K; ++h)
        for (Index i = 0; i < X.rows(); ++i) (*amplitude[static_cast<std::size_t>(h)])(i) += Dual(X(i, h), X(i, K + h));
    }
    return p.particular.emplace(&md, std::move(out)).first->second;
  }

  /// ∂(p, p')/∂p of a particular solution at t, times `sign`, added to the column ζ.
  static void add_particular(const Particular& pt, const Dual& W, double t, double sign, Eigen::Ref<VectorXd> zeta) {
    const Index n = pt.a0.size();
    const Dual c = cos(W * Dual(t)), s = sin(W * Dual(t));
    zeta.head(n) += sign * derivative(VecD(pt.a0 + pt.ac * c + pt.as * s));
    zeta.tail(n) += sign * derivative(VecD(W * (pt.as * c - pt.ac * s)));
    for (std::size_t h = 0; h < pt.rates.size(); ++h) {
      const Dual& r = pt.rates[h];
      const Dual ch = cos(r * Dual(t)), sh = sin(r * Dual(t));
      zeta.head(n) += sign * derivative(VecD(pt.hc[h] * ch + pt.hs[h] * sh));
      zeta.tail(n) += sign * derivative(VecD(r * (pt.hs[h] * ch - pt.hc[h] * sh)));
    }
  }

  /// Columns between physical (δx; δv) and the free chain's modal coordinates (δu; δu').
  void to_modal(Eigen::Ref<MatrixXd> D) const {
    const Index n = mech.dof(), p = D.cols();
    MatrixXd Y(n, 2 * p), U(n, 2 * p);
    Y << D.topRows(n), D.bottomRows(n);
    free->tangent_to_modal(Y, U, work);
    D.topRows(n) = U.leftCols(p);
    D.bottomRows(n) = U.rightCols(p);
  }
  void to_physical(Eigen::Ref<MatrixXd> D) const {
    const Index n = mech.dof(), p = D.cols();
    MatrixXd U(n, 2 * p), Y(n, 2 * p);
    U << D.topRows(n), D.bottomRows(n);
    free->tangent_to_physical(U, Y, work);
    D.topRows(n) = Y.leftCols(p);
    D.bottomRows(n) = Y.rightCols(p);
  }

  /// The homogeneous flow of a segment on the columns of D (see the header).
  void apply(const Flight& f, Eigen::Ref<MatrixXd> D) const {
    const ModalContactMode& md = *f.mode;
    const Index n = mech.dof(), nr = md.size(), p = D.cols();
    if (nr == 0) {  // every mass prescribed
      D.setZero();
      return;
    }
    MatrixXd Y(nr, 2 * p);  // [δy | δy']
    Y << project(md, D.topRows(n)), project(md, D.bottomRows(n));
    MatrixXd U(nr, 2 * p);
    md.modes->tangent_to_modal(Y, U, work);
    md.modes->advance_columns(f.tau, U.leftCols(p), U.rightCols(p));
    md.modes->tangent_to_physical(U, Y, work);
    lift(md, Y.leftCols(p), D.topRows(n));
    lift(md, Y.rightCols(p), D.bottomRows(n));
  }

  VectorXd mass_of_chain;
};

namespace {

/// Records the run: segments and events as ops of ModalTangent::Record, and the TangentMap's
/// descriptive parts (as linearisation.cpp's TangentRecorder does for the dense engine).
class Recorder final : public Observer {
 public:
  Recorder(ModalTangent::Record& record, const ModalChainSimulator& sim, TangentMap& out,
           const LinearisationOptions& options)
      : rec_(record), sim_(sim), out_(out), n_(sim.modes().dof()), phases_(out.phases, sim.stops().size()),
        features_(options.features), window_(options.past_release_window) {}

  void begin(const RunContext& /*run*/, double /*t0*/) override {
    dropped_ = sim_.modes_dropped();
    min_dim_ = 2 * n_;
    least_rate_ = std::numeric_limits<double>::infinity();
  }

  // The state at a segment's end is needed only at events, and for a free-flight impact only at
  // the impacting masses and their neighbours: the segment is kept (O(n_r)) and asked later, so a
  // record costs O(N) per free-flight segment rather than a full O(N²) basis change.
  void segment(const SegmentView& view) override {
    const auto* mv = dynamic_cast<const ModalSegmentView*>(&view);
    if (!mv) throw std::logic_error("ModalTangent: a segment not of the modal engine");
    // A contact set dropped from the engine's cache may be the kept segment's: nothing more is
    // recorded (the map is then refused, see the constructor).
    if (sim_.modes_dropped() != dropped_) broken_ = true;
    if (broken_) return;
    const double tb = view.t_begin(), te = view.t_end();
    // The set's key, as the dense map keys it: the held rigid stops and the engaged compliant ones.
    const ContactSet S = mv->mode().engaged.empty() ? mv->mode().stuck
                                                    : detail::set_union(mv->mode().stuck, mv->mode().engaged);
    if (first_) {
      first_ = false;
      VectorXd xb(n_), vb(n_);
      view.state(tb, xb, vb);
      out_.starts_held = !mv->mode().stuck.empty();
      held_ = S;
      for (int j : mv->mode().stuck) phases_.open(j, tb);
      out_.rate_start = rate(S, tb, xb, vb);
    } else if (pending_) {
      finish_transition(view, S);
    }
    rec_.ops.emplace_back(Flight{&mv->mode(), te - tb, tb, te});
    const Index dim = 2 * mv->mode().size();
    if (dim < min_dim_) {
      min_dim_ = dim;
      rec_.split = rec_.ops.size();
      rec_.split_mode = &mv->mode();
    }
    last_ = mv->keep();
    te_ = te;
    pending_ = true;
    events_.clear();
    if (features_ && te > tb) features(tb, te);
  }

  void event(const Event& e) override {
    events_.push_back(e);
    out_.events.push_back(e);
  }

  void end(double t) override {
    if (!events_.empty()) out_.ends_at_event = true;
    out_.t1 = t;
    if (sim_.modes_dropped() != dropped_) broken_ = true;
    if (first_ || broken_) return;  // no segment, or no usable record
    out_.x1.resize(n_);
    out_.v1.resize(n_);
    last_.state(te_, out_.x1, out_.v1);
    out_.rate_end = rate(held_, te_, out_.x1, out_.v1);  // held_: the last segment's set
    phases_.end(t);
    out_.free_dimension = min_dim_;
    out_.least_guard_rate = least_rate_;
  }

 private:
  VectorXd rate(const ContactSet& S, double t, const VectorXd& x, const VectorXd& v) const {
    VectorXd f(2 * n_);
    f << v, rec_.mech.acceleration(S, x, v, t);
    return f;
  }

  /// The features of the kept segment over [tb, te] (linearisation.hpp, as the dense recorder finds
  /// them): the interior maxima of the gaps of the stops not held (for an engaged compliant stop,
  /// of its penetration: minima of its guard −g), the interior minima of the held stops' forces
  /// (maxima of their guards −λ), each by the certified search on the modal guards.
  void features(double tb, double te) {
    const ModalContactMode& md = last_.mode();
    const double tau = te - tb;
    const auto rows = static_cast<Index>(md.watched.size());
    for (Index row = 0; row < rows; ++row) {
      const bool engaged = row >= md.engaged_rows_from;
      if (row >= md.gap_rows && !engaged) continue;  // −λ of a held stop
      const double sign = engaged ? -1.0 : 1.0;      // the gap g from the guard (g, or −g engaged)
      const int j = md.watched[static_cast<std::size_t>(row)];
      const double g_start = sign * last_.guard(row, tb);
      const double size =
          std::max({std::abs(g_start), std::abs(last_.guard(row, tb + 0.5 * tau)), std::abs(last_.guard(row, te))});
      const std::vector<Minimum> peaks = engaged ? last_.guard_local_minima(row, tb, te, sim_.gap_tolerance())
                                                 : last_.guard_local_maxima(row, tb, te, sim_.gap_tolerance());
      for (const Minimum& peak : peaks) {
        const double g = sign * peak.value;
        if (detail::flight_start_artifact(peak.tau - tb, tau, g, g_start, size)) continue;
        out_.gap_peaks.push_back({j, peak.tau, g});
      }
    }
    for (std::size_t a = 0; a < md.stuck.size(); ++a)
      for (const Minimum& dip : last_.guard_local_maxima(md.gap_rows + static_cast<Index>(a), tb, te,
                                                          sim_.force_tolerance()))
        out_.force_dips.push_back({md.stuck[a], dip.tau, -dip.value, false});
  }

  /// After a release, the held flow of the segment before continued past it to its next interior
  /// force minimum, within window_ periods.
  void past_release(const ContactSet& released) {
    if (!features_ || released.empty() || window_ <= 0.0) return;
    const ModalContactMode& md = last_.mode();
    const double omega = sim_.modes().frequency();
    const double to = te_ + window_ * (omega > 0.0 ? 2.0 * std::numbers::pi / omega : 1.0);
    for (int j : released) {
      const auto it = std::lower_bound(md.stuck.begin(), md.stuck.end(), j);
      if (it == md.stuck.end() || *it != j) continue;
      const std::vector<Minimum> found =
          last_.guard_local_maxima(md.gap_rows + (it - md.stuck.begin()), te_, to, sim_.force_tolerance());
      if (!found.empty()) out_.force_dips.push_back({j, found.front().tau, -found.front().value, true});
    }
  }

  /// The saltation of one resolution at (x, v⁻, t) with the guard of stop `guard`, landing in v⁺.
  Salt salt(const ResetRule& rule, int guard, bool impact, const VectorXd& x, const VectorXd& vm,
            const VectorXd& vp, double t) const {
    Salt s;
    s.rule = rule;
    s.guard = guard;
    s.impact = impact;
    s.t = t;
    s.x = x;
    s.vm = vm;
    // x⁺: moved only by the chatter rule (mechanics.hpp, step 2).
    const VectorXd xp = rec_.mech.reset(rule, x, vm, t).head(n_);
    const VectorXd fm = rate(rule.held_before, t, x, vm), fp = rate(rule.held_after, t, xp, vp);
    // c = R_z f⁻ + R_t: the reset along the flow.
    const VectorXd c = derivative(rec_.dual.reset(rule, seeded(x, fm.head(n_)), seeded(vm, fm.tail(n_)), Dual(t, 1.0)));
    s.jump = fp - c;
    if (guard >= 0 && impact) {
      s.rate = rec_.mech.gap_rate(guard, vm, t);
    } else if (guard >= 0) {
      s.rate = -rec_.force_derivative(rule.held_before, guard, x, vm, t, fm.head(n_), fm.tail(n_), 1.0);
    }
    return s;
  }

  void finish_transition(const SegmentView& next, const ContactSet& held_after) {
    pending_ = false;
    const double t = te_;
    const detail::Transition tr = detail::classify(events_);
    const ContactSet& impacting = tr.impacting;
    const ContactSet& caught = tr.caught;
    const ContactSet& released = tr.released;
    SaltationRecord record = detail::record_of(t, held_, tr, held_after);
    phases_.change(t, rec_.mech.held_part(held_), rec_.mech.held_part(held_after));

    const bool free_flight_impact = held_.empty() && held_after.empty() && impacting.size() == 1 && caught.empty() &&
                                    released.empty() && tr.switched.empty() &&
                                    rec_.mech.normal(impacting.front()).dense.size() == 0;  // (general: below)
    if (rec_.modal_events && free_flight_impact) {
      record.guard_stop = impacting.front();
      record.impact = true;
      rec_.ops.emplace_back(free_impact(impacting.front(), t));
      const FreeImpact& f = std::get<FreeImpact>(rec_.ops.back());
      record.guard_rate = f.rate;
      least_rate_ = std::min(least_rate_, record.guard_rate);
      out_.saltations.push_back(record);
      if (features_) out_.impacts.push_back({f.stop, t, f.rate, f.acceleration});
      return;
    }
    xe_.resize(n_);
    ve_.resize(n_);
    last_.state(t, xe_, ve_);
    if (features_) {
      const VectorXd a = rec_.mech.acceleration(held_, xe_, ve_, t);
      for (int j : impacting)
        out_.impacts.push_back({j, t, rec_.mech.gap_rate(j, ve_, t),
                                rec_.mech.normal_dot(j, a) - rec_.mech.stop_position(j, t, 2)});
    }
    past_release(released);
    VectorXd xb(n_), vp(n_);
    next.state(next.t_begin(), xb, vp);
    Jump jump;
    // Compliant stops' engagements and disengagements first (the engine resolves them before the
    // rigid stops' events at one instant), one at a time in index order, as the dense map takes
    // them: each the saltation of linearisation.hpp with the guard g_j and no reset but the held
    // rigid stops' projection (the identity when c_j = 0; with c_j > 0 the acceleration jumps by
    // ∓M⁻¹w_j c_j ġ_j, f⁺ − f⁻ in the salt's jump). held_ moves along to the key the rigid part starts from.
    double least_switch = std::numeric_limits<double>::infinity();
    for (int j : tr.switched) {
      ContactSet after = held_;
      const auto at = std::lower_bound(after.begin(), after.end(), j);
      if (at != after.end() && *at == j) after.erase(at);
      else after.insert(at, j);
      const ResetRule rule{held_, {}, {}, {}, after, rule_};
      jump.salts.push_back(salt(rule, j, true, xe_, ve_, ve_, t));
      least_switch = std::min(least_switch, std::abs(jump.salts.back().rate));
      held_ = std::move(after);
    }
    if (!tr.switched.empty()) {
      record.guard_stop = tr.switched.front();
      record.guard_rate = least_switch;
      if (impacting.empty() && released.empty() && rec_.mech.held_part(held_) == rec_.mech.held_part(held_after)) {
        out_.saltations.push_back(record);
        rec_.ops.emplace_back(std::move(jump));
        held_ = held_after;
        return;
      }
    }
    if (impacting.size() <= 1) {
      const ResetRule rule{held_, impacting, caught,
                           detail::impulse_set(rec_.mech, held_, impacting, caught, ve_, t), held_after,
                           rule_};
      const bool impact = !impacting.empty();
      const int guard = impact ? impacting.front() : (released.empty() ? -1 : released.front());
      record.impact = impact;
      jump.salts.push_back(salt(rule, guard, impact, xe_, ve_, vp, t));
      if (guard >= 0 || tr.switched.empty()) {  // else the switches' guard and rate stand
        record.guard_stop = guard;
        record.guard_rate = jump.salts.back().rate;
      }
    } else {
      record.simultaneous = true;
      record.guard_stop = impacting.front();
      record.impact = true;
      const Jump forward = in_sequence(tr, held_after, vp, t, false);
      const Jump backward = in_sequence(tr, held_after, vp, t, true);
      record.order_spread = spread(forward, backward);
      if (record.order_spread > 1e-8 && !out_.non_smooth) {
        out_.non_smooth = true;
        out_.non_smooth_reason = "simultaneous impacts at t = " + number_text(t) +
                                 " whose order changes the tangent map (relative difference " +
                                 number_text(record.order_spread) + ")";
      }
      record.guard_rate = std::numeric_limits<double>::infinity();
      for (const Salt& s : forward.salts) record.guard_rate = std::min(record.guard_rate, s.rate);
      jump.salts.insert(jump.salts.end(), forward.salts.begin(), forward.salts.end());
    }
    if (record.impact) least_rate_ = std::min(least_rate_, record.guard_rate);
    out_.saltations.push_back(record);
    rec_.ops.emplace_back(std::move(jump));
    held_ = held_after;
  }

  /// A free-flight impact of stop j at the pending event (see FreeImpact), from the kept segment's
  /// state at the impacting masses and their neighbours (K is tridiagonal): O(N).
  FreeImpact free_impact(int j, double t) const {
    const detail::SparseNormal& w = rec_.mech.normal(j);
    const BandedChain& ch = sim_.modes().chain();
    std::vector<Index> masses;
    for (Index l : {w.i, w.k})
      if (l >= 0)
        for (Index m = std::max<Index>(l - 1, 0); m <= std::min<Index>(l + 1, n_ - 1); ++m) masses.push_back(m);
    VectorXd x, v;
    last_.rows(t, masses, x, v);
    auto at = [&](const VectorXd& y, Index l) {
      return y(std::find(masses.begin(), masses.end(), l) - masses.begin());
    };
    const double W = sim_.modes().frequency(), c = std::cos(W * t), s = std::sin(W * t);
    auto stiffness = [&](const VectorXd& y, Index l) {  // (K y)_l
      double out = ch.stiffness_diagonal(l) * at(y, l);
      if (l > 0) out += ch.stiffness_off(l - 1) * at(y, l - 1);
      if (l + 1 < n_) out += ch.stiffness_off(l) * at(y, l + 1);
      return out;
    };
    auto acceleration = [&](Index l) {  // M⁻¹ (f − C v − K x), C = αM + βK
      double f = ch.forcing.constant(l) + ch.forcing.cosine(l) * c + ch.forcing.sine(l) * s;
      for (const ForcingHarmonic& h : ch.forcing.harmonics) {
        const double r = h.rate(W);
        f += h.cosine(l) * std::cos(r * t) + h.sine(l) * std::sin(r * t);
      }
      return (f - ch.rayleigh_mass * ch.mass(l) * at(v, l) - ch.rayleigh_stiffness * stiffness(v, l) - stiffness(x, l)) /
             ch.mass(l);
    };
    auto along = [&](auto&& value) { return w.a * value(w.i) + (w.k >= 0 ? w.b * value(w.k) : 0.0); };
    FreeImpact f;
    f.stop = j;
    f.t = t;
    f.phi = w.a * rec_.free->phi_row(w.i);
    if (w.k >= 0) f.phi += w.b * rec_.free->phi_row(w.k);
    const double G = w.a * w.a / ch.mass(w.i) + (w.k >= 0 ? w.b * w.b / ch.mass(w.k) : 0.0);
    f.delassus = G;
    f.rate = along([&](Index l) { return at(v, l); }) - rec_.mech.stop_position(j, t, 1);
    const double r = rec_.mech.restitution(j);
    // The impulse LCP of one stop (as detail::impulse_set solves it): active iff its impulse > 0.
    const bool impulse = solve_lcp(Eigen::MatrixXd::Constant(1, 1, G), VectorXd::Constant(1, (1.0 + r) * f.rate))(0) > 0.0;
    f.acceleration = along(acceleration) - rec_.mech.stop_position(j, t, 2);
    if (impulse) {
      f.newton = (1.0 + r) / G;
      f.impulse = (1.0 + r) * f.rate / G;
      f.curvature = (1.0 + r) * f.acceleration / G;
    }
    return f;
  }

  /// Simultaneous impacts one at a time (index order or reversed), as linearisation.cpp.
  Jump in_sequence(const detail::Transition& tr, const ContactSet& held_after, const VectorXd& vp, double t,
                   bool reverse) const {
    Jump out;
    for (const detail::SequenceStep& s :
         detail::impact_sequence(rec_.mech, held_, tr, held_after, xe_, ve_, vp, t, rule_, reverse))
      out.salts.push_back(salt(s.rule, s.stop, true, s.x_before, s.v_before, s.v_after, t));
    return out;
  }

  /// ‖A d − B d‖ / ‖A d‖ over fixed test vectors d (the dense map compares the matrices).
  double spread(const Jump& a, const Jump& b) const {
    MatrixXd D(2 * n_, 4);
    for (Index i = 0; i < D.rows(); ++i)
      for (Index c = 0; c < 4; ++c) D(i, c) = std::sin(1.0 + 0.7 * static_cast<double>(i) + 1.3 * static_cast<double>(c));
    MatrixXd Da = D, Db = D;
    for (const Salt& s : a.salts) rec_.apply(s, Da, nullptr);
    for (const Salt& s : b.salts) rec_.apply(s, Db, nullptr);
    return (Da - Db).norm() / std::max(Da.norm(), 1e-300);
  }

 public:
  ChatterRule rule_ = ChatterRule::third_order;

 private:
  ModalTangent::Record& rec_;
  const ModalChainSimulator& sim_;
  TangentMap& out_;
  Index n_;
  bool first_ = true, pending_ = false, broken_ = false;
  long dropped_ = 0;
  ContactSet held_;
  ModalSegmentState last_;  // the segment before the pending event
  VectorXd xe_, ve_;        // its end state (general events only)
  double te_ = 0.0;
  std::vector<Event> events_;
  Index min_dim_ = 0;
  double least_rate_ = 0.0;
  detail::PhaseBook phases_;
  bool features_ = false;
  double window_ = 0.0;  // past_release_window (periods)
};

}  // namespace

ModalTangent::ModalTangent(ModalEngine& engine, double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                           bool modal_events)
    : ModalTangent(engine, t0, x0, v0, t1, LinearisationOptions{}, modal_events) {}

ModalTangent::ModalTangent(ModalEngine& engine, double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                           const LinearisationOptions& options, bool modal_events)
    : sim_(&engine.simulator()), n_(engine.simulator().modes().dof()) {
  ModalChainSimulator& sim = engine.simulator();
  record_ = std::make_unique<Record>(sim.modes().chain(), sim.stops());
  record_->mass_of_chain = sim.modes().chain().mass;
  record_->free = &sim.modes();
  record_->modal_events = modal_events;
  map_.t0 = t0;
  map_.x0 = x0;
  map_.v0 = v0;
  Recorder recorder(*record_, sim, map_, options);
  recorder.rule_ = sim.options().chatter_rule;
  const long dropped = sim.modes_dropped();
  const ModalRunSummary s = sim.run(t0, x0, v0, t1, {&recorder});
  map_.summary = s;
  run_ = sim.runs_started();
  if (sim.modes_dropped() != dropped && map_.summary.status == RunStatus::completed) {
    // The record points into the cache: a set dropped during the run may be one of its segments'.
    map_.summary.status = RunStatus::unsupported;
    map_.summary.message = "the tangent map needs every contact set of the run at once, and the engine's cache "
                           "(solver mode_cache_bytes) dropped one during it: raise the budget";
  }
  if (map_.summary.velocity_scale > 0.0) map_.least_guard_rate /= map_.summary.velocity_scale;
  if (map_.x1.size() == 0) {  // a run without a segment (t1 = t0), or no usable record
    map_.t1 = s.t;
    map_.x1 = s.x;
    map_.v1 = s.v;
  }
}

ModalTangent::~ModalTangent() = default;

void ModalTangent::apply_range(std::size_t from, std::size_t to, MatrixXd& D, bool modal_in, bool modal_out,
                               Sensitivity* p, const std::atomic<bool>* stop) const {
  if (map_.summary.status != RunStatus::completed)
    throw std::logic_error("ModalTangent: the run did not complete (" + std::string(to_string(map_.summary.status)) +
                           "); its tangent map is not defined");
  if (sim_->runs_started() != run_)
    throw std::logic_error("ModalTangent: the engine has run again since this record (its contact sets may be gone)");
  const Record& r = *record_;
  // The columns stay in the free chain's modal coordinates through free flights and free-flight
  // impacts (O(N) each) and go to physical ones only for the other events and contact sets.
  bool modal = modal_in;
  auto want = [&](bool in_modal) {
    if (in_modal && !modal) r.to_modal(D);
    if (!in_modal && modal) r.to_physical(D);
    modal = in_modal;
  };
  for (std::size_t i = from; i < to; ++i) {
    if (stop && stop->load(std::memory_order_relaxed)) throw Interrupted();
    const Op& op = r.ops[i];
    if (const auto* f = std::get_if<Flight>(&op)) {
      // A flight maps z to z_p(t_end) + J_h (z − z_p(t_begin)), z_p the set's particular solution
      // and J_h its homogeneous flow (independent of Ω, the forcing and the stops' data): along
      // dD, ζ ← J_h (ζ − ∂z_p(t_begin)/∂p) + ∂z_p(t_end)/∂p.
      const bool free_set = r.free_set(*f->mode);
      want(free_set);
      const Particular* pt = p ? &r.particular(*p, *f->mode) : nullptr;
      if (pt) Record::add_particular(*pt, p->data.frequency(), f->t_begin, -1.0, D.col(p->column));
      if (free_set) r.free->advance_columns(f->tau, D.topRows(n_), D.bottomRows(n_));
      else r.apply(*f, D);
      if (pt) Record::add_particular(*pt, p->data.frequency(), f->t_end, 1.0, D.col(p->column));
    } else if (const auto* impact = std::get_if<FreeImpact>(&op)) {
      want(true);
      r.apply_modal(*impact, D, p);
    } else {
      want(false);
      r.apply(std::get<Jump>(op), D, p);
    }
  }
  want(modal_out);
}

MatrixXd ModalTangent::through(const MatrixXd& directions, bool modal, const std::atomic<bool>* stop) const {
  if (directions.rows() != 2 * n_)
    throw InvalidInput("modal tangent: directions have " + std::to_string(directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * n_));
  MatrixXd D = directions;
  apply_range(0, record_->ops.size(), D, modal, modal, nullptr, stop);
  return D;
}

MatrixXd ModalTangent::apply(const MatrixXd& directions) const {
  return through(directions, false, sim_->options().interrupt);
}

VectorXd ModalTangent::parameter(const SystemDerivative& derivative) const {
  check_derivative(derivative, n_, sim_->stops());
  Sensitivity p(sim_->modes().chain(), sim_->stops(), derivative, 0);
  MatrixXd zeta = MatrixXd::Zero(2 * n_, 1);  // ζ(t0) = 0: the start is fixed
  apply_range(0, record_->ops.size(), zeta, false, false, &p);
  return zeta.col(0);
}

MatrixXd ModalTangent::apply_modal(const MatrixXd& directions) const { return through(directions, true); }

MatrixXd ModalTangent::modal_coordinates(const MatrixXd& physical) const {
  MatrixXd D = physical;
  record_->to_modal(D);
  return D;
}

MatrixXd ModalTangent::physical_coordinates(const MatrixXd& modal) const {
  MatrixXd D = modal;
  record_->to_physical(D);
  return D;
}

void ModalTangent::fill_jacobian(TangentMap& out) const {
  const Index N2 = 2 * n_;
  const std::atomic<bool>* stop = sim_->options().interrupt;
  // J = J I, its columns in blocks (the header): a block of at least 64 columns keeps every
  // basis change a matrix product (ChainModes' times(): more than 8 columns), whose entries do
  // not depend on how many columns it has, so the blocks give J's bits as one pass does
  // (tests/analysis/test_modal_tangent.cpp).
  constexpr Index kBlock = 64;
  MatrixXd J(N2, N2);
  for (Index first = 0; first < N2;) {
    const Index cols = N2 - first < 2 * kBlock ? N2 - first : kBlock;
    MatrixXd D = MatrixXd::Identity(N2, N2).middleCols(first, cols);
    apply_range(0, record_->ops.size(), D, false, false, nullptr, stop);
    J.middleCols(first, cols) = D;
    first += cols;
  }
  out.jacobian = std::move(J);
  if (map_.free_dimension >= N2 || !record_->split_mode) {
    out.reduced = out.jacobian;
    out.lift = MatrixXd::Identity(N2, N2);
    return;
  }
  // J = J₂ J₁ split after the first segment of least dimension; B an orthonormal basis of that
  // set's tangent space: x = T y, so the columns of T normalised (disjoint groups) and the same
  // for v. reduced = Bᵀ J₁ J₂ B shares J's non-zero eigenvalues (linearisation.hpp).
  const ModalContactMode& md = *record_->split_mode;
  const Index nr = md.size();
  MatrixXd B = MatrixXd::Zero(N2, 2 * nr);
  for (Index r = 0; r < nr; ++r) {
    const Index first = md.first[static_cast<std::size_t>(r)], last = md.last[static_cast<std::size_t>(r)];
    const double w = 1.0 / std::sqrt(static_cast<double>(last - first + 1));
    for (Index l = first; l <= last; ++l) {
      B(l, r) = w;
      B(n_ + l, nr + r) = w;
    }
  }
  MatrixXd L = B;
  apply_range(record_->split, record_->ops.size(), L, false, false, nullptr, stop);  // J₂ B
  out.lift = L;
  apply_range(0, record_->split, L, false, false, nullptr, stop);                     // J₁ J₂ B
  out.reduced = B.transpose() * L;
}

TangentMap linearise(ModalEngine& engine, double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                     const LinearisationOptions& options) {
  if (options.parameter)
    check_derivative(*options.parameter, engine.simulator().modes().dof(), engine.simulator().stops());
  const Index n2 = 2 * engine.simulator().modes().dof();
  if (options.directions.size() > 0 && options.directions.rows() != n2)
    throw InvalidInput("linearisation: directions have " + std::to_string(options.directions.rows()) +
                       " rows, expected 2n = " + std::to_string(n2));
  ModalTangent tangent(engine, t0, x0, v0, t1, options);
  TangentMap out = tangent.map();
  if (out.summary.status != RunStatus::completed) return out;
  try {
    if (options.directions.size() > 0)
      out.products = tangent.apply(options.directions);
    else if (options.jacobian)
      tangent.fill_jacobian(out);
  } catch (const Interrupted&) {  // as the dense engine's map interrupted while J is formed
    out.jacobian = out.reduced = out.lift = out.products = MatrixXd();
    out.summary.status = RunStatus::interrupted;
    out.summary.message = "interrupted at t = " + number_text(out.summary.t) + " while the tangent map was formed";
    return out;
  }
  if (options.parameter) out.parameter = tangent.parameter(*options.parameter);
  return out;
}

}  // namespace vibro
