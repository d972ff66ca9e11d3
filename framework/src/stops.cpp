#include "vibro/stops.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace vibro {
namespace {

/// α s_a(t) + β s_b(t) as a trigonometric polynomial in θ = Ωt: c0 + Σ_k (c_k cos kθ + d_k sin kθ),
/// one term per order k present (the first harmonic included).
struct TrigSum {
  double c0 = 0.0;
  std::map<int, std::pair<double, double>> terms;  // order: (c_k, d_k)
  /// f(θ) (derivative 0), f'(θ) (1) or f''(θ) (2).
  double at(double theta, int derivative) const {
    double out = derivative == 0 ? c0 : 0.0;
    for (const auto& [k, cd] : terms) {
      const double w = static_cast<double>(k), c = std::cos(w * theta), s = std::sin(w * theta);
      switch (derivative) {
        case 0: out += cd.first * c + cd.second * s; break;
        case 1: out += w * (cd.second * c - cd.first * s); break;
        default: out -= w * w * (cd.first * c + cd.second * s); break;
      }
    }
    return out;
  }
};

/// The least value of f over a period [0, 2π), decided against 0 with a certificate: on an interval
/// of width h between samples, f ≥ min(f(a), f(b)) − M₂h²/8 with M₂ = Σ_k k² √(c_k² + d_k²) ≥ |f''|
/// (the linear interpolant's error bound), less a rounding margin for the evaluations. Intervals
/// whose bound is not positive are halved until every one is certified positive (returns a
/// positive value: the least sample, polished by Newton's method on f') or a sample is ≤ 0 (returns
/// that sample's value, polished likewise: the pair closes). An interval still undecided at width
/// 2π·1e-12 holds a minimum within rounding of 0, counted as closing (0 returned at worst).
double least_value(const TrigSum& f) {
  double m2 = 0.0, size = std::abs(f.c0);
  int top = 1;
  for (const auto& [k, cd] : f.terms) {
    const double r = std::hypot(cd.first, cd.second);
    m2 += static_cast<double>(k) * static_cast<double>(k) * r;
    size += r;
    top = std::max(top, k);
  }
  const double rounding = 16.0 * std::numeric_limits<double>::epsilon() * size;
  const double period = 2.0 * std::numbers::pi;
  double best = std::numeric_limits<double>::infinity(), best_theta = 0.0;
  auto sample = [&](double theta) {
    const double v = f.at(theta, 0);
    if (v < best) {
      best = v;
      best_theta = theta;
    }
    return v;
  };
  struct Piece {
    double a, b, fa, fb;
  };
  std::vector<Piece> open;
  const int first = 8 * top;
  double previous = sample(0.0);
  for (int i = 1; i <= first; ++i) {
    const double a = period * (i - 1) / first, b = period * i / first;
    const double fb = i == first ? f.at(0.0, 0) : sample(b);
    open.push_back({a, b, previous, fb});
    previous = fb;
  }
  bool closes = best <= 0.0;
  while (!closes && !open.empty()) {
    const Piece p = open.back();
    open.pop_back();
    const double h = p.b - p.a;
    if (std::min(p.fa, p.fb) - m2 * h * h / 8.0 - rounding > 0.0) continue;  // certified positive
    if (h < period * 1e-12) {
      closes = true;  // a minimum within rounding of 0
      best = std::min(best, 0.0);
      break;
    }
    const double mid = 0.5 * (p.a + p.b), fm = sample(mid);
    if (fm <= 0.0) {
      closes = true;
      break;
    }
    open.push_back({p.a, mid, p.fa, fm});
    open.push_back({mid, p.b, fm, p.fb});
  }
  // Polish the least sample towards its local minimum (for the value reported).
  double theta = best_theta;
  for (int i = 0; i < 50; ++i) {
    const double d1 = f.at(theta, 1), d2 = f.at(theta, 2);
    if (!(d2 > 0.0)) break;
    const double step = d1 / d2;
    theta -= step;
    const double v = f.at(theta, 0);
    if (v < best) best = v;
    if (std::abs(step) <= 1e-15 * period) break;
  }
  return closes ? std::min(best, 0.0) : best;
}

/// The least clearance min_t (α s_a(t) + β s_b(t)) between two stops on opposite sides of one
/// direction (α, β > 0 scale each to the unit normal). With the first harmonic only, s(t) = s0 +
/// s_c cos Ωt + s_s sin Ωt and the sum's least value is its mean minus the amplitude of the summed
/// harmonic, exactly: two stops that move together (fixed to one shaken rig) keep their clearance
/// however far they move, while the amplitudes summed would refuse them. With higher harmonics the
/// sum is a trigonometric polynomial whose least value over a period is decided against 0 by the
/// certified search of least_value: a pair is refused exactly when its clearance reaches 0.
double least_room(const Stop& a, const Stop& b, double alpha, double beta) {
  if (!a.has_higher_harmonics() && !b.has_higher_harmonics())
    return alpha * a.s0() + beta * b.s0() -
           std::hypot(alpha * a.s_cos() + beta * b.s_cos(), alpha * a.s_sin() + beta * b.s_sin());
  TrigSum f;
  f.c0 = alpha * a.s0() + beta * b.s0();
  f.terms[1] = {alpha * a.s_cos() + beta * b.s_cos(), alpha * a.s_sin() + beta * b.s_sin()};
  for (std::size_t h = 0; h < a.harmonics.size(); ++h) {
    std::pair<double, double>& sum = f.terms[a.harmonics[h].order];
    sum.first += alpha * a.h_cos(h);
    sum.second += alpha * a.h_sin(h);
  }
  for (std::size_t h = 0; h < b.harmonics.size(); ++h) {
    std::pair<double, double>& sum = f.terms[b.harmonics[h].order];
    sum.first += beta * b.h_cos(h);
    sum.second += beta * b.h_sin(h);
  }
  return least_value(f);
}

std::string label(const Stop& stop, std::size_t j) {
  return "stops[" + std::to_string(j) + "] (" + stop.name + ")";
}

const char* kind_name(Stop::Kind k) {
  switch (k) {
    case Stop::Kind::upper: return "upper";
    case Stop::Kind::lower: return "lower";
    case Stop::Kind::between: return "between";
    case Stop::Kind::normal: return "normal";
  }
  return "?";
}

/// "normal 1·x0 - 0.5·x1" (the first four nonzero terms, then "…").
std::string general_name(const Eigen::VectorXd& n) {
  std::string out = "normal";
  int terms = 0;
  for (Eigen::Index i = 0; i < n.size(); ++i) {
    if (n(i) == 0.0) continue;
    if (terms == 4) return out + " + …";
    if (terms == 0) out += " " + number_text(n(i));
    else out += (n(i) < 0.0 ? " - " : " + ") + number_text(std::abs(n(i)));
    out += "·x" + std::to_string(i);
    ++terms;
  }
  return out;
}

/// The checks of a general stop's normal: length n, finite entries, not zero.
void check_general(const Stop& s, const std::string& who, Eigen::Index n) {
  if (s.direction.size() != n)
    throw InvalidInput(who + ": normal has " + std::to_string(s.direction.size()) +
                       " entries: expected one per degree of freedom, " + std::to_string(n));
  for (Eigen::Index i = 0; i < n; ++i)
    if (!std::isfinite(s.direction(i)))
      throw InvalidInput(who + ": normal[" + std::to_string(i) + "] is " + number_text(s.direction(i)) +
                         ": must be finite");
  if (s.direction.lpNorm<Eigen::Infinity>() == 0.0)
    throw InvalidInput(who + ": normal is zero: a stop needs a nonzero normal n (nᵀx ≤ position)");
}

/// Parallel and antiparallel pairs among stops of which at least one is general, compared on
/// unit normals u = w/|w| with offsets s/|w|: |u_a·u_b| ≥ 1 − 1e-12 (angle below ~1.4e-6 rad)
/// counts as parallel. The pairs are visited in the order (j, k), j < k.
void check_general_pairs(const std::vector<Stop>& stops, Eigen::Index n) {
  std::vector<std::size_t> general;
  for (std::size_t j = 0; j < stops.size(); ++j)
    if (stops[j].kind == Stop::Kind::normal) general.push_back(j);
  if (general.empty()) return;
  for (std::size_t j = 0; j < stops.size(); ++j) {
    const Eigen::VectorXd wa = stops[j].normal(n);
    const double na = wa.norm();
    for (std::size_t k = j + 1; k < stops.size(); ++k) {
      const Stop& a = stops[j];
      const Stop& b = stops[k];
      if (a.kind != Stop::Kind::normal && b.kind != Stop::Kind::normal) continue;
      if (a.is_compliant() || b.is_compliant()) continue;  // may overlap (a two-stage stop)
      const Eigen::VectorXd wb = b.normal(n);
      const double nb = wb.norm();
      const double cosine = wa.dot(wb) / (na * nb);
      if (cosine >= 1.0 - 1e-12)
        throw InvalidInput(label(b, k) + ": duplicates " + label(a, j) +
                           " (parallel normals, same side: the nearer stop always binds first); keep one stop per side");
      if (cosine <= -1.0 + 1e-12) {
        // u x ≤ s_a/|w_a| and -u x ≤ s_b/|w_b| need room between them at all times
        // (least_room: two stops moving together keep their clearance).
        const double clearance = a.s0() / na + b.s0() / nb;
        const double room = least_room(a, b, 1.0 / na, 1.0 / nb);
        if (!(room > 0.0))
          throw InvalidInput(label(a, j) + " and " + label(b, k) +
                             " leave no room between them (opposite normals; clearance along the unit normal " +
                             number_text(clearance) + ", stop amplitudes " + number_text(a.motion_extent() / na) +
                             " + " + number_text(b.motion_extent() / nb) + ", least clearance while they move " +
                             number_text(room) + "): the clearance must stay positive");
      }
    }
  }
}

}  // namespace

