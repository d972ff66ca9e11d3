#include "baseline_events.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vibro::bench {

BaselineAlgebra::BaselineAlgebra(const ImpactSystem& scene, ContactModes& modes)
    : scene_(scene), modes_(modes), omega_(scene.system().forcing().frequency) {
  // The dense engine's tables (framework/src/simulator.cpp, StopTables), from the same scene.
  const LinearSystem& sys = scene.system();
  const Eigen::Index n = scene.dof(), m = static_cast<Eigen::Index>(scene.stop_count());
  const Eigen::LLT<Eigen::MatrixXd> mass_llt(sys.mass());
  normals_ = scene.normals();
  minv_normals_ = m > 0 ? Eigen::MatrixXd(mass_llt.solve(normals_)) : Eigen::MatrixXd(n, 0);
  const Eigen::MatrixXd g = m > 0 ? Eigen::MatrixXd(normals_.transpose() * minv_normals_) : Eigen::MatrixXd(0, 0);
  delassus_ = 0.5 * (g + g.transpose());
  minv_damping_ = mass_llt.solve(sys.damping());
  damped_normals_ = m > 0 ? Eigen::MatrixXd(minv_damping_ * minv_normals_) : Eigen::MatrixXd(n, 0);
  stiff_normals_ = m > 0 ? Eigen::MatrixXd(mass_llt.solve(sys.stiffness() * minv_normals_)) : Eigen::MatrixXd(n, 0);
  s0_.resize(m);
  sc_.resize(m);
  ss_.resize(m);
  alpha_.resize(m);
  beta_.resize(m);
  for (Eigen::Index j = 0; j < m; ++j) {
    const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
    s0_(j) = st.s0();
    sc_(j) = st.s_cos();
    ss_(j) = st.s_sin();
    const auto q = minv_normals_.col(j);
    const double G = delassus_(j, j), qcq = q.dot(sys.damping() * q);
    alpha_(j) = -qcq / G;
    beta_(j) = (q.dot(sys.damping() * damped_normals_.col(j)) - q.dot(sys.stiffness() * q)) / G - (qcq / G) * (qcq / G);
  }
  residual_.resize(n);
  reduced_state_.resize(2 * n + 3);
  q_.resize(m);
  G_.resize(m, m);
  lcp_.reserve(m);
}

double BaselineAlgebra::gap(int j, double t, const Eigen::VectorXd& x) const {
  return normals_.col(j).dot(x) - (s0_(j) + sc_(j) * std::cos(omega_ * t) + ss_(j) * std::sin(omega_ * t));
}

void BaselineAlgebra::gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const {
  const double c = std::cos(omega_ * t), s = std::sin(omega_ * t);
  for (Eigen::Index j = 0; j < out.size(); ++j) out(j) = normals_.col(j).dot(v) - omega_ * (-sc_(j) * s + ss_(j) * c);
}

void BaselineAlgebra::settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                             const ContactSet& candidates, ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) {
  held.clear();
  if (candidates.empty()) return;
  const LinearSystem& sys = scene_.system();
  const HarmonicForcing& f = sys.forcing();
  const double c = std::cos(omega_ * t), s = std::sin(omega_ * t);
  residual_.noalias() = -sys.damping() * v;
  residual_.noalias() -= sys.stiffness() * x;
  residual_ += f.constant + f.cosine * c + f.sine * s;
  const auto k = static_cast<Eigen::Index>(candidates.size());
  auto q = q_.head(k);
  auto G = G_.topLeftCorner(k, k);
  delassus(candidates, G);
  for (Eigen::Index a = 0; a < k; ++a) {
    const int j = candidates[static_cast<std::size_t>(a)];
    const double s_dd = -omega_ * omega_ * (sc_(j) * c + ss_(j) * s);
    q(a) = minv_normals_.col(j).dot(residual_) - s_dd;
  }
  solve_lcp(G, q, forces, lcp_);
  for (Eigen::Index a = 0; a < k; ++a)
    if (forces(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
}

void BaselineAlgebra::delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const {
  for (std::size_t a = 0; a < set.size(); ++a)
    for (std::size_t b = 0; b < set.size(); ++b)
      G(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = delassus_(set[a], set[b]);
}

void BaselineAlgebra::apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                                    Eigen::VectorXd& v) const {
  for (std::size_t a = 0; a < set.size(); ++a) v -= minv_normals_.col(set[a]) * impulse(static_cast<Eigen::Index>(a));
}

void BaselineAlgebra::shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const {
  z -= minv_normals_.col(set[static_cast<std::size_t>(a)]) * s;
}

void BaselineAlgebra::force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x,
                                  const Eigen::VectorXd& v, double* slope, double* curvature) {
  // λ_j' and λ_j'' along the sticking flow of `held`, as the dense engine takes them: from the
  // contact mode's reduced flow (contact.hpp; the force rows differentiated exactly).
  const ContactMode& mode = modes_.get(held);
  const ContactMode::Reduced& red = mode.reduced();
  auto z = reduced_state_.head(red.flow->size());
  mode.reduce(t, x, v, z);
  const auto a_idx = std::lower_bound(held.begin(), held.end(), j) - held.begin();
  *slope = -red.watch->rows(1).row(red.gap_rows + a_idx).dot(z);
  *curvature = -red.watch->rows(2).row(red.gap_rows + a_idx).dot(z);
}

void BaselineAlgebra::damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) {
  e.noalias() = minv_damping_ * d;
  e -= stiff_normals_.col(j);
}

