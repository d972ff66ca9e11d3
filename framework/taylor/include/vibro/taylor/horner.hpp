#pragma once
/// \file horner.hpp
/// Σ_{k=0}^{p} a_k τ^k by compensated Horner (Graillat, Langlois & Louvet 2005, Alg. 4): the
/// rounding error of each product (TwoProduct) and each sum (TwoSum, Knuth) is carried along and
/// added at the end, so the value is as accurate as if computed in twice the working precision
/// and then rounded. A Taylor step's state (TaylorStep::state) and the Taylor engine's dense
/// output (taylor_simulator.cpp) evaluate their polynomials with it, so they carry only the
/// coefficients' own rounding.
///
/// TwoProduct: the exact error s·τ − fl(s·τ) by a fused multiply-add where the processor has
/// one (x86: detected once at run time, so a build for the baseline instruction set still uses it;
/// other targets: where the compiler targets it, __FMA__), else by Dekker's product (Dekker 1971;
/// Ogita, Rump & Oishi 2005, Alg. 3.3) with Veltkamp's splitting of τ done once per polynomial —
/// the same value (both are exact barring overflow and underflow), so the result does not depend
/// on the processor. horner.cpp is compiled without floating-point contraction: a multiply-add
/// fused by the compiler would break the error-free transformations.

namespace vibro::taylor {

double horner_compensated(const double* a, int p, double tau);

}  // namespace vibro::taylor