Stop Stop::general(Eigen::VectorXd normal, double position, double restitution) {
  Stop s;
  s.kind = Kind::normal;
  s.mass = -1;
  s.direction = std::move(normal);
  s.position = position;
  s.restitution = restitution;
  return s;
}

Stop Stop::upper(Eigen::Index mass, double position, double restitution) {
  Stop s;
  s.kind = Kind::upper;
  s.mass = mass;
  s.position = position;
  s.restitution = restitution;
  return s;
}

Stop Stop::lower(Eigen::Index mass, double position, double restitution) {
  Stop s = upper(mass, position, restitution);
  s.kind = Kind::lower;
  return s;
}

Stop Stop::between(Eigen::Index mass, Eigen::Index other, double gap, double restitution) {
  Stop s = upper(mass, gap, restitution);
  s.kind = Kind::between;
  s.other = other;
  return s;
}

Stop Stop::moving(double a, double phi) const {
  Stop s = *this;
  s.amplitude = a;
  s.phase = phi;
  return s;
}

Stop Stop::with_harmonics(std::vector<StopHarmonic> higher) const {
  Stop s = *this;
  s.harmonics.insert(s.harmonics.end(), higher.begin(), higher.end());
  return s;
}

Stop Stop::compliant(double k, double c, double preload_force) const {
  Stop s = *this;
  s.law = Law::compliant;
  s.stiffness = k;
  s.damping = c;
  s.preload = preload_force;
  return s;
}

