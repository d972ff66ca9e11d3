/// The tangent map on the Taylor engine (linearisation.hpp, nonlinear forces): the engine's run
/// observed by linearisation.cpp's recorder, with nonlinear_part.hpp filled in from the Taylor
/// core's variational equations.
#include "nonlinear_part.hpp"
#include "orthonormal_frame.hpp"

#include "vibro/linearisation.hpp"
#include "vibro/taylor/guard_roots.hpp"
#include "vibro/taylor/harmonic_series.hpp"
#include "vibro/taylor/horner.hpp"
#include "vibro/taylor/taylor_step.hpp"
#include "vibro/taylor_simulator.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>

namespace vibro {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

/// A real number as expression text that reads back to the same double ("%.17g", parenthesised
/// so that a sign or an exponent composes).
std::string exact(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "(%.17g)", v);
  return buf;
}

/// `value` moved along the direction: "(value + s*dvalue)" (exactly `value` at s = 0), or the
/// plain number when it does not move.
std::string moving(double value, double dvalue, const std::string& s) {
  return dvalue == 0.0 ? exact(value) : "(" + exact(value) + " + " + s + "*" + exact(dvalue) + ")";
}

/// `text` with every identifier found in `with` replaced by its (parenthesised) value; numbers
/// (with their exponents) and the other identifiers are copied as they are.
std::string substitute(const std::string& text, const std::map<std::string, std::string>& with) {
  std::string out;
  std::size_t i = 0;
  auto alpha = [](char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; };
  auto digit = [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; };
  while (i < text.size()) {
    const char c = text[i];
    std::size_t j = i + 1;
    if (alpha(c)) {
      while (j < text.size() && (alpha(text[j]) || digit(text[j]))) ++j;
      const std::string id = text.substr(i, j - i);
      const auto it = with.find(id);
      out += it == with.end() ? id : "(" + it->second + ")";
    } else if (digit(c) || c == '.') {
      while (j < text.size() && (digit(text[j]) || text[j] == '.')) ++j;
      if (j < text.size() && (text[j] == 'e' || text[j] == 'E')) {
        std::size_t k = j + 1;
        if (k < text.size() && (text[k] == '+' || text[k] == '-')) ++k;
        if (k < text.size() && digit(text[k])) {
          j = k;
          while (j < text.size() && digit(text[j])) ++j;
        }
      }
      out += text.substr(i, j - i);
    } else {
      out += c;
    }
    i = j;
  }
  return out;
}

using taylor::harmonic_series;

/// A linear combination Σ c_i (text_i) as expression text ("" when every term vanishes).
std::string combination(const std::vector<std::pair<double, std::string>>& terms) {
  std::string out;
  for (const auto& [c, text] : terms) {
    if (c == 0.0 || text.empty()) continue;
    if (!out.empty()) out += " + ";
    out += exact(c) + "*(" + text + ")";
  }
  return out;
}

