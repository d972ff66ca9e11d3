/// Tests of vibro::LinearFlow (framework/src/flow.cpp): z(t0 + τ) = exp(Âτ) z(t0).
///
/// What is checked, and against what:
///  1. one degree of freedom, every damping regime, forced and free, singular K, exact resonance:
///     closed-form solutions derived below (long double);
///  2. random n-DOF systems (n = 2…12, non-proportional and rank-deficient damping, a rigid mode):
///     an independent Cooper–Verner RK8 integration in long double (support/reference_integrator);
///  3. the group property exp(Â(t1 + t2)) = exp(Ât2) exp(Ât1), also for negative times;
///  4. spectral against exponential, and which of them Method::automatic picks;
///  5. the energy balance E(t) - E(0) = -∫ vᵀCv dt of an unforced damped system;
///  6. the acceleration returned by state() against LinearSystem::acceleration.
/// The worst errors of every category are printed by the hidden test "[.report]":
///     ./vibro_tests_framework "[.report]"
#include "support/reference_integrator.hpp"
#include "vibro/flow.hpp"
#include "vibro/system.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace {

using vibro::FlowMethod;
using vibro::FlowOptions;
using vibro::HarmonicForcing;
using vibro::LinearFlow;
using vibro::LinearSystem;
using vibro::test::GaussLegendre;
using vibro::test::ReferenceIntegrator;

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr long double kPi = std::numbers::pi_v<long double>;

const char* name_of(FlowMethod method) {
  switch (method) {
    case FlowMethod::automatic: return "automatic";
    case FlowMethod::spectral: return "spectral";
    case FlowMethod::exponential: return "exponential";
  }
  return "?";
}

/// Worst errors of x and of v over a trajectory, each divided by the largest |x| (resp. |v|)
/// of the reference trajectory (max norm over components and sample times).
struct Errors {
  double x = 0.0;
  double v = 0.0;
  double worst() const { return std::max(x, v); }
};

Errors worst_of(const Errors& a, const Errors& b) { return {std::max(a.x, b.x), std::max(a.v, b.v)}; }

// =============================================================================================
// 1. One degree of freedom: m x'' + c x' + k x = f0 + fc cos Ωt + fs sin Ωt, in closed form.
//
// Every solution is x(t) = x_p(t) + x_h(t - t0): x_p is one particular solution written in
// absolute time (so the forcing phase at t0 is right) and x_h solves the free equation with
// x_h(0) = x0 - x_p(t0), x_h'(0) = v0 - x_p'(t0).
//
// Free part x_h(τ), with σ = c/(2m), ω0² = k/m, from the roots r of m r² + c r + k = 0:
//  * k = 0, c = 0: x'' = 0, so x = x0 + v0 τ.
//  * k = 0, c > 0: v' = -α v (α = c/m), so v = v0 e^{-ατ}, x = x0 + v0 (1 - e^{-ατ})/α.
//  * under-damped, c² < 4mk (c = 0 included): r = -σ ± iωd, ωd = √(ω0² - σ²),
//      x = e^{-στ} (x0 cos ωdτ + (v0 + σx0)/ωd sin ωdτ)      (x(0) = x0, x'(0) = v0),
//      v = e^{-στ} (v0 cos ωdτ - (σv0 + ω0²x0)/ωd sin ωdτ)   (differentiate, use σ² + ωd² = ω0²).
//  * critical, c² = 4mk: double root r = -σ = -ω0, x = (x0 + (v0 + σx0) τ) e^{-στ},
//      v = (v0 - σ(v0 + σx0) τ) e^{-στ}.
//  * over-damped, c² > 4mk: r₁,₂ = -σ ± √(σ² - ω0²), x = a₁e^{r₁τ} + a₂e^{r₂τ} with a₁ + a₂ = x0
//      and r₁a₁ + r₂a₂ = v0: a₁ = (v0 - r₂x0)/(r₁ - r₂), a₂ = (r₁x0 - v0)/(r₁ - r₂).
//
// Particular part x_p(t), the sum of the responses to the constant and to the harmonic force:
//  * f0 with k > 0: x_p = f0/k, the static deflection.
//    f0 with k = 0, c > 0: x_p = (f0/c) t, the terminal velocity (m·0 + c·f0/c = f0).
//    f0 with k = c = 0: x_p = f0 t²/(2m).
//  * fc cos Ωt + fs sin Ωt = Re((fc - i fs) e^{iΩt}). Off resonance, D = k - mΩ² + icΩ ≠ 0, and
//    x_p = Re(X e^{iΩt}) with X = (fc - i fs)/D, x_p' = Re(iΩ X e^{iΩt}).
//  * exact undamped resonance (c = 0, k = mΩ²): with g = a sin Ωt - b cos Ωt, x_p = t g gives
//    m x_p'' + k x_p = 2m g' + t (k - mΩ²) g = 2mΩ (a cos Ωt + b sin Ωt), so a = fc/(2mΩ),
//    b = fs/(2mΩ): secular growth, x_p' = g + Ωt (a cos Ωt + b sin Ωt).
// =============================================================================================

struct Oscillator {
  long double m = 1.0L, c = 0.0L, k = 0.0L;
  long double f0 = 0.0L, fc = 0.0L, fs = 0.0L, omega = 0.0L;
};

struct Motion {
  long double x, v;
};

Motion particular(const Oscillator& o, long double t) {
  Motion p{0.0L, 0.0L};
  if (o.f0 != 0.0L) {
    if (o.k > 0.0L) {
      p.x += o.f0 / o.k;
    } else if (o.c > 0.0L) {
      p.x += o.f0 / o.c * t;
      p.v += o.f0 / o.c;
    } else {
      p.x += o.f0 * t * t / (2 * o.m);
      p.v += o.f0 * t / o.m;
    }
  }
  if (o.fc != 0.0L || o.fs != 0.0L) {
    const long double w = o.omega;
    const long double cos_wt = std::cos(w * t), sin_wt = std::sin(w * t);
    const long double detuning = o.k - o.m * w * w;
    if (o.c == 0.0L && detuning == 0.0L) {
      const long double a = o.fc / (2 * o.m * w), b = o.fs / (2 * o.m * w);
      p.x += t * (a * sin_wt - b * cos_wt);
      p.v += (a * sin_wt - b * cos_wt) + w * t * (a * cos_wt + b * sin_wt);
    } else {
      using Complex = std::complex<long double>;
      const Complex amplitude = Complex(o.fc, -o.fs) / Complex(detuning, o.c * w);
      const Complex phase(cos_wt, sin_wt);
      p.x += (amplitude * phase).real();
      p.v += (Complex(0.0L, w) * amplitude * phase).real();
    }
  }
  return p;
}

