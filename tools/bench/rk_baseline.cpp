#include "rk_baseline.hpp"

#include <boost/numeric/odeint.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>

namespace vibro::bench {
namespace odeint = boost::numeric::odeint;
using State = std::vector<double>;

const char* to_string(RkMethod m) {
  switch (m) {
    case RkMethod::dopri5: return "dopri5";
    case RkMethod::fehlberg78: return "rkf78";
  }
  return "?";
}

namespace {

bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

ContactSet merge(const ContactSet& a, const ContactSet& b) {
  ContactSet out;
  std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
  return out;
}

/// What the right-hand side needs for one contact set S.
struct ModeData {
  ContactSet set;
  Eigen::MatrixXd B;          ///< M⁻¹ W_S G_S⁻¹ (n × m)
  Eigen::MatrixXd Ginv;       ///< G_S⁻¹
  Eigen::MatrixXd Wt;         ///< W_Sᵀ (m × n)
  Eigen::VectorXd s_cos, s_sin;  ///< moving-stop coefficients of the stops in S
};

/// The equations of motion, allocation-free (scratch vectors sized once).
struct Dynamics {
  Eigen::Index n = 0;
  Eigen::MatrixXd MinvK, MinvC;
  Eigen::VectorXd f0, fc, fs;  ///< M⁻¹ F0, M⁻¹ Fc, M⁻¹ Fs
  double omega = 0.0;
  const ModeData* mode = nullptr;
  mutable Eigen::VectorXd a_free, q, lambda;
  mutable long evaluations = 0;

  /// Free acceleration M⁻¹(f - C v - K x) into a_free.
  void free_acceleration(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                         const Eigen::Ref<const Eigen::VectorXd>& v) const {
    const double c = std::cos(omega * t), s = std::sin(omega * t);
    a_free.noalias() = f0 + c * fc + s * fs;
    a_free.noalias() -= MinvK * x;
    a_free.noalias() -= MinvC * v;
  }
  /// Contact forces λ of the held stops (after free_acceleration).
  void forces(double t) const {
    const ModeData& md = *mode;
    const double c = std::cos(omega * t), s = std::sin(omega * t);
    q.noalias() = md.Wt * a_free;
    q += omega * omega * (md.s_cos * c + md.s_sin * s);  // - s''
    lambda.noalias() = md.Ginv * q;
  }
  void operator()(const State& z, State& dz, double t) const {
    ++evaluations;
    const Eigen::Map<const Eigen::VectorXd> x(z.data(), n), v(z.data() + n, n);
    Eigen::Map<Eigen::VectorXd> dx(dz.data(), n), dv(dz.data() + n, n);
    free_acceleration(t, x, v);
    dx = v;
    if (mode->set.empty()) {
      dv = a_free;
    } else {
      const ModeData& md = *mode;
      const double c = std::cos(omega * t), s = std::sin(omega * t);
      q.noalias() = md.Wt * a_free;
      q += omega * omega * (md.s_cos * c + md.s_sin * s);
      dv = a_free;
      dv.noalias() -= md.B * q;
    }
  }
};

/// odeint takes systems by value: a pointer-sized handle.
struct Rhs {
  const Dynamics* d;
  void operator()(const State& z, State& dz, double t) const { (*d)(z, dz, t); }
};

/// Common interface of the two steppers: one accepted step [t0, t1] at a time, and states
/// anywhere inside it.
class Stepper {
 public:
  virtual ~Stepper() = default;
  virtual void init(double t, const State& z, double dt) = 0;
  /// One accepted step, not beyond t_limit for steppers that can honour it. False if the step
  /// size underflows.
  virtual bool step(double t_limit) = 0;
  virtual double t0() const = 0;
  virtual double t1() const = 0;
  virtual const State& z1() const = 0;
  virtual void state_at(double t, State& out) = 0;
  virtual double dt() const = 0;
};

class Dopri5 : public Stepper {
 public:
  using Dense = odeint::result_of::make_dense_output<odeint::runge_kutta_dopri5<State>>::type;
  Dopri5(const Dynamics& d, double atol, double rtol)
      : rhs_{&d}, dense_(odeint::make_dense_output(atol, rtol, odeint::runge_kutta_dopri5<State>())) {}
  void init(double t, const State& z, double dt) override {
    dense_.initialize(z, t, dt);
    t0_ = t1_ = t;
  }
  bool step(double) override {
    const auto iv = dense_.do_step(rhs_);
    t0_ = iv.first;
    t1_ = iv.second;
    return t1_ > t0_;
  }
  double t0() const override { return t0_; }
  double t1() const override { return t1_; }
  const State& z1() const override { return dense_.current_state(); }
  void state_at(double t, State& out) override {
    if (t == t1_) out = dense_.current_state();
    else dense_.calc_state(t, out);
  }
  double dt() const override { return dense_.current_time_step(); }

