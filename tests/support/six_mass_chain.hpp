#pragma once
/// \file six_mass_chain.hpp
/// The scene text of the io tests that run one chain on both engines (tests only): six unit masses
/// and springs with dampers 0.05 (C = 0.05 K, so the modal engine applies), driven by 0.6 cos Ωt
/// on mass 0 at Ω = 0.35, a stop above mass 0 (r = 0.6) that the orbit chatters into and is held by
/// once per period, and one below mass 3 (r = 0.8). The model, forcing and stops sections, to be
/// followed by the test's own initial, solver and run sections.
namespace vibro::test {

inline constexpr const char* kSixMassChain = R"(model:
  chain:
    masses: [1, 1, 1, 1, 1, 1]
    springs: [1, 1, 1, 1, 1]
    dampers: [0.05, 0.05, 0.05, 0.05, 0.05]
    left_wall: {spring: 1, damper: 0.05}
forcing:
  frequency: 0.35
  cosine: [0.6, 0, 0, 0, 0, 0]
stops:
  - {mass: 0, side: upper, position: 0.3, restitution: 0.6}
  - {mass: 3, side: lower, position: -0.2, restitution: 0.8}
)";

}  // namespace vibro::test