/// The nonlinear part from Taylor systems:
///  * `forces_`: M and the forces only (no C, K, drive): its rate's velocity part is M⁻¹F;
///  * per held set S (none: free flight; Flow), M, C, K, the forces and the drive written as
///    expressions of t, with S's constraint forces: with W the held normals, G = WᵀM⁻¹W and
///    r = f(t) − C v − K x + F the free force,
///
///        M x'' = Π r + W G⁻¹ s̈(t),   Π = I − W G⁻¹WᵀM⁻¹,
///        λ = G⁻¹WᵀM⁻¹ r − G⁻¹ s̈(t)   (one guard per held stop),
///
///    which is a = a_free − M⁻¹W λ with λ = G⁻¹(Wᵀa_free − s̈) (taylor_step.hpp, StepTerms),
///    written on the whole state space (C and K enter as ΠC, ΠK). Its variational steps give the
///    flow's tangent map and λ's gradient (the engine supplies the drive and s̈ as closed-form
///    series instead; both are the same functions, their coefficients agree to rounding);
///  * with a parameter derivative dD/dp, per held set, the same system with one more coordinate
///    s, s' = 0, s(t0) = 0, along which every moving datum is written as D + s dD/dp — Ω, the
///    drive's amplitudes, the stops' motion, the named parameters of the forces, C and K (as the
///    forces −s (dC v + dK x)). ∂z(t1)/∂s(t0) is then the parameter column of the variational
///    equations, ζ' = (∂f/∂z) ζ + ∂f/∂p, and ∂λ/∂s its force's, with no other machinery. A moving
///    M is refused (InvalidInput).
class TaylorPart final : public detail::NonlinearPart {
 public:
  TaylorPart(const ImpactSystem& scene, const NonlinearForces& forces, const SystemDerivative* d)
      : scene_(scene), n_(scene.dof()), tolerance_(forces.tolerance) {
    const LinearSystem& sys = scene.system();
    const HarmonicForcing& f = sys.forcing();
    taylor::TaylorSystemSpec spec;
    spec.mass = sys.mass();
    spec.frequency = f.frequency;
    spec.parameters = forces.parameters;
    spec.forces = forces.forces;
    forces_ = std::make_unique<taylor::TaylorSystem>(spec);
    rate_step_ = std::make_unique<taylor::TaylorStep>(*forces_, taylor::TaylorSettings{.tolerance = tolerance_});
    base_ = spec;
    driven_ = with_drive(forces.forces, sys, nullptr, "Omega", "");

    if (d) {
      if (d->mass.size() && !d->mass.isZero(0.0))
        throw InvalidInput("linearisation: the parameter moves the mass matrix; with nonlinear forces the "
                           "derivative follows Ω, the drive, C, K, the stops and the forces' parameters only");
      if (d->force_parameters.size() != 0 && d->force_parameters.size() != static_cast<Index>(forces.parameters.size()))
        throw InvalidInput("linearisation: the derivative has " + std::to_string(d->force_parameters.size()) +
                           " entries for the forces' parameters, the forces have " +
                           std::to_string(forces.parameters.size()));
      derivative_ = *d;
      const std::string s = "x" + std::to_string(n_);
      std::map<std::string, std::string> with;
      omega_ = d->frequency != 0.0 ? moving(f.frequency, d->frequency, s) : "Omega";
      if (d->frequency != 0.0) with["Omega"] = omega_;
      for (std::size_t j = 0; j < forces.parameters.size(); ++j) {
        const double dj = d->force_parameters.size() ? d->force_parameters(static_cast<Index>(j)) : 0.0;
        if (dj != 0.0) with[forces.parameters[j].first] = moving(forces.parameters[j].second, dj, s);
      }
      std::vector<std::string> user(static_cast<std::size_t>(n_));
      for (std::size_t i = 0; i < forces.forces.size(); ++i) user[i] = substitute(forces.forces[i], with);
      lifted_driven_ = with_drive(user, sys, &*derivative_, omega_, s);
    }
    z_.resize(2 * n_);
    out_.resize(2 * n_);
    end_.resize(2 * n_);
    lifted_z_.resize(2 * (n_ + 1));
    lifted_end_.resize(2 * (n_ + 1));
  }

  VectorXd acceleration(double t, const VectorXd& x, const VectorXd& v) override {
    z_ << x, v;
    const taylor::StepStatus s = rate_step_->rate(t, z_, out_);
    if (s != taylor::StepStatus::ok)
      throw InvalidInput("linearisation: the forces at t = " + number_text(t) + ": " + rate_step_->trouble());
    return out_.tail(n_);
  }

  MatrixXd transition(const ContactSet& key, double t0, const VectorXd& x, const VectorXd& v, double t1) override {
    Flow& flow = flow_for(key);
    MatrixXd phi;
    if (!flow.lifted) {
      z_ << x, v;
      check(taylor::advance(*flow.variational, t0, z_, t1, end_, &phi), *flow.variational, t0);
    } else {
      MatrixXd big;
      lift(x, v);
      check(taylor::advance(*flow.lifted, t0, lifted_z_, t1, lifted_end_, &big), *flow.lifted, t0);
      // rows and columns of (x, v) in the lifted state, then the column of s
      phi.resize(2 * n_, 2 * n_ + 1);
      for (Index i = 0; i < 2 * n_; ++i) {
        const Index r = i < n_ ? i : i + 1;
        for (Index k = 0; k < 2 * n_; ++k) phi(i, k) = big(r, k < n_ ? k : k + 1);
        phi(i, 2 * n_) = big(r, n_);
      }
    }
    if (!phi.allFinite())
      throw InvalidInput("linearisation: the tangent map over [" + number_text(t0) + ", " + number_text(t1) +
                         "] is not finite");
    return phi;
  }