BaselineEvents::BaselineEvents(const ImpactSystem& scene, const BaselineRules& rules)
    : scene_(scene), rules_(rules), n_(scene.dof()), stops_(static_cast<int>(scene.stop_count())),
      omega_(scene.system().forcing().frequency), modes_(scene), algebra_(scene, modes_),
      mass_llt_(scene.system().mass()) {
  if (!(rules.length_scale > 0.0) || !(rules.velocity_scale > 0.0) || !(rules.force_scale > 0.0) ||
      !(rules.time_scale > 0.0) || !(rules.chatter_height >= 0.0) || rules.max_events < 1)
    throw InvalidInput("baseline: the scales must be > 0, chatter_height ≥ 0 and max_events ≥ 1");
  eps_gap_ = rules.trigger * rules.length_scale;
  eps_force_ = rules.trigger * rules.force_scale;
  dt_simultaneous_ = rules.simultaneity * rules.time_scale;
  event_rules_ = {0.0, rules.chatter_height * rules.length_scale, rules.contact_velocity * rules.velocity_scale,
                  rules.chatter_rule, rules.trigger * rules.time_scale};
  work_.reserve(stops_, n_);
  for (int j = 0; j < stops_; ++j) moving_.push_back(stop(j).s_cos() != 0.0 || stop(j).s_sin() != 0.0);
  const LinearSystem& sys = scene.system();
  minv_k_ = mass_llt_.solve(sys.stiffness());
  minv_c_ = mass_llt_.solve(sys.damping());
  minv_f0_ = mass_llt_.solve(sys.forcing().constant);
  minv_fc_ = mass_llt_.solve(sys.forcing().cosine);
  minv_fs_ = mass_llt_.solve(sys.forcing().sine);
  // Zeno guard ring, as the framework's (framework/src/event_rate.hpp): left uninitialised, each
  // slot read only after it is written.
  ring_ = static_cast<std::size_t>(rules.max_events) + 1;
  recent_ = std::make_unique_for_overwrite<double[]>(ring_);
}

const ModeTables& BaselineEvents::mode(const ContactSet& set) {
  auto it = tables_.find(set);
  if (it != tables_.end()) return it->second;
  ModeTables t;
  t.set = set;
  const auto m = static_cast<Eigen::Index>(set.size());
  t.K = minv_k_;
  t.C = minv_c_;
  t.f0 = minv_f0_;
  t.fc = minv_fc_;
  t.fs = minv_fs_;
  t.LK.resize(m, n_);
  t.LC.resize(m, n_);
  t.l0.resize(m);
  t.lc.resize(m);
  t.ls.resize(m);
  if (m > 0) {
    const ContactMode& cm = modes_.get(set);
    const Eigen::MatrixXd Ginv = cm.delassus().inverse();
    Eigen::MatrixXd Wt(m, n_);
    Eigen::VectorXd sc(m), ss(m);
    for (Eigen::Index a = 0; a < m; ++a) {
      const int j = set[static_cast<std::size_t>(a)];
      Wt.row(a) = scene_.normals().col(j).transpose();
      sc(a) = stop(j).s_cos();
      ss(a) = stop(j).s_sin();
    }
    const Eigen::MatrixXd GW = Ginv * Wt;
    const double w2 = omega_ * omega_;
    t.LK = GW * minv_k_;
    t.LC = GW * minv_c_;
    t.l0 = GW * minv_f0_;
    t.lc = GW * minv_fc_ + w2 * (Ginv * sc);
    t.ls = GW * minv_fs_ + w2 * (Ginv * ss);
    const Eigen::MatrixXd& B = cm.mass_inverse_normals();  // M⁻¹ W_S
    t.K -= B * t.LK;
    t.C -= B * t.LC;
    t.f0 -= B * t.l0;
    t.fc -= B * t.lc;
    t.fs -= B * t.ls;
  }
  return tables_.emplace(set, std::move(t)).first->second;
}

bool BaselineEvents::resolve(double t, Eigen::VectorXd& x, Eigen::VectorXd& v, ContactSet& stuck,
                             const ContactSet& impacting, const ContactSet& releasing, const ContactSet& resting,
                             std::vector<Event>& events, std::string* why) {
  const std::function<void(const Event&)> emit = [&events](const Event& e) { events.push_back(e); };
  return detail::resolve_event(algebra_, scene_.stops(), event_rules_, t, x, v, stuck, impacting, releasing, resting,
                               emit, summary_, why, work_);
}

bool BaselineEvents::too_many(double t) {
  recent_[head_] = t;
  head_ = (head_ + 1) % ring_;
  count_ = std::min(count_ + 1, ring_);
  return count_ == ring_ && t - recent_[head_] < rules_.time_scale;
}

}  // namespace vibro::bench