Motion free_motion(const Oscillator& o, Motion s, long double tau) {
  if (o.k == 0.0L) {
    if (o.c == 0.0L) return {s.x + s.v * tau, s.v};
    const long double alpha = o.c / o.m, decay = std::exp(-alpha * tau);
    return {s.x + s.v * (1.0L - decay) / alpha, s.v * decay};
  }
  const long double sigma = o.c / (2 * o.m), w0sq = o.k / o.m;
  const long double discriminant = o.c * o.c - 4 * o.m * o.k;
  const long double decay = std::exp(-sigma * tau);
  if (discriminant < 0.0L) {
    const long double wd = std::sqrt(w0sq - sigma * sigma);
    const long double cs = std::cos(wd * tau), sn = std::sin(wd * tau);
    return {decay * (s.x * cs + (s.v + sigma * s.x) / wd * sn),
            decay * (s.v * cs - (sigma * s.v + w0sq * s.x) / wd * sn)};
  }
  if (discriminant == 0.0L) {
    const long double slope = s.v + sigma * s.x;
    return {(s.x + slope * tau) * decay, (s.v - sigma * slope * tau) * decay};
  }
  const long double root = std::sqrt(sigma * sigma - w0sq);
  const long double r1 = -sigma + root, r2 = -sigma - root;
  const long double a1 = (s.v - r2 * s.x) / (r1 - r2), a2 = (r1 * s.x - s.v) / (r1 - r2);
  const long double e1 = std::exp(r1 * tau), e2 = std::exp(r2 * tau);
  return {a1 * e1 + a2 * e2, a1 * r1 * e1 + a2 * r2 * e2};
}

/// Exact (x, v) at t from (x0, v0) at t0.
Motion exact_motion(const Oscillator& o, long double t0, Motion start, long double t) {
  const Motion p0 = particular(o, t0);
  const Motion h = free_motion(o, {start.x - p0.x, start.v - p0.v}, t - t0);
  const Motion p = particular(o, t);
  return {p.x + h.x, p.v + h.v};
}

Eigen::MatrixXd scalar(long double value) {
  return Eigen::MatrixXd::Constant(1, 1, static_cast<double>(value));
}

Eigen::VectorXd vector1(long double value) {
  return Eigen::VectorXd::Constant(1, static_cast<double>(value));
}

/// The parameters are chosen exactly representable (and M⁻¹K, M⁻¹C exact: m is a power of 2),
/// so the system the flow sees is exactly the one the closed form describes.
LinearSystem make_system(const Oscillator& o) {
  HarmonicForcing f{.constant = vector1(o.f0),
                    .cosine = vector1(o.fc),
                    .sine = vector1(o.fs),
                    .frequency = static_cast<double>(o.omega)};
  return LinearSystem(scalar(o.m), scalar(o.c), scalar(o.k), f);
}

struct ClosedFormCase {
  std::string name;
  Oscillator oscillator;
  Motion start;
  double t0;
  double span;                            // sampled on [t0, t0 + span]
  FlowMethod automatic;                   // what Method::automatic must pick
};

// m = 4, k = 16: ω0 = 2, natural period π. ζ = c/(2√(km)) = c/16.
std::vector<ClosedFormCase> closed_form_cases() {
  const Motion start{0.3L, -0.7L};
  const double t0 = 0.4;
  const double four_periods = 4 * kPi;  // four natural periods (and > 3 forcing periods at Ω = 1.3)
  return {
      {"under-damped (zeta = 0.05), free", {4, 0.8L, 16}, start, t0, four_periods,
       FlowMethod::spectral},
      {"under-damped (zeta = 0.05), harmonic forcing",
       {4, 0.8L, 16, 0, 1.5L, -0.4L, 1.3L}, start, t0, four_periods, FlowMethod::spectral},
      // ζ = 1 exactly: c = 16, c² = 4mk = 256. The eigenvalue -2 of Â is defective.
      {"critically damped (zeta = 1), harmonic and constant forcing",
       {4, 16, 16, 0.2L, 1.0L, 0.5L, 1.3L}, start, t0, four_periods, FlowMethod::exponential},
      {"over-damped (zeta = 3), harmonic forcing", {4, 48, 16, 0, 2.0L, 0, 0.9L}, start, t0,
       4 * 2 * kPi / 0.9, FlowMethod::spectral},
      {"undamped (C = 0), forced off resonance", {4, 0, 16, 0, 1.0L, 0.3L, 1.3L}, start, t0,
       4 * 2 * kPi / 1.3, FlowMethod::spectral},
      // Ω = ω0 = 2 exactly: ±2i are double, defective eigenvalues of Â.
      {"undamped exact resonance (Omega = omega)", {4, 0, 16, 0, 1.0L, 0.5L, 2.0L}, start, t0,
       4 * 2 * kPi / 2.0, FlowMethod::exponential},
      {"free mass (K = 0, C = 0), constant force", {4, 0, 0, 0.6L}, start, t0, 10.0,
       FlowMethod::exponential},
      // α = c/m = 0.2: the velocity relaxes to F0/c = 0.75 on the time scale 5.
      {"free mass with damping (K = 0, C > 0), constant force", {4, 0.8L, 0, 0.6L}, start, t0,
       20.0, FlowMethod::exponential},
      {"free mass with damping (K = 0, C > 0), constant and harmonic force",
       {4, 0.8L, 0, 0.6L, 1.0L, -0.5L, 1.3L}, start, t0, 20.0, FlowMethod::exponential},
      {"constant force with K > 0 (static deflection F0/k)", {4, 0.8L, 16, 3.0L}, start, t0,
       four_periods, FlowMethod::spectral},
  };
}

/// Errors of flow.state against the closed form at 41 equally spaced times of [t0, t0 + span].
Errors closed_form_errors(const ClosedFormCase& c, FlowMethod method) {
  const LinearSystem sys = make_system(c.oscillator);
  const LinearFlow flow(sys, FlowOptions{.method = method});
  const int samples = 40;
  double worst_x = 0.0, worst_v = 0.0, scale_x = 0.0, scale_v = 0.0;
  for (int j = 0; j <= samples; ++j) {
    const double t = c.t0 + c.span * j / samples;
    const Motion exact = exact_motion(c.oscillator, c.t0, c.start, t);
    const LinearFlow::State s = flow.state(c.t0, vector1(c.start.x), vector1(c.start.v), t);
    if (!std::isfinite(s.x(0)) || !std::isfinite(s.v(0))) return {kInfinity, kInfinity};
    worst_x = std::max(worst_x, static_cast<double>(std::fabs(s.x(0) - exact.x)));
    worst_v = std::max(worst_v, static_cast<double>(std::fabs(s.v(0) - exact.v)));
    scale_x = std::max(scale_x, static_cast<double>(std::fabs(exact.x)));
    scale_v = std::max(scale_v, static_cast<double>(std::fabs(exact.v)));
  }
  return {worst_x / scale_x, worst_v / scale_v};
}

/// The demand: 1e-12 relative. Rounding in the flow is a few ε times the growth of
/// ‖exp(Âτ)‖ and the number of squarings (Padé) or cond(V) (spectral, ≤ 1e4 by the rule, ≈ 2
/// for these cases), all of which keep it near 1e-14 for these moderate spans (measured: ≤ 4e-15).
constexpr double kClosedFormTolerance = 1e-12;

void check_closed_form(const std::string& name) {
  for (const ClosedFormCase& c : closed_form_cases()) {
    if (c.name != name) continue;
    INFO("case: " << c.name);
    const LinearFlow automatic(make_system(c.oscillator));
    INFO("automatic picked " << name_of(automatic.method()) << ", cond(V) = "
                             << automatic.eigenvector_condition());
    CHECK(automatic.method() == c.automatic);
    for (FlowMethod method : {FlowMethod::automatic, FlowMethod::exponential}) {
      INFO("method: " << name_of(method));
      const Errors e = closed_form_errors(c, method);
      CHECK(e.x <= kClosedFormTolerance);
      CHECK(e.v <= kClosedFormTolerance);
    }
    return;
  }
  FAIL("no closed-form case named " << name);
}