  HeldForce held_force(const ContactSet& key, int a, double t, const VectorXd& x, const VectorXd& v) override {
    Flow& flow = flow_for(key);
    z_ << x, v;
    check(flow.variational->expand(t, z_), *flow.variational, t);
    HeldForce out;
    out.value = flow.variational->guard_coefficients(a)[0];
    out.gradient.resize(2 * n_);
    for (Index d = 0; d < 2 * n_; ++d) out.gradient(d) = flow.variational->guard_gradient(a, static_cast<int>(d));
    out.rate = flow.variational->guard_coefficients(a)[1];
    // ∂λ/∂t at fixed z: the rate along the held flow less ∂λ/∂z · ż (ż the held system's rate,
    // its state series' first coefficients).
    out.time = out.rate;
    for (Index d = 0; d < 2 * n_; ++d)
      out.time -= out.gradient(d) * flow.variational->state_coefficients(static_cast<int>(d))[1];
    if (flow.lifted) {
      lift(x, v);
      check(flow.lifted->expand(t, lifted_z_), *flow.lifted, t);
      out.dp = flow.lifted->guard_gradient(a, static_cast<int>(n_));
    }
    if (!std::isfinite(out.value) || !out.gradient.allFinite() || !std::isfinite(out.time) || !std::isfinite(out.rate) ||
        !std::isfinite(out.dp))
      throw InvalidInput("linearisation: the contact force of stop " + std::to_string(flow.held[static_cast<std::size_t>(a)]) +
                         " at t = " + number_text(t) + " has a derivative that is not finite");
    return out;
  }

  /// Interior local maxima of the gaps of `stops` over (t0, t1) of the flow of the mode `key`
  /// from (t0, x, v) (maxima(): the gaps' series from the steps' state and the stops' motion).
  std::vector<GapPeak> gap_peaks(const ContactSet& key, double t0, const VectorXd& x, const VectorXd& v, double t1,
                                 const std::vector<int>& stops) override {
    std::vector<GapPeak> out;
    if (stops.empty()) return out;
    const MatrixXd& W = scene_.normals();
    const double omega = scene_.system().forcing().frequency;
    taylor::TaylorStep& step = *flow_for(key).plain;
    const int p = step.order();
    const auto width = static_cast<std::size_t>(p) + 1;
    std::vector<double> cs(width + 1), sn(width + 1), hc(width), hs(width);
    double at_t = std::numeric_limits<double>::quiet_NaN();
    auto fill = [&](int row, double t, double* g) {
      if (t != at_t) {
        harmonic_series(omega, t, p, cs.data(), sn.data());
        at_t = t;
      }
      const int j = stops[static_cast<std::size_t>(row)];
      const Stop& st = scene_.stops()[static_cast<std::size_t>(j)];
      for (int k = 0; k <= p; ++k) {
        double sum = 0.0;
        for (Index l = 0; l < n_; ++l)
          if (W(l, j) != 0.0) sum += W(l, j) * step.state_coefficients(static_cast<int>(l))[k];
        const auto kk = static_cast<std::size_t>(k);
        g[kk] = sum - ((k == 0 ? st.s0() : 0.0) + st.s_cos() * cs[kk] + st.s_sin() * sn[kk]);
      }
      for (std::size_t q = 0; q < st.harmonics.size(); ++q) {  // the motion's harmonics of order ≥ 2
        harmonic_series(st.harmonics[q].rate(omega), t, p, hc.data(), hs.data());
        for (std::size_t k = 0; k < width; ++k) g[k] -= st.h_cos(q) * hc[k] + st.h_sin(q) * hs[k];
      }
    };
    maxima(step, t0, x, v, t1, static_cast<int>(stops.size()), fill,
           [&](int row, double t, double value) { out.push_back({stops[static_cast<std::size_t>(row)], t, value}); });
    return out;
  }