bool has_compliant(const std::vector<Stop>& stops) {
  return std::any_of(stops.begin(), stops.end(), [](const Stop& s) { return s.is_compliant(); });
}

Eigen::VectorXd Stop::normal(Eigen::Index n) const {
  if (kind == Kind::normal) return direction;
  Eigen::VectorXd w = Eigen::VectorXd::Zero(n);
  switch (kind) {
    case Kind::upper: w(mass) = 1.0; break;
    case Kind::lower: w(mass) = -1.0; break;
    case Kind::between:
      w(mass) = 1.0;
      w(other) = -1.0;
      break;
    case Kind::normal: break;
  }
  return w;
}

// s(t) = ±(p + a cos(Ωt + φ)) = ±(p + a cos φ cos Ωt - a sin φ sin Ωt); minus for a lower stop.
double Stop::s0() const { return kind == Kind::lower ? -position : position; }
double Stop::s_cos() const {
  const double v = amplitude * std::cos(phase);
  return kind == Kind::lower ? -v : v;
}
double Stop::s_sin() const {
  const double v = -amplitude * std::sin(phase);
  return kind == Kind::lower ? -v : v;
}

double Stop::h_cos(std::size_t h) const {
  const double v = harmonics[h].cosine;
  return kind == Kind::lower ? -v : v;
}
double Stop::h_sin(std::size_t h) const {
  const double v = harmonics[h].sine;
  return kind == Kind::lower ? -v : v;
}

double Stop::motion_extent() const {
  double e = amplitude;
  for (const StopHarmonic& h : harmonics) e += std::hypot(h.cosine, h.sine);
  return e;
}

