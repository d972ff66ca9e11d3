#pragma once
/// \file baseline_events.hpp
/// What the benchmark's conventional integrators (rk_baseline.hpp, sundials_peer.hpp) share:
/// the equations of motion in each contact mode as fixed-size tables, the guards, and the
/// framework's own event resolution.
///
/// Event rules: the baselines call vibro::detail::resolve_event (framework/src/event_resolution.hpp,
/// linked from vibro_core), the function the framework's engines call, through an algebra of the
/// stops (BaselineAlgebra) computed from the same tables as the dense engine's: the same impact
/// law (impulse LCP over held ∪ impacting stops, Newton restitution per stop), the same chatter
/// test (a stop that would hold and whose next bounce would rise less than chatter_height·L),
/// the same chatter rule (third order by default, with its state correction), the same
/// acceleration LCP for the held set and the same residual-velocity removal. Only the time
/// integration between events and the location of the events are each integrator's own.
///
/// Motion in contact set S (stops held), index-reduced in full coordinates: with
///   a_free = M⁻¹ (F0 + F_c cos Ωt + F_s sin Ωt − C v − K x),
///   λ = G_S⁻¹ (W_Sᵀ a_free − s_S''(t)),   G_S = W_Sᵀ M⁻¹ W_S,   s'' = −Ω² (s_c cos Ωt + s_s sin Ωt),
///   x'' = a_free − M⁻¹ W_S λ,
/// both are affine in (x, v, cos Ωt, sin Ωt): per mode, once,
///   λ = l0 + l_c cos Ωt + l_s sin Ωt − L_K x − L_C v,
///   x'' = f0 + f_c cos Ωt + f_s sin Ωt − K_S x − C_S v,
/// so a right-hand side costs two n × n products and one cos and sin, held stops or not.
///
/// Guards (an event is a guard crossing its trigger level upwards): g_j = w_jᵀ x − s_j(t) for a
/// free stop (s_j evaluated only for a moving stop), −λ_j for a held one.
#include "vibro/contact.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"

#include "event_resolution.hpp"  // framework/src: the framework's event rules

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace vibro::bench {

/// The framework's rules and their defaults (fractions of L, V, T), shared by every baseline.
struct BaselineRules {
  double chatter_height = 1e-9;
  ChatterRule chatter_rule = ChatterRule::third_order;
  double contact_velocity = 1e-11;
  double simultaneity = 1e-12;
  double trigger = 1e-13;    ///< a guard must exceed this (× L or F) to fire
  long max_events = 100000;  ///< per time scale T, as the framework's Zeno guard
  /// Scales L, V, F, T (take them from the framework's RunSummary for the same start).
  double length_scale = 1.0, velocity_scale = 1.0, force_scale = 1.0, time_scale = 1.0;
};

/// Affine tables of one contact mode (dynamic sizes; the integrators copy them into fixed ones).
struct ModeTables {
  ContactSet set;
  Eigen::MatrixXd K, C;        ///< n × n
  Eigen::VectorXd f0, fc, fs;  ///< n
  Eigen::MatrixXd LK, LC;      ///< m × n (rows of the held stops, in the order of `set`)
  Eigen::VectorXd l0, lc, ls;  ///< m
};

/// The stops' algebra at an event for resolve_event (as the dense engine's, framework/src/simulator.cpp).
class BaselineAlgebra final : public detail::ContactAlgebra {
 public:
  BaselineAlgebra(const ImpactSystem& scene, ContactModes& modes);
  double gap(int j, double t, const Eigen::VectorXd& x) const override;
  void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const override;
  void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& candidates,
              ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) override;
  void delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const override;
  double delassus_diagonal(int j) const override { return delassus_(j, j); }
  void apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                     Eigen::VectorXd& v) const override;
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const override;
  bool accept(const ContactSet&, std::string*) override { return true; }
  double chatter_alpha(int j) const override { return alpha_(j); }
  double chatter_beta(int j) const override { return beta_(j); }
  void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                   double* slope, double* curvature) override;
  double normal_dot(int j, const Eigen::VectorXd& y) const override { return normals_.col(j).dot(y); }
  void damped_normal(int j, Eigen::VectorXd& d) override { d = damped_normals_.col(j); }
  void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) override;

 private:
  const ImpactSystem& scene_;
  ContactModes& modes_;
  double omega_;
  Eigen::MatrixXd normals_, minv_normals_, delassus_, damped_normals_, stiff_normals_, minv_damping_;
  Eigen::VectorXd s0_, sc_, ss_, alpha_, beta_, residual_, reduced_state_, q_;
  Eigen::MatrixXd G_;
  LcpWorkspace lcp_;
};

/// What every baseline keeps for a run: the scene's tables, the contact modes visited, the
/// framework's event resolution and the Zeno guard. Not templated: the integrators copy the
/// tables they need into fixed-size ones.
class BaselineEvents {
 public:
  BaselineEvents(const ImpactSystem& scene, const BaselineRules& rules);
  const ImpactSystem& scene() const { return scene_; }
  Eigen::Index dof() const { return n_; }
  int stops() const { return stops_; }
  double omega() const { return omega_; }
  bool moving(int j) const { return moving_[static_cast<std::size_t>(j)]; }
  const Stop& stop(int j) const { return scene_.stops()[static_cast<std::size_t>(j)]; }
  double eps_gap() const { return eps_gap_; }
  double eps_force() const { return eps_force_; }
  double dt_simultaneous() const { return dt_simultaneous_; }
  /// The tables of a contact set (built on first use, then cached).
  const ModeTables& mode(const ContactSet& set);
  /// The framework's event rules at (t, x, v) (resolve_event); events appended to `events`.
  /// `stuck` becomes the held set. Returns false, with the reason, if they fail.
  bool resolve(double t, Eigen::VectorXd& x, Eigen::VectorXd& v, ContactSet& stuck, const ContactSet& impacting,
               const ContactSet& releasing, const ContactSet& resting, std::vector<Event>& events, std::string* why);
  /// Counts an event at time t for the Zeno guard: true when more than max_events fell within T.
  bool too_many(double t);
  long impacts() const { return summary_.impacts; }

 private:
  const ImpactSystem& scene_;
  BaselineRules rules_;
  Eigen::Index n_;
  int stops_;
  double omega_, eps_gap_, eps_force_, dt_simultaneous_;
  std::vector<bool> moving_;
  ContactModes modes_;
  BaselineAlgebra algebra_;
  detail::EventRules event_rules_;
  detail::EventWorkspace work_;
  RunSummary summary_;
  Eigen::LLT<Eigen::MatrixXd> mass_llt_;
  Eigen::MatrixXd minv_k_, minv_c_;
  Eigen::VectorXd minv_f0_, minv_fc_, minv_fs_;
  std::map<ContactSet, ModeTables> tables_;
  std::unique_ptr<double[]> recent_;
  std::size_t ring_ = 0, head_ = 0, count_ = 0;
};

}  // namespace vibro::bench