 private:
  Rhs rhs_;
  Dense dense_;
  double t0_ = 0.0, t1_ = 0.0;
};

class Fehlberg78 : public Stepper {
 public:
  using Controlled = odeint::result_of::make_controlled<odeint::runge_kutta_fehlberg78<State>>::type;
  Fehlberg78(const Dynamics& d, double atol, double rtol)
      : rhs_{&d}, controlled_(odeint::make_controlled(atol, rtol, odeint::runge_kutta_fehlberg78<State>())) {}
  void init(double t, const State& z, double dt) override {
    z0_ = z;
    z1_ = z;
    t0_ = t1_ = t;
    dt_ = dt;
  }
  bool step(double t_limit) override {
    z0_ = z1_;
    t0_ = t1_;
    double t = t0_;
    for (int tries = 0; tries < 500; ++tries) {
      double dt = std::min(dt_, t_limit - t0_);
      const double dt_taken = dt;
      t = t0_;
      if (controlled_.try_step(rhs_, z0_, t, z1_, dt) == odeint::success) {
        t1_ = t0_ + dt_taken;
        // Keep the controller's proposal unless the step was only cut short by t_limit.
        dt_ = dt_taken < dt_ ? std::max(dt_, dt) : dt;
        return t1_ > t0_;
      }
      dt_ = dt;
      ++rejected;
    }
    return false;
  }
  double t0() const override { return t0_; }
  double t1() const override { return t1_; }
  const State& z1() const override { return z1_; }
  void state_at(double t, State& out) override {
    if (t == t1_) out = z1_;
    else if (t == t0_) out = z0_;
    else explicit_.do_step(rhs_, z0_, t0_, out, t - t0_);
  }
  double dt() const override { return dt_; }
  long rejected = 0;

 private:
  Rhs rhs_;
  Controlled controlled_;
  odeint::runge_kutta_fehlberg78<State> explicit_;
  State z0_, z1_;
  double t0_ = 0.0, t1_ = 0.0, dt_ = 0.0;
};

/// Brent's zeroin (Brent 1973, ch. 4) for f(a) ≤ 0 < f(b); stops at |b - a| ≤ tol.
template <class F>
double brent(F&& f, double a, double b, double fa, double fb, double tol) {
  double c = a, fc = fa, d = b - a, e = d;
  for (int it = 0; it < 200; ++it) {
    if ((fb > 0.0) == (fc > 0.0)) {
      c = a;
      fc = fa;
      d = e = b - a;
    }
    if (std::abs(fc) < std::abs(fb)) {
      a = b; b = c; c = a;
      fa = fb; fb = fc; fc = fa;
    }
    const double m = 0.5 * (c - b);
    if (std::abs(m) <= tol || fb == 0.0) return b;
    if (std::abs(e) >= tol && std::abs(fa) > std::abs(fb)) {
      double p, q, r;
      const double s = fb / fa;
      if (a == c) {
        p = 2.0 * m * s;
        q = 1.0 - s;
      } else {
        q = fa / fc;
        r = fb / fc;
        p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0));
        q = (q - 1.0) * (r - 1.0) * (s - 1.0);
      }
      if (p > 0.0) q = -q;
      else p = -p;
      if (2.0 * p < std::min(3.0 * m * q - std::abs(tol * q), std::abs(e * q))) {
        e = d;
        d = p / q;
      } else {
        d = m;
        e = m;
      }
    } else {
      d = m;
      e = m;
    }
    a = b;
    fa = fb;
    b += std::abs(d) > tol ? d : (m > 0.0 ? tol : -tol);
    fb = f(b);
  }
  return b;
}

}  // namespace

