#pragma once
/// \file signals.hpp
/// SIGINT, SIGTERM and SIGHUP for `vibro run`, from the moment its arguments are read. A run
/// answers them within a second in every phase (docs/results.md, "Signals"):
///
///  * until the run makes its output's lock — while the scene is loaded, built and checked, its
///    work estimated and a sweep's points validated: nothing is on disk yet, and this can sit in
///    Eigen decompositions of n × n matrices that cannot be polled — a signal ends the process at
///    once from its handler: `line` on stderr, exit code 130;
///  * from then on (and on MPI ranks other than 0 from the start of the run kind), the signal only raises a flag that the
///    engines and analyses poll (every event, search step, Krylov product, orbit, point), and the
///    run ends as its kind documents (a simulation writes nothing, a sweep keeps OUT.partial, the
///    other kinds write what was done), with exit code 130.
///
/// A caller with its own flag (RunRequest::interrupt: the Python module) makes no RunSignals.
#include <memory>
#include <string>

namespace vibro::io {

class RunSignals {
 public:
  /// `line`: what a signal before the run prints (one line, no newline; empty: nothing, as on
  /// MPI ranks other than 0).
  explicit RunSignals(const std::string& line);
  ~RunSignals();
  RunSignals(const RunSignals&) = delete;
  RunSignals& operator=(const RunSignals&) = delete;

 private:
  struct Guard;
  std::unique_ptr<Guard> guard_;
};

}  // namespace vibro::io