  /// The held stops' force minima: the maxima of −λ_a, λ_a's series the held system's guards.
  std::vector<ForceDip> force_minima(const ContactSet& key, double t0, const VectorXd& x, const VectorXd& v,
                                     double t1) override {
    std::vector<ForceDip> out;
    const Flow& flow = flow_for(key);
    const ContactSet& held = flow.held;
    if (held.empty()) return out;
    taylor::TaylorStep& step = *flow.plain;
    const auto width = static_cast<std::size_t>(step.order()) + 1;
    auto fill = [&](int row, double /*t*/, double* g) {
      const double* lambda = step.guard_coefficients(row);
      for (std::size_t k = 0; k < width; ++k) g[k] = -lambda[k];
    };
    maxima(step, t0, x, v, t1, static_cast<int>(held.size()), fill, [&](int row, double t, double value) {
      out.push_back({held[static_cast<std::size_t>(row)], t, -value, false});
    });
    return out;
  }

 private:
  /// The systems of one mode (Flow: none for free flight), built on first use: its held rigid
  /// stops and its engaged compliant ones.
  struct Flow {
    ContactSet held, engaged;
    std::unique_ptr<taylor::TaylorSystem> system, lifted_system;
    std::unique_ptr<taylor::TaylorStep> variational, plain, lifted;
  };

  Flow& flow_for(const ContactSet& key) {
    const auto it = flows_.find(key);
    if (it != flows_.end()) return *it->second;
    auto f = std::make_unique<Flow>();
    for (int j : key) (scene_.stops()[static_cast<std::size_t>(j)].is_compliant() ? f->engaged : f->held).push_back(j);
    const ContactSet& held = f->held;
    const LinearSystem& sys = scene_.system();
    const auto k = static_cast<Index>(held.size());
    MatrixXd W(n_, k);
    for (Index a = 0; a < k; ++a) W.col(a) = scene_.normals().col(held[static_cast<std::size_t>(a)]);
    MatrixXd Pi = MatrixXd::Identity(n_, n_), R(k, n_), Ginv(k, k), WG(n_, k);
    if (k > 0) {
      const Eigen::LLT<MatrixXd> mass(sys.mass());
      const MatrixXd minv_w = mass.solve(W);
      Ginv = (W.transpose() * minv_w).llt().solve(MatrixXd::Identity(k, k));
      R = Ginv * minv_w.transpose();  // G⁻¹WᵀM⁻¹ (M symmetric)
      Pi -= W * R;
      WG = W * Ginv;
    }
    const taylor::TaylorSettings plain{.tolerance = tolerance_};
    const taylor::TaylorSettings variational{.tolerance = tolerance_, .variational = true};
    taylor::TaylorSystemSpec spec = base_;
    spec.damping = Pi * sys.damping();
    spec.stiffness = Pi * sys.stiffness();
    constrained(spec, held, Pi, R, Ginv, WG, with_engaged(driven_, f->engaged, nullptr, "Omega", ""), nullptr, "Omega", "");
    f->system = std::make_unique<taylor::TaylorSystem>(spec);
    f->variational = std::make_unique<taylor::TaylorStep>(*f->system, variational);
    f->plain = std::make_unique<taylor::TaylorStep>(*f->system, plain);
    if (derivative_) {
      const Index m = n_ + 1;
      taylor::TaylorSystemSpec lifted = base_;
      lifted.mass = MatrixXd::Identity(m, m);
      lifted.mass.topLeftCorner(n_, n_) = sys.mass();
      lifted.damping = MatrixXd::Zero(m, m);
      lifted.damping.topLeftCorner(n_, n_) = spec.damping;
      lifted.stiffness = MatrixXd::Zero(m, m);
      lifted.stiffness.topLeftCorner(n_, n_) = spec.stiffness;
      const std::string s = "x" + std::to_string(n_);
      constrained(lifted, held, Pi, R, Ginv, WG, with_engaged(lifted_driven_, f->engaged, &*derivative_, omega_, s),
                  &*derivative_, omega_, s);
      lifted.forces.emplace_back();
      f->lifted_system = std::make_unique<taylor::TaylorSystem>(lifted);
      f->lifted = std::make_unique<taylor::TaylorStep>(*f->lifted_system, variational);
    }
    return *flows_.emplace(key, std::move(f)).first->second;
  }

