#include "vibro/linearisation.hpp"

#include "mechanics.hpp"
#include "nonlinear_part.hpp"
#include "orthonormal_frame.hpp"
#include "reset_derivative.hpp"
#include "sign_changes.hpp"
#include "transition.hpp"
#include "vibro/bounded_wait.hpp"
#include "vibro/contact.hpp"
#include "vibro/contact_law.hpp"
#include "vibro/flow.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <numbers>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

namespace vibro {
namespace {

/// Systems of at least this many degrees of freedom run their dense set-ups and products under
/// run_bounded (TangentRecorder::bounded).
constexpr Eigen::Index kBoundedFromCoordinates = 64;

using detail::Dual;
using detail::Mechanics;
using detail::ResetRule;
using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using VecD = detail::VecT<Dual>;
using MatD = detail::MatT<Dual>;

using detail::derivative;
using detail::seeded;

bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

using detail::SignChanges;

/// Orthonormal basis (2n × d) of {(δx, δv) : Wᵀδx = 0, Wᵀδv = 0}.
MatrixXd tangent_basis(const MatrixXd& W, Index n) {
  MatrixXd null;
  if (W.cols() == 0) {
    null = MatrixXd::Identity(n, n);
  } else {
    Eigen::JacobiSVD<MatrixXd> svd(W, Eigen::ComputeFullU);
    const double tol = 1e-12 * std::max(1.0, svd.singularValues()(0));
    Index rank = 0;
    for (Index i = 0; i < svd.singularValues().size(); ++i) rank += svd.singularValues()(i) > tol;
    null = svd.matrixU().rightCols(n - rank);
  }
  const Index d = null.cols();
  MatrixXd B = MatrixXd::Zero(2 * n, 2 * d);
  B.topLeftCorner(n, d) = null;
  B.bottomRightCorner(n, d) = null;
  return B;
}

/// What one contact set's motion needs, built on first use.
struct Mode {
  ContactSet set;           // the key: held rigid stops and engaged compliant ones
  ContactSet held;          // its held rigid stops (the constraints, the force rows)
  MatrixXd generator;       // Â_S
  MatrixXd force_rows;      // λ_S = L z (|S| × N)
  MatrixXd dgenerator;      // dÂ_S/dp (parameter runs)
  MatrixXd dforce_rows;     // dL/dp
  MatrixXd basis;           // tangent space of the manifold, 2n × d
  Eigen::MatrixXcd dmodal;  // V⁻¹ dÂ_S V (parameter runs on the spectral path; empty until used)
  MatrixXd projection;      // nonlinear forces with held stops: I − M⁻¹W G⁻¹Wᵀ (a_S's part M⁻¹F)
  std::shared_ptr<const LinearFlow> flow;  // shared with a set-up or product under run_bounded
  std::unique_ptr<Functionals> rows;  // features: gaps, gap rates, forces, force rates
};

class TangentRecorder final : public Observer {
 public:
  TangentRecorder(const ImpactSystem& system, const SimulatorOptions& solver,
                  const LinearisationOptions& options, TangentMap& out, detail::NonlinearPart* nonlinear = nullptr)
      : system_(system), solver_(solver), options_(options), out_(out), nonlinear_(nonlinear), n_(system.dof()),
        mech_(system), mech0_(system), frame_(options.directions.size() > 0),
        phases_(out.phases, system.stop_count()) {
    if (options.parameter) mechp_ = std::make_unique<Mechanics<Dual>>(system, &*options.parameter);
    if (nonlinear_) {  // the chatter rule's capture reads the contact force with the forces' part
      mech_.set_chatter_forces(detail::chatter_forces(mech_, *nonlinear_, false));
      mech0_.set_chatter_forces(detail::chatter_forces(mech0_, *nonlinear_, false));
      if (mechp_) mechp_->set_chatter_forces(detail::chatter_forces(*mechp_, *nonlinear_, true));
    }
  }

  /// Re-orthonormalise the carried directions after every event, adding log|R_ii| to *log_growth
  /// (orthonormal_frame.hpp). Before the run.
  void orthonormalise_into(VectorXd* log_growth) { log_growth_ = log_growth; }

  void begin(const RunContext& /*run*/, double t0) override {
    t0_ = t0;
    K_ = MatrixXd::Identity(2 * n_, 2 * n_);
    Jmid_ = K_;
    if (frame_) K_ = options_.directions;
    min_dim_ = 2 * n_;
    basis_ = K_;
    if (log_growth_) log_growth_->setZero(K_.cols());
    zeta_ = VectorXd::Zero(2 * n_);
    least_rate_ = std::numeric_limits<double>::infinity();
  }