// =============================================================================================
// Random n-DOF systems.
// =============================================================================================

/// Deterministic across platforms: std::mt19937_64 is fully specified; the std distributions
/// are not, so uniforms are made from the top 53 bits by hand.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(engine_() >> 11) * 0x1.0p-53;
  }
  Eigen::VectorXd vector(Eigen::Index n, double lo, double hi) {
    Eigen::VectorXd v(n);
    for (Eigen::Index i = 0; i < n; ++i) v(i) = uniform(lo, hi);
    return v;
  }
  /// A random orthogonal matrix (Q of the QR factorisation of a uniform random matrix).
  Eigen::MatrixXd orthogonal(Eigen::Index n) {
    Eigen::MatrixXd a(n, n);
    for (Eigen::Index j = 0; j < n; ++j)
      for (Eigen::Index i = 0; i < n; ++i) a(i, j) = uniform(-1.0, 1.0);
    return Eigen::HouseholderQR<Eigen::MatrixXd>(a).householderQ();
  }

 private:
  std::mt19937_64 engine_;
};

/// Q diag(d) Qᵀ, symmetrised exactly (so it passes LinearSystem's symmetry check).
Eigen::MatrixXd with_spectrum(const Eigen::MatrixXd& q, const Eigen::VectorXd& d) {
  const Eigen::MatrixXd s = q * d.asDiagonal() * q.transpose();
  return 0.5 * (s + s.transpose());
}

enum class Damping { proportional, full, rank_deficient };

const char* name_of(Damping d) {
  switch (d) {
    case Damping::proportional: return "proportional";
    case Damping::full: return "non-proportional";
    case Damping::rank_deficient: return "non-proportional, rank n - n/2";
  }
  return "?";
}

struct RandomSpec {
  int n;
  std::uint64_t seed;
  Damping damping;
  bool rigid_mode = false;  // K singular (its null vector damped by C, which is then full rank)
  bool forced = true;
};

struct RandomProblem {
  LinearSystem system;
  Eigen::VectorXd x0, v0;
  double t0;
};

/// M with eigenvalues in [0.5, 2], K in [0.5, 4] (natural frequencies ≈ 0.5…2.8), C with
/// eigenvalues in [0.05, 0.6] (modal damping ratios ≈ 0.01…0.5), Ω in [0.4, 2.5]: the forcing
/// period is comparable to the natural ones, so 50 periods stay a few 10⁴ RK steps.
RandomProblem random_problem(const RandomSpec& spec) {
  Random rng(1000 * spec.seed + static_cast<std::uint64_t>(spec.n));
  const Eigen::Index n = spec.n;
  const Eigen::MatrixXd mass = with_spectrum(rng.orthogonal(n), rng.vector(n, 0.5, 2.0));
  Eigen::VectorXd k = rng.vector(n, 0.5, 4.0);
  if (spec.rigid_mode) k(0) = 0.0;
  const Eigen::MatrixXd stiffness = with_spectrum(rng.orthogonal(n), k);
  Eigen::MatrixXd damping;
  switch (spec.damping) {
    case Damping::proportional:
      damping = rng.uniform(0.01, 0.08) * mass + rng.uniform(0.01, 0.08) * stiffness;
      break;
    case Damping::full:
      damping = with_spectrum(rng.orthogonal(n), rng.vector(n, 0.05, 0.6));
      break;
    case Damping::rank_deficient: {
      Eigen::VectorXd c = rng.vector(n, 0.05, 0.6);
      c.tail(n / 2).setZero();
      damping = with_spectrum(rng.orthogonal(n), c);
      break;
    }
  }
  HarmonicForcing forcing = HarmonicForcing::zero(n);
  if (spec.forced) {
    forcing.constant = rng.vector(n, -0.5, 0.5);
    forcing.cosine = rng.vector(n, -1.0, 1.0);
    forcing.sine = rng.vector(n, -1.0, 1.0);
    forcing.frequency = rng.uniform(0.4, 2.5);
  }
  Eigen::VectorXd x0 = rng.vector(n, -1.0, 1.0);
  Eigen::VectorXd v0 = rng.vector(n, -1.0, 1.0);
  const double t0 = rng.uniform(0.0, 5.0);
  return {LinearSystem(mass, damping, stiffness, forcing), x0, v0, t0};
}

std::string describe(const RandomSpec& s) {
  return "n = " + std::to_string(s.n) + ", seed " + std::to_string(s.seed) + ", " +
         name_of(s.damping) + " damping" + (s.rigid_mode ? ", rigid mode" : "");
}

// ---------------------------------------------------------------------------------------------
// 2. Against the RK8 reference over 50 forcing periods.
// ---------------------------------------------------------------------------------------------

std::vector<RandomSpec> reference_specs(int n_min = 2, int n_max = 12) {
  std::vector<RandomSpec> specs;
  for (int n = n_min; n <= n_max; ++n)
    for (std::uint64_t seed : {1u, 2u}) {
      const auto damping = static_cast<Damping>((n + static_cast<int>(seed)) % 3);
      const bool rigid = (n == 5 && seed == 2) || (n == 10 && seed == 1);
      specs.push_back({n, seed, rigid ? Damping::full : damping, rigid});
    }
  return specs;
}

struct ReferenceComparison {
  Errors automatic, exponential;
  FlowMethod picked;
  double condition;
  long steps;
};

/// 4 samples per forcing period over 50 periods; the flow always starts from (t0, x0, v0), so
/// the longest τ is 50 periods. The exponential method (O(N³) per call) is sampled at every
/// period end only. Errors are relative to the largest ‖x‖∞ (‖v‖∞) of the reference trajectory.
ReferenceComparison compare_with_reference(const RandomProblem& p) {
  const LinearFlow automatic(p.system);
  const LinearFlow exponential(p.system, FlowOptions{.method = FlowMethod::exponential});
  ReferenceIntegrator reference(p.system);
  const int periods = 50, per_period = 4;
  const double dt = 2 * std::numbers::pi / p.system.forcing().frequency / per_period;

  ReferenceIntegrator::State s{p.t0, p.x0.cast<long double>(), p.v0.cast<long double>()};
  double scale_x = p.x0.lpNorm<Eigen::Infinity>(), scale_v = p.v0.lpNorm<Eigen::Infinity>();
  Errors automatic_abs, exponential_abs;
  long steps = 0;
  for (int j = 1; j <= periods * per_period; ++j) {
    const double t = p.t0 + j * dt;  // the same double time for both: no phase mismatch
    const long count = reference.steps_for(t - s.t);
    reference.advance(s, t, count);
    steps += count;
    const Eigen::VectorXd x = s.x.cast<double>(), v = s.v.cast<double>();
    scale_x = std::max(scale_x, x.lpNorm<Eigen::Infinity>());
    scale_v = std::max(scale_v, v.lpNorm<Eigen::Infinity>());
    const auto error = [&](const LinearFlow& flow, Errors& e) {
      const LinearFlow::State f = flow.state(p.t0, p.x0, p.v0, t);
      e.x = std::max(e.x, (f.x - x).lpNorm<Eigen::Infinity>());
      e.v = std::max(e.v, (f.v - v).lpNorm<Eigen::Infinity>());
      if (!f.x.allFinite() || !f.v.allFinite()) e = {kInfinity, kInfinity};
    };
    error(automatic, automatic_abs);
    if (j % per_period == 0) error(exponential, exponential_abs);
  }
  return {{automatic_abs.x / scale_x, automatic_abs.v / scale_v},
          {exponential_abs.x / scale_x, exponential_abs.v / scale_v},
          automatic.method(),
          automatic.eigenvector_condition(),
          steps};
}

