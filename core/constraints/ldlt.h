// LDL^T of a small symmetric positive (semi-)definite matrix, in place.
//
// Section 4.3: Cholesky took square roots of small negatives on
// near-singular K; LDL^T needs no square roots. A pivot that is not
// clearly positive (a row that depends on earlier rows, e.g. two joints'
// coincident anchors with CFM = 0) gets 1/D = 0, which leaves that
// direction to the other rows instead of producing inf or NaN.
#pragma once

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

namespace blockstep {

using BlockMatrix = Eigen::Matrix<double, 6, 6>;

// The kernels take the size as a template argument so the compiler unrolls
// them; ldltFactor/ldltSolve pick the kernel for a block's row count.
template <int N>
void ldltFactorFixed(BlockMatrix& a) {
  double scale = 0.0;
  for (int i = 0; i < N; ++i)
    scale = std::max(scale, std::abs(a(i, i)));
  const double tiny = 1e-12 * (scale > 0.0 ? scale : 1.0);
  for (int j = 0; j < N; ++j) {
    double d = a(j, j);
    for (int k = 0; k < j; ++k)
      d -= a(j, k) * a(j, k) * a(k, k);  // a(k,k) holds D_k here
    const bool pivotOk = d > tiny;
    const double invD = pivotOk ? 1.0 / d : 0.0;
    for (int i = j + 1; i < N; ++i) {
      double s = a(i, j);
      for (int k = 0; k < j; ++k)
        s -= a(i, k) * a(j, k) * a(k, k);
      a(i, j) = s * invD;
    }
    a(j, j) = pivotOk ? d : 0.0;
  }
  // Store 1/D: the solve multiplies, never divides.
  for (int j = 0; j < N; ++j)
    a(j, j) = a(j, j) > 0.0 ? 1.0 / a(j, j) : 0.0;
}

// Solves (L D L^T) x = b with the factor from ldltFactorFixed; b is overwritten.
template <int N>
void ldltSolveFixed(const BlockMatrix& f, double* b) {
  for (int i = 1; i < N; ++i)
    for (int k = 0; k < i; ++k)
      b[i] -= f(i, k) * b[k];
  for (int i = 0; i < N; ++i)
    b[i] *= f(i, i);
  for (int i = N - 2; i >= 0; --i)
    for (int k = i + 1; k < N; ++k)
      b[i] -= f(k, i) * b[k];
}

inline void ldltFactor(BlockMatrix& a, int n) {
  switch (n) {
    case 1:
      return ldltFactorFixed<1>(a);
    case 2:
      return ldltFactorFixed<2>(a);
    case 3:
      return ldltFactorFixed<3>(a);
    case 4:
      return ldltFactorFixed<4>(a);
    case 5:
      return ldltFactorFixed<5>(a);
    case 6:
      return ldltFactorFixed<6>(a);
    default:
      return;
  }
}

inline void ldltSolve(const BlockMatrix& f, int n, double* b) {
  switch (n) {
    case 1:
      return ldltSolveFixed<1>(f, b);
    case 2:
      return ldltSolveFixed<2>(f, b);
    case 3:
      return ldltSolveFixed<3>(f, b);
    case 4:
      return ldltSolveFixed<4>(f, b);
    case 5:
      return ldltSolveFixed<5>(f, b);
    case 6:
      return ldltSolveFixed<6>(f, b);
    default:
      return;
  }
}

}  // namespace blockstep