  void segment(const SegmentView& view) override {
    const double tb = view.t_begin(), te = view.t_end();
    const ContactSet& S = mode_key(view);
    VectorXd xb(n_), vb(n_);
    view.state(tb, xb, vb);
    if (first_) {
      first_ = false;
      held_ = S;
      const ContactSet R = mech_.held_part(S);
      out_.starts_held = !R.empty();
      for (int j : R) phases_.open(j, tb);
    } else if (pending_) {
      finish_transition(vb, S);
    }
    Mode& mode = mode_for(S);
    if (out_.rate_start.size() == 0) out_.rate_start = rate(mode, tb, xb, vb);
    const VectorXd zb = mode.flow->augment(tb, xb, vb);
    propagate(mode, te - tb, tb, zb);
    if (options_.features && te > tb) features(mode, tb, te, zb);
    last_mode_ = &mode;
    last_tb_ = tb;
    last_zb_ = zb;
    xe_.resize(n_);
    ve_.resize(n_);
    view.state(te, xe_, ve_);
    te_ = te;
    pending_ = true;
    events_.clear();
  }

  void event(const Event& e) override {
    events_.push_back(e);
    out_.events.push_back(e);
    if (e.kind == EventKind::engage || e.kind == EventKind::disengage) {  // mode_key's engaged set
      const auto at = std::lower_bound(engaged_.begin(), engaged_.end(), e.stop);
      const bool in = at != engaged_.end() && *at == e.stop;
      if (e.kind == EventKind::engage && !in) engaged_.insert(at, e.stop);
      if (e.kind == EventKind::disengage && in) engaged_.erase(at);
    }
  }

  void end(double t) override {
    if (!events_.empty()) out_.ends_at_event = true;
    out_.t1 = t;
    out_.x1 = xe_;
    out_.v1 = ve_;
    if (last_mode_) out_.rate_end = rate(*last_mode_, te_, xe_, ve_);
    phases_.end(t);
    const Index N2 = 2 * n_;
    out_.free_dimension = min_dim_;
    if (frame_) {
      out_.products = K_;
    } else if (options_.jacobian) {
      // J = K Jmid and its reduced form, O(N³): bounded (bounded()). The run ends here, so an
      // interruption is only noted (cut_short()) for linearise to report: end() never throws.
      struct Products {
        MatrixXd jacobian, reduced, lift;
      };
      try {
        Products p = bounded([K = K_, J = Jmid_, B = basis_, N2, reduce = min_dim_ < N2] {
          Products r;
          r.jacobian = K * J;
          if (reduce) {
            r.reduced = B.transpose() * J * K * B;
            r.lift = K * B;
          } else {
            r.reduced = r.jacobian;
            r.lift = MatrixXd::Identity(N2, N2);
          }
          return r;
        });
        out_.jacobian = std::move(p.jacobian);
        out_.reduced = std::move(p.reduced);
        out_.lift = std::move(p.lift);
      } catch (const Interrupted&) {
        cut_short_ = true;
      }
    }
    if (options_.parameter) out_.parameter = zeta_;
    out_.least_guard_rate = least_rate_;
  }

 private:
  /// The mode of a segment: its held rigid stops (view.active()) and, in a scene with compliant
  /// stops, the engaged ones, as the engine keys it: the dense engine's ContactMode::engaged();
  /// on another engine (the Taylor engine's view) those followed through the run: penetrated at
  /// its start (CompliantStopLaw::engaged_at_start), then each engage and disengage event.
  const ContactSet& mode_key(const SegmentView& view) {
    if (!mech_.any_compliant()) return view.active();
    key_.clear();
    const ContactSet& held = view.active();
    const auto* dense = dynamic_cast<const DenseSegmentView*>(&view);
    if (!dense && first_) {
      VectorXd x(n_), v(n_);
      view.state(view.t_begin(), x, v);
      for (int j = 0; j < static_cast<int>(system_.stop_count()); ++j)
        if (mech_.compliant(j) && CompliantStopLaw::engaged_at_start(mech_.gap(j, x, view.t_begin())))
          engaged_.push_back(j);
    }
    const ContactSet& engaged = dense ? dense->mode().engaged() : engaged_;
    std::set_union(held.begin(), held.end(), engaged.begin(), engaged.end(), std::back_inserter(key_));
    return key_;
  }

