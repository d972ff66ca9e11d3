// The expression language (expression.hpp) and its compilation (dag.hpp): values, precedence,
// sharing and folding, and the text and column of every kind of error.
#include "vibro/taylor/dag.hpp"
#include "vibro/taylor/expression.hpp"
#include "vibro/taylor/taylor_step.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <string>

using namespace vibro::taylor;

namespace {

/// The value of `text` at x = (0.3, -0.7), v = (1.1, 0.4), t = 2.5, Ω = 1.7, a = 0.9, beta = 2,
/// through the whole chain (parser, Dag, order-0 recurrences).
double value_of(const std::string& text) {
  TaylorSystemSpec spec;
  spec.mass = Eigen::MatrixXd::Identity(2, 2);
  spec.frequency = 1.7;
  spec.parameters = {{"a", 0.9}, {"beta", 2.0}};
  spec.guards = {text};
  TaylorSystem system(spec);
  TaylorStep step(system);
  Eigen::Vector4d z(0.3, -0.7, 1.1, 0.4);
  REQUIRE(step.expand(2.5, z) == StepStatus::ok);
  return step.guard_coefficients(0)[0];
}

/// The error thrown by parsing `text` (n = 2, parameters a and beta) at line 7, column 10.
ExpressionError error_of(const std::string& text) {
  Symbols symbols{.coordinates = 2, .parameters = {"a", "beta"}};
  ExpressionTree tree;
  try {
    parse_expression(text, symbols, tree, {7, 10});
  } catch (const ExpressionError& e) {
    CHECK(tree.nodes.empty());  // a failed parse leaves nothing behind
    return e;
  }
  FAIL("no error for '" << text << "'");
  return ExpressionError(0, 0, "");
}

}  // namespace

TEST_CASE("expressions evaluate with the stated precedence and functions") {
  const double x0 = 0.3, x1 = -0.7, v0 = 1.1, v1 = 0.4, t = 2.5, W = 1.7, a = 0.9, beta = 2.0;
  CHECK(value_of("x0 + x1*v0") == Approx(x0 + x1 * v0).epsilon(1e-15));
  CHECK(value_of("-x0^2") == Approx(-(x0 * x0)).epsilon(1e-15));
  CHECK(value_of("2^3^2") == Approx(512.0).epsilon(1e-15));
  CHECK(value_of("x1^-2") == Approx(1.0 / (x1 * x1)).epsilon(1e-15));
  CHECK(value_of("v0^1.5") == Approx(std::pow(v0, 1.5)).epsilon(1e-15));
  CHECK(value_of("v0^a") == Approx(std::pow(v0, a)).epsilon(1e-15));
  CHECK(value_of("x0 - x1 - v1") == Approx(x0 - x1 - v1).epsilon(1e-15));
  CHECK(value_of("x0 / x1 / v0") == Approx(x0 / x1 / v0).epsilon(1e-15));
  CHECK(value_of("-beta*x0^3 + a*cos(Omega*t)") == Approx(-beta * x0 * x0 * x0 + a * std::cos(W * t)).epsilon(1e-15));
  CHECK(value_of("sin(x0)*cos(x0) + tan(v1) + atan(x1)") ==
        Approx(std::sin(x0) * std::cos(x0) + std::tan(v1) + std::atan(x1)).epsilon(1e-15));
  CHECK(value_of("exp(x1) + log(v0) + sqrt(v1) + tanh(x1)") ==
        Approx(std::exp(x1) + std::log(v0) + std::sqrt(v1) + std::tanh(x1)).epsilon(1e-15));
  CHECK(value_of("pi * 2e-1 + 1.5E+1") == Approx(M_PI * 0.2 + 15.0).epsilon(1e-15));
  CHECK(value_of("+(x0)") == x0);
}

TEST_CASE("the compiler shares common subexpressions and folds constants") {
  Symbols symbols{.coordinates = 1, .parameters = {"beta"}};
  ExpressionTree tree;
  Dag dag(1, {"Omega", "beta"});
  const int first = dag.compile(tree, parse_expression("sin(x0) * (2*3) + x0^3", symbols, tree));
  const int size = dag.size();
  // The same expression again (commuted, other spelling) adds no node.
  const int second = dag.compile(tree, parse_expression("x0*x0^2 + 6*sin(x0)", symbols, tree));
  CHECK(second == first);
  CHECK(dag.size() == size);
  // 2*3 folded: a single Constant 6; cos(x0) reuses the sin(x0) pair (one new node: Cos).
  int constants = 0;
  for (const auto& n : dag.nodes()) constants += n.op == Op::Constant && n.value == 6.0;
  CHECK(constants == 1);
  dag.compile(tree, parse_expression("cos(x0)", symbols, tree));
  CHECK(dag.size() == size + 1);
  // A parameter stays a leaf (a continuation may change it), x + 0 and 1*x simplify away.
  const int b = dag.compile(tree, parse_expression("1*beta + 0", symbols, tree));
  CHECK(dag.nodes()[b].op == Op::Parameter);
  CHECK(dag.nodes()[b].time_constant);
}

