/// \file bench_continuation.cpp
/// Cost of the analysis layer (framework/analysis): a Newton iteration (one exact tangent map
/// over a period: flows and saltation matrices), Newton shooting of a periodic orbit, a
/// continuation point — against the running method (running_orbit.hpp: simulate until the orbit
/// repeats) finding the same orbit, for chains of N = 2, 10, 100 masses on the dense engine.
///
/// Problems: N = 2 is the paper's system at Ω = 0.255 (sticking orbit, chatter); N = 10 and 100
/// are uniform chains (m = k = 1, every link and the left wall damped by c = 0.2), driven by
/// 0.5 cos Ωt on mass 0 at Ω = 0.3, with a lower stop at −0.3 under mass 0 and an upper stop at
/// 0.5 above the last mass, r = 0.7.
///
/// For each: the running method from rest (periods until z(t + T) = z(t) to 1e-10); shooting
/// from the state after 5 periods (iterations, time per iteration, the orbits' distance from the
/// running method's); a continuation of 6 points in Ω from that orbit (time per point, tangent
/// maps per point). CPU seconds of this process (std::clock), one thread.
///
/// Usage: bench_continuation [--max-n N]      (N = 2, 10, 100 by default; --max-n 10 for a quick run)
#include "vibro/continuation.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/running_orbit.hpp"
#include "vibro/shooting.hpp"

#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <cstring>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

namespace {

double cpu() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

vibro::ImpactSystem uniform_chain(int n, double omega) {
  vibro::models::Chain c;
  c.masses.assign(static_cast<std::size_t>(n), 1.0);
  c.springs.assign(static_cast<std::size_t>(n - 1), 1.0);
  c.dampers.assign(static_cast<std::size_t>(n - 1), 0.2);
  c.left_spring = 1.0;
  c.left_damper = 0.2;
  c.force_cosine.assign(static_cast<std::size_t>(n), 0.0);
  c.force_cosine[0] = 0.5;
  c.frequency = omega;
  return vibro::ImpactSystem(vibro::models::build_chain(c),
                             {vibro::Stop::lower(0, -0.3, 0.7), vibro::Stop::upper(n - 1, 0.5, 0.7)});
}

struct Problem {
  std::string name;
  int n;
  double omega;
  std::function<vibro::ImpactSystem(double)> at;
};

}  // namespace

int main(int argc, char** argv) {
  int max_n = 100;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--max-n") == 0 && i + 1 < argc) {
      max_n = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: bench_continuation [--max-n N]\n");
      return 2;
    }
  }
  std::vector<Problem> problems;
  problems.push_back({"paper (Wagg 2004)", 2, 0.255, [](double w) {
                        vibro::models::Wagg2004 p;
                        p.frequency = w;
                        return vibro::models::wagg2004(p);
                      }});
  for (int n : {10, 100})
    if (n <= max_n) problems.push_back({"uniform chain", n, 0.3, [n](double w) { return uniform_chain(n, w); }});

  std::printf("| N | problem | running: periods | running: s | shooting: iterations | s per iteration | "
              "shooting: s (incl. 5-period guess) | running / shooting | |Δz| vs running | continuation: s per point | tangent maps per point |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Problem& pr : problems) {
    const vibro::ImpactSystem sys = pr.at(pr.omega);
    const double T = 2.0 * std::numbers::pi / pr.omega;
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(pr.n);

    // The running method from rest.
    vibro::RunningOrbitOptions oo;
    oo.max_periods = 20000;
    oo.max_period = 1;
    double t = cpu();
    const vibro::RunningOrbit run = vibro::run_to_periodic_orbit(sys, oo, 0.0, zero, zero);
    const double run_s = cpu() - t;

    // Shooting from 5 periods of running.
    t = cpu();
    vibro::Simulator sim(sys);
    const vibro::RunSummary guess = sim.run(0.0, zero, zero, 5.0 * T);
    vibro::ShootingOptions so;
    const vibro::ShootingResult shot = vibro::shoot(sys, so, 5.0 * T, guess.x, guess.v);
    const double shoot_s = cpu() - t;
    // A Newton iteration is one tangent map over T (plus the trial's): time it alone.
    t = cpu();
    const int reps = pr.n >= 100 ? 1 : 5;
    for (int r = 0; r < reps; ++r)
      (void)vibro::linearise(sys, {}, shot.t0, shot.x, shot.v, shot.t0 + T);
    const double per_iteration = (cpu() - t) / reps;
    // Distance from the running method's orbit, at the shooting section.
    double dz = -1.0;
    if (run.periodic && shot.converged()) {
      const vibro::RunSummary at = sim.run(0.0, run.x, run.v, shot.t0);
      dz = std::max((at.x - shot.x).cwiseAbs().maxCoeff(), (at.v - shot.v).cwiseAbs().maxCoeff());
    }

    // Six continuation points in Ω (no location: the cost of stepping).
    double per_point = -1.0, maps_per_point = -1.0;
    if (shot.converged()) {
      vibro::ContinuationOptions co;
      co.p_min = pr.omega - 0.01;
      co.p_max = pr.omega + 0.01;
      co.max_points = 6;
      co.step = 0.05;
      co.locate = false;
      co.max_doublings = 0;
      co.direction = 1;
      const vibro::ParameterFamily family = [&pr](double w) {
        return vibro::FamilyPoint{pr.at(w), vibro::SystemDerivative::frequency_only()};
      };
      t = cpu();
      const vibro::ContinuationResult cr = vibro::continue_orbits(family, pr.omega, shot.t0, shot.x, shot.v, co);
      const double cont_s = cpu() - t;
      std::size_t points = 0;
      for (const vibro::Branch& b : cr.branches) points += b.points.size();
      per_point = cont_s / static_cast<double>(points);
      maps_per_point = static_cast<double>(cr.maps) / static_cast<double>(points);
    }
    std::printf("| %d | %s | %s | %.3g | %d%s | %.3g | %.3g | %.2g | %.1e | %.3g | %.1f |\n", pr.n, pr.name.c_str(),
                run.periodic ? std::to_string(run.periods_run).c_str() : "not periodic", run_s, shot.iterations,
                shot.converged() ? "" : " (not converged)", per_iteration, shoot_s, run_s / shoot_s, dz, per_point,
                maps_per_point);
    std::fflush(stdout);
  }
  return 0;
}