  /// The held set's forces Π r + W G⁻¹ s̈ (n entries) and guards λ = G⁻¹WᵀM⁻¹ r − G⁻¹ s̈ of `spec`,
  /// r the free force: `driven` (the forces and the drive, along a derivative −s (dC v + dK x)
  /// too) minus C v + K x written out.
  void constrained(taylor::TaylorSystemSpec& spec, const ContactSet& held, const MatrixXd& Pi, const MatrixXd& R,
                   const MatrixXd& Ginv, const MatrixXd& WG, const std::vector<std::string>& driven,
                   const SystemDerivative* d, const std::string& omega, const std::string& s) const {
    const auto k = static_cast<Index>(held.size());
    if (k == 0) {
      spec.forces = driven;
      return;
    }
    std::vector<std::string> acc(static_cast<std::size_t>(k));
    for (Index a = 0; a < k; ++a) acc[static_cast<std::size_t>(a)] = stop_acceleration(held[static_cast<std::size_t>(a)], d, omega, s);
    const LinearSystem& sys = scene_.system();
    std::vector<std::string> free(static_cast<std::size_t>(n_));
    for (Index i = 0; i < n_; ++i) {
      std::vector<std::pair<double, std::string>> terms{{1.0, driven[static_cast<std::size_t>(i)]}};
      for (Index j = 0; j < n_; ++j) {
        terms.emplace_back(-sys.damping()(i, j), "v" + std::to_string(j));
        terms.emplace_back(-sys.stiffness()(i, j), "x" + std::to_string(j));
      }
      free[static_cast<std::size_t>(i)] = combination(terms);
    }
    spec.forces.assign(static_cast<std::size_t>(n_), "");
    for (Index i = 0; i < n_; ++i) {
      std::vector<std::pair<double, std::string>> terms;
      for (Index l = 0; l < n_; ++l) terms.emplace_back(Pi(i, l), driven[static_cast<std::size_t>(l)]);
      for (Index a = 0; a < k; ++a) terms.emplace_back(WG(i, a), acc[static_cast<std::size_t>(a)]);
      spec.forces[static_cast<std::size_t>(i)] = combination(terms);
    }
    spec.guards.clear();
    for (Index a = 0; a < k; ++a) {
      std::vector<std::pair<double, std::string>> terms;
      for (Index l = 0; l < n_; ++l) terms.emplace_back(R(a, l), free[static_cast<std::size_t>(l)]);
      for (Index b = 0; b < k; ++b) terms.emplace_back(-Ginv(a, b), acc[static_cast<std::size_t>(b)]);
      const std::string text = combination(terms);
      spec.guards.push_back(text.empty() ? "0" : text);
    }
  }

  /// Stop j's acceleration s̈_j(t) as an expression of t ("" for a fixed stop); along a
  /// derivative d (coordinate s) its amplitudes and Ω move.
  std::string stop_acceleration(int j, const SystemDerivative* d, const std::string& omega, const std::string& s) const {
    return stop_motion(j, d, omega, s, 2);
  }