TEST_CASE("unknown names and functions are reported with the nearest known one and their column") {
  auto e = error_of("x0 + bta*x1");
  CHECK(e.line == 7);
  CHECK(e.column == 15);  // 'bta' starts at offset 5: column 10 + 5
  CHECK(e.message == "unknown name 'bta' (did you mean 'beta'?)");
  CHECK(std::string(e.what()) == "7:15: unknown name 'bta' (did you mean 'beta'?)");
  e = error_of("sinn(x0)");
  CHECK(e.column == 10);
  CHECK(e.message == "unknown function 'sinn' (did you mean 'sin'?)");
  e = error_of("omega*t");
  CHECK(e.message == "unknown name 'omega' (did you mean 'Omega'?)");
  e = error_of("zzzzzz");
  CHECK(e.message == "unknown name 'zzzzzz'");
}

TEST_CASE("coordinate indices beyond n - 1 are refused") {
  auto e = error_of("x0 + v2");
  CHECK(e.column == 15);
  CHECK(e.message == "'v2': index out of range, the system has n = 2 coordinates (v0 … v1)");
  e = error_of("x10");
  CHECK(e.message == "'x10': index out of range, the system has n = 2 coordinates (x0 … x1)");
}

TEST_CASE("non-smooth functions are refused with the reason") {
  for (const char* name : {"abs", "sign", "floor", "min", "max"}) {
    const auto e = error_of(std::string("1 + ") + name + "(x0)");
    CHECK(e.column == 14);
    CHECK(e.message == std::string("'") + name +
                           "' is not smooth: the Taylor engine needs a right-hand side with every derivative "
                           "along a step; model the switch as a stop or a contact law");
  }
}

TEST_CASE("functions called with the wrong number of arguments are refused") {
  auto e = error_of("sin(x0, x1)");
  CHECK(e.column == 13);  // the '('
  CHECK(e.message == "'sin' takes 1 argument, got 2");
  e = error_of("exp()");
  CHECK(e.message == "'exp' takes 1 argument, got 0");
  e = error_of("2*cos");
  CHECK(e.column == 12);
  CHECK(e.message == "function 'cos' needs an argument: cos(...)");
}

TEST_CASE("syntax errors name the place") {
  auto e = error_of("(x0 + 1");
  CHECK(e.column == 17);
  CHECK(e.message == "missing ')' for the '(' at column 10");
  e = error_of("x0 + ");
  CHECK(e.column == 15);
  CHECK(e.message == "expression ends where an operand is expected");
  e = error_of("x0 ) ");
  CHECK(e.column == 13);
  CHECK(e.message == "unmatched ')'");
  e = error_of("2x0");
  CHECK(e.column == 11);
  CHECK(e.message == "a name directly after the number '2': write '*' for a product");
  e = error_of("x0**2");
  CHECK(e.column == 12);
  CHECK(e.message == "'**' is not an operator: write a power as x^2");
  e = error_of("x0 # 1");
  CHECK(e.column == 13);
  CHECK(e.message == "unexpected '#' after a complete expression");
  e = error_of("   ");
  CHECK(e.message == "empty expression");
  e = error_of("1e999");
  CHECK(e.message == "'1e999' is not a finite number");
}

TEST_CASE("the system rejects bad parameters and sizes") {
  TaylorSystemSpec spec;
  spec.mass = Eigen::MatrixXd::Identity(2, 2);
  spec.forces = {"x0"};
  CHECK_THROWS_WITH(TaylorSystem(spec), "forces has 1 entries, expected n = 2 (one per coordinate, \"\" for none)");
  spec.forces = {"x0", ""};
  spec.parameters = {{"x1", 1.0}};
  CHECK_THROWS_WITH(TaylorSystem(spec), "parameter name 'x1' is taken by a built-in symbol or another parameter");
  spec.parameters = {{"k", 1.0}, {"k", 2.0}};
  CHECK_THROWS_WITH(TaylorSystem(spec), "parameter name 'k' is taken by a built-in symbol or another parameter");
  spec.parameters = {};
  spec.forces = {"x0", "-q*x1"};
  spec.force_sources = {{3, 12}, {4, 12}};
  CHECK_THROWS_WITH(TaylorSystem(spec), "4:13: unknown name 'q'");
}

TEST_CASE("a domain error at the step's start is reported, not hidden") {
  TaylorSystemSpec spec;
  spec.mass = Eigen::MatrixXd::Identity(1, 1);
  spec.forces = {"log(x0)"};
  TaylorSystem system(spec);
  TaylorStep step(system);
  CHECK(step.expand(1.5, Eigen::Vector2d(-0.25, 0.0)) == StepStatus::domain_error);
  CHECK(step.trouble() == "log(x0): logarithm of -0.25 (needs a positive argument) at t = 1.5");
}
