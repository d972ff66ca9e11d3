#include "vibro/base_motion.hpp"

#include <cmath>
#include <string>

namespace vibro {
namespace {

double rate(const BaseHarmonic& h, double frequency) { return static_cast<double>(h.order) * frequency; }

Eigen::VectorXd& harmonic_slot(HarmonicForcing& f, int order, bool cosine) {
  if (order == 1) return cosine ? f.cosine : f.sine;
  for (ForcingHarmonic& h : f.harmonics)
    if (h.order == order) return cosine ? h.cosine : h.sine;
  const Eigen::Index n = f.constant.size();
  f.harmonics.push_back({order, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n)});
  return cosine ? f.harmonics.back().cosine : f.harmonics.back().sine;
}

std::string stop_label(const std::vector<Stop>& stops, std::size_t j) {
  std::string s = "stops[" + std::to_string(j) + "]";
  if (!stops[j].name.empty()) s += " (" + stops[j].name + ")";
  return s;
}

}  // namespace

double BaseExcitation::position(double frequency, double t) const {
  double x = 0.0;
  for (const BaseHarmonic& h : displacement) {
    const double w = rate(h, frequency);
    x += h.cosine * std::cos(w * t) + h.sine * std::sin(w * t);
  }
  return x;
}

double BaseExcitation::velocity(double frequency, double t) const {
  double v = 0.0;
  for (const BaseHarmonic& h : displacement) {
    const double w = rate(h, frequency);
    v += w * (-h.cosine * std::sin(w * t) + h.sine * std::cos(w * t));
  }
  return v;
}

double BaseExcitation::acceleration(double frequency, double t) const {
  double a = 0.0;
  for (const BaseHarmonic& h : displacement) {
    const double w = rate(h, frequency);
    a -= w * w * (h.cosine * std::cos(w * t) + h.sine * std::sin(w * t));
  }
  return a;
}

bool BaseExcitation::has_higher_harmonics() const {
  for (const BaseHarmonic& h : displacement)
    if (h.order >= 2 && (h.cosine != 0.0 || h.sine != 0.0)) return true;
  return false;
}

double BaseExcitation::first_cosine() const {
  for (const BaseHarmonic& h : displacement)
    if (h.order == 1) return h.cosine;
  return 0.0;
}

double BaseExcitation::first_sine() const {
  for (const BaseHarmonic& h : displacement)
    if (h.order == 1) return h.sine;
  return 0.0;
}

void BaseExcitation::validate(Eigen::Index n) const {
  for (std::size_t i = 0; i < displacement.size(); ++i) {
    const BaseHarmonic& h = displacement[i];
    const std::string where = "base displacement harmonic " + std::to_string(i);
    if (h.order < 1) throw InvalidInput(where + ": order " + std::to_string(h.order) + " (expected a whole number ≥ 1)");
    for (std::size_t k = 0; k < i; ++k)
      if (displacement[k].order == h.order)
        throw InvalidInput(where + ": order " + std::to_string(h.order) + " is given twice");
    if (!std::isfinite(h.cosine) || !std::isfinite(h.sine))
      throw InvalidInput(where + ": an amplitude is not finite");
  }
  const std::pair<const char*, const Eigen::VectorXd*> vectors[] = {
      {"influence", &influence}, {"stiffness", &stiffness}, {"damping", &damping}, {"inertia", &inertia}};
  for (const auto& [name, v] : vectors) {
    if (v->size() != n)
      throw InvalidInput(std::string("base ") + name + " vector has " + std::to_string(v->size()) + " entries, expected " +
                         std::to_string(n));
    if (!v->allFinite()) throw InvalidInput(std::string("base ") + name + " vector has a value that is not finite");
  }
}