/// The demand: 1e-10 relative to max ‖x‖. The reference's own error is ≲ 1e-12 (see
/// reference_integrator.hpp and the order test below), so a failure is the flow's.
constexpr double kReferenceTolerance = 1e-10;

// ---------------------------------------------------------------------------------------------
// 3. Group property.
// ---------------------------------------------------------------------------------------------

struct NamedFlow {
  std::string name;
  LinearSystem system;
  FlowMethod method;
  /// Longest backward time b of the pairs (b, -b) and (-b, -b/2). Backward propagation of a
  /// damped system is ill-conditioned: a rounding of ε in z(b) comes back amplified by about
  /// e^{σ b} (σ the fastest decay rate), so b is kept to σ b ≲ 3 for damped systems; that is
  /// "where negative τ makes sense". (With b = 6 the critically damped case, σ = 2, loses
  /// e^{12} ≈ 1.6e5: 1e-10, the conditioning of the problem, not an error of the flow.)
  double backward;
};

std::vector<NamedFlow> group_flows() {
  const RandomSpec damped{3, 7, Damping::full};
  const RandomSpec undamped_spec{2, 8, Damping::proportional};
  RandomProblem undamped = random_problem(undamped_spec);
  const LinearSystem conservative(undamped.system.mass(),
                                  Eigen::MatrixXd::Zero(2, 2), undamped.system.stiffness(),
                                  undamped.system.forcing());
  // Decay rates: random 3-DOF ≤ 0.6 (b = 5); critically damped σ = 2 (b = 1.5).
  return {
      {"random 3-DOF damped, automatic", random_problem(damped).system, FlowMethod::automatic, 5.0},
      {"random 3-DOF damped, exponential", random_problem(damped).system, FlowMethod::exponential,
       5.0},
      {"2-DOF undamped forced, automatic", conservative, FlowMethod::automatic, 8.0},
      {"2-DOF undamped forced, exponential", conservative, FlowMethod::exponential, 8.0},
      {"1-DOF critically damped, automatic", make_system({4, 16, 16, 0.2L, 1.0L, 0.5L, 1.3L}),
       FlowMethod::automatic, 1.5},
      {"1-DOF exact resonance, automatic", make_system({4, 0, 16, 0, 1.0L, 0.5L, 2.0L}),
       FlowMethod::automatic, 8.0},
  };
}

/// max over (t1, t2) of ‖z(t1 + t2) - exp(Ât2) exp(Ât1) z‖∞ / max(‖z‖∞, ‖z(t1)‖∞, ‖z(t1+t2)‖∞).
double group_error(const NamedFlow& nf) {
  const LinearFlow flow(nf.system, FlowOptions{.method = nf.method});
  const Eigen::Index n = flow.dof();
  const Eigen::VectorXd x0 = Eigen::VectorXd::LinSpaced(n, 0.4, -0.8);
  const Eigen::VectorXd v0 = Eigen::VectorXd::LinSpaced(n, -0.3, 0.9);
  const Eigen::VectorXd z = flow.augment(0.6, x0, v0);
  const double b = nf.backward;
  const std::pair<double, double> times[] = {{0.7, 1.9},  {3.1, 4.6},    {2.5, -1.2},
                                             {b, -b},     {-b, -b / 2},  {-0.5, 2.5}};
  Eigen::VectorXd z1(flow.size()), z12(flow.size()), direct(flow.size());
  double worst = 0.0;
  for (const auto& [t1, t2] : times) {
    flow.propagate(z, t1, z1);
    flow.propagate(z1, t2, z12);
    flow.propagate(z, t1 + t2, direct);
    const double scale = std::max({z.lpNorm<Eigen::Infinity>(), z1.lpNorm<Eigen::Infinity>(),
                                   direct.lpNorm<Eigen::Infinity>()});
    worst = std::max(worst, (z12 - direct).lpNorm<Eigen::Infinity>() / scale);
  }
  return worst;
}

/// About 1e-13: a composition is two propagations, each rounding at a few ε times cond(V)
/// (spectral; ≤ 1e2 for these systems) or the ~log₂‖Âτ‖ squarings of the Padé scheme.
constexpr double kGroupTolerance = 1e-13;

// ---------------------------------------------------------------------------------------------
// 4. Spectral against exponential.
// ---------------------------------------------------------------------------------------------

std::vector<RandomSpec> agreement_specs() {
  std::vector<RandomSpec> specs;
  for (int n = 2; n <= 6; ++n)
    for (std::uint64_t seed : {3u, 4u}) specs.push_back({n, seed, static_cast<Damping>(n % 3)});
  return specs;
}

struct Agreement {
  double error;
  double condition;
  FlowMethod picked;
};

/// max over τ of ‖spectral - exponential‖∞ / max(‖z‖∞, ‖z(τ)‖∞).
Agreement agreement(const RandomProblem& p) {
  const LinearFlow automatic(p.system);
  const LinearFlow spectral(p.system, FlowOptions{.method = FlowMethod::spectral});
  const LinearFlow exponential(p.system, FlowOptions{.method = FlowMethod::exponential});
  const Eigen::VectorXd z = spectral.augment(p.t0, p.x0, p.v0);
  Eigen::VectorXd a(z.size()), b(z.size());
  double worst = 0.0;
  for (double tau : {-0.5, 0.3, 1.0, 4.0, 15.0, 40.0}) {
    spectral.propagate(z, tau, a);
    exponential.propagate(z, tau, b);
    const double scale = std::max(z.lpNorm<Eigen::Infinity>(), b.lpNorm<Eigen::Infinity>());
    worst = std::max(worst, (a - b).lpNorm<Eigen::Infinity>() / scale);
  }
  return {worst, automatic.eigenvector_condition(), automatic.method()};
}

/// The rule admits cond(V) ≤ 1e4, i.e. spectral rounding up to ~1e4 ε ≈ 2e-12; these random
/// systems have cond(V) ≲ 1e2, so 1e-12 has a margin of ten while still catching any real
/// disagreement (a wrong eigenvector or a lost conjugate pair is O(1)).
constexpr double kAgreementTolerance = 1e-12;

/// A chain of three unit masses joined by unit springs and dashpots (c = 0.1), attached to
/// nothing: K and C share the rigid mode (1, 1, 1), so Â has a Jordan block there.
LinearSystem free_free_chain() {
  Eigen::MatrixXd laplacian(3, 3);
  laplacian << 1, -1, 0, -1, 2, -1, 0, -1, 1;
  HarmonicForcing f{.constant = Eigen::Vector3d(0.3, 0.0, -0.1),
                    .cosine = Eigen::Vector3d(0.5, 0.0, 0.0),
                    .sine = Eigen::Vector3d(0.0, 0.0, 0.25),
                    .frequency = 0.7};
  return LinearSystem(Eigen::MatrixXd::Identity(3, 3), 0.1 * laplacian, laplacian, f);
}

