#include "event_loop.hpp"

#include <cmath>
#include <sstream>

namespace vibro::detail {

std::string vector_text(const Eigen::VectorXd& v) {
  std::ostringstream s;
  s.precision(17);
  s << "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v(i);
  s << "]";
  return s.str();
}

void check_run_input(Eigen::Index n, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end) {
  if (x0.size() != n || v0.size() != n)
    throw InvalidInput("initial state: x has " + std::to_string(x0.size()) + " and v has " +
                       std::to_string(v0.size()) + " entries, expected " + std::to_string(n));
  if (!x0.allFinite() || !v0.allFinite())
    throw InvalidInput("initial state: x = " + vector_text(x0) + ", v = " + vector_text(v0) + " is not finite");
  if (!std::isfinite(t0) || !std::isfinite(t_end) || t_end < t0)
    throw InvalidInput("time span: [" + number_text(t0) + ", " + number_text(t_end) + "] must be finite with t_end ≥ t0");
}

std::string event_cap_message(const SimulatorOptions& options, double window, double t, const Stop& stop, int j,
                              const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  // The state itself only where it is short enough to read (RunSummary holds it anyway).
  constexpr Eigen::Index kStateInMessage = 12;
  std::string state;
  if (x.size() <= kStateInMessage) state = ", x = " + vector_text(x) + ", v = " + vector_text(v);
  return "event cap: more than " + std::to_string(options.max_events) + " events within " + number_text(window) +
         " time units, at t = " + number_text(t) + ", stops[" + std::to_string(j) + "] (" + stop.name + ")" + state +
         " (Zeno behaviour the chatter rule did not resolve: raise solver.chatter_velocity or solver.max_events)";
}

}  // namespace vibro::detail