  Mode& mode_for(const ContactSet& S) {
    auto it = modes_.find(S);
    if (it != modes_.end()) return *it->second;
    auto m = std::make_unique<Mode>();
    m->set = S;
    m->held = mech_.held_part(S);
    m->generator = mech_.generator(S);
    m->force_rows = m->held.empty() ? MatrixXd(0, mech_.augmented()) : mech_.force_rows(S);
    if (mechp_) {
      m->dgenerator = derivative(mechp_->generator(S));
      m->dforce_rows = m->held.empty() ? MatrixXd(0, mech_.augmented()) : derivative(mechp_->force_rows(S));
    }
    m->basis = tangent_basis(mech_.normals(m->held), n_);
    if (nonlinear_ && !m->held.empty()) {
      const MatrixXd W = mech_.normals(m->held), QW = mech_.mass_inverse(W);
      m->projection = MatrixXd::Identity(n_, n_) - QW * (W.transpose() * QW).llt().solve(W.transpose());
    }
    m->flow = bounded([g = m->generator, n = n_, w = value_of_omega(), o = solver_.flow] {
      return std::shared_ptr<const LinearFlow>(std::make_shared<LinearFlow>(g, n, w, o));
    });
    if (options_.features) {
      const Index N = mech_.augmented(), ms = static_cast<Index>(system_.stop_count());
      const Index h = static_cast<Index>(m->held.size());
      MatrixXd rows(2 * ms + 2 * h, N);
      for (Index j = 0; j < ms; ++j) {
        const VectorXd g = mech_.gap_row(static_cast<int>(j));
        rows.row(j) = g.transpose();
        rows.row(ms + j) = g.transpose() * m->generator;
      }
      if (h > 0) {
        rows.middleRows(2 * ms, h) = m->force_rows;
        rows.middleRows(2 * ms + h, h) = m->force_rows * m->generator;
      }
      m->rows = std::make_unique<Functionals>(*m->flow, rows);
    }
    return *modes_.emplace(S, std::move(m)).first->second;
  }

  double value_of_omega() const { return mech_.frequency(); }

  /// f(z, t) = (v, a_S) from the generator.
  VectorXd rate(const Mode& mode, double t, const VectorXd& x, const VectorXd& v) const {
    const VectorXd z = mode.flow->augment(t, x, v);
    VectorXd f = (mode.generator * z).head(2 * n_);
    if (nonlinear_) {
      const VectorXd a = nonlinear_->acceleration(t, x, v);
      f.tail(n_) += mode.projection.size() ? VectorXd(mode.projection * a) : a;
    }
    return f;
  }

  /// The state block of exp(Â_S τ): from the eigen-decomposition for large well-conditioned
  /// systems, else the Padé exponential (exact to rounding; cheap at these sizes).
  static MatrixXd transition(const LinearFlow& f, double tau, Index N2) {
    if (f.size() > 64 && f.method() == LinearFlow::Method::spectral) {
      const Eigen::VectorXcd e = (f.eigenvalues() * tau).array().exp();
      const Eigen::MatrixXcd left = f.eigenvectors().topRows(N2) * e.asDiagonal();
      return (left * f.inverse_eigenvectors().leftCols(N2)).real();
    }
    return f.transition_matrix(tau).topLeftCorner(N2, N2);
  }

  /// K ← Φ(τ) K over a segment of `mode` (O(N³)): bounded for large systems (see bounded()).
  void carry_over(const Mode& mode, double tau) {
    K_ = bounded([f = mode.flow, tau, N2 = 2 * n_, K = K_] { return MatrixXd(transition(*f, tau, N2) * K); });
  }

  /// K ← S K at an event (O(N³)), bounded likewise.
  void carry_through(const MatrixXd& S) {
    K_ = bounded([S, K = K_] { return MatrixXd(S * K); });
  }

  /// The dense set-ups and products of a large system (a flow's eigen-decomposition, Φ K and
  /// S K: seconds from a few hundred coordinates on) cannot be polled: from
  /// kBoundedFromCoordinates on they run under run_bounded with the run's interrupt flag
  /// (bounded_wait.hpp), on copies of their inputs, so that raising the flag ends the run
  /// (Interrupted, which the engine's event loop takes as an interruption) within 10 ms. The
  /// same code on the same data: the same bits.
  template <class F>
  auto bounded(F fn) const -> decltype(fn()) {
    return run_bounded(n_ >= kBoundedFromCoordinates ? solver_.interrupt : nullptr, std::move(fn));
  }

  /// Large, well-conditioned flows use their eigen-decomposition (transition(); the parameter
  /// sensitivity below); small ones the Padé exponential, exact to rounding.
  static bool spectral(const Mode& mode) {
    return mode.flow->size() > 64 && mode.flow->method() == LinearFlow::Method::spectral;
  }

  /// The extra harmonics' part of ∂z(tb)/∂p: d/dp (cos k_hΩt, sin k_hΩt) = k_h t dΩ/dp
  /// (−sin k_hΩt, cos k_hΩt) (the first harmonic's is written where this is called).
  void forcing_sensitivity(double tb, double dw, VectorXd& zeta_aug) const {
    for (std::size_t h = 0; h < mech_.harmonics(); ++h) {
      const Index c = augmented_size(n_, h);
      const double wh = mech_.harmonic_rate(h), k = mech_.harmonic_order(h);
      zeta_aug(c) = -k * tb * std::sin(wh * tb) * dw;
      zeta_aug(c + 1) = k * tb * std::cos(wh * tb) * dw;
    }
  }

