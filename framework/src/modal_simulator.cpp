// The modal chain engine: its stops, its cache of contact modes, its stops' algebra at events
// and its side of the event loop shared with the dense engine (event_loop.hpp). A contact set's
// modes and guards are built in modal_modes.cpp, searched by events.hpp's CrossingFinder on a
// ModalGuardSource (modal_guards.cpp), and shown to observers in modal_views.cpp.
#include "vibro/modal.hpp"

#include "vibro/contact.hpp"  // solve_lcp
#include "vibro/engine.hpp"   // modal_options

#include "event_loop.hpp"
#include "modal_internal.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>

namespace vibro {
using detail::Buffers;
using detail::Harmonic;
using detail::Normal;
using detail::build_mode;
using detail::delassus_entry;
using detail::normal_of;
using detail::seconds_since;
using detail::stiffness_times;
using detail::stop_motion;
using detail::to_modal;
using detail::to_physical;
using detail::value_at;

namespace {

/// The modal engine's side of event resolution (event_resolution.hpp), in physical coordinates:
/// sparse normals, diagonal M and tridiagonal K, so O(N) per event; contact sets through the
/// simulator's cache (`mode_of`, null with a reason when a set cannot be reduced).
class ChainAlgebra final : public detail::ContactAlgebra {
 public:
  using ModeOf = std::function<const ModalContactMode*(const ContactSet&, std::string*)>;
  ChainAlgebra(const BandedChain& chain, const std::vector<Stop>& stops, ModeOf mode_of, Buffers& buffers)
      : ch_(chain), stops_(stops), W_(chain.forcing.frequency), mode_of_(std::move(mode_of)), b_(buffers) {
    const auto m = static_cast<Eigen::Index>(stops.size());
    const Eigen::Index n = chain.dof();
    q_.resize(m);
    G_.resize(m, m);
    lcp_.reserve(m);
    G_diag_.resize(m);
    alpha_.resize(m);
    kx_.resize(n);
    kv_.resize(n);
    acc_.resize(n);
    for (Eigen::Index j = 0; j < m; ++j) {
      normal_.push_back(normal_of(stops[static_cast<std::size_t>(j)]));
      G_diag_(j) = delassus_entry(normal_.back(), normal_.back(), ch_.mass);
    }
    beta_.resize(m);
    for (Eigen::Index j = 0; j < m; ++j) {  // α_j, β_j (simulator.hpp, ChatterRule), C = αM + βK
      b_.z.setZero();
      add_minv_w(static_cast<int>(j), 1.0, b_.z);  // q = M⁻¹ w_j
      stiffness_times(ch_, b_.z, b_.kz);
      alpha_(j) = -(ch_.rayleigh_mass * G_diag_(j) + ch_.rayleigh_stiffness * b_.z.dot(b_.kz)) / G_diag_(j);
      // qᵀCq, qᵀ K q and qᵀ C M⁻¹ C q with M⁻¹ C q = α q + β M⁻¹ K q.
      const double G = G_diag_(j), qkq = b_.z.dot(b_.kz);
      const double qcq = ch_.rayleigh_mass * G + ch_.rayleigh_stiffness * qkq;
      kx_ = ch_.rayleigh_mass * b_.z + ch_.rayleigh_stiffness * b_.kz.cwiseQuotient(ch_.mass);  // d = M⁻¹ C q
      stiffness_times(ch_, kx_, kv_);
      const double qcd = ch_.rayleigh_mass * b_.z.dot(ch_.mass.cwiseProduct(kx_)) + ch_.rayleigh_stiffness * b_.z.dot(kv_);
      beta_(j) = (qcd - qkq) / G - (qcq / G) * (qcq / G);
    }
  }