void add_base_forcing(HarmonicForcing& f, const BaseExcitation& base) {
  for (const BaseHarmonic& h : base.displacement) {
    const double w = rate(h, f.frequency);
    Eigen::VectorXd& c = harmonic_slot(f, h.order, true);
    Eigen::VectorXd& s = harmonic_slot(f, h.order, false);
    if (base.frame == BaseFrame::absolute) {
      c += base.stiffness * h.cosine + base.damping * (h.sine * w);
      s += base.stiffness * h.sine - base.damping * (h.cosine * w);
    } else {
      c += base.inertia * (w * w * h.cosine);
      s += base.inertia * (w * w * h.sine);
    }
  }
}

HarmonicForcing base_forcing_rate(const HarmonicForcing& f, const BaseExcitation& base) {
  const Eigen::Index n = f.constant.size();
  HarmonicForcing d = HarmonicForcing::zero(n, f.frequency);
  for (const ForcingHarmonic& h : f.harmonics)
    d.harmonics.push_back({h.order, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n)});
  for (const BaseHarmonic& h : base.displacement) {
    const double k = static_cast<double>(h.order), w = rate(h, f.frequency);
    Eigen::VectorXd& c = harmonic_slot(d, h.order, true);
    Eigen::VectorXd& s = harmonic_slot(d, h.order, false);
    if (base.frame == BaseFrame::absolute) {  // d/dΩ of C ι b ω and −C ι a ω, ω = kΩ
      c += base.damping * (h.sine * k);
      s -= base.damping * (h.cosine * k);
    } else {  // d/dΩ of M ι ω² (a, b) = 2 k ω M ι (a, b)
      c += base.inertia * (2.0 * k * w * h.cosine);
      s += base.inertia * (2.0 * k * w * h.sine);
    }
  }
  return d;
}

double base_coefficient(const Stop& stop, const Eigen::VectorXd& influence) {
  switch (stop.kind) {
    case Stop::Kind::upper:
    case Stop::Kind::lower: return influence(stop.mass);
    case Stop::Kind::between: return influence(stop.mass) - influence(stop.other);
    case Stop::Kind::normal: return stop.direction.dot(influence);
  }
  return 0.0;
}

void move_stops_with_base(std::vector<Stop>& stops, const std::vector<bool>& attached, const BaseExcitation& base) {
  if (attached.size() != stops.size())
    throw InvalidInput("base: " + std::to_string(attached.size()) + " attachment flags for " +
                       std::to_string(stops.size()) + " stops");
  const bool relative = base.frame == BaseFrame::relative;
  for (std::size_t j = 0; j < stops.size(); ++j) {
    Stop& s = stops[j];
    const double c = base_coefficient(s, base.influence);
    // The stop's position moves by m x_b(t): absolute frame, attached: m = c; relative frame,
    // fixed in the laboratory: m = −c; otherwise it keeps its own motion.
    const double m = attached[j] == relative ? 0.0 : (relative ? -c : c);
    if (m == 0.0) continue;
    if (s.amplitude != 0.0 || s.has_higher_harmonics())
      throw InvalidInput(stop_label(stops, j) + ": " +
                         (relative ? std::string("a stop with its own motion (amplitude, harmonics) that is not attached to the base "
                                                 "moves by its own and the base's motion in the relative frame; use "
                                                 "base.frame: absolute")
                                   : std::string("a stop attached to the base moves with it; its own amplitude or harmonics "
                                                 "would add a second motion: remove them or the attachment")));
    // m (a cos Ωt + b sin Ωt) = A cos(Ωt + φ): A cos φ = m a, −A sin φ = m b.
    const double a = m * base.first_cosine(), b = m * base.first_sine();
    s.amplitude = std::hypot(a, b);
    s.phase = std::atan2(-b, a);
    // Orders ≥ 2 follow as the stop's own higher harmonics, m (a_k cos kΩt + b_k sin kΩt).
    for (const BaseHarmonic& h : base.displacement)
      if (h.order >= 2) s.harmonics.push_back({h.order, m * h.cosine, m * h.sine});
  }
}

}  // namespace vibro
