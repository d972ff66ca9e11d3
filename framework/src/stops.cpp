#include "vibro/stops.hpp"

#include <cmath>
#include <sstream>

namespace vibro {
namespace {

std::string label(const Stop& stop, std::size_t j) {
  return "stops[" + std::to_string(j) + "] (" + stop.name + ")";
}

const char* kind_name(Stop::Kind k) {
  switch (k) {
    case Stop::Kind::upper: return "upper";
    case Stop::Kind::lower: return "lower";
    case Stop::Kind::between: return "between";
  }
  return "?";
}

}  // namespace

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

Eigen::VectorXd Stop::normal(Eigen::Index n) const {
  Eigen::VectorXd w = Eigen::VectorXd::Zero(n);
  switch (kind) {
    case Kind::upper: w(mass) = 1.0; break;
    case Kind::lower: w(mass) = -1.0; break;
    case Kind::between:
      w(mass) = 1.0;
      w(other) = -1.0;
      break;
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

ImpactSystem::ImpactSystem(LinearSystem system, std::vector<Stop> stops)
    : system_(std::move(system)), stops_(std::move(stops)) {
  const Eigen::Index n = system_.dof();
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    Stop& s = stops_[j];
    if (s.name.empty()) {
      s.name = std::string(kind_name(s.kind)) + " x" + std::to_string(s.mass);
      if (s.kind == Stop::Kind::between) s.name += "-x" + std::to_string(s.other);
    }
    const std::string who = label(s, j);
    if (s.mass < 0 || s.mass >= n)
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
    if (s.amplitude > 0.0 && system_.forcing().frequency == 0.0)
      throw InvalidInput(who + ": a moving stop needs a forcing frequency > 0 (it moves at Ω)");
  }
  normals_.resize(n, static_cast<Eigen::Index>(stops_.size()));
  for (std::size_t j = 0; j < stops_.size(); ++j)
    normals_.col(static_cast<Eigen::Index>(j)) = stops_[j].normal(n);

  // Duplicates (same normal, same side) and contradictions (opposite normals leaving no room).
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    for (std::size_t k = j + 1; k < stops_.size(); ++k) {
      const auto wj = normals_.col(static_cast<Eigen::Index>(j));
      const auto wk = normals_.col(static_cast<Eigen::Index>(k));
      const Stop& a = stops_[j];
      const Stop& b = stops_[k];
      if ((wj - wk).cwiseAbs().maxCoeff() == 0.0)
        throw InvalidInput(label(b, k) + ": duplicates " + label(a, j) +
                           " (same coordinate, same side); keep one stop per side");
      if ((wj + wk).cwiseAbs().maxCoeff() == 0.0) {
        // g_j = w x - s_j ≤ 0 and g_k = -w x - s_k ≤ 0 need -s_k ≤ w x ≤ s_j at all times.
        const double room = a.s0() + b.s0() - a.amplitude - b.amplitude;
        if (!(room > 0.0))
          throw InvalidInput(label(a, j) + " and " + label(b, k) +
                             " leave no room between them (clearance " + number_text(a.s0() + b.s0()) +
                             ", stop amplitudes " + number_text(a.amplitude) + " + " + number_text(b.amplitude) +
                             "): the clearance must stay positive");
      }
    }
  }
}

Eigen::VectorXd ImpactSystem::gaps(double t, const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const double w = system_.forcing().frequency;
  Eigen::VectorXd g = normals_.transpose() * x;
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    const Stop& s = stops_[j];
    g(static_cast<Eigen::Index>(j)) -= s.s0() + s.s_cos() * std::cos(w * t) + s.s_sin() * std::sin(w * t);
  }
  return g;
}

Eigen::VectorXd ImpactSystem::gap_rates(double t, const Eigen::Ref<const Eigen::VectorXd>& v) const {
  const double w = system_.forcing().frequency;
  Eigen::VectorXd g = normals_.transpose() * v;
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    const Stop& s = stops_[j];
    g(static_cast<Eigen::Index>(j)) -= w * (-s.s_cos() * std::sin(w * t) + s.s_sin() * std::cos(w * t));
  }
  return g;
}

double ImpactSystem::length_scale(double extra) const {
  double L = std::abs(extra);
  for (const Stop& s : stops_) L = std::max({L, std::abs(s.position), s.amplitude});
  return std::max(L, 1e-300);
}

void ImpactSystem::check_admissible(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                    double tolerance) const {
  const Eigen::VectorXd g = gaps(t, x);
  for (std::size_t j = 0; j < stops_.size(); ++j)
    if (g(static_cast<Eigen::Index>(j)) > tolerance)
      throw InvalidInput("initial state violates " + label(stops_[j], j) + " by " +
                         number_text(g(static_cast<Eigen::Index>(j))) + " at t = " + number_text(t) +
                         " (x" + std::to_string(stops_[j].mass) + " = " + number_text(x(stops_[j].mass)) +
                         ", stop position " + number_text(stops_[j].position) + ")");
}

}  // namespace vibro