  double gap(int j, double t, const Eigen::VectorXd& x) const override {
    return w_dot(j, x) - value_at(motion(j), W_, t) - higher(j, t, 0);
  }
  double gap_rate(int j, double t, const Eigen::VectorXd& v) const {
    return w_dot(j, v) - value_at(motion(j).derivative(W_), W_, t) - higher(j, t, 1);
  }
  void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const override {
    for (Eigen::Index j = 0; j < out.size(); ++j) out(j) = gap_rate(static_cast<int>(j), t, v);
  }
  /// The engaged compliant stops whose forces act alongside (nullptr or empty: none); the held
  /// rigid stops' contact sets are then keyed with them (mode_key).
  void set_engaged(const ContactSet* engaged) { engaged_ = engaged; }
  /// The contact set of the held rigid stops `held` with the engaged compliant ones (sorted union).
  const ContactSet& mode_key(const ContactSet& held) {
    if (!engaged_ || engaged_->empty()) return held;
    key_.clear();
    std::set_union(held.begin(), held.end(), engaged_->begin(), engaged_->end(), std::back_inserter(key_));
    return key_;
  }
  /// N = k_s g + c_s g' + F_p of compliant stop j at (t, x, v) (stops.hpp).
  double compliant_force(int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
    const Stop& s = stops_[static_cast<std::size_t>(j)];
    return s.stiffness * gap(j, t, x) + s.damping * gap_rate(j, t, v) + s.preload;
  }
  void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& candidates,
              ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) override {
    held.clear();
    if (candidates.empty()) return;
    // Free acceleration M⁻¹(f - C v - K x - Σ_engaged w N), C = αM + βK: O(n).
    stiffness_times(ch_, x, kx_);
    stiffness_times(ch_, v, kv_);
    const HarmonicForcing& f = ch_.forcing;
    const double c = std::cos(W_ * t), s = std::sin(W_ * t);
    acc_ = f.constant + f.cosine * c + f.sine * s - kx_ - ch_.rayleigh_stiffness * kv_;
    for (const ForcingHarmonic& h : f.harmonics) {
      const double r = h.rate(W_);
      acc_ += h.cosine * std::cos(r * t) + h.sine * std::sin(r * t);
    }
    if (engaged_)
      for (int j : *engaged_) add_w(j, -compliant_force(j, t, x, v), acc_);
    acc_.array() /= ch_.mass.array();
    acc_ -= ch_.rayleigh_mass * v;
    const auto k = static_cast<Eigen::Index>(candidates.size());
    auto q = q_.head(k);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = candidates[static_cast<std::size_t>(a)];
      q(a) = w_dot(j, acc_) - value_at(motion(j).derivative(W_).derivative(W_), W_, t) - higher(j, t, 2);
    }
    auto G = G_.topLeftCorner(k, k);
    delassus(candidates, G);
    solve_lcp(G, q, forces, lcp_);
    for (Eigen::Index a = 0; a < k; ++a)
      if (forces(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
  }
  void delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const override {
    const auto k = static_cast<Eigen::Index>(set.size());
    for (Eigen::Index a = 0; a < k; ++a)
      for (Eigen::Index b = 0; b < k; ++b)
        G(a, b) = delassus_entry(normal_[static_cast<std::size_t>(set[static_cast<std::size_t>(a)])],
                                 normal_[static_cast<std::size_t>(set[static_cast<std::size_t>(b)])], ch_.mass);
  }
  double delassus_diagonal(int j) const override { return G_diag_(j); }
  void apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                     Eigen::VectorXd& v) const override {
    for (std::size_t a = 0; a < set.size(); ++a) add_minv_w(set[a], -impulse(static_cast<Eigen::Index>(a)), v);
  }
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const override {
    add_minv_w(set[static_cast<std::size_t>(a)], -s, z);
  }
  bool accept(const ContactSet& held, std::string* why) override { return mode_of_(mode_key(held), why) != nullptr; }
  double chatter_alpha(int j) const override { return alpha_(j); }
  void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                   double* slope, double* curvature) override {
    std::string why;
    const ModalContactMode* mode = mode_of_(mode_key(held), &why);
    if (!mode) throw std::logic_error("force_rates: the held set was not accepted: " + why);
    auto u = b_.fu.head(mode->size()), ud = b_.fud.head(mode->size());
    to_modal(*mode, ch_.mass, W_, t, x, v, u, ud, b_);
    const auto a_idx = std::lower_bound(held.begin(), held.end(), j) - held.begin();
    double value;
    guard_at(*mode, W_, t, u, ud, 0.0, mode->gap_rows + a_idx, &value, slope, b_, curvature);
    *slope = -*slope;  // the guard is -λ
    *curvature = -*curvature;
  }
  double chatter_beta(int j) const override { return beta_(j); }
  double normal_dot(int j, const Eigen::VectorXd& y) const override { return w_dot(j, y); }
  // C = αM + βK: M⁻¹ C y = α y + β M⁻¹ K y, O(n).
  void damped_normal(int j, Eigen::VectorXd& d) override {
    b_.z.setZero();
    add_minv_w(j, 1.0, b_.z);
    stiffness_times(ch_, b_.z, b_.kz);
    d = ch_.rayleigh_mass * b_.z + ch_.rayleigh_stiffness * b_.kz.cwiseQuotient(ch_.mass);
  }
  void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) override {
    stiffness_times(ch_, d, kx_);  // M⁻¹ C d
    e = ch_.rayleigh_mass * d + ch_.rayleigh_stiffness * kx_.cwiseQuotient(ch_.mass);
    b_.z.setZero();  // − M⁻¹ K M⁻¹ w_j
    add_minv_w(j, 1.0, b_.z);
    stiffness_times(ch_, b_.z, b_.kz);
    e -= b_.kz.cwiseQuotient(ch_.mass);
  }

 private:
  // O(1) per stop on one mass or two, O(N) along a general normal.
  double w_dot(int j, const Eigen::VectorXd& z) const {
    const Normal& w = normal_[static_cast<std::size_t>(j)];
    if (w.general()) return w.dense.dot(z);
    return w.wi * z(w.i) + (w.k >= 0 ? w.wk * z(w.k) : 0.0);
  }
  void add_minv_w(int j, double scale, Eigen::VectorXd& z) const {  // z += scale M⁻¹ w_j
    const Normal& w = normal_[static_cast<std::size_t>(j)];
    if (w.general()) {
      z += scale * w.dense.cwiseQuotient(ch_.mass);
      return;
    }
    z(w.i) += scale * w.wi / ch_.mass(w.i);
    if (w.k >= 0) z(w.k) += scale * w.wk / ch_.mass(w.k);
  }
  void add_w(int j, double scale, Eigen::VectorXd& z) const {  // z += scale w_j
    const Normal& w = normal_[static_cast<std::size_t>(j)];
    if (w.general()) {
      z += scale * w.dense;
      return;
    }
    z(w.i) += scale * w.wi;
    if (w.k >= 0) z(w.k) += scale * w.wk;
  }
  Harmonic motion(int j) const { return stop_motion(stops_[static_cast<std::size_t>(j)]); }
  /// The stop's higher harmonics' part of s_j (derivative 0), s_j' (1) or s_j'' (2): 0 without them.
  double higher(int j, double t, int derivative) const {
    const Stop& s = stops_[static_cast<std::size_t>(j)];
    return s.has_higher_harmonics() ? stop_higher_motion(s, W_, t, derivative) : 0.0;
  }

  const BandedChain& ch_;
  const std::vector<Stop>& stops_;
  double W_;
  ModeOf mode_of_;
  Buffers& b_;
  std::vector<Normal> normal_;
  Eigen::VectorXd G_diag_, alpha_, beta_, kx_, kv_, acc_, q_;
  Eigen::MatrixXd G_;
  LcpWorkspace lcp_;
  const ContactSet* engaged_ = nullptr;
  ContactSet key_;
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Options, cache, construction