  /// ζ ← Φ ζ + Ψ z over a segment from the eigen-decomposition Â = V Λ V⁻¹: with B = V⁻¹ dÂ V,
  ///     Ψ = V (B ∘ Δ) V⁻¹,   Δ_ij = ∫₀^τ e^{λ_i (τ − s)} e^{λ_j s} ds = e^{λ_j τ} τ φ₁((λ_i − λ_j) τ),
  /// φ₁(x) = (eˣ − 1)/x (a series near 0): O(N²) per segment instead of a 2N × 2N exponential.
  /// Its rounding is cond(V) ε like the flow's own spectral path (the flow accepts it only for
  /// cond(V) ≤ max_condition).
  void propagate_spectral(Mode& mode, double tau, double tb, const VectorXd& zb) {
    const LinearFlow& f = *mode.flow;
    const Index N = f.size(), N2 = 2 * n_;
    const Eigen::MatrixXcd& V = f.eigenvectors();
    const Eigen::MatrixXcd& W = f.inverse_eigenvectors();
    const Eigen::VectorXcd& L = f.eigenvalues();
    if (mode.dmodal.size() == 0)
      mode.dmodal = bounded([f = mode.flow, d = mode.dgenerator] {
        return Eigen::MatrixXcd(f->inverse_eigenvectors() * d.cast<std::complex<double>>() * f->eigenvectors());
      });
    VectorXd zeta_aug = VectorXd::Zero(N);
    zeta_aug.head(N2) = zeta_;
    const double w = mech_.frequency(), dw = options_.parameter->frequency;
    zeta_aug(N2) = -tb * std::sin(w * tb) * dw;
    zeta_aug(N2 + 1) = tb * std::cos(w * tb) * dw;
    forcing_sensitivity(tb, dw, zeta_aug);
    const Eigen::VectorXcd e = (L * tau).array().exp();
    const Eigen::VectorXcd a = W * zeta_aug.cast<std::complex<double>>();
    const Eigen::VectorXcd b = W * zb.cast<std::complex<double>>();
    Eigen::VectorXcd c = e.cwiseProduct(a);
    for (Index i = 0; i < N; ++i) {
      std::complex<double> sum = 0.0;
      for (Index j = 0; j < N; ++j) {
        const std::complex<double> x = (L(i) - L(j)) * tau;
        const std::complex<double> phi1 =
            std::abs(x) < 1e-4 ? 1.0 + x / 2.0 + x * x / 6.0 + x * x * x / 24.0 : (std::exp(x) - 1.0) / x;
        sum += mode.dmodal(i, j) * (e(j) * tau * phi1) * b(j);
      }
      c(i) += sum;
    }
    zeta_ = (V * c).real().head(N2);
    if (carries()) carry_over(mode, tau);
  }

  void propagate(Mode& mode, double tau, double tb, const VectorXd& zb) {
    const Index N2 = 2 * n_;
    const Index dim = mode.basis.cols();
    if (nonlinear_) {
      if (tau > 0.0 && (carries() || mechp_)) {
        const MatrixXd T = nonlinear_->transition(mode.set, tb, zb.head(n_), zb.segment(n_, n_), tb + tau);
        if (mechp_) zeta_ = T.leftCols(N2) * zeta_ + T.col(N2);
        if (carries()) K_ = T.leftCols(N2) * K_;
      }
    } else if (tau > 0.0) {
      if (mechp_ && spectral(mode)) {
        propagate_spectral(mode, tau, tb, zb);
      } else if (mechp_) {
        const Index N = mode.generator.rows();
        MatrixXd block = MatrixXd::Zero(2 * N, 2 * N);
        block.topLeftCorner(N, N) = mode.generator * tau;
        block.topRightCorner(N, N) = mode.dgenerator * tau;
        block.bottomRightCorner(N, N) = mode.generator * tau;
        const MatrixXd E = block.exp();
        VectorXd zeta_aug = VectorXd::Zero(N);
        zeta_aug.head(N2) = zeta_;
        const double w = mech_.frequency(), dw = options_.parameter->frequency;
        zeta_aug(N2) = -tb * std::sin(w * tb) * dw;
        zeta_aug(N2 + 1) = tb * std::cos(w * tb) * dw;
        forcing_sensitivity(tb, dw, zeta_aug);
        zeta_ = (E.topLeftCorner(N, N) * zeta_aug + E.topRightCorner(N, N) * zb).head(N2);
        if (carries()) K_ = E.topLeftCorner(N2, N2) * K_;
      } else if (carries()) {
        carry_over(mode, tau);
      }
    }
    if (dim < min_dim_) {
      min_dim_ = dim;
      // A new least tangent dimension: split J here (see linearisation.hpp, structural zeros).
      if (options_.jacobian && !frame_) {
        Jmid_ = K_ * Jmid_;
        K_.setIdentity();
        basis_ = mode.basis;
      }
    }
  }

