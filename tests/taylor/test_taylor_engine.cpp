// The Taylor engine (vibro/taylor_simulator.hpp) inside the shared event loop, against the exact
// dense engine on a linear scene with impacts, chatter and sticking.
#include "vibro/io/scene.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"
#include "vibro/taylor_simulator.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

namespace {

vibro::io::Scene wagg_scene() {
  return vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml").build();
}

}  // namespace

// The seed paper's sticking orbit (Wagg 2004, fig. 2): two masses, two stops, impacts that chatter
// to sticking and release, 20 forcing periods (~1200 events). The dense engine's flow is exact to
// ~1e-15 of the scales; the Taylor engine's series is truncated at the unit roundoff of the state's
// scale per step and evaluated by compensated Horner, so both carry only rounding, and they must
// resolve every event alike (same stops, kinds and order). How far their event times may differ is
// set by conditioning: an event time is a root of a guard, and a state difference δ moves it by
// δ/|g'|. The two roundings random-walk apart over the ~1500 steps and ~1200 events (each impact
// passes a velocity error on through the restitution law): measured 6e-14 L in x and 5e-13 V in v
// at the end. In a chatter sequence the approach speeds fall to ~1e-5 V, so the times themselves
// differ by up to ~1e-11 T, while the time error measured on the gap, |Δt|·|g'|/L, is of the
// states' size (measured 1.7e-13). Both that and the states are held to 1e-12 (a few times the
// rounding measured), events at rest (stick, release: both speeds 0; measured 5e-15 T) to 1e-13 T;
// a missed or differently resolved event differs by O(1).
TEST_CASE("a linear scene through the Taylor engine agrees with the exact dense engine", "[taylor][engine]") {
  const vibro::io::Scene scene = wagg_scene();
  const vibro::ImpactSystem system = scene.impact_system();
  const double T = scene.period(), t_end = 20.0 * T;
  vibro::Simulator dense(system, scene.solver);
  vibro::TaylorSimulator taylor(system, {}, scene.solver);
  vibro::EventLog dense_events, taylor_events;
  const vibro::RunSummary a = dense.run(0.0, scene.x0, scene.v0, t_end, {&dense_events});
  const vibro::RunSummary b = taylor.run(0.0, scene.x0, scene.v0, t_end, {&taylor_events});
  REQUIRE(a.status == vibro::RunStatus::completed);
  INFO(b.message);
  REQUIRE(b.status == vibro::RunStatus::completed);
  REQUIRE(a.sticks > 0);
  REQUIRE(a.chatters > 0);
  CHECK(b.impacts == a.impacts);
  CHECK(b.sticks == a.sticks);
  CHECK(b.releases == a.releases);
  CHECK(b.chatters == a.chatters);
  REQUIRE(dense_events.events.size() == taylor_events.events.size());
  const double L = a.length_scale, V = a.velocity_scale;
  double dt_raw = 0.0, dt_gap = 0.0, dt_rest = 0.0;
  for (std::size_t i = 0; i < dense_events.events.size(); ++i) {
    const vibro::Event& e = dense_events.events[i];
    const vibro::Event& f = taylor_events.events[i];
    REQUIRE(e.stop == f.stop);
    REQUIRE(e.kind == f.kind);
    const double dt = std::abs(e.t - f.t), speed = std::max(std::abs(e.v_before), std::abs(e.v_after));
    dt_raw = std::max(dt_raw, dt / T);
    if (speed > 0.0) dt_gap = std::max(dt_gap, dt * speed / L);
    else dt_rest = std::max(dt_rest, dt / T);
  }
  const double dx = (a.x - b.x).cwiseAbs().maxCoeff() / L;
  const double dv = (a.v - b.v).cwiseAbs().maxCoeff() / V;
  INFO(dense_events.events.size() << " events (" << a.impacts << " impacts, " << a.chatters << " chatters, " << a.sticks
                                  << " sticks): max |dt|/T = " << dt_raw << ", |dt||g'|/L = " << dt_gap
                                  << ", at rest |dt|/T = " << dt_rest << "; end |dx|/L = " << dx << ", |dv|/V = " << dv
                                  << "; " << taylor.steps() << " Taylor steps");
  CHECK(dt_gap < 1e-12);
  CHECK(dt_rest < 1e-13);
  CHECK(dt_raw < 1e-10);
  CHECK(dx < 1e-12);
  CHECK(dv < 1e-12);
  WARN("Taylor vs dense: " << dense_events.events.size() << " events, max |dt|/T = " << dt_raw << ", |dt||g'|/L = "
                           << dt_gap << ", at rest |dt|/T = " << dt_rest << "; end |dx|/L = " << dx << ", |dv|/V = " << dv);
}