std::string compliant_refusal(const Stop& s, const BandedChain& chain) {
  if (!(s.stiffness > 0.0) || !std::isfinite(s.stiffness) || !(s.damping >= 0.0) || !std::isfinite(s.damping) ||
      !(s.preload >= 0.0) || !std::isfinite(s.preload))
    return "a compliant stop needs finite k_s > 0, c_s ≥ 0 and F_p ≥ 0 (stiffness " + number_text(s.stiffness) +
           ", damping " + number_text(s.damping) + ", preload " + number_text(s.preload) + ")";
  if (s.kind == Stop::Kind::normal)
    return "a compliant stop along a general normal would couple the masses of its normal in the chain's "
           "stiffness: the modal engine takes compliant stops on one mass or between neighbouring masses (the "
           "dense engine takes any)";
  if (s.kind == Stop::Kind::between && std::abs(s.mass - s.other) != 1)
    return "a compliant stop between masses " + std::to_string(s.mass) + " and " + std::to_string(s.other) +
           ", which are not neighbours, would break the chain's tridiagonal stiffness: the modal engine takes "
           "compliant stops on one mass or between neighbouring masses (the dense engine takes any)";
  // The engaged chain's damping C + c_s w wᵀ stays αM + β(K + k_s w wᵀ) only when c_s = β k_s
  // (to 1e-12 relative, the tolerance BandedChain::from_links allows the chain's own dampers).
  const double beta = chain.rayleigh_stiffness, expected = beta * s.stiffness;
  if (std::abs(s.damping - expected) > 1e-12 * std::max(s.damping, expected))
    return "a compliant stop's damping c_s = " + number_text(s.damping) + " is not β k_s = " + number_text(expected) +
           " (β = " + number_text(beta) + ", the chain's C = αM + βK): the modal engine needs the engaged chain's "
           "damping proportional too; the dense engine takes any c_s";
  return "";
}