double Stop::motion_speed(double frequency) const {
  double e = amplitude;
  for (const StopHarmonic& h : harmonics) e += static_cast<double>(h.order) * std::hypot(h.cosine, h.sine);
  return frequency * e;
}

double stop_higher_motion(const Stop& stop, double frequency, double t, int derivative) {
  double out = 0.0;
  for (std::size_t h = 0; h < stop.harmonics.size(); ++h) {
    const double w = stop.harmonics[h].rate(frequency), c = std::cos(w * t), s = std::sin(w * t);
    const double a = stop.h_cos(h), b = stop.h_sin(h);
    switch (derivative) {
      case 0: out += a * c + b * s; break;
      case 1: out += w * (-a * s + b * c); break;
      default: out -= w * w * (a * c + b * s); break;
    }
  }
  return out;
}

double stop_motion(const Stop& s, double frequency, double t, int derivative) {
  const double w = frequency, c = std::cos(w * t), sn = std::sin(w * t);
  double first = 0.0;
  switch (derivative) {
    case 0: first = s.s0() + s.s_cos() * c + s.s_sin() * sn; break;
    case 1: first = w * (-s.s_cos() * sn + s.s_sin() * c); break;
    default: first = -w * w * (s.s_cos() * c + s.s_sin() * sn); break;
  }
  return first + stop_higher_motion(s, frequency, t, derivative);
}

std::size_t forcing_slot(const HarmonicForcing& forcing, int order) {
  for (std::size_t h = 0; h < forcing.harmonics.size(); ++h)
    if (forcing.harmonics[h].order == order) return h;
  throw std::logic_error("forcing_slot: the forcing has no harmonic of order " + std::to_string(order) +
                         " (ImpactSystem adds one for every order a stop moves at)");
}