  // ---- events --------------------------------------------------------------------------

  /// One impact (or none) resolved at (x, v⁻, t): the saltation matrix and the parameter column.
  struct Jump {
    MatrixXd S;
    VectorXd sp;
    VectorXd v_after;
    double rate = 0.0;
  };

  ContactSet impulse_set(const ContactSet& held, const ContactSet& impacting, const ContactSet& caught,
                         const VectorXd& v, double t) const {
    return detail::impulse_set(mech_, held, impacting, caught, v, t);
  }

  /// The saltation of one resolution (`rule`) at (x, v⁻, t), with the guard of stop `guard`
  /// (a gap if `impact`, else the contact force of a held stop, −λ), landing in the state
  /// (x, v⁺) of the set rule.held_after.
  Jump jump(const ResetRule& rule, int guard, bool impact, const VectorXd& x, const VectorXd& vm,
            const VectorXd& vp, double t) {
    const Index n = n_, N2 = 2 * n;
    Mode& before = mode_for(rule.held_before);
    Mode& after = mode_for(rule.held_after);
    const VectorXd fm = rate(before, t, x, vm);
    // x⁺: moved only by the chatter rule (mechanics.hpp, step 2).
    const VectorXd xp = mech_.reset(rule, x, vm, t).head(n);
    const VectorXd fp = rate(after, t, xp, vp);
    Jump out;
    out.v_after = vp;
    // R_z column by column, and c = R_z f⁻ + R_t along the flow.
    const detail::ResetDerivative rd = detail::reset_derivative(mech0_, rule, x, vm, t, fm);
    const MatrixXd& Rz = rd.state;
    const VectorXd& c = rd.along_flow;
    // The guard: h_z, ḣ⁻, h_p.
    VectorXd hz = VectorXd::Zero(N2);
    double hdot = 0.0, hp = 0.0;
    if (guard >= 0 && impact) {
      mech_.normal(guard).scatter(hz.head(n));
      hdot = mech_.gap_rate(guard, vm, t);
      if (mechp_) hp = mechp_->gap(guard, seeded(x, VectorXd()), Dual(t)).d;
    } else if (guard >= 0) {
      const ContactSet& S = before.held;
      const auto a = static_cast<Index>(std::lower_bound(S.begin(), S.end(), guard) - S.begin());
      if (nonlinear_) {  // λ_a with the forces' part (nonlinear_part.hpp)
        const detail::NonlinearPart::HeldForce lambda =
            nonlinear_->held_force(before.set, static_cast<int>(a), t, x, vm);
        hz = -lambda.gradient;
        hdot = -lambda.rate;
        hp = -lambda.dp;
      } else {
        const VectorXd z = before.flow->augment(t, x, vm);
        hz = -before.force_rows.row(a).head(N2).transpose();
        hdot = -before.force_rows.row(a).dot(before.generator * z);
        if (mechp_) hp = -before.dforce_rows.row(a).dot(z);
      }
    }
    out.rate = hdot;
    out.S = Rz;
    if (guard >= 0 && hdot != 0.0) out.S += (fp - c) * hz.transpose() / hdot;
    if (mechp_) {
      out.sp = detail::reset_parameter(*mechp_, rule, x, vm, t);
      if (guard >= 0 && hdot != 0.0) out.sp += (fp - c) * (hp / hdot);
    }
    return out;
  }