void ModalSimulatorOptions::validate() const {
  SimulatorOptions::validate();  // the shared fields, by the dense engine's rules
  if (!std::isfinite(mode_cache_bytes) || mode_cache_bytes < 0.0)
    throw InvalidInput("solver.mode_cache_bytes = " + number_text(mode_cache_bytes) + ": must be a finite number ≥ 0");
  if (stop_after_impacts < 0)
    throw InvalidInput("stop_after_impacts = " + std::to_string(stop_after_impacts) + ": must be ≥ 0");
}

ModalSimulatorOptions modal_options(const SimulatorOptions& options) {
  ModalSimulatorOptions m;
  static_cast<SimulatorOptions&>(m) = options;
  return m;
}

struct ModalChainSimulator::Cache {
  struct Entry {
    std::unique_ptr<ModalContactMode> mode;
    long last_use = 0;
  };
  std::map<ContactSet, Entry> modes;
  std::map<ContactSet, std::string> unsupported;
  std::set<ContactSet> ever_built;
  long clock = 0;
  std::size_t bytes = 0;
};

ModalChainSimulator::ModalChainSimulator(const ChainModes& modes, std::vector<Stop> stops,
                                         ModalSimulatorOptions options)
    : modes_(&modes), stops_(std::move(stops)), options_(options), cache_(std::make_unique<Cache>()) {
  options_.validate();
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Index n = modes.dof();
  const double W = modes.frequency();
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    Stop& s = stops_[j];
    const std::string label = "stops[" + std::to_string(j) + "]";
    if (s.kind == Stop::Kind::normal) {  // its gap, impacts and chatter in O(N); held, it is refused (modal.hpp)
      if (s.direction.size() != n || !s.direction.allFinite() || s.direction.lpNorm<Eigen::Infinity>() == 0.0)
        throw InvalidInput(label + ": a general normal needs " + std::to_string(n) +
                           " finite entries, not all zero (one per mass)");
    } else if (s.mass < 0 || s.mass >= n) {
      throw InvalidInput(label + ": mass " + std::to_string(s.mass) + " is not in [0, " +
                         std::to_string(n - 1) + "]");
    }
    if (s.kind == Stop::Kind::between && (s.other < 0 || s.other >= n || s.other == s.mass))
      throw InvalidInput(label + ": other mass " + std::to_string(s.other) +
                         " must be in [0, " + std::to_string(n - 1) + "] and differ from mass");
    if (!std::isfinite(s.position) || !std::isfinite(s.amplitude) || !std::isfinite(s.phase) ||
        s.amplitude < 0.0)
      throw InvalidInput(label + ": position, amplitude and phase must be finite, amplitude ≥ 0");
    if (!(s.restitution >= 0.0 && s.restitution <= 1.0))
      throw InvalidInput(label + ": restitution = " + number_text(s.restitution) + ": must be in [0, 1]");
    if (s.amplitude > 0.0 && !(W > 0.0))
      throw InvalidInput(label + ": a moving stop needs forcing.frequency > 0");
    for (const StopHarmonic& h : s.harmonics) {
      if (h.order < 2 || !std::isfinite(h.cosine) || !std::isfinite(h.sine))
        throw InvalidInput(label + ": a harmonic of order " + std::to_string(h.order) + " (cosine " +
                           number_text(h.cosine) + ", sine " + number_text(h.sine) +
                           "): the order must be ≥ 2 and the amplitudes finite");
      if (!(W > 0.0)) throw InvalidInput(label + ": a moving stop needs forcing.frequency > 0");
      bool slot = false;
      for (const ForcingHarmonic& fh : modes.chain().forcing.harmonics) slot = slot || fh.order == h.order;
      if (!slot)
        throw InvalidInput(label + ": moves at order " + std::to_string(h.order) +
                           ", which the modes' forcing lacks: build the modes from with_stop_orders(chain, stops)");
    }
    if (s.is_compliant()) {
      const std::string why = compliant_refusal(s, modes.chain());
      if (!why.empty()) throw InvalidInput(label + ": " + why);
    }
    if (s.name.empty() && s.kind == Stop::Kind::normal) {
      s.name = validated_stops({s}, n, W).front().name;  // "normal 1·x0 + 0.5·x1", as ImpactSystem names it
    } else if (s.name.empty()) {
      s.name = s.kind == Stop::Kind::upper ? "upper" : (s.kind == Stop::Kind::lower ? "lower" : "between");
      s.name += " x" + std::to_string(s.mass);
      if (s.kind == Stop::Kind::between) s.name += "-x" + std::to_string(s.other);
    }
  }
  std::string why;
  cache_->modes[ContactSet{}].mode = build_mode(modes, stops_, {}, &why);
  stop_setup_seconds_ = seconds_since(start);
}

ModalChainSimulator::~ModalChainSimulator() = default;