  /// Stop j's position s_j(t) (order 0), rate s_j'(t) (1) or acceleration s̈_j(t) (2) as an
  /// expression of t ("" where it vanishes: a fixed stop's rate); along a derivative d
  /// (coordinate s) its offset, amplitudes and Ω move.
  std::string stop_motion(int j, const SystemDerivative* d, const std::string& omega, const std::string& s,
                          int order) const {
    const Stop& st = scene_.stops()[static_cast<std::size_t>(j)];
    const auto ju = static_cast<std::size_t>(j);
    const StopDerivative sd = d && ju < d->stops.size() ? d->stops[ju] : StopDerivative{};
    std::string out = order == 0 ? moving(st.s0(), sd.offset, s) : "";
    auto harmonic = [&](const std::string& rate, double c, double dc, double sn, double ds) {
      if (c == 0.0 && dc == 0.0 && sn == 0.0 && ds == 0.0) return;
      if (!out.empty()) out += " + ";
      const std::string cosine = moving(c, dc, s), sine = moving(sn, ds, s);
      const std::string cos_t = "cos(" + rate + "*t)", sin_t = "sin(" + rate + "*t)";
      if (order == 2) out += "-(" + rate + ")*(" + rate + ")*(" + cosine + "*" + cos_t + " + " + sine + "*" + sin_t + ")";
      else if (order == 1) out += "(" + rate + ")*(" + sine + "*" + cos_t + " - " + cosine + "*" + sin_t + ")";
      else out += cosine + "*" + cos_t + " + " + sine + "*" + sin_t;
    };
    harmonic("(" + omega + ")", st.s_cos(), sd.cosine, st.s_sin(), sd.sine);
    for (std::size_t q = 0; q < st.harmonics.size(); ++q) {
      auto at = [&](const std::vector<std::vector<double>>& v) {
        return d && ju < v.size() && q < v[ju].size() ? v[ju][q] : 0.0;
      };
      harmonic("(" + std::to_string(st.harmonics[q].order) + "*" + omega + ")", st.h_cos(q),
               d ? at(d->stop_harmonic_cosine) : 0.0, st.h_sin(q), d ? at(d->stop_harmonic_sine) : 0.0);
    }
    return out;
  }

  /// The forces of each coordinate `driven` with the engaged compliant stops' −w_j N_j added,
  /// N_j = k_s g_j + c_s g_j' + F_p (stops.hpp) written out in x, v and t (its law and the stop's
  /// motion moving along a derivative d, coordinate s); `driven` itself when none is engaged.
  std::vector<std::string> with_engaged(const std::vector<std::string>& driven, const ContactSet& engaged,
                                        const SystemDerivative* d, const std::string& omega,
                                        const std::string& s) const {
    if (engaged.empty()) return driven;
    const MatrixXd& W = scene_.normals();
    std::vector<std::string> force;
    for (int j : engaged) {
      const Stop& st = scene_.stops()[static_cast<std::size_t>(j)];
      const auto ju = static_cast<std::size_t>(j);
      const StopDerivative sd = d && ju < d->stops.size() ? d->stops[ju] : StopDerivative{};
      std::vector<std::pair<double, std::string>> gap, rate;
      for (Index l = 0; l < n_; ++l) {
        gap.emplace_back(W(l, j), "x" + std::to_string(l));
        rate.emplace_back(W(l, j), "v" + std::to_string(l));
      }
      gap.emplace_back(-1.0, stop_motion(j, d, omega, s, 0));
      rate.emplace_back(-1.0, stop_motion(j, d, omega, s, 1));
      force.push_back(moving(st.stiffness, sd.stiffness, s) + "*(" + combination(gap) + ") + " +
                      moving(st.damping, sd.damping, s) + "*(" + (combination(rate).empty() ? "0" : combination(rate)) +
                      ") + " + moving(st.preload, sd.preload, s));
    }
    std::vector<std::string> out(static_cast<std::size_t>(n_));
    for (Index i = 0; i < n_; ++i) {
      std::vector<std::pair<double, std::string>> terms{{1.0, driven[static_cast<std::size_t>(i)]}};
      for (std::size_t e = 0; e < engaged.size(); ++e) terms.emplace_back(-W(i, engaged[e]), force[e]);
      out[static_cast<std::size_t>(i)] = combination(terms);
    }
    return out;
  }

  /// lifted_z_ ← (x, 0, v, 0).
  void lift(const VectorXd& x, const VectorXd& v) {
    const Index m = n_ + 1;
    lifted_z_.setZero();
    lifted_z_.head(n_) = x;
    lifted_z_.segment(m, n_) = v;
  }