struct RkBaseline::Impl {
  const ImpactSystem& scene;
  const RkOptions& opt;
  Eigen::Index n;
  int stops;
  Dynamics dyn;
  ContactModes modes;
  std::map<ContactSet, ModeData> mode_data;
  Eigen::LLT<Eigen::MatrixXd> mass_llt;
  double eps_gap, eps_force, h_chatter, v_contact, dt_simultaneous;

  // Run state.
  double t = 0.0;
  Eigen::VectorXd x, v;
  ContactSet stuck;
  RkResult* out = nullptr;

  Impl(const ImpactSystem& s, const RkOptions& o)
      : scene(s), opt(o), n(s.dof()), stops(static_cast<int>(s.stop_count())), modes(s),
        mass_llt(s.system().mass()) {
    const LinearSystem& sys = s.system();
    dyn.n = n;
    dyn.MinvK = mass_llt.solve(sys.stiffness());
    dyn.MinvC = mass_llt.solve(sys.damping());
    dyn.f0 = mass_llt.solve(sys.forcing().constant);
    dyn.fc = mass_llt.solve(sys.forcing().cosine);
    dyn.fs = mass_llt.solve(sys.forcing().sine);
    dyn.omega = sys.forcing().frequency;
    dyn.a_free.resize(n);
    eps_gap = opt.trigger * opt.length_scale;
    eps_force = opt.trigger * opt.force_scale;
    h_chatter = opt.chatter_height * opt.length_scale;
    v_contact = opt.contact_velocity * opt.velocity_scale;
    dt_simultaneous = opt.simultaneity * opt.time_scale;
  }

  const ModeData& data(const ContactSet& set) {
    auto it = mode_data.find(set);
    if (it != mode_data.end()) return it->second;
    ModeData md;
    md.set = set;
    const auto m = static_cast<Eigen::Index>(set.size());
    md.Wt.resize(m, n);
    md.s_cos.resize(m);
    md.s_sin.resize(m);
    if (m > 0) {
      const ContactMode& mode = modes.get(set);
      md.Ginv = mode.delassus().inverse();
      md.B = mode.mass_inverse_normals() * md.Ginv;
      for (Eigen::Index a = 0; a < m; ++a) {
        const Stop& st = scene.stops()[static_cast<std::size_t>(set[static_cast<std::size_t>(a)])];
        md.Wt.row(a) = scene.normals().col(set[static_cast<std::size_t>(a)]).transpose();
        md.s_cos(a) = st.s_cos();
        md.s_sin(a) = st.s_sin();
      }
    }
    return mode_data.emplace(set, std::move(md)).first->second;
  }

  bool contains_stuck(int j) const { return contains(stuck, j); }

  void set_mode() {
    dyn.mode = &data(stuck);
    const auto m = static_cast<Eigen::Index>(stuck.size());
    dyn.q.resize(m);
    dyn.lambda.resize(m);
  }

  double s_rate(int j, double time) const {
    const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
    const double w = dyn.omega;
    return w * (-st.s_cos() * std::sin(w * time) + st.s_sin() * std::cos(w * time));
  }

  /// Guard of stop j at (time, z): gap if free, -λ if held (needs the current mode).
  double guard(int j, double time, const State& z) const {
    const Eigen::Map<const Eigen::VectorXd> xs(z.data(), n), vs(z.data() + n, n);
    if (!contains(stuck, j)) return scene.normals().col(j).dot(xs) - scene.stops()[static_cast<std::size_t>(j)].s0() -
                                       scene.stops()[static_cast<std::size_t>(j)].s_cos() * std::cos(dyn.omega * time) -
                                       scene.stops()[static_cast<std::size_t>(j)].s_sin() * std::sin(dyn.omega * time);
    dyn.free_acceleration(time, xs, vs);
    dyn.forces(time);
    const auto a = std::lower_bound(stuck.begin(), stuck.end(), j) - stuck.begin();
    return -dyn.lambda(a);
  }

