#pragma once
/// \file info.hpp
/// `vibro info`: natural frequencies, modal damping, stops, and for each contact set the
/// restitution matrix (and its modal form) and the reduced sticking equations with their contact
/// forces — for the paper's system, its eqs. 8, 10, 11, 12, 14 and 15 — and the run kinds.
#include "vibro/io/scene.hpp"

#include <string>

namespace vibro::cli {

std::string describe_scene(const io::Scene& scene);

/// The scene's run kind and every run kind there is, one line each (from the table, run_kinds.hpp).
std::string run_text(const io::Scene& scene);

}  // namespace vibro::cli