// ---------------------------------------------------------------------------------------------
// 5. Energy balance.
// ---------------------------------------------------------------------------------------------

struct EnergyBalance {
  double error;        // max over check times of |E(t) - E(0) + ∫vᵀCv| / E(0)
  double final_ratio;  // E(T)/E(0): the test must dissipate a good part of the energy
};

/// Unforced 3-DOF with non-proportional damping, over t ∈ [0, 30] (≈ 10 slowest periods).
/// ∫₀ᵗ vᵀCv by composite 10-point Gauss–Legendre with panels of width h, h·|λ|max ≤ 0.5: the
/// integrand is a sum of exponentials of rates ≤ 2|λ|max, so each panel errs by about
/// (h·2|λ|max)^20/20! < 1e-18 relative.
EnergyBalance energy_balance(FlowMethod method) {
  const RandomProblem p = random_problem({3, 11, Damping::full, false, false});
  const LinearSystem& sys = p.system;
  const LinearFlow flow(sys, FlowOptions{.method = method});
  const ReferenceIntegrator rates(sys);  // only for |λ|max, to size the panels
  const GaussLegendre rule(10);
  const Eigen::MatrixXd& damping = sys.damping();
  const auto dissipation = [&](long double t) {
    const Eigen::VectorXd v = flow.state(0.0, p.x0, p.v0, static_cast<double>(t)).v;
    return static_cast<long double>(v.dot(damping * v));
  };
  const double e0 = sys.energy(p.x0, p.v0);
  double worst = 0.0, final_ratio = 1.0;
  for (double t : {2.5, 10.0, 30.0}) {
    const long panels = static_cast<long>(std::ceil(t * rates.rate() / 0.5L));
    const long double dissipated = rule.integrate(dissipation, 0.0L, t, panels);
    const LinearFlow::State s = flow.state(0.0, p.x0, p.v0, t);
    const double e = sys.energy(s.x, s.v);
    worst = std::max(worst, static_cast<double>(std::fabs(e - e0 + dissipated)) / e0);
    final_ratio = e / e0;
  }
  return {worst, final_ratio};
}

/// 1e-10 as the issue asks; the quadrature error is < 1e-15 (above) and the flow's ~1e-14.
constexpr double kEnergyTolerance = 1e-10;

// ---------------------------------------------------------------------------------------------
// 6. Acceleration.
// ---------------------------------------------------------------------------------------------

/// max over 80 times in 10 forcing periods of ‖a_flow - a_system‖∞ / max ‖a_system‖∞. Both are
/// M⁻¹(f - Cv - Kx) evaluated in a different order (flow: (M⁻¹K)x, system: M⁻¹(Kx)), so they
/// differ by a few ε·cond(M) ‖M⁻¹‖(‖f‖ + ‖Cv‖ + ‖Kx‖); cond(M) ≤ 4 here.
double acceleration_error(const RandomProblem& p, FlowMethod method) {
  const LinearFlow flow(p.system, FlowOptions{.method = method});
  const double period = 2 * std::numbers::pi / p.system.forcing().frequency;
  double worst = 0.0, scale = 0.0;
  for (int j = 0; j <= 80; ++j) {
    const double t = p.t0 + period * j / 8.0;
    const LinearFlow::State s = flow.state(p.t0, p.x0, p.v0, t);
    const Eigen::VectorXd a = p.system.acceleration(t, s.x, s.v);
    worst = std::max(worst, (s.a - a).lpNorm<Eigen::Infinity>());
    scale = std::max(scale, a.lpNorm<Eigen::Infinity>());
  }
  return worst / scale;
}

constexpr double kAccelerationTolerance = 1e-12;

// ---------------------------------------------------------------------------------------------
// The reference integrator's own order and accuracy.
// ---------------------------------------------------------------------------------------------

/// The forced, under-damped oscillator of the closed-form tests (with a constant force too, so
/// that the non-autonomous stage conditions are exercised).
const Oscillator kOrderOscillator{4, 0.8L, 16, 0.25L, 1.5L, -0.4L, 1.3L};

/// Relative error (max |x| scale) at t0 + span of RK8 with step rate h·ρ.
double reference_error(long double step_rate, long double span) {
  const LinearSystem sys = make_system(kOrderOscillator);
  ReferenceIntegrator reference(sys);
  const Motion start{0.3L, -0.7L};
  const long double t0 = 0.4L;
  ReferenceIntegrator::State s{t0, vector1(start.x).cast<long double>(),
                               vector1(start.v).cast<long double>()};
  const long double t1 = t0 + span;
  reference.advance(s, t1, reference.steps_for(span, step_rate));
  const Motion exact = exact_motion(kOrderOscillator, t0, start, t1);
  long double scale = 0.0L;  // max |x| over the trajectory, sampled finely
  for (int j = 0; j <= 400; ++j)
    scale = std::max(scale, std::fabs(exact_motion(kOrderOscillator, t0, start,
                                                   t0 + span * j / 400).x));
  return static_cast<double>(std::fabs(s.x(0) - exact.x) / scale);
}

}  // namespace

// =============================================================================================
// Test cases
// =============================================================================================

TEST_CASE("flow: 1-DOF under-damped free vibration matches the closed form", "[flow][closed-form]") {
  check_closed_form("under-damped (zeta = 0.05), free");
}

TEST_CASE("flow: 1-DOF under-damped harmonically forced vibration matches the closed form",
          "[flow][closed-form]") {
  check_closed_form("under-damped (zeta = 0.05), harmonic forcing");
}

TEST_CASE("flow: 1-DOF critically damped motion matches the closed form, automatic falls back",
          "[flow][closed-form]") {
  check_closed_form("critically damped (zeta = 1), harmonic and constant forcing");
}

TEST_CASE("flow: 1-DOF over-damped motion matches the closed form", "[flow][closed-form]") {
  check_closed_form("over-damped (zeta = 3), harmonic forcing");
}

TEST_CASE("flow: 1-DOF undamped vibration forced off resonance matches the closed form",
          "[flow][closed-form]") {
  check_closed_form("undamped (C = 0), forced off resonance");
}

TEST_CASE("flow: 1-DOF exact resonance grows secularly, finite, as the closed form",
          "[flow][closed-form]") {
  const std::string name = "undamped exact resonance (Omega = omega)";
  check_closed_form(name);
  // The secular term is really there: at t = 40 the amplitude fc/(2mω) t = 2.5 dominates the
  // free motion (|x0|, |v0|/ω ≤ 0.35), and nothing is NaN.
  const Oscillator o{4, 0, 16, 0, 1.0L, 0.5L, 2.0L};
  const LinearFlow flow(make_system(o));
  const LinearFlow::State s = flow.state(0.4, vector1(0.3L), vector1(-0.7L), 40.0);
  REQUIRE(s.x.allFinite());
  REQUIRE(s.v.allFinite());
  CHECK(std::fabs(s.x(0)) > 1.5);
  const Motion exact = exact_motion(o, 0.4L, {0.3L, -0.7L}, 40.0L);
  // Relative to the amplitude reached, |x| ≲ √(a² + b²) t + 0.4 ≈ 3.2 with a = 1/16, b = 1/32.
  CHECK(std::fabs(s.x(0) - exact.x) <= kClosedFormTolerance * 3.2);
}