  /// The events since the last segment, resolved: their saltation applied to J and ζ.
  void finish_transition(const VectorXd& vp, const ContactSet& held_after) {
    pending_ = false;
    const double t = te_;
    const detail::Transition tr = detail::classify(events_);
    const ContactSet& impacting = tr.impacting;
    const ContactSet& caught = tr.caught;
    const ContactSet& released = tr.released;
    SaltationRecord rec = detail::record_of(t, held_, tr, held_after);
    if (options_.features) {
      phases_.change(t, mech_.held_part(held_), mech_.held_part(held_after));
      Mode& before = mode_for(held_);
      const VectorXd a = rate(before, t, xe_, ve_).tail(n_);
      for (int j : impacting)
        out_.impacts.push_back({j, t, mech_.gap_rate(j, ve_, t),
                                mech_.normal_dot(j, a) - mech_.stop_position(j, t, 2)});
    }
    past_release(released);

    // Compliant stops' engagements and disengagements come first (the engine resolves them
    // before the rigid stops' events at the same instant), one at a time in index order: each a
    // switch of the vector field at the zero of the stop's gap, no reset.
    Jump switched;
    if (!tr.switched.empty()) {
      switched = switches(tr.switched, rec);
      if (impacting.empty() && released.empty() && mech_.held_part(held_) == mech_.held_part(held_after)) {
        if (carries()) carry_through(switched.S);
        if (frame_ && log_growth_) orthonormalise();
        if (mechp_) zeta_ = switched.S * zeta_ + switched.sp;
        out_.saltations.push_back(rec);
        held_ = held_after;
        return;
      }
    }

    Jump total;
    if (impacting.size() <= 1) {
      ResetRule rule{held_, impacting, caught, impulse_set(held_, impacting, caught, ve_, t), held_after,
                     solver_.chatter_rule};
      const bool impact = !impacting.empty();
      const int guard = impact ? impacting.front() : (released.empty() ? -1 : released.front());
      rec.guard_stop = guard;
      rec.impact = impact;
      total = jump(rule, guard, impact, xe_, ve_, vp, t);
    } else {
      rec.simultaneous = true;
      rec.guard_stop = impacting.front();
      rec.impact = true;
      const Jump forward = in_sequence(tr, held_after, vp, t, false);
      const Jump backward = in_sequence(tr, held_after, vp, t, true);
      rec.order_spread = (forward.S - backward.S).norm() / std::max(forward.S.norm(), 1e-300);
      if (rec.order_spread > 1e-8 && !out_.non_smooth) {
        out_.non_smooth = true;
        out_.non_smooth_reason = "simultaneous impacts at t = " + number_text(t) +
                                 " whose order changes the tangent map (relative difference " +
                                 number_text(rec.order_spread) + ")";
      }
      total = forward;
    }
    if (rec.guard_stop >= 0 || tr.switched.empty()) rec.guard_rate = total.rate;
    if (rec.guard_stop < 0 && !tr.switched.empty()) rec.guard_stop = tr.switched.front();
    if (rec.impact) least_rate_ = std::min(least_rate_, total.rate);
    if (!tr.switched.empty()) {  // the rigid stops' part after the switches
      if (mechp_) total.sp = total.S * switched.sp + total.sp;
      total.S = total.S * switched.S;
    }
    if (carries()) carry_through(total.S);
    if (frame_ && log_growth_) orthonormalise();
    if (mechp_) zeta_ = total.S * zeta_ + total.sp;
    out_.saltations.push_back(rec);
    held_ = held_after;
  }

  /// The compliant stops `stops` switching at te_ (engaging if not in held_, disengaging if in
  /// it), one at a time with the state unchanged: each the saltation of linearisation.hpp with
  /// the guard g_j, no reset but the held rigid stops' projection. held_ moves along (to the
  /// key the rigid stops' part of the event starts from); rec.guard_rate gets the least |ġ|.
  Jump switches(const ContactSet& stops, SaltationRecord& rec) {
    Jump total;
    total.S = MatrixXd::Identity(2 * n_, 2 * n_);
    if (mechp_) total.sp = VectorXd::Zero(2 * n_);
    total.rate = std::numeric_limits<double>::infinity();
    for (int j : stops) {
      ContactSet next = held_;
      const auto at = std::lower_bound(next.begin(), next.end(), j);
      if (at != next.end() && *at == j) next.erase(at);
      else next.insert(at, j);
      const ResetRule rule{held_, {}, {}, {}, next, solver_.chatter_rule};
      const Jump step = jump(rule, j, true, xe_, ve_, ve_, te_);
      total.S = step.S * total.S;
      if (mechp_) total.sp = step.S * total.sp + step.sp;
      total.rate = std::min(total.rate, std::abs(step.rate));
      held_ = std::move(next);
    }
    rec.guard_stop = stops.front();
    rec.guard_rate = total.rate;
    return total;
  }

  /// Simultaneous impacts taken one at a time (index order, or reversed), each with its own
  /// guard; the last lands in the engine's post-event state.
  Jump in_sequence(const detail::Transition& tr, const ContactSet& held_after, const VectorXd& vp, double t,
                   bool reverse) {
    Jump total;
    total.S = MatrixXd::Identity(2 * n_, 2 * n_);
    if (mechp_) total.sp = VectorXd::Zero(2 * n_);
    total.rate = std::numeric_limits<double>::infinity();
    for (const detail::SequenceStep& s :
         detail::impact_sequence(mech_, held_, tr, held_after, xe_, ve_, vp, t, solver_.chatter_rule, reverse)) {
      const Jump step = jump(s.rule, s.stop, true, s.x_before, s.v_before, s.v_after, t);
      total.S = step.S * total.S;
      if (mechp_) total.sp = step.S * total.sp + step.sp;
      total.rate = std::min(total.rate, step.rate);
    }
    return total;
  }

  // ---- features ------------------------------------------------------------------------