  /// The interior local maxima over (t0, t1) of `rows` series along the flow of `step` from
  /// (t0, x, v): per Taylor step, `fill(row, t, g)` writes a row's coefficients at the step's
  /// start t, and the roots where g' falls through zero are isolated by the certified root
  /// search (guard_roots.hpp; the bound is the polynomial's evaluation rounding plus the step's
  /// remainder), alternating with the minima so that it moves from extremum to extremum, as the
  /// engine finds a held stop's force minima. `found(row, t, g(t))` for each.
  template <class Fill, class Found>
  void maxima(taylor::TaylorStep& step, double t0, const VectorXd& x, const VectorXd& v, double t1, int rows,
              Fill fill, Found found) {
    if (rows == 0 || !(t1 > t0)) return;
    const int p = step.order();
    const auto width = static_cast<std::size_t>(p) + 1;
    std::vector<double> g(width + 1), dg(width), shifted(width);
    taylor::GuardRootFinder finder(p);
    z_ << x, v;
    double t = t0, carry = 0.0;
    while (true) {
      const double remaining = (t1 - t) + carry;
      if (!(remaining > 0.0)) break;
      check(step.expand(t, z_), step, t);
      const double h = std::min(step.step_size(), remaining);
      for (int row = 0; row < rows; ++row) {
        fill(row, t, g.data());
        for (int k = 0; k < p; ++k) dg[static_cast<std::size_t>(k)] = (k + 1) * g[static_cast<std::size_t>(k) + 1];
        dg[static_cast<std::size_t>(p)] = 0.0;
        const double tail = step.remainder(dg.data(), h);
        double lo = 0.0;
        double sign = taylor::horner_compensated(dg.data(), p, 0.0) > 0.0 ? -1.0 : 1.0;  // a maximum first where g' > 0
        for (int guard = 0; guard < 4 * p && lo < h; ++guard) {
          for (std::size_t k = 0; k < width; ++k) shifted[k] = sign * dg[k];
          for (int i = 0; i < p; ++i)
            for (int k = p - 1; k >= i; --k) shifted[static_cast<std::size_t>(k)] += lo * shifted[static_cast<std::size_t>(k) + 1];
          double abs_sum = 0.0, power = 1.0;
          for (std::size_t k = 0; k < width; ++k, power *= h - lo) abs_sum += std::abs(shifted[k]) * power;
          const double delta = 8.0 * (p + 1) * std::numeric_limits<double>::epsilon() * abs_sum + tail;
          const taylor::GuardCrossing c = finder.first_crossing(shifted.data(), p, h - lo, 0.0, delta);
          if (c.kind == taylor::CrossingKind::none) break;
          const double at = lo + (c.kind == taylor::CrossingKind::crossing ? c.tau : c.upper);
          if (c.kind == taylor::CrossingKind::crossing && sign < 0.0 && at > 0.0 && at < h)
            found(row, t + at, taylor::horner_compensated(g.data(), p, at));
          if (c.kind == taylor::CrossingKind::crossing) sign = -sign;
          lo = std::max(at, lo) + 4.0 * std::numeric_limits<double>::epsilon() * std::max(h, 1.0);
        }
      }
      step.state(h, z_);
      const double y = h - carry;
      const double sum = t + y;
      carry = (sum - t) - y;
      t = sum;
    }
  }