TEST_CASE("flow: free mass (K = 0, C = 0) under a constant force moves as x0 + v0 t + F t²/2m",
          "[flow][closed-form]") {
  check_closed_form("free mass (K = 0, C = 0), constant force");
}

TEST_CASE("flow: free damped mass (K = 0, C > 0) reaches the terminal velocity F0/c",
          "[flow][closed-form]") {
  check_closed_form("free mass with damping (K = 0, C > 0), constant force");
  check_closed_form("free mass with damping (K = 0, C > 0), constant and harmonic force");
  // After 40 relaxation times e^{-αt} ≈ 4e-18: v = F0/c = 0.75 to rounding.
  const LinearFlow flow(make_system({4, 0.8L, 0, 0.6L}));
  CHECK(flow.state(0.0, vector1(0.3L), vector1(-0.7L), 200.0).v(0) ==
        Approx(0.75).epsilon(1e-12));
}

TEST_CASE("flow: constant force with K > 0 settles at the static deflection F0/k",
          "[flow][closed-form]") {
  check_closed_form("constant force with K > 0 (static deflection F0/k)");
  // σ = c/2m = 0.1: at t = 400, e^{-σt} ≈ 4e-18, so x = F0/k = 3/16 to rounding.
  const LinearFlow flow(make_system({4, 0.8L, 16, 3.0L}));
  const LinearFlow::State s = flow.state(0.0, vector1(0.3L), vector1(-0.7L), 400.0);
  CHECK(s.x(0) == Approx(3.0 / 16.0).epsilon(1e-12));
  CHECK(std::fabs(s.v(0)) <= 1e-12);
}

TEST_CASE("reference integrator: Cooper-Verner RK8 has order 8 and is accurate to < 1e-12",
          "[flow][reference]") {
  // Halving h must divide the error by 2⁸ = 256 (log₂ ratio 8 ± 0.5, the pre-asymptotic slack).
  const long double span = 10.0L;
  const double e1 = reference_error(0.4L, span);
  const double e2 = reference_error(0.2L, span);
  const double e3 = reference_error(0.1L, span);
  INFO("errors " << e1 << ", " << e2 << ", " << e3);
  CHECK(std::log2(e1 / e2) == Approx(8.0).margin(0.5));
  CHECK(std::log2(e2 / e3) == Approx(8.0).margin(0.5));
  // At the production step rule over 50 forcing periods the reference must be ≥ 100 times more
  // accurate than the 1e-10 it is used to check.
  const double production = reference_error(ReferenceIntegrator::default_step_rate,
                                            50 * 2 * kPi / kOrderOscillator.omega);
  INFO("production error " << production);
  CHECK(production <= 1e-12);
}

TEST_CASE("reference quadrature: Gauss-Legendre integrates exponentials and polynomials",
          "[flow][reference]") {
  const GaussLegendre rule(10);
  long double weights = 0.0L;
  for (int i = 0; i < rule.points(); ++i) weights += rule.weight(i);
  CHECK(std::fabs(weights - 2.0L) <= 1e-17L);
  // Exact for degree 19: ∫₋₁¹ x¹⁸ = 2/19; not for degree 20 (so the rule is not a lucky constant).
  const auto power = [](long double p) { return [p](long double x) { return std::pow(x, p); }; };
  CHECK(std::fabs(rule.integrate(power(18), -1, 1, 1) - 2.0L / 19) <= 1e-17L);
  CHECK(std::fabs(rule.integrate(power(20), -1, 1, 1) - 2.0L / 21) > 1e-8L);
  // ∫₀³ e^{-2t} cos 5t dt on 6 panels.
  const auto g = [](long double t) { return std::exp(-2 * t) * std::cos(5 * t); };
  const long double exact = (2.0L + std::exp(-6.0L) * (5 * std::sin(15.0L) - 2 * std::cos(15.0L))) / 29;
  CHECK(std::fabs(rule.integrate(g, 0, 3, 6) - exact) <= 1e-17L);
}

namespace {

void check_against_reference(int n_min, int n_max) {
  for (const RandomSpec& spec : reference_specs(n_min, n_max)) {
    const RandomProblem p = random_problem(spec);
    const ReferenceComparison r = compare_with_reference(p);
    INFO(describe(spec) << "; automatic picked " << name_of(r.picked) << ", cond(V) = "
                        << r.condition << "; " << r.steps << " RK steps");
    INFO("automatic: x " << r.automatic.x << ", v " << r.automatic.v << "; exponential: x "
                         << r.exponential.x << ", v " << r.exponential.v);
    CHECK(r.automatic.worst() <= kReferenceTolerance);
    CHECK(r.exponential.worst() <= kReferenceTolerance);
  }
}

}  // namespace

// Two test cases so that ctest can run them in parallel (each ~1-2 s in Release).
TEST_CASE("flow: random 2..8-DOF systems agree with the RK8 reference over 50 periods",
          "[flow][reference]") {
  check_against_reference(2, 8);
}

TEST_CASE("flow: random 9..12-DOF systems agree with the RK8 reference over 50 periods",
          "[flow][reference]") {
  check_against_reference(9, 12);
}

TEST_CASE("flow: group property exp(A(t1+t2)) = exp(A t2) exp(A t1), negative times included",
          "[flow]") {
  for (const NamedFlow& nf : group_flows()) {
    INFO(nf.name);
    CHECK(group_error(nf) <= kGroupTolerance);
  }
}

TEST_CASE("flow: spectral and exponential methods agree on well-conditioned systems", "[flow]") {
  for (const RandomSpec& spec : agreement_specs()) {
    const RandomProblem p = random_problem(spec);
    const Agreement a = agreement(p);
    INFO(describe(spec) << "; cond(V) = " << a.condition << "; error " << a.error);
    // The comparison is meaningful only if the system is well conditioned in the rule's sense.
    REQUIRE(a.picked == FlowMethod::spectral);
    CHECK(a.error <= kAgreementTolerance);
  }
}

TEST_CASE("flow: automatic picks spectral for a well-conditioned damped system", "[flow][rule]") {
  const LinearSystem sys = random_problem({4, 5, Damping::full}).system;
  const LinearFlow flow(sys);
  INFO("cond(V) = " << flow.eigenvector_condition());
  CHECK(flow.method() == FlowMethod::spectral);
  CHECK(flow.eigenvector_condition() <= FlowOptions{}.max_condition);
  CHECK(flow.eigenvalues().size() == flow.size());
  // Explicit choices are honoured, and an impossible threshold forces the fallback.
  CHECK(LinearFlow(sys, {.method = FlowMethod::exponential}).method() == FlowMethod::exponential);
  CHECK(LinearFlow(sys, {.method = FlowMethod::exponential}).eigenvalues().size() == 0);
  CHECK(LinearFlow(sys, {.method = FlowMethod::spectral}).method() == FlowMethod::spectral);
  CHECK(LinearFlow(sys, {.method = FlowMethod::automatic, .max_condition = 0.5}).method() ==
        FlowMethod::exponential);
}