std::size_t ModalChainSimulator::cached_modes() const { return cache_->modes.size() - 1; }

const ModalContactMode& ModalChainSimulator::contact_mode(const ContactSet& set) {
  for (std::size_t a = 0; a < set.size(); ++a)
    if (set[a] < 0 || set[a] >= static_cast<int>(stops_.size()) || (a > 0 && set[a] <= set[a - 1]))
      throw InvalidInput("contact set: stop indices must be sorted, distinct and in [0, " +
                         std::to_string(stops_.size()) + ")");
  ModalRunSummary scratch;
  std::string why;
  const ModalContactMode* mode = mode_for(set, &why, scratch);
  if (!mode) throw InvalidInput("contact set: " + why);
  return *mode;
}

const ModalContactMode* ModalChainSimulator::mode_for(const ContactSet& set, std::string* why_not,
                                                       ModalRunSummary& summary) {
  Cache& c = *cache_;
  ++c.clock;
  if (auto it = c.modes.find(set); it != c.modes.end()) {
    it->second.last_use = c.clock;
    return it->second.mode.get();
  }
  if (auto it = c.unsupported.find(set); it != c.unsupported.end()) {
    *why_not = it->second;
    return nullptr;
  }
  auto mode = build_mode(*modes_, stops_, set, why_not, options_.contact_modes);
  if (!mode) {
    c.unsupported[set] = *why_not;
    return nullptr;
  }
  summary.mode_build_seconds += mode->build_seconds;
  summary.mode_build_max_seconds = std::max(summary.mode_build_max_seconds, mode->build_seconds);
  if (!c.ever_built.insert(set).second) ++summary.modes_rebuilt;
  c.bytes += mode->bytes;
  const ModalContactMode* out = mode.get();
  c.modes[set] = {std::move(mode), c.clock};
  // Drop the least recently used subsystems beyond the budget (never the free set or this one).
  while (static_cast<double>(c.bytes) > options_.mode_cache_bytes) {
    auto victim = c.modes.end();
    for (auto it = c.modes.begin(); it != c.modes.end(); ++it)
      if (!it->first.empty() && it->first != set &&
          (victim == c.modes.end() || it->second.last_use < victim->second.last_use))
        victim = it;
    if (victim == c.modes.end()) break;
    c.bytes -= victim->second.mode->bytes;
    c.modes.erase(victim);
    ++modes_dropped_;
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// The run

/// The modal engine's side of the event loop (event_loop.hpp): a mode's segment is its modal
/// state (u0_, ud0_ at seg_t0_), its guards a ModalGuardSource searched by the CrossingFinder of
/// events.hpp (one finder for every mode: each has one row per stop); a lone impact in free
/// flight that leaves its stop is a rank-1 update of the modal velocities (modal.hpp), any other
/// event is resolved in physical coordinates by the rules shared with the dense engine
/// (event_resolution.hpp, on ChainAlgebra) and the next mode entered from there.
class ModalChainSimulator::Loop {
 public:
  Loop(ModalChainSimulator& sim, const std::vector<Observer*>& observers, ModalRunSummary& summary, double t_end)
      : sim_(sim), md_(*sim.modes_), ch_(md_.chain()), W_(md_.frequency()), observers_(observers),
        summary_(summary), t_end_(t_end), buffers_(md_.dof()), source_(md_.dof()) {}

  Eigen::Index dof() const { return md_.dof(); }
  const std::vector<Stop>& stops() const { return sim_.stops_; }
  double frequency() const { return W_; }
  detail::ScaleInputs scale_inputs() const {
    const Eigen::Index n = md_.dof();
    const double kmax = std::max(ch_.stiffness_diagonal.cwiseAbs().maxCoeff(),
                                 n > 1 ? ch_.stiffness_off.cwiseAbs().maxCoeff() : 0.0);
    double fmax = ch_.forcing.constant.cwiseAbs().maxCoeff() + ch_.forcing.cosine.cwiseAbs().maxCoeff() +
                        ch_.forcing.sine.cwiseAbs().maxCoeff();
    for (const ForcingHarmonic& h : ch_.forcing.harmonics)
      fmax += h.cosine.cwiseAbs().maxCoeff() + h.sine.cwiseAbs().maxCoeff();
    return {W_ > 0.0 ? W_ : md_.omega().maxCoeff(), kmax, ch_.mass.maxCoeff(), fmax};
  }
  void check_scene(const detail::RunScales& /*sc*/, std::vector<std::string>& /*warnings*/) const {}
  void start(const detail::RunScales& sc, detail::RunState& st) {
    const Eigen::Index n = md_.dof();
    eps_gap_ = sc.eps_gap;
    eps_force_ = sc.eps_force;
    rules_ = sc.rules;
    resolution_ = 8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end_), sc.T);
    sim_.force_tolerance_ = eps_force_;
    sim_.gap_tolerance_ = eps_gap_;
    // Storage for the whole run, sized once for the free chain's N (modes have n_r ≤ N).
    sim_.u0_.resize(n);
    sim_.ud0_.resize(n);
    algebra_ = std::make_unique<ChainAlgebra>(
        ch_, sim_.stops_,
        [this](const ContactSet& set, std::string* why) {
          return set.empty() ? sim_.cache_->modes.at(ContactSet{}).mode.get() : sim_.mode_for(set, why, summary_);
        },
        buffers_);
    work_.reserve(static_cast<Eigen::Index>(sim_.stops_.size()), n);
    emit_ = [this](const Event& e) {
      for (Observer* o : observers_) o->event(e);
    };
    visit_ = [this](const ContactSet& set) { sets_seen_.insert(set); };
    mode_ = sim_.cache_->modes.at(ContactSet{}).mode.get();
    // Compliant stops (stops.hpp): those penetrated at t0 start engaged (CompliantStopLaw).
    engaged_.clear();
    compliant_ = has_compliant(sim_.stops_);
    if (compliant_) {
      const auto m = sim_.stops_.size();
      for (ContactSet* set : {&engaged_, &rigid_impacts_, &rigid_releases_}) set->reserve(m);
      for (std::size_t j = 0; j < m; ++j)
        if (sim_.stops_[j].is_compliant() &&
            CompliantStopLaw::engaged_at_start(algebra_->gap(static_cast<int>(j), st.t, st.x)))
          engaged_.push_back(static_cast<int>(j));
      algebra_->set_engaged(&engaged_);
      if (!engaged_.empty()) {
        std::string why;
        mode_ = sim_.mode_for(engaged_, &why, summary_);
        if (!mode_) throw InvalidInput("the compliant stops engaged at t0: " + why);
        sets_seen_.insert(engaged_);
      }
    }
    sim_.seg_t0_ = st.t;
    sim_.nr_ = mode_->size();
    to_modal(*mode_, ch_.mass, W_, st.t, st.x, st.v, u0(), ud0(), buffers_);
  }
  void initial_guards(const detail::RunState& st, Eigen::VectorXd& g, Eigen::VectorXd& gd) const {
    for (int j = 0; j < static_cast<int>(g.size()); ++j) {
      g(j) = algebra_->gap(j, st.t, st.x);
      gd(j) = algebra_->gap_rate(j, st.t, st.v);
    }
  }
  bool resolve(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, const ContactSet& resting,
               std::string* why) {
    ++summary_.general_events;
    return detail::resolve_event(*algebra_, sim_.stops_, rules_, st.t, st.x, st.v, st.stuck, impacts, releases,
                                 resting, emit_, summary_, why, work_, visit_) &&
           enter(st, why);
  }
  double stiffness(const detail::RunState& /*st*/, double T) const { return T * top_rate(); }

  detail::SegmentPlan begin_segment(const detail::RunState& st, double t_end) {
    const ModalGuards& guards = mode_->guards;
    const Eigen::Index rows = guards.rows();
    base_.resize(rows);
    for (Eigen::Index i = 0; i < rows; ++i)  // gaps (and engaged compliant stops' -g) against ε·L
      base_(i) = i < mode_->gap_rows || i >= mode_->engaged_rows_from ? eps_gap_ : eps_force_;
    source_.retarget(mode_->modes, guards, W_, st.t, u0(), ud0());
    // A guard that starts inside its band while moving away (just after an impact or a release)
    // is re-armed above where it starts, so rounding cannot re-fire it.
    finder_.retarget(source_, base_, resolution_, true);
    const double top = top_rate(), span = t_end - st.t;
    return {top > 0.0 ? 1.0 / top : std::max(span, 1e-300), span};
  }
  bool search(double a, double b, Crossing* hit) {
    if (base_.size() == 0) return false;
    const std::optional<Crossing> c = finder_.first(a, b);
    if (c) *hit = *c;
    return c.has_value();
  }
  void end_search() const {}
  void report(double t, double t_next, const std::vector<Observer*>& observers) const {
    const ModalSegmentView view(sim_, *mode_, t, t_next);
    for (Observer* o : observers) o->segment(view);
  }
  bool advance(detail::RunState& /*st*/, const Crossing* /*hit*/, double tau, double t_next) {
    auto u = buffers_.u.head(sim_.nr_), ud = buffers_.ud.head(sim_.nr_);
    source_.state(tau, u, ud);
    u0() = u;
    ud0() = ud;
    sim_.seg_t0_ = t_next;
    return u0().allFinite() && ud0().allFinite();
  }
  detail::FiredGuards fired() const {
    const SegmentSample& at = finder_.crossing_sample();
    return {at.h, at.d, finder_.triggers(), mode_->gap_rows, mode_->watched};
  }
  /// Compliant stops' switches (engage, disengage: the state unchanged, the contact set changes)
  /// come first, then the rigid stops' impacts and releases, resolved with the new engaged set's
  /// forces acting; held rigid stops are settled again after a switch, as the dense engine does.
  bool event(detail::RunState& st, const ContactSet& impacting, const ContactSet& releasing, std::string* why) {
    if (!compliant_) {
      if (st.stuck.empty() && releasing.empty() && impacting.size() == 1 && free_impact(st.t, impacting))
        return true;
      to_physical(*mode_, W_, st.t, u0(), ud0(), st.x, st.v, buffers_);
      return resolve(st, impacting, releasing, {}, why);
    }
    rigid_impacts_.clear();
    rigid_releases_.clear();
    bool physical = false, switched = false;
    for (const auto* list : {&impacting, &releasing}) {
      const bool engage = list == &impacting;
      for (int j : *list) {
        if (!sim_.stops_[static_cast<std::size_t>(j)].is_compliant()) {
          (engage ? rigid_impacts_ : rigid_releases_).push_back(j);
          continue;
        }
        const auto at = std::lower_bound(engaged_.begin(), engaged_.end(), j);
        const bool is_engaged = at != engaged_.end() && *at == j;
        if (engage == is_engaged) continue;  // already in that state
        if (!physical) {
          to_physical(*mode_, W_, st.t, u0(), ud0(), st.x, st.v, buffers_);
          physical = true;
        }
        if (engage) engaged_.insert(at, j);
        else engaged_.erase(at);
        const double rate = algebra_->gap_rate(j, st.t, st.v);
        emit_({st.t, j, engage ? EventKind::engage : EventKind::disengage, rate, rate,
               engage ? algebra_->compliant_force(j, st.t, st.x, st.v) : 0.0});
        switched = true;
      }
    }
    if (!switched && st.stuck.empty() && rigid_releases_.empty() && rigid_impacts_.size() == 1 &&
        free_impact(st.t, rigid_impacts_))
      return true;
    if (!physical) to_physical(*mode_, W_, st.t, u0(), ud0(), st.x, st.v, buffers_);
    if (rigid_impacts_.empty() && rigid_releases_.empty() && !(switched && !st.stuck.empty())) {
      if (!switched) return true;
      ++summary_.general_events;
      return enter(st, why);
    }
    return resolve(st, rigid_impacts_, rigid_releases_, {}, why);
  }
  bool stop_requested(std::string* why) const {
    const long cap = sim_.options_.stop_after_impacts;
    if (cap <= 0 || summary_.impacts < cap) return false;
    *why = "stopped after " + std::to_string(summary_.impacts) + " impacts as asked (t_end not reached)";
    return true;
  }
  void state(const detail::RunState& st, bool physical, Eigen::VectorXd& x, Eigen::VectorXd& v) {
    if (physical) {
      x = st.x;
      v = st.v;
    } else {
      to_physical(*mode_, W_, st.t, u0(), ud0(), x, v, buffers_);
    }
  }
  void finish(RunSummary& /*summary*/) {
    summary_.evaluations = source_.evaluations();
    summary_.contact_sets_built = sets_seen_.size();
    summary_.sticking_flows_built = sim_.cache_->ever_built.size();
  }

 private:
  Eigen::VectorXd::SegmentReturnType u0() { return sim_.u0_.head(sim_.nr_); }
  Eigen::VectorXd::SegmentReturnType ud0() { return sim_.ud0_.head(sim_.nr_); }
  /// The search's step rate: the forcing's (its highest harmonic's) or the mode's fastest
  /// frequency (1/ω_max steps).
  double top_rate() const {
    const ModalGuards& g = mode_->guards;
    const double drive = g.harmonics() > 0 ? std::max(W_, g.rates.maxCoeff()) : W_;
    return std::max(drive, mode_->modes ? mode_->modes->omega().maxCoeff() : 0.0);
  }
  /// Enters the mode of `stuck` from the physical state (x, v) at t. False if unsupported.
  bool enter(const detail::RunState& st, std::string* why) {
    const ContactSet& key = algebra_->mode_key(st.stuck);
    const ModalContactMode* next = sim_.mode_for(key, why, summary_);
    if (!next) return false;
    mode_ = next;
    sets_seen_.insert(key);
    sim_.nr_ = mode_->size();
    to_modal(*mode_, ch_.mass, W_, st.t, st.x, st.v, u0(), ud0(), buffers_);
    sim_.seg_t0_ = st.t;
    return true;
  }
  /// Fast path, O(n): one impact (`impacting` = {j}) in free flight that leaves the stop (no chatter, no
  /// rest): the impulse is a rank-1 update of the modal velocities (modal.hpp). False (nothing
  /// done) when the impact needs the general resolution.
  bool free_impact(double t, const ContactSet& impacting) {
    const int j = impacting.front();
    const ModalGuards& guards = mode_->guards;
    const SegmentSample& P = finder_.crossing_sample();
    const auto row = static_cast<Eigen::Index>(std::find(mode_->watched.begin(), mode_->watched.end(), j) -
                                               mode_->watched.begin());
    const double r = sim_.stops_[static_cast<std::size_t>(j)].restitution;
    const double before = P.d(row);  // the gap's slope is its normal rate
    const double after = before > 0.0 ? -r * before : before;
    bool slow = false;
    if (r > 0.0 && r < 1.0) {
      // Free gap acceleration (the acceleration LCP of one stop holds iff it is > 0).
      // The current set's modes: the free chain's, or with engaged compliant stops the engaged chain's.
      const ChainModes& md = *mode_->modes;
      auto udd = buffers_.udd.head(sim_.nr_);
      udd = -(2.0 * md.decay().cwiseProduct(ud0()) + md.omega_squared().cwiseProduct(u0()));
      const double c = std::cos(W_ * t), s = std::sin(W_ * t);
      double accel = guards.P.row(row).dot(udd) - W_ * W_ * (guards.hc(row) * c + guards.hs(row) * s);
      if (guards.harmonics() > 0) {
        double value = 0.0, slope = 0.0;
        guards.add_extra_row(row, t, &value, &slope, &accel);
      }
      slow = accel > 0.0 &&
             (before <= rules_.v_chatter || (r * before) * (r * before) / (2.0 * accel) <= rules_.h_chatter);
    }
    if (slow || !(after < -rules_.v_contact)) return false;
    sets_seen_.insert(impacting);
    const double impulse = before > 0.0 ? (1.0 + r) * before / algebra_->delassus_diagonal(j) : 0.0;
    ud0() -= guards.P.row(row).transpose() * impulse;
    double g = guards.P.row(row).dot(u0()) + value_at({guards.h0(row), guards.hc(row), guards.hs(row)}, W_, t);
    const double c = std::cos(W_ * t), s = std::sin(W_ * t);
    double after_rate = W_ * (guards.hs(row) * c - guards.hc(row) * s);
    if (guards.harmonics() > 0) guards.add_extra_row(row, t, &g, &after_rate, nullptr);
    if (g > 0.0) u0() -= guards.P.row(row).transpose() * (g / algebra_->delassus_diagonal(j));
    after_rate += guards.P.row(row).dot(ud0());
    emit_({t, j, EventKind::impact, before, after_rate, 0.0});
    ++summary_.impacts;
    return true;
  }

  ModalChainSimulator& sim_;
  const ChainModes& md_;
  const BandedChain& ch_;
  double W_;
  const std::vector<Observer*>& observers_;
  ModalRunSummary& summary_;
  double t_end_;
  Buffers buffers_;
  ModalGuardSource source_;
  CrossingFinder finder_;
  double eps_gap_ = 0.0, eps_force_ = 0.0, resolution_ = 0.0;
  detail::EventRules rules_;
  std::unique_ptr<ChainAlgebra> algebra_;
  detail::EventWorkspace work_;
  std::function<void(const Event&)> emit_;
  std::function<void(const ContactSet&)> visit_;
  std::set<ContactSet> sets_seen_;  // impact and contact sets visited (contact_sets_built)
  const ModalContactMode* mode_ = nullptr;
  Eigen::VectorXd base_;
  bool compliant_ = false;                                // the scene has compliant stops
  ContactSet engaged_, rigid_impacts_, rigid_releases_;  // engaged compliant stops; scratch
};

ModalRunSummary ModalChainSimulator::run(double t0, const Eigen::VectorXd& x0,
                                         const Eigen::VectorXd& v0, double t_end,
                                         const std::vector<Observer*>& observers) {
  ++runs_started_;
  ModalRunSummary summary;
  Loop loop(*this, observers, summary, t_end);
  detail::run_event_loop(loop, options_, t0, x0, v0, t_end, observers, summary);
  return summary;
}

}  // namespace vibro