std::vector<Stop> validated_stops(std::vector<Stop> stops, Eigen::Index n, double frequency) {
  for (std::size_t j = 0; j < stops.size(); ++j) {
    Stop& s = stops[j];
    if (s.name.empty() && s.kind == Stop::Kind::normal) {
      s.name = general_name(s.direction);
    } else if (s.name.empty()) {
      s.name = std::string(kind_name(s.kind)) + " x" + std::to_string(s.mass);
      if (s.kind == Stop::Kind::between) s.name += "-x" + std::to_string(s.other);
    }
    const std::string who = label(s, j);
    if (s.kind == Stop::Kind::normal) check_general(s, who, n);
    if (s.kind != Stop::Kind::normal && (s.mass < 0 || s.mass >= n))
      throw InvalidInput(who + ": mass index " + std::to_string(s.mass) + " is out of range [0, " +
                         std::to_string(n - 1) + "]");
    if (s.kind == Stop::Kind::between) {
      if (s.other < 0 || s.other >= n)
        throw InvalidInput(who + ": other mass index " + std::to_string(s.other) +
                           " is out of range [0, " + std::to_string(n - 1) + "]");
      if (s.other == s.mass)
        throw InvalidInput(who + ": a stop between masses needs two different masses, got " +
                           std::to_string(s.mass) + " twice");
    }
    if (!std::isfinite(s.position))
      throw InvalidInput(who + ": position is " + number_text(s.position) + ": must be finite");
    if (!(s.restitution >= 0.0 && s.restitution <= 1.0))
      throw InvalidInput(who + ": restitution is " + number_text(s.restitution) +
                         ": must lie in [0, 1]");
    if (!std::isfinite(s.amplitude) || s.amplitude < 0.0)
      throw InvalidInput(who + ": amplitude is " + number_text(s.amplitude) + ": must be finite and ≥ 0");
    if (!std::isfinite(s.phase))
      throw InvalidInput(who + ": phase is " + number_text(s.phase) + ": must be finite");
    if (s.is_compliant()) {
      if (!std::isfinite(s.stiffness) || !(s.stiffness > 0.0))
        throw InvalidInput(who + ": stiffness is " + number_text(s.stiffness) +
                           ": a compliant stop needs a finite stiffness > 0");
      if (!std::isfinite(s.damping) || s.damping < 0.0)
        throw InvalidInput(who + ": damping is " + number_text(s.damping) + ": must be finite and ≥ 0");
      if (!std::isfinite(s.preload) || s.preload < 0.0)
        throw InvalidInput(who + ": preload is " + number_text(s.preload) + ": must be finite and ≥ 0");
    }
    if (s.amplitude > 0.0 && frequency == 0.0)
      throw InvalidInput(who + ": a moving stop needs a forcing frequency > 0 (it moves at Ω)");
    for (std::size_t h = 0; h < s.harmonics.size(); ++h) {
      const StopHarmonic& hh = s.harmonics[h];
      const std::string at = who + ": harmonics[" + std::to_string(h) + "]";
      if (hh.order < 2)
        throw InvalidInput(at + ": order " + std::to_string(hh.order) +
                           " (expected a whole number ≥ 2; the first harmonic is amplitude and phase)");
      for (std::size_t k = 0; k < h; ++k)
        if (s.harmonics[k].order == hh.order)
          throw InvalidInput(at + ": order " + std::to_string(hh.order) + " is given twice");
      if (!std::isfinite(hh.cosine) || !std::isfinite(hh.sine))
        throw InvalidInput(at + ": cosine " + number_text(hh.cosine) + ", sine " + number_text(hh.sine) +
                           ": must be finite");
      if (frequency == 0.0)
        throw InvalidInput(at + ": a moving stop needs a forcing frequency > 0 (it moves at multiples of Ω)");
    }
  }

  // Duplicates (same normal, same side) and contradictions (opposite normals leaving no room).
  // A normal has one or two nonzero entries ±1; as sorted (index, sign) pairs it is a key, and
  // only stops with equal or opposite keys can conflict. The pairs are checked in the order
  // (j, k), j < k, that a check of all pairs would take, so the first conflict reported is the
  // same.
  using Key = std::array<long long, 4>;  // (index, sign, index, sign); (-1, 0) when unused
  auto key_of = [](const Stop& s, int flip) {
    const int sign = (s.kind == Stop::Kind::lower ? -1 : 1) * flip;
    Key key{static_cast<long long>(s.mass), sign, -1, 0};
    if (s.kind == Stop::Kind::between) {
      key[2] = static_cast<long long>(s.other);
      key[3] = -sign;
      if (key[2] < key[0]) key = {key[2], key[3], key[0], key[1]};
    }
    return key;
  };
  std::map<Key, std::vector<std::size_t>> by_key;
  for (std::size_t j = 0; j < stops.size(); ++j)
    if (stops[j].kind != Stop::Kind::normal) by_key[key_of(stops[j], 1)].push_back(j);
  for (std::size_t j = 0; j < stops.size(); ++j) {
    if (stops[j].kind == Stop::Kind::normal) continue;
    std::vector<std::size_t> later;
    for (int flip : {1, -1}) {
      const auto it = by_key.find(key_of(stops[j], flip));
      if (it == by_key.end()) continue;
      for (std::size_t k : it->second)
        if (k > j) later.push_back(k);
    }
    std::sort(later.begin(), later.end());
    for (std::size_t k : later) {
      const Stop& a = stops[j];
      const Stop& b = stops[k];
      if (a.is_compliant() || b.is_compliant()) continue;  // may overlap (a two-stage stop)
      if (key_of(a, 1) == key_of(b, 1))
        throw InvalidInput(label(b, k) + ": duplicates " + label(a, j) +
                           " (same coordinate, same side); keep one stop per side");
      // g_j = w x - s_j ≤ 0 and g_k = -w x - s_k ≤ 0 need -s_k ≤ w x ≤ s_j at all times.
      const double room = least_room(a, b, 1.0, 1.0);
      if (!(room > 0.0))
        throw InvalidInput(label(a, j) + " and " + label(b, k) +
                           " leave no room between them (clearance " + number_text(a.s0() + b.s0()) +
                           ", stop amplitudes " + number_text(a.motion_extent()) + " + " +
                           number_text(b.motion_extent()) +
                           ", least clearance while they move " + number_text(room) +
                           "): the clearance must stay positive");
    }
  }
  check_general_pairs(stops, n);
  return stops;
}

double stop_gap(const Stop& s, double frequency, double t, const Eigen::Ref<const Eigen::VectorXd>& x) {
  double wx = 0.0;
  switch (s.kind) {
    case Stop::Kind::upper: wx = x(s.mass); break;
    case Stop::Kind::lower: wx = -x(s.mass); break;
    case Stop::Kind::between: wx = x(s.mass) - x(s.other); break;
    case Stop::Kind::normal: wx = s.direction.dot(x); break;
  }
  const double g = wx - (s.s0() + s.s_cos() * std::cos(frequency * t) + s.s_sin() * std::sin(frequency * t));
  return s.has_higher_harmonics() ? g - stop_higher_motion(s, frequency, t, 0) : g;
}

