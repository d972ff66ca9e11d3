#include "vibro/models/chain.hpp"
#include "vibro/simulator.hpp"
#include <catch2/catch.hpp>
TEST_CASE("placeholder") { CHECK(true); }