TEST_CASE("flow: automatic picks exponential for critical damping, resonance, free-free chain",
          "[flow][rule]") {
  const auto check_fallback = [](const std::string& what, const LinearSystem& sys) {
    const LinearFlow flow(sys);
    INFO(what << ": cond(V) = " << flow.eigenvector_condition());
    CHECK(flow.method() == FlowMethod::exponential);
    CHECK(flow.eigenvector_condition() > FlowOptions{}.max_condition);
  };
  check_fallback("critical damping", make_system({4, 16, 16, 0, 1.0L, 0, 1.3L}));
  check_fallback("undamped resonance", make_system({4, 0, 16, 0, 1.0L, 0, 2.0L}));
  check_fallback("free-free chain", free_free_chain());
}

TEST_CASE("flow: free-free chain conserves momentum: the centre of mass moves as a free mass",
          "[flow]") {
  // Σᵢ (M x'')ᵢ = Σᵢ fᵢ because the rows of K and C sum to zero: the centre of mass x̄ = Σx/3
  // is a free mass 3 under the summed force, whose closed form is above (k = c = 0).
  const LinearSystem sys = free_free_chain();
  const LinearFlow flow(sys);
  const HarmonicForcing& f = sys.forcing();
  const Oscillator centre{3, 0, 0, f.constant.sum(), f.cosine.sum(), f.sine.sum(), f.frequency};
  const Eigen::Vector3d x0(0.1, -0.2, 0.4), v0(0.3, 0.0, -0.1);
  const double t0 = 0.25;
  const Motion start{x0.sum() / 3.0L, v0.sum() / 3.0L};
  double worst = 0.0, scale = 0.0;
  for (int j = 0; j <= 40; ++j) {
    const double t = t0 + 0.5 * j;
    const LinearFlow::State s = flow.state(t0, x0, v0, t);
    const Motion exact = exact_motion(centre, t0, start, t);
    worst = std::max(worst, static_cast<double>(std::fabs(s.x.sum() / 3.0L - exact.x)));
    scale = std::max(scale, static_cast<double>(std::fabs(exact.x)));
  }
  INFO("relative error " << worst / scale);
  CHECK(worst / scale <= kClosedFormTolerance);
}

TEST_CASE("flow: energy of an unforced damped system decays by the dissipated work", "[flow]") {
  for (FlowMethod method : {FlowMethod::automatic, FlowMethod::exponential}) {
    INFO("method " << name_of(method));
    const EnergyBalance b = energy_balance(method);
    INFO("relative error " << b.error << ", E(T)/E(0) = " << b.final_ratio);
    CHECK(b.final_ratio < 0.5);  // a test that dissipates nothing could not fail
    CHECK(b.error <= kEnergyTolerance);
  }
}

TEST_CASE("flow: the acceleration of state() is M^-1 (f - Cv - Kx)", "[flow]") {
  for (const RandomSpec& spec : {RandomSpec{4, 21, Damping::full}, RandomSpec{7, 22, Damping::rank_deficient}}) {
    const RandomProblem p = random_problem(spec);
    for (FlowMethod method : {FlowMethod::automatic, FlowMethod::exponential}) {
      INFO(describe(spec) << ", method " << name_of(method));
      CHECK(acceleration_error(p, method) <= kAccelerationTolerance);
    }
  }
}

TEST_CASE("flow accuracy report", "[.report]") {
  std::printf("\n%-62s %11s %11s\n", "closed form (x, v rel. to max|x|, max|v|)", "automatic",
              "exponential");
  Errors closed_auto, closed_exp;
  for (const ClosedFormCase& c : closed_form_cases()) {
    const Errors a = closed_form_errors(c, FlowMethod::automatic);
    const Errors e = closed_form_errors(c, FlowMethod::exponential);
    const LinearFlow flow(make_system(c.oscillator));
    std::printf("  %-60s %11.2e %11.2e  [%s, cond %.1e]\n", c.name.c_str(), a.worst(), e.worst(),
                name_of(flow.method()), flow.eigenvector_condition());
    closed_auto = worst_of(closed_auto, a);
    closed_exp = worst_of(closed_exp, e);
  }
  std::printf("  %-60s %11.2e %11.2e\n", "WORST", closed_auto.worst(), closed_exp.worst());

  std::printf("\nRK8 reference, 50 periods (rel. to max|x|, max|v|)\n");
  Errors ref_auto, ref_exp;
  for (const RandomSpec& spec : reference_specs()) {
    const ReferenceComparison r = compare_with_reference(random_problem(spec));
    std::printf("  %-50s %-11s cond %8.1e  %11.2e %11.2e  (%ld steps)\n", describe(spec).c_str(),
                name_of(r.picked), r.condition, r.automatic.worst(), r.exponential.worst(),
                r.steps);
    ref_auto = worst_of(ref_auto, r.automatic);
    ref_exp = worst_of(ref_exp, r.exponential);
  }
  std::printf("  %-50s %-11s %13s  %11.2e %11.2e\n", "WORST", "", "", ref_auto.worst(),
              ref_exp.worst());
  std::printf("  reference self-check: errors at h*rate = 0.4, 0.2, 0.1: %.2e %.2e %.2e; "
              "at 0.05 over 50 periods %.2e\n",
              reference_error(0.4L, 10), reference_error(0.2L, 10), reference_error(0.1L, 10),
              reference_error(ReferenceIntegrator::default_step_rate,
                              50 * 2 * kPi / kOrderOscillator.omega));

  std::printf("\ngroup property\n");
  for (const NamedFlow& nf : group_flows())
    std::printf("  %-50s %11.2e\n", nf.name.c_str(), group_error(nf));

  double worst_agreement = 0.0, worst_condition = 0.0;
  for (const RandomSpec& spec : agreement_specs()) {
    const Agreement a = agreement(random_problem(spec));
    worst_agreement = std::max(worst_agreement, a.error);
    worst_condition = std::max(worst_condition, a.condition);
  }
  std::printf("\nspectral vs exponential: worst %.2e (largest cond(V) %.1e)\n", worst_agreement,
              worst_condition);

  for (FlowMethod method : {FlowMethod::automatic, FlowMethod::exponential}) {
    const EnergyBalance b = energy_balance(method);
    std::printf("energy balance (%s): %.2e of E(0); E(T)/E(0) = %.3f\n", name_of(method), b.error,
                b.final_ratio);
  }
  for (FlowMethod method : {FlowMethod::automatic, FlowMethod::exponential}) {
    double worst = 0.0;
    for (const RandomSpec& spec : {RandomSpec{4, 21, Damping::full}, RandomSpec{7, 22, Damping::rank_deficient}})
      worst = std::max(worst, acceleration_error(random_problem(spec), method));
    std::printf("acceleration consistency (%s): %.2e\n", name_of(method), worst);
  }
  SUCCEED();
}