  void features(Mode& mode, double tb, double te, const VectorXd& zb) {
    if (nonlinear_) {  // the gaps' peaks and the held forces' minima from the Taylor steps
      // Held rigid stops have no gap peaks; an engaged compliant stop's are its penetration's
      // maxima, as below.
      std::vector<int> free;
      for (int j = 0; j < static_cast<int>(system_.stop_count()); ++j)
        if (!contains(mode.held, j)) free.push_back(j);
      const double tau = te - tb;
      const VectorXd x = zb.head(n_), v = zb.segment(n_, n_);
      for (const ForceDip& dip : nonlinear_->force_minima(mode.set, tb, x, v, te)) out_.force_dips.push_back(dip);
      const std::vector<GapPeak> peaks = nonlinear_->gap_peaks(mode.set, tb, x, v, te, free);
      for (const GapPeak& pk : peaks) {
        const double g_start = mech_.gap(pk.stop, x, tb);
        const double size = std::max(std::abs(g_start), std::abs(pk.value));
        if (detail::flight_start_artifact(pk.t - tb, tau, pk.value, g_start, size)) continue;
        out_.gap_peaks.push_back(pk);
      }
      return;
    }
    const Segment seg(*mode.rows, tb, zb);
    const Index ms = static_cast<Index>(system_.stop_count());
    const double resolution = 16.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(te), 1.0);
    const double tau = te - tb;
    for (Index j = 0; j < ms; ++j) {
      // Held rigid stops have no gap peaks; an engaged compliant stop's are its penetration's
      // maxima (g > 0), the other side of its grazing test function (test_functions.hpp).
      if (contains(mode.held, static_cast<int>(j))) continue;
      SignChanges peaks(seg, ms + j, 1.0, resolution, solver_.interrupt);
      // Not a peak: a rounding sign change at the start of a flight from the stop (transition.hpp).
      const double g_start = seg.value(j, 0.0);
      const double size = std::max({std::abs(g_start), std::abs(seg.value(j, 0.5 * tau)), std::abs(seg.value(j, tau))});
      for (double s : peaks.in(0.0, tau)) {
        const double g = seg.value(j, s);
        if (detail::flight_start_artifact(s, tau, g, g_start, size)) continue;
        out_.gap_peaks.push_back({static_cast<int>(j), tb + s, g});
      }
    }
    const Index h = static_cast<Index>(mode.held.size());
    for (Index a = 0; a < h; ++a) {
      SignChanges dips(seg, 2 * ms + h + a, -1.0, resolution, solver_.interrupt);
      for (double s : dips.in(0.0, tau))
        out_.force_dips.push_back({mode.held[static_cast<std::size_t>(a)], tb + s, seg.value(2 * ms + a, s), false});
    }
  }

  /// After a release, the held flow continued past it to its next interior force minimum.
  void past_release(const ContactSet& released) {
    if (!options_.features || released.empty() || !last_mode_ || options_.past_release_window <= 0.0) return;
    const Mode& mode = *last_mode_;
    if (nonlinear_) {  // the held flow continued by the Taylor steps: its first minimum after te_
      const double omega = mech_.frequency();
      const double T = omega > 0.0 ? 2.0 * std::numbers::pi / omega : 1.0;
      const std::vector<ForceDip> dips = nonlinear_->force_minima(mode.set, last_tb_, last_zb_.head(n_),
                                                                  last_zb_.segment(n_, n_),
                                                                  te_ + options_.past_release_window * T);
      for (int j : released)
        for (const ForceDip& d : dips)
          if (d.stop == j && d.t > te_) {
            out_.force_dips.push_back({j, d.t, d.value, true});
            break;
          }
      return;
    }
    const Segment seg(*mode.rows, last_tb_, last_zb_);
    const Index ms = static_cast<Index>(system_.stop_count());
    const Index h = static_cast<Index>(mode.held.size());
    const double omega = mech_.frequency();
    const double T = omega > 0.0 ? 2.0 * std::numbers::pi / omega : 1.0;
    const double from = te_ - last_tb_, to = from + options_.past_release_window * T;
    const double resolution = 16.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(te_ + to), 1.0);
    for (int j : released) {
      const auto it = std::lower_bound(mode.held.begin(), mode.held.end(), j);
      if (it == mode.held.end() || *it != j) continue;
      const Index a = it - mode.held.begin();
      SignChanges dips(seg, 2 * ms + h + a, -1.0, resolution, solver_.interrupt);
      const std::vector<double> found = dips.in(from, to);
      if (!found.empty())
        out_.force_dips.push_back({j, last_tb_ + found.front(), seg.value(2 * ms + a, found.front()), true});
    }
  }

  /// Tangent vectors are carried: the whole Jacobian, or the given directions.
  bool carries() const { return options_.jacobian || frame_; }

 public:
  /// The run's end was interrupted while J was formed (end()): the map has no J.
  bool cut_short() const { return cut_short_; }

 private:

