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

// A block's matrix is n x n doubles, column-major (Eigen's order), packed:
// a ball joint's takes 72 bytes, not a 6 x 6's 288.
template <int N>
using BlockMap = Eigen::Map<Eigen::Matrix<double, N, N>>;

// The kernels take the size as a template argument so the compiler unrolls
// them; ldltFactor/ldltSolve pick the kernel for a block's row count.
template <int N>
void ldltFactorFixed(double* data) {
  BlockMap<N> a(data);
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
void ldltSolveFixed(const double* data, double* b) {
  const Eigen::Map<const Eigen::Matrix<double, N, N>> f(data);
  for (int i = 1; i < N; ++i)
    for (int k = 0; k < i; ++k)
      b[i] -= f(i, k) * b[k];
  for (int i = 0; i < N; ++i)
    b[i] *= f(i, i);
  for (int i = N - 2; i >= 0; --i)
    for (int k = i + 1; k < N; ++k)
      b[i] -= f(k, i) * b[k];
}

// Replaces a factor from ldltFactorFixed by the matrix of its solve,
// column j = ldltSolve(e_j): K^-1, or on a singular K the map that leaves
// the redundant directions to the other rows, as the solve does. A block
// solved many times between factors (Solver::carryRows: every sweep of a
// step's kept sub-steps) then takes one product, whose terms do not wait
// on each other as the substitutions' do: softcube's 6 x 6 solves took
// 14% of its time.
template <int N>
void ldltInvertFixed(double* data) {
  Eigen::Matrix<double, N, N> inverse;
  for (int j = 0; j < N; ++j) {
    double e[N] = {};
    e[j] = 1.0;
    ldltSolveFixed<N>(data, e);
    for (int i = 0; i < N; ++i)
      inverse(i, j) = e[i];
  }
  BlockMap<N> out(data);
  out = inverse;
}

// K^-1 of a symmetric 3 x 3 (its lower triangle given) by cofactors, in
// place of its factor, when no pivot of an LDL^T could vanish: every
// diagonal above 1e-6 of the largest, and det K above 1e-6 K00 K11 K22
// (the product of the ratios pivot_j / K_jj, each at most 1, so every
// pivot is above 1e-6 of its diagonal). A ball joint's block is 3 x 3 and
// a sub-step that prepares its rows solves it twice (sweep and relax):
// factor and substitutions were 8% of cloth32's time. Returns false, K
// untouched, otherwise: LDL^T then leaves a redundant row to the others.
inline bool invertSymmetric3(double* data) {
  BlockMap<3> k(data);
  const double a = k(0, 0), b = k(1, 0), c = k(2, 0), d = k(1, 1), e = k(2, 1), f = k(2, 2);
  const double largest = std::max({a, d, f});
  if (!(std::min({a, d, f}) > 1e-6 * largest)) return false;
  const double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
  const double det = a * c00 + b * c01 + c * c02;
  if (!(det > 1e-6 * a * d * f)) return false;
  const double s = 1.0 / det;
  const double i01 = c01 * s, i02 = c02 * s, i12 = (b * c - a * e) * s;
  k(0, 0) = c00 * s;
  k(1, 1) = (a * f - c * c) * s;
  k(2, 2) = (a * d - b * b) * s;
  k(0, 1) = k(1, 0) = i01;
  k(0, 2) = k(2, 0) = i02;
  k(1, 2) = k(2, 1) = i12;
  return true;
}

// b = M b (an inverse from ldltInvertFixed).
template <int N>
void multiplyFixed(const double* data, double* b) {
  const Eigen::Map<const Eigen::Matrix<double, N, N>> m(data);
  Eigen::Map<Eigen::Matrix<double, N, 1>> v(b);
  const Eigen::Matrix<double, N, 1> x = m * v;
  v = x;
}

// Runs kernel.operator()<N>() for a block of n = N rows (1 to 6; other
// sizes do nothing): each kernel below is unrolled for its size.
template <typename Kernel>
void forBlockSize(int n, Kernel&& kernel) {
  switch (n) {
    case 1:
      return kernel.template operator()<1>();
    case 2:
      return kernel.template operator()<2>();
    case 3:
      return kernel.template operator()<3>();
    case 4:
      return kernel.template operator()<4>();
    case 5:
      return kernel.template operator()<5>();
    case 6:
      return kernel.template operator()<6>();
    default:
      return;
  }
}

inline void ldltFactor(double* a, int n) {
  forBlockSize(n, [&]<int N>() { ldltFactorFixed<N>(a); });
}

inline void ldltSolve(const double* f, int n, double* b) {
  forBlockSize(n, [&]<int N>() { ldltSolveFixed<N>(f, b); });
}

inline void ldltInvert(double* f, int n) {
  forBlockSize(n, [&]<int N>() { ldltInvertFixed<N>(f); });
}

inline void multiplyBlock(const double* m, int n, double* b) {
  forBlockSize(n, [&]<int N>() { multiplyFixed<N>(m, b); });
}

}  // namespace blockstep