TEST_CASE("segment: values, slopes, curvatures and states at short steps agree with the matrix exponential to rounding",
          "[flow][segment]") {
  // Segment evaluates e^{λτ} by a series where |λτ| ≤ 2⁻⁵, from τ = 0 or from a cached point
  // (flow.cpp, Segment::fill_exponentials), and by exp and sincos elsewhere. Every path is
  // compared with the Padé exponential z(τ) = exp(Âτ) z0: on the spectral method (a damped,
  // forced 4-DOF system) and on the closed form of the Schur clusters (a free-free chain: a
  // Jordan block at 0). Tolerance 1e-13 of the rows' magnitude: both sides are right to a few
  // ulps of it (the Padé exponential to ~1e-15 here, kAgreementTolerance's cases to 1e-12 over
  // whole periods); a wrong series term (e.g. 1/k! off by one) errs by |λτ|ᵏ ≥ 1e-11 at the
  // steps below, a wrong base by O(1).
  struct Case {
    const char* name;
    LinearSystem system;
  };
  const std::vector<Case> cases{{"spectral, 4-DOF forced", random_problem({4, 7, Damping::full}).system},
                                {"closed form, free-free chain", free_free_chain()}};
  for (const Case& c : cases) {
    INFO(c.name);
    const LinearFlow flow(c.system);
    REQUIRE(flow.closed_form());
    const Eigen::Index N = flow.size();
    Eigen::MatrixXd rows = Eigen::MatrixXd::Identity(N, N);
    const vibro::Functionals functionals(flow, rows);
    Eigen::VectorXd z0 = flow.augment(0.3, Eigen::VectorXd::LinSpaced(flow.dof(), -0.7, 0.9),
                                      Eigen::VectorXd::LinSpaced(flow.dof(), 0.4, -0.2));
    const vibro::Segment segment(functionals, 0.3, z0);
    double rate = 0.0;
    for (const auto& term : flow.terms()) rate = std::max(rate, std::abs(term.lambda));
    const double far = 1.3 / rate;  // evaluated directly: a base for the points after it
    const std::vector<double> taus{0.0,           1e-9 / rate,        1e-4 / rate,        0.01 / rate,
                                   0.031 / rate,  0.032 / rate,       far,                far + 1e-7 / rate,
                                   far - 0.02 / rate, far + 0.03 / rate, 3.1 / rate};
    vibro::SegmentSample sample;
    Eigen::VectorXd state(N);
    for (const double tau : taus) {
      INFO("tau = " << tau << " (|λτ| ≤ " << rate * tau << ")");
      const Eigen::VectorXd z = flow.transition_matrix(tau) * z0;
      segment.sample(tau, sample);
      segment.state(tau, state);
      for (Eigen::Index i = 0; i < N; ++i) {
        const double scale = std::max(segment.magnitude(i), z.cwiseAbs().maxCoeff());
        CHECK(std::abs(sample.h(i) - functionals.rows(0).row(i).dot(z)) <= 1e-13 * scale);
        CHECK(std::abs(sample.d(i) - functionals.rows(1).row(i).dot(z)) <= 1e-13 * scale * std::max(1.0, rate));
        CHECK(std::abs(sample.c(i) - functionals.rows(2).row(i).dot(z)) <= 1e-13 * scale * std::max(1.0, rate * rate));
        CHECK(std::abs(segment.value(i, tau) - sample.h(i)) <= 1e-15 * scale);
        CHECK(std::abs(state(i) - z(i)) <= 1e-13 * scale);
      }
    }
  }
}

TEST_CASE("segment: evaluate over many times gives, column by column, evaluate at each time bit for bit",
          "[flow][segment]") {
  // The batched Segment::evaluate (the observers' dense samples) settles the method and the
  // table once and must then do per τ the very arithmetic of the single-τ call: exact equality,
  // on every path: spectral (a damped, forced 2-DOF system), the closed form on a Jordan block
  // (a unit mass falling under a constant force: one polynomial term), the closed form with
  // complex clusters of degree > 0 (the free-free chain) and the Padé exponential. The rows
  // (more than the state's, an odd count) are split unevenly between the two outputs, which
  // are windows of wider matrices: a row sent to the wrong output, a column shifted, a τ taken
  // from the wrong origin, a table or exponentials not renewed per column all break equality
  // or the sentinels around the windows.
  struct Case {
    const char* name;
    LinearSystem system;
    FlowOptions options;
    bool closed_form;
  };
  const FlowOptions pade{.method = FlowMethod::exponential, .closed_form = false};
  const std::vector<Case> cases{
      {"spectral, 2-DOF damped and forced", random_problem({2, 7, Damping::full}).system, {}, true},
      {"closed form, falling unit mass", make_system({1, 0, 0, -1}), {}, true},
      {"closed form, free-free chain", free_free_chain(), {}, true},
      {"Padé, 2-DOF damped and forced", random_problem({2, 7, Damping::full}).system, pade, false}};
  Random rng(41);
  for (const Case& c : cases) {
    INFO(c.name);
    const LinearFlow flow(c.system, c.options);
    REQUIRE(flow.closed_form() == c.closed_form);
    if (std::string(c.name).starts_with("spectral")) REQUIRE(flow.method() == FlowMethod::spectral);
    if (std::string(c.name).starts_with("closed form, falling")) {
      REQUIRE(flow.terms().size() == 1);
      REQUIRE(flow.terms()[0].degree == 2);
    }
    const Eigen::Index N = flow.size(), n = flow.dof();
    const vibro::Functionals own(flow, Eigen::MatrixXd::Identity(1, N));
    Eigen::MatrixXd rows(2 * n + 1, N);
    for (Eigen::Index i = 0; i < rows.rows(); ++i) rows.row(i) = rng.vector(N, -1.0, 1.0).transpose();
    const vibro::Functionals other(flow, rows);
    const double t0 = 0.7;
    const vibro::Segment segment(own, t0, flow.augment(t0, rng.vector(n, -1.0, 1.0), rng.vector(n, -1.0, 1.0)));
    // Two groups of the eight times evaluate() takes side by side, and three more alone.
    const std::vector<double> times{t0,  0.71, 0.9, 1.3, 1.3, 2.05, 3.7, 5.2, 6.0, 6.1,
                                    6.4, 7.0,  7.7, 8.1, 8.8, 9.3,  9.9, 10.4, 11.0};
    const auto count = static_cast<Eigen::Index>(times.size());
    const double sentinel = 12345.0;
    const Eigen::Index split = n + 1;
    Eigen::MatrixXd top = Eigen::MatrixXd::Constant(split, count + 2, sentinel);
    Eigen::MatrixXd bottom = Eigen::MatrixXd::Constant(rows.rows() - split, count + 2, sentinel);
    segment.evaluate(other, times.data(), count, t0, top.middleCols(1, count), bottom.middleCols(1, count));
    Eigen::VectorXd single(rows.rows());
    for (Eigen::Index k = 0; k < count; ++k) {
      INFO("t = " << times[static_cast<std::size_t>(k)]);
      segment.evaluate(other, times[static_cast<std::size_t>(k)] - t0, single);
      CHECK(single.allFinite());
      CHECK((top.col(k + 1).array() == single.head(split).array()).all());
      CHECK((bottom.col(k + 1).array() == single.tail(rows.rows() - split).array()).all());
    }
    for (const Eigen::Index k : {Eigen::Index{0}, count + 1}) {
      CHECK((top.col(k).array() == sentinel).all());
      CHECK((bottom.col(k).array() == sentinel).all());
    }
    // And the values are the state's: to rounding against rows × state(τ).
    Eigen::VectorXd z(N);
    segment.state(times.back() - t0, z);
    const Eigen::VectorXd expected = rows * z;
    CHECK((single - expected).cwiseAbs().maxCoeff() <= 1e-12 * std::max(1.0, expected.cwiseAbs().maxCoeff()));
  }
}
