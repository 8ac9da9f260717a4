// LDL^T of a small symmetric positive (semi-)definite matrix, in place.
//
// Section 4.3: Cholesky took square roots of small negatives on
// near-singular K; LDL^T needs no square roots. A pivot that is not
// clearly positive (a row that depends on earlier rows, e.g. two joints'
// coincident anchors with CFM = 0) gets 1/D = 0, which leaves that
// direction to the other rows instead of producing inf or NaN.
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace blockstep {

template <int N>
void ldltFactor(Eigen::Matrix<double, N, N>& a, int n) {
  double scale = 0.0;
  for (int i = 0; i < n; ++i)
    scale = std::max(scale, std::abs(a(i, i)));
  const double tiny = 1e-12 * (scale > 0.0 ? scale : 1.0);
  for (int j = 0; j < n; ++j) {
    double d = a(j, j);
    for (int k = 0; k < j; ++k)
      d -= a(j, k) * a(j, k) * a(k, k);  // a(k,k) holds D_k here
    const bool pivotOk = d > tiny;
    for (int i = j + 1; i < n; ++i) {
      double s = a(i, j);
      for (int k = 0; k < j; ++k)
        s -= a(i, k) * a(j, k) * a(k, k);
      a(i, j) = pivotOk ? s / d : 0.0;
    }
    a(j, j) = pivotOk ? d : 0.0;
  }
  // Store 1/D: the solve multiplies, never divides.
  for (int j = 0; j < n; ++j)
    a(j, j) = a(j, j) > 0.0 ? 1.0 / a(j, j) : 0.0;
}

// Solves (L D L^T) x = b with the factor from ldltFactor; b is overwritten.
template <int N>
void ldltSolve(const Eigen::Matrix<double, N, N>& f, int n, double* b) {
  for (int i = 1; i < n; ++i)
    for (int k = 0; k < i; ++k)
      b[i] -= f(i, k) * b[k];
  for (int i = 0; i < n; ++i)
    b[i] *= f(i, i);
  for (int i = n - 2; i >= 0; --i)
    for (int k = i + 1; k < n; ++k)
      b[i] -= f(k, i) * b[k];
}

}  // namespace blockstep
