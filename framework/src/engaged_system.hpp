#pragma once
// Private to vibro_core: a scene's linear system with compliant stops engaged, shared by the
// dense engine's modes (contact.cpp) and the Taylor engine (taylor_simulator.cpp).
#include "vibro/contact.hpp"

namespace vibro::detail {

/// The damping, stiffness and forcing of a scene's system with the compliant stops `engaged`
/// engaged (stops.hpp): each adds its spring k_s w wᵀ to K, its dashpot c_s w wᵀ to C and
/// w (k_s s(t) + c_s s'(t) − F_p) to f (the stop's motion s, every harmonic of it).
struct EngagedSystem {
  Eigen::MatrixXd damping, stiffness;
  HarmonicForcing forcing;
};
EngagedSystem engaged_system(const ImpactSystem& scene, const ContactSet& engaged);

}  // namespace vibro::detail
