#include "vibro/parameter.hpp"

#include "vibro/system.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <vector>

namespace vibro {
namespace {

void check_size(const char* what, Eigen::Index rows, Eigen::Index cols, Eigen::Index n_rows, Eigen::Index n_cols) {
  if (rows == 0 && cols == 0) return;
  if (rows != n_rows || cols != n_cols)
    throw InvalidInput(std::string("parameter derivative: ") + what + " is " + std::to_string(rows) + "x" +
                       std::to_string(cols) + ", expected " + std::to_string(n_rows) + "x" + std::to_string(n_cols));
}

template <class Derived>
void check_finite(const char* what, const Eigen::MatrixBase<Derived>& m) {
  if (!m.allFinite()) throw InvalidInput(std::string("parameter derivative: ") + what + " has a value that is not finite");
}

}  // namespace

SystemDerivative SystemDerivative::frequency_only() {
  SystemDerivative d;
  d.frequency = 1.0;
  return d;
}

bool SystemDerivative::is_zero() const {
  auto zero = [](const auto& m) { return m.size() == 0 || m.isZero(0.0); };
  if (!zero(mass) || !zero(damping) || !zero(stiffness) || !zero(constant) || !zero(cosine) || !zero(sine) ||
      !zero(force_parameters))
    return false;
  if (frequency != 0.0) return false;
  for (const auto* list : {&harmonic_cosine, &harmonic_sine})
    for (const Eigen::VectorXd& v : *list)
      if (!zero(v)) return false;
  for (const StopDerivative& s : stops)
    if (!s.is_zero()) return false;
  for (const FrictionDerivative& f : friction)
    if (!f.is_zero()) return false;
  for (const auto* list : {&stop_harmonic_cosine, &stop_harmonic_sine})
    for (const std::vector<double>& stop : *list)
      for (double v : stop)
        if (v != 0.0) return false;
  return true;
}

void SystemDerivative::validate(Eigen::Index n, std::size_t m) const {
  check_size("dM/dp", mass.rows(), mass.cols(), n, n);
  check_size("dC/dp", damping.rows(), damping.cols(), n, n);
  check_size("dK/dp", stiffness.rows(), stiffness.cols(), n, n);
  check_size("dF0/dp", constant.rows(), constant.size() ? 1 : 0, n, 1);
  check_size("dFc/dp", cosine.rows(), cosine.size() ? 1 : 0, n, 1);
  check_size("dFs/dp", sine.rows(), sine.size() ? 1 : 0, n, 1);
  check_finite("dM/dp", mass);
  check_finite("dC/dp", damping);
  check_finite("dK/dp", stiffness);
  check_finite("dF0/dp", constant);
  check_finite("dFc/dp", cosine);
  check_finite("dFs/dp", sine);
  check_finite("d(forces' parameters)/dp", force_parameters);
  for (const auto* list : {&harmonic_cosine, &harmonic_sine})
    for (const Eigen::VectorXd& v : *list) {
      check_size("dFc_h/dp or dFs_h/dp", v.rows(), v.size() ? 1 : 0, n, 1);
      check_finite("dFc_h/dp or dFs_h/dp", v);
    }
  for (const auto* mat : {&mass, &damping, &stiffness}) {
    if (mat->size() == 0) continue;
    const double scale = std::max(mat->cwiseAbs().maxCoeff(), 1e-300);
    if ((*mat - mat->transpose()).cwiseAbs().maxCoeff() > 1e-12 * scale)
      throw InvalidInput("parameter derivative: a matrix derivative is not symmetric");
  }
  if (!std::isfinite(frequency)) throw InvalidInput("parameter derivative: dΩ/dp is not finite");
  if (!stops.empty() && stops.size() != m)
    throw InvalidInput("parameter derivative: " + std::to_string(stops.size()) + " stop derivatives for " +
                       std::to_string(m) + " stops");
  for (const StopDerivative& s : stops)
    if (!std::isfinite(s.offset) || !std::isfinite(s.cosine) || !std::isfinite(s.sine) || !std::isfinite(s.restitution) ||
        !std::isfinite(s.stiffness) || !std::isfinite(s.damping) || !std::isfinite(s.preload))
      throw InvalidInput("parameter derivative: a stop derivative is not finite");
  for (const FrictionDerivative& f : friction)
    if (!std::isfinite(f.normal_load) || !std::isfinite(f.static_coefficient) || !std::isfinite(f.kinetic_coefficient))
      throw InvalidInput("parameter derivative: a frictional contact's derivative is not finite");
  for (const auto* list : {&stop_harmonic_cosine, &stop_harmonic_sine}) {
    if (list->size() > m)
      throw InvalidInput("parameter derivative: stop harmonic derivatives for " + std::to_string(list->size()) +
                         " stops, the system has " + std::to_string(m));
    for (const std::vector<double>& stop : *list)
      for (double v : stop)
        if (!std::isfinite(v)) throw InvalidInput("parameter derivative: a stop harmonic's derivative is not finite");
  }
}

SystemDerivative SystemDerivative::combined(double a, const SystemDerivative& o, double b) const {
  auto mix = [&](const auto& x, const auto& y) -> std::decay_t<decltype(x)> {
    if (x.size() == 0 && y.size() == 0) return x;
    if (x.size() == 0) return b * y;
    if (y.size() == 0) return a * x;
    return a * x + b * y;
  };
  SystemDerivative out;
  out.mass = mix(mass, o.mass);
  out.damping = mix(damping, o.damping);
  out.stiffness = mix(stiffness, o.stiffness);
  out.constant = mix(constant, o.constant);
  out.cosine = mix(cosine, o.cosine);
  out.sine = mix(sine, o.sine);
  out.force_parameters = mix(force_parameters, o.force_parameters);
  for (auto [mine, theirs, into] : {std::tuple{&harmonic_cosine, &o.harmonic_cosine, &out.harmonic_cosine},
                                    std::tuple{&harmonic_sine, &o.harmonic_sine, &out.harmonic_sine}}) {
    into->resize(std::max(mine->size(), theirs->size()));
    for (std::size_t h = 0; h < into->size(); ++h)
      (*into)[h] = mix(h < mine->size() ? (*mine)[h] : Eigen::VectorXd(), h < theirs->size() ? (*theirs)[h] : Eigen::VectorXd());
  }
  out.frequency = a * frequency + b * o.frequency;
  const std::size_t m = std::max(stops.size(), o.stops.size());
  out.stops.resize(m);
  for (std::size_t j = 0; j < m; ++j) {
    const StopDerivative x = j < stops.size() ? stops[j] : StopDerivative{};
    const StopDerivative y = j < o.stops.size() ? o.stops[j] : StopDerivative{};
    out.stops[j] = {a * x.offset + b * y.offset,       a * x.cosine + b * y.cosine,
                    a * x.sine + b * y.sine,           a * x.restitution + b * y.restitution,
                    a * x.stiffness + b * y.stiffness, a * x.damping + b * y.damping,
                    a * x.preload + b * y.preload};
  }
  out.friction.resize(std::max(friction.size(), o.friction.size()));
  for (std::size_t j = 0; j < out.friction.size(); ++j) {
    const FrictionDerivative x = j < friction.size() ? friction[j] : FrictionDerivative{};
    const FrictionDerivative y = j < o.friction.size() ? o.friction[j] : FrictionDerivative{};
    out.friction[j] = {a * x.normal_load + b * y.normal_load, a * x.static_coefficient + b * y.static_coefficient,
                       a * x.kinetic_coefficient + b * y.kinetic_coefficient};
  }
  for (auto [mine, theirs, into] : {std::tuple{&stop_harmonic_cosine, &o.stop_harmonic_cosine, &out.stop_harmonic_cosine},
                                    std::tuple{&stop_harmonic_sine, &o.stop_harmonic_sine, &out.stop_harmonic_sine}}) {
    into->resize(std::max(mine->size(), theirs->size()));
    for (std::size_t j = 0; j < into->size(); ++j) {
      const std::vector<double> none;
      const std::vector<double>& x = j < mine->size() ? (*mine)[j] : none;
      const std::vector<double>& y = j < theirs->size() ? (*theirs)[j] : none;
      (*into)[j].resize(std::max(x.size(), y.size()));
      for (std::size_t i = 0; i < (*into)[j].size(); ++i)
        (*into)[j][i] = a * (i < x.size() ? x[i] : 0.0) + b * (i < y.size() ? y[i] : 0.0);
    }
  }
  return out;
}

}  // namespace vibro