  /// The forces of each coordinate with the drive f_i(t) added as expressions; along a
  /// derivative d (lifted system, coordinate s), every amplitude moves and C, K enter as forces.
  std::vector<std::string> with_drive(const std::vector<std::string>& user, const LinearSystem& sys,
                                      const SystemDerivative* d, const std::string& omega, const std::string& s) const {
    const HarmonicForcing& f = sys.forcing();
    std::vector<std::string> out(static_cast<std::size_t>(n_));
    for (Index i = 0; i < n_; ++i) {
      std::string text = static_cast<std::size_t>(i) < user.size() ? user[static_cast<std::size_t>(i)] : "";
      if (!text.empty()) text = "(" + text + ")";
      auto term = [&](double c, double dc, const std::string& factor) {
        if (c == 0.0 && dc == 0.0) return;
        if (!text.empty()) text += " + ";
        text += moving(c, dc, s) + factor;
      };
      auto at = [&](const Eigen::VectorXd& a) { return a.size() ? a(i) : 0.0; };
      auto dat = [&](const Eigen::VectorXd& a) { return d && a.size() ? a(i) : 0.0; };
      term(at(f.constant), d ? dat(d->constant) : 0.0, "");
      term(at(f.cosine), d ? dat(d->cosine) : 0.0, "*cos(" + omega + "*t)");
      term(at(f.sine), d ? dat(d->sine) : 0.0, "*sin(" + omega + "*t)");
      for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
        const ForcingHarmonic& fh = f.harmonics[h];
        const std::string arg = "(" + std::to_string(fh.order) + "*" + omega + "*t)";
        const double dc = d && h < d->harmonic_cosine.size() ? dat(d->harmonic_cosine[h]) : 0.0;
        const double ds = d && h < d->harmonic_sine.size() ? dat(d->harmonic_sine[h]) : 0.0;
        term(at(fh.cosine), dc, "*cos" + arg);
        term(at(fh.sine), ds, "*sin" + arg);
      }
      if (d) {  // −s (dC v + dK x)_i
        std::string lin;
        for (Index j = 0; j < n_; ++j) {
          const double dk = d->stiffness.size() ? d->stiffness(i, j) : 0.0;
          const double dcv = d->damping.size() ? d->damping(i, j) : 0.0;
          if (dk != 0.0) lin += (lin.empty() ? "" : " + ") + exact(dk) + "*x" + std::to_string(j);
          if (dcv != 0.0) lin += (lin.empty() ? "" : " + ") + exact(dcv) + "*v" + std::to_string(j);
        }
        if (!lin.empty()) text += (text.empty() ? "-" : " - ") + s + "*(" + lin + ")";
      }
      out[static_cast<std::size_t>(i)] = text;
    }
    return out;
  }

  static void check(taylor::StepStatus status, const taylor::TaylorStep& step, double t0) {
    if (status != taylor::StepStatus::ok)
      throw InvalidInput("linearisation: the Taylor steps from t = " + number_text(t0) + ": " + step.trouble());
  }

  const ImpactSystem& scene_;
  Index n_;
  double tolerance_;
  taylor::TaylorSystemSpec base_;  // M, Ω and the forces' parameters
  std::vector<std::string> driven_, lifted_driven_;
  std::optional<SystemDerivative> derivative_;
  std::string omega_ = "Omega";
  std::unique_ptr<taylor::TaylorSystem> forces_;
  std::unique_ptr<taylor::TaylorStep> rate_step_;
  std::map<ContactSet, std::unique_ptr<Flow>> flows_;
  VectorXd z_, out_, end_, lifted_z_, lifted_end_;
};

}  // namespace

TangentMap linearise(const ImpactSystem& system, const NonlinearForces& forces, const SimulatorOptions& solver,
                     double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                     const LinearisationOptions& options) {
  if (options.parameter) options.parameter->validate(system.dof(), system.stop_count());
  TaylorSimulator sim(system, forces, solver);
  TaylorPart part(system, forces, options.parameter ? &*options.parameter : nullptr);
  return detail::linearise_nonlinear(
      system, solver, part, [&](const std::vector<Observer*>& observers) { return sim.run(t0, x0, v0, t1, observers); },
      t0, x0, v0, options);
}

namespace detail {

CarriedFrame carry_orthonormal_frame(const ImpactSystem& system, const NonlinearForces& forces,
                                     const SimulatorOptions& solver, double t0, const VectorXd& x0,
                                     const VectorXd& v0, double t1, const MatrixXd& directions) {
  if (directions.rows() != 2 * system.dof() || directions.cols() == 0)
    throw InvalidInput("linearisation: directions have " + std::to_string(directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * system.dof()));
  LinearisationOptions options;
  options.jacobian = false;
  options.directions = directions;
  TaylorSimulator sim(system, forces, solver);
  TaylorPart part(system, forces, nullptr);
  CarriedFrame frame;
  frame.map = linearise_nonlinear(
      system, solver, part, [&](const std::vector<Observer*>& observers) { return sim.run(t0, x0, v0, t1, observers); },
      t0, x0, v0, options, &frame.log_growth);
  return frame;
}

}  // namespace detail

}  // namespace vibro