double stops_length_scale(const std::vector<Stop>& stops, double extra) {
  double L = std::abs(extra);
  for (const Stop& s : stops) L = std::max({L, std::abs(s.position), s.motion_extent()});
  return std::max(L, 1e-300);
}

void check_admissible(const std::vector<Stop>& stops, double frequency, double t,
                      const Eigen::Ref<const Eigen::VectorXd>& x, double tolerance) {
  for (std::size_t j = 0; j < stops.size(); ++j) {
    if (stops[j].is_compliant()) continue;  // a compliant stop may start penetrated (engaged)
    const double g = stop_gap(stops[j], frequency, t, x);
    if (g > tolerance && stops[j].kind == Stop::Kind::normal)
      throw InvalidInput("initial state violates " + label(stops[j], j) + " by " + number_text(g) +
                         " at t = " + number_text(t) + " (nᵀx = " + number_text(stops[j].direction.dot(x)) +
                         ", stop position " + number_text(stops[j].position) + ")");
    if (g > tolerance)
      throw InvalidInput("initial state violates " + label(stops[j], j) + " by " + number_text(g) +
                         " at t = " + number_text(t) + " (x" + std::to_string(stops[j].mass) + " = " +
                         number_text(x(stops[j].mass)) + ", stop position " +
                         number_text(stops[j].position) + ")");
  }
}

namespace {

/// The system with a zero forcing harmonic of every order ≥ 2 a stop moves at and the drive
/// lacks (the system itself when none is missing).
LinearSystem with_stop_orders(LinearSystem system, const std::vector<Stop>& stops) {
  HarmonicForcing f = system.forcing();
  const std::size_t had = f.harmonics.size();
  for (const Stop& s : stops)
    for (const StopHarmonic& h : s.harmonics) {
      bool present = false;
      for (const ForcingHarmonic& fh : f.harmonics) present = present || fh.order == h.order;
      if (!present)
        f.harmonics.push_back({h.order, Eigen::VectorXd::Zero(system.dof()), Eigen::VectorXd::Zero(system.dof())});
    }
  if (f.harmonics.size() == had) return system;
  return LinearSystem(system.mass(), system.damping(), system.stiffness(), std::move(f));
}

}  // namespace

ImpactSystem::ImpactSystem(LinearSystem system, std::vector<Stop> stops)
    : system_(std::move(system)),
      stops_(validated_stops(std::move(stops), system_.dof(), system_.forcing().frequency)) {
  system_ = with_stop_orders(std::move(system_), stops_);
  const Eigen::Index n = system_.dof();
  normals_.resize(n, static_cast<Eigen::Index>(stops_.size()));
  for (std::size_t j = 0; j < stops_.size(); ++j)
    normals_.col(static_cast<Eigen::Index>(j)) = stops_[j].normal(n);
}

Eigen::VectorXd ImpactSystem::gaps(double t, const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const double w = system_.forcing().frequency;
  Eigen::VectorXd g = normals_.transpose() * x;
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    const Stop& s = stops_[j];
    g(static_cast<Eigen::Index>(j)) -= s.s0() + s.s_cos() * std::cos(w * t) + s.s_sin() * std::sin(w * t);
    if (s.has_higher_harmonics()) g(static_cast<Eigen::Index>(j)) -= stop_higher_motion(s, w, t, 0);
  }
  return g;
}

Eigen::VectorXd ImpactSystem::gap_rates(double t, const Eigen::Ref<const Eigen::VectorXd>& v) const {
  const double w = system_.forcing().frequency;
  Eigen::VectorXd g = normals_.transpose() * v;
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    const Stop& s = stops_[j];
    g(static_cast<Eigen::Index>(j)) -= w * (-s.s_cos() * std::sin(w * t) + s.s_sin() * std::cos(w * t));
    if (s.has_higher_harmonics()) g(static_cast<Eigen::Index>(j)) -= stop_higher_motion(s, w, t, 1);
  }
  return g;
}

double ImpactSystem::length_scale(double extra) const { return stops_length_scale(stops_, extra); }

void ImpactSystem::check_admissible(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                    double tolerance) const {
  vibro::check_admissible(stops_, system_.forcing().frequency, t, x, tolerance);
}

}  // namespace vibro