  /// K ← Q for the Householder QR K = Q R of the carried directions, log|R_ii| added to
  /// *log_growth_ (orthonormal_frame.hpp). A direction the event annihilated (sticking) has
  /// R_ii = 0: its log growth is −∞ from then on.
  void orthonormalise() {
    const Eigen::HouseholderQR<MatrixXd> qr(K_);
    const Index p = K_.cols();
    for (Index i = 0; i < p; ++i) (*log_growth_)(i) += std::log(std::abs(qr.matrixQR()(i, i)));
    K_ = qr.householderQ() * MatrixXd::Identity(K_.rows(), p);
  }

  const ImpactSystem& system_;
  SimulatorOptions solver_;
  const LinearisationOptions& options_;
  TangentMap& out_;
  detail::NonlinearPart* nonlinear_;
  Index n_;
  Mechanics<double> mech_;
  Mechanics<Dual> mech0_;
  bool frame_;
  std::unique_ptr<Mechanics<Dual>> mechp_;
  std::map<ContactSet, std::unique_ptr<Mode>> modes_;

  double t0_ = 0.0, te_ = 0.0;
  bool first_ = true, pending_ = false;
  ContactSet held_, key_, engaged_;
  VectorXd xe_, ve_;
  std::vector<Event> events_;
  MatrixXd K_, Jmid_, basis_;
  VectorXd* log_growth_ = nullptr;  ///< re-orthonormalise the frame at events, logs here
  Index min_dim_ = 0;
  VectorXd zeta_;
  double least_rate_ = 0.0;
  const Mode* last_mode_ = nullptr;
  double last_tb_ = 0.0;
  VectorXd last_zb_;
  detail::PhaseBook phases_;
  bool cut_short_ = false;
};

/// A run whose recorder was cut short (TangentRecorder::cut_short) is reported as interrupted.
void note_cut_short(const TangentRecorder& recorder, RunSummary& summary) {
  if (!recorder.cut_short() || summary.status != RunStatus::completed) return;
  summary.status = RunStatus::interrupted;
  summary.message = "interrupted at t = " + number_text(summary.t) + " while the tangent map was formed";
}

}  // namespace

TangentMap linearise(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                     const VectorXd& x0, const VectorXd& v0, double t1, const LinearisationOptions& options) {
  if (options.parameter) options.parameter->validate(system.dof(), system.stop_count());
  if (options.directions.size() > 0 && options.directions.rows() != 2 * system.dof())
    throw InvalidInput("linearisation: directions have " + std::to_string(options.directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * system.dof()));
  TangentMap out;
  out.t0 = t0;
  out.x0 = x0;
  out.v0 = v0;
  Simulator sim(system, solver);
  TangentRecorder recorder(system, solver, options, out);
  out.summary = sim.run(t0, x0, v0, t1, {&recorder});
  note_cut_short(recorder, out.summary);
  if (out.summary.velocity_scale > 0.0) out.least_guard_rate /= out.summary.velocity_scale;
  return out;
}

namespace detail {

CarriedFrame carry_orthonormal_frame(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                                     const VectorXd& x0, const VectorXd& v0, double t1,
                                     const Eigen::MatrixXd& directions) {
  if (directions.rows() != 2 * system.dof() || directions.cols() == 0)
    throw InvalidInput("linearisation: directions have " + std::to_string(directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * system.dof()));
  LinearisationOptions options;
  options.jacobian = false;
  options.directions = directions;
  CarriedFrame frame;
  TangentMap& out = frame.map;
  out.t0 = t0;
  out.x0 = x0;
  out.v0 = v0;
  Simulator sim(system, solver);
  TangentRecorder recorder(system, solver, options, out);
  recorder.orthonormalise_into(&frame.log_growth);
  out.summary = sim.run(t0, x0, v0, t1, {&recorder});
  if (out.summary.velocity_scale > 0.0) out.least_guard_rate /= out.summary.velocity_scale;
  return frame;
}

TangentMap linearise_nonlinear(const ImpactSystem& system, const SimulatorOptions& solver, NonlinearPart& part,
                               const ObservedRun& run, double t0, const VectorXd& x0, const VectorXd& v0,
                               const LinearisationOptions& options, VectorXd* log_growth) {
  if (options.directions.size() > 0 && options.directions.rows() != 2 * system.dof())
    throw InvalidInput("linearisation: directions have " + std::to_string(options.directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * system.dof()));
  TangentMap out;
  out.t0 = t0;
  out.x0 = x0;
  out.v0 = v0;
  TangentRecorder recorder(system, solver, options, out, &part);
  if (log_growth) recorder.orthonormalise_into(log_growth);
  out.summary = run({&recorder});
  if (out.summary.velocity_scale > 0.0) out.least_guard_rate /= out.summary.velocity_scale;
  return out;
}

}  // namespace detail

}  // namespace vibro