  /// Time derivative of that guard.
  double guard_rate(int j, double time, const State& z) const {
    const Eigen::Map<const Eigen::VectorXd> xs(z.data(), n), vs(z.data() + n, n);
    if (!contains(stuck, j)) return scene.normals().col(j).dot(vs) - s_rate(j, time);
    // λ' = G⁻¹ (Wᵀ a_free' - s'''),  a_free' = M⁻¹ f'(t) - M⁻¹C a - M⁻¹K v.
    State dz(z.size());
    dyn(z, dz, time);
    const Eigen::Map<const Eigen::VectorXd> acc(dz.data() + n, n);
    const double w = dyn.omega, c = std::cos(w * time), s = std::sin(w * time);
    const Eigen::VectorXd da = w * (-s * dyn.fc + c * dyn.fs) - dyn.MinvC * acc - dyn.MinvK * vs;
    const ModeData& md = *dyn.mode;
    const Eigen::VectorXd s3 = w * w * w * (md.s_cos * s - md.s_sin * c);
    const Eigen::VectorXd dl = md.Ginv * (md.Wt * da - s3);
    const auto a = std::lower_bound(stuck.begin(), stuck.end(), j) - stuck.begin();
    return -dl(a);
  }

  ContactSet settle(const ContactSet& candidates, Eigen::VectorXd* forces) const {
    if (candidates.empty()) {
      if (forces) forces->resize(0);
      return {};
    }
    const LinearSystem& sys = scene.system();
    const double w = dyn.omega;
    const auto m = static_cast<Eigen::Index>(candidates.size());
    const Eigen::VectorXd acc = mass_llt.solve(sys.forcing().at(t) - sys.damping() * v - sys.stiffness() * x);
    Eigen::VectorXd q(m);
    Eigen::MatrixXd Wc(n, m);
    for (Eigen::Index a = 0; a < m; ++a) {
      const int j = candidates[static_cast<std::size_t>(a)];
      const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
      const double s_dd = -w * w * (st.s_cos() * std::cos(w * t) + st.s_sin() * std::sin(w * t));
      q(a) = scene.normals().col(j).dot(acc) - s_dd;
      Wc.col(a) = scene.normals().col(j);
    }
    const Eigen::MatrixXd G = Wc.transpose() * mass_llt.solve(Wc);
    const Eigen::VectorXd lambda = solve_lcp(G, q);
    ContactSet held;
    for (Eigen::Index a = 0; a < m; ++a)
      if (lambda(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
    if (forces) *forces = lambda;
    return held;
  }

  void emit(const Event& e) {
    out->events.push_back(e);
    if (e.kind == EventKind::impact) ++out->impacts;
  }

  /// The framework's event rules (simulator.hpp), applied at (t, x, v).
  void handle(const ContactSet& impacting, const ContactSet& releasing, const ContactSet& resting) {
    ContactSet candidates;
    std::set_difference(stuck.begin(), stuck.end(), releasing.begin(), releasing.end(),
                        std::back_inserter(candidates));
    candidates = merge(candidates, resting);
    ContactSet chatter;
    Eigen::VectorXd g_before;
    auto delassus_diagonal = [&](int j) {
      return scene.normals().col(j).dot(mass_llt.solve(scene.normals().col(j)));
    };
    if (!impacting.empty()) {
      g_before = scene.gap_rates(t, v);
      ContactSet slow;
      for (int j : impacting) {
        const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
        if (r > 0.0 && r < 1.0) slow.push_back(j);
      }
      if (!slow.empty()) {
        Eigen::VectorXd hold_force;
        const ContactSet test = merge(candidates, slow);
        const ContactSet held = settle(test, &hold_force);
        for (int j : slow) {
          if (!contains(held, j)) continue;
          const auto a_idx = std::lower_bound(test.begin(), test.end(), j) - test.begin();
          const double accel = delassus_diagonal(j) * hold_force(a_idx);
          const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
          const double u = g_before(j);
          if ((r * u) * (r * u) / (2.0 * accel) <= h_chatter) chatter.push_back(j);
        }
      }
      const ContactSet all = merge(stuck, impacting);
      const ContactMode& mode = modes.get(all);
      const auto m = static_cast<Eigen::Index>(all.size());
      Eigen::VectorXd q(m);
      for (Eigen::Index a = 0; a < m; ++a) {
        const int j = all[static_cast<std::size_t>(a)];
        const bool rest = contains(stuck, j) || contains(chatter, j);
        const double r = rest ? 0.0 : scene.stops()[static_cast<std::size_t>(j)].restitution;
        q(a) = (1.0 + r) * g_before(j);
      }
      const Eigen::VectorXd impulse = solve_lcp(mode.delassus(), q);
      v -= mode.mass_inverse_normals() * impulse;
      const Eigen::VectorXd g_now = scene.gaps(t, x);
      for (Eigen::Index a = 0; a < m; ++a) {
        const int j = all[static_cast<std::size_t>(a)];
        if (g_now(j) > 0.0) x -= mode.mass_inverse_normals().col(a) * (g_now(j) / mode.delassus()(a, a));
      }
      const Eigen::VectorXd g_after = scene.gap_rates(t, v);
      for (int j : impacting) emit({t, j, EventKind::impact, g_before(j), g_after(j), 0.0});
      for (int j : all)
        if (g_after(j) >= -v_contact && !contains(candidates, j)) candidates.push_back(j);
      std::sort(candidates.begin(), candidates.end());
    }
    Eigen::VectorXd forces;
    const ContactSet next = settle(candidates, &forces);
    if (!next.empty()) {
      // Held stops: gaps and normal rates exactly zero (projection along M⁻¹W).
      const ContactMode& mode = modes.get(next);
      const Eigen::VectorXd g = scene.gap_rates(t, v), p = scene.gaps(t, x);
      Eigen::VectorXd gn(static_cast<Eigen::Index>(next.size())), pn(gn.size());
      for (std::size_t a = 0; a < next.size(); ++a) {
        gn(static_cast<Eigen::Index>(a)) = g(next[a]);
        pn(static_cast<Eigen::Index>(a)) = p(next[a]);
      }
      const auto llt = mode.delassus().llt();
      v -= mode.mass_inverse_normals() * llt.solve(gn);
      x -= mode.mass_inverse_normals() * llt.solve(pn);
    }
    auto force_of = [&](int j) {
      for (std::size_t a = 0; a < candidates.size(); ++a)
        if (candidates[a] == j) return forces(static_cast<Eigen::Index>(a));
      return 0.0;
    };
    for (int j : next) {
      if (contains(stuck, j)) continue;
      if (contains(chatter, j)) {
        const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
        const double a = delassus_diagonal(j) * force_of(j);
        const double u = g_before(j);
        const double t_limit = a > 0.0 ? t + 2.0 * r * u / (a * (1.0 - r)) : t;
        emit({t_limit, j, EventKind::chatter_limit, r * u, 0.0, force_of(j)});
      } else {
        emit({t, j, EventKind::stick, g_before.size() ? g_before(j) : 0.0, 0.0, force_of(j)});
      }
    }
    const Eigen::VectorXd g_now = scene.gap_rates(t, v);
    for (int j : stuck)
      if (!contains(next, j)) emit({t, j, EventKind::release, 0.0, g_now(j), 0.0});
    stuck = next;
    set_mode();
  }
};

RkBaseline::RkBaseline(const ImpactSystem& scene, RkOptions options) : scene_(&scene), options_(options) {
  if (!(options_.rtol > 0.0) || !(options_.length_scale > 0.0) || !(options_.velocity_scale > 0.0) ||
      !(options_.force_scale > 0.0) || !(options_.time_scale > 0.0))
    throw InvalidInput("RkBaseline: rtol and the scales must be > 0");
}

RkResult RkBaseline::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                         const std::vector<double>& sample_times) {
  RkResult result;
  Impl im(*scene_, options_);
  im.out = &result;
  const Eigen::Index n = im.n;
  im.t = t0;
  im.x = x0;
  im.v = v0;
  im.set_mode();
  const double atol = options_.atol > 0.0 ? options_.atol
                                           : options_.rtol * std::min(options_.length_scale, options_.velocity_scale);
  std::unique_ptr<Stepper> stepper;
  Fehlberg78* rk78 = nullptr;
  if (options_.method == RkMethod::dopri5) {
    stepper = std::make_unique<Dopri5>(im.dyn, atol, options_.rtol);
  } else {
    auto p = std::make_unique<Fehlberg78>(im.dyn, atol, options_.rtol);
    rk78 = p.get();
    stepper = std::move(p);
  }
  std::size_t next_sample = 0;
  while (next_sample < sample_times.size() && sample_times[next_sample] < t0) ++next_sample;
  const auto wanted = static_cast<Eigen::Index>(
      std::upper_bound(sample_times.begin(), sample_times.end(), t_end) - sample_times.begin()) -
      static_cast<Eigen::Index>(next_sample);
  result.x.resize(n, std::max<Eigen::Index>(wanted, 0));
  result.v.resize(n, result.x.cols());
  Eigen::Index taken = 0;
  auto trim_samples = [&] {  // a run that stopped early took fewer
    result.x.conservativeResize(Eigen::NoChange, taken);
    result.v.conservativeResize(Eigen::NoChange, taken);
  };
  auto fail = [&](const std::string& why) {
    trim_samples();
    result.ok = false;
    result.message = why + " at t = " + number_text(im.t);
    result.rhs = im.dyn.evaluations;
    if (rk78) result.rejected = rk78->rejected;
    return result;
  };
  State z(static_cast<std::size_t>(2 * n)), zt(z.size());
  auto pack = [&] {
    Eigen::Map<Eigen::VectorXd>(z.data(), n) = im.x;
    Eigen::Map<Eigen::VectorXd>(z.data() + n, n) = im.v;
  };
  auto unpack = [&](const State& s) {
    im.x = Eigen::Map<const Eigen::VectorXd>(s.data(), n);
    im.v = Eigen::Map<const Eigen::VectorXd>(s.data() + n, n);
  };
  auto record_until = [&](double t_hi) {  // samples in (previous, t_hi] from the current step
    while (next_sample < sample_times.size() && sample_times[next_sample] <= t_hi && taken < result.x.cols()) {
      stepper->state_at(sample_times[next_sample], zt);
      result.x.col(taken) = Eigen::Map<const Eigen::VectorXd>(zt.data(), n);
      result.v.col(taken) = Eigen::Map<const Eigen::VectorXd>(zt.data() + n, n);
      ++taken;
      ++next_sample;
    }
  };
  // Event-rate guard, as the framework's (framework/src/event_rate.hpp): a ring left
  // uninitialised, each slot read only after it is written (zero-filling its 100 001 slots cost
  // 8 µs per run, 6 % of RK 4(5) on problem (c): a cost the framework does not pay).
  const std::size_t ring = static_cast<std::size_t>(options_.max_events) + 1;
  const auto recent = std::make_unique_for_overwrite<double[]>(ring);
  std::size_t head = 0, count = 0;
  auto too_many = [&](double time) {
    recent[head] = time;
    head = (head + 1) % ring;
    count = std::min(count + 1, ring);
    return count == ring && time - recent[head] < options_.time_scale;
  };
  // The step's end state and the root finder's state, allocated once (a pair of vectors per
  // step was the baseline's own overhead, not the method's).
  State zb_copy(z.size()), zs(z.size());

  try {
    {  // initial contacts
      const Eigen::VectorXd g = scene_->gaps(im.t, im.x), gd = scene_->gap_rates(im.t, im.v);
      ContactSet impacting, resting;
      for (int j = 0; j < im.stops; ++j) {
        if (g(j) < -im.eps_gap) continue;
        if (gd(j) > im.v_contact) impacting.push_back(j);
        else if (gd(j) >= -im.v_contact) resting.push_back(j);
      }
      im.handle(impacting, {}, resting);
    }
    pack();
    double dt = 1e-3 * options_.time_scale;
    stepper->init(im.t, z, dt);
    Eigen::VectorXd triggers(im.stops);
    auto arm = [&] {  // trigger levels, re-armed above a guard that starts positive moving away
      for (int j = 0; j < im.stops; ++j) {
        triggers(j) = im.contains_stuck(j) ? im.eps_force : im.eps_gap;
        const double h0 = im.guard(j, im.t, z);
        if (h0 > 0.0 && im.guard_rate(j, im.t, z) <= 0.0) triggers(j) += h0;
      }
    };
    arm();
    const double resolution = 4.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end), options_.time_scale);
    while (im.t < t_end) {
      if (++result.steps > options_.max_steps) return fail("step budget exhausted");
      if (!stepper->step(t_end)) return fail("step size underflow");
      const double ta = stepper->t0();
      const double tb = std::min(stepper->t1(), t_end);
      const State* zb = &stepper->z1();
      if (tb < stepper->t1()) {
        stepper->state_at(tb, zt);
        zb = &zt;
      }
      for (double c : *zb)
        if (!std::isfinite(c)) return fail("non-finite state");
      zb_copy = *zb;  // same size: no allocation
      // Earliest guard crossing in (ta, tb].
      double best = std::numeric_limits<double>::infinity();
      int best_stop = -1;
      for (int j = 0; j < im.stops; ++j) {
        const double hb = im.guard(j, tb, zb_copy);
        if (!(hb > triggers(j))) continue;
        auto f = [&](double time) {
          stepper->state_at(time, zs);
          return im.guard(j, time, zs);
        };
        double a = ta, fa = f(ta);
        if (fa >= 0.0) {  // starts on or above zero (just after an event): find a point below
          bool found = false;
          for (int k = 1; k <= 60 && !found; ++k) {
            const double tk = ta + (tb - ta) * std::ldexp(1.0, -k);
            if (tk <= ta) break;
            const double fk = f(tk);
            if (fk < 0.0) {
              a = tk;
              fa = fk;
              found = true;
            }
          }
          if (!found) {  // positive throughout: the event is at the step start
            if (ta < best) {
              best = ta;
              best_stop = j;
            }
            continue;
          }
        }
        const double root = brent(f, a, tb, fa, hb, resolution);
        if (root < best) {
          best = root;
          best_stop = j;
        }
      }
      if (best_stop < 0) {
        record_until(tb);
        im.t = tb;
        z = zb_copy;
        continue;
      }
      record_until(best);
      stepper->state_at(best, z);
      im.t = best;
      unpack(z);
      ContactSet impacting, releasing;
      for (int j = 0; j < im.stops; ++j) {
        const double h = im.guard(j, best, z), hd = im.guard_rate(j, best, z);
        const bool fired = j == best_stop || (hd > 0.0 && h >= -std::max(triggers(j), hd * im.dt_simultaneous));
        if (!fired) continue;
        (im.contains_stuck(j) ? releasing : impacting).push_back(j);
      }
      im.handle(impacting, releasing, {});
      if (too_many(im.t)) return fail("event cap: more than " + std::to_string(options_.max_events) + " events within T");
      pack();
      dt = std::max(stepper->dt(), 1e-12 * options_.time_scale);
      stepper->init(im.t, z, dt);
      arm();
    }
  } catch (const std::runtime_error& e) {
    return fail(e.what());
  }
  trim_samples();
  result.rhs = im.dyn.evaluations;
  if (rk78) result.rejected = rk78->rejected;
  return result;
}

}  // namespace vibro::bench
