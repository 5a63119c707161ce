#pragma once
// Exact non-negative least squares with an optional L1 term (thesis eq. 5.28):
//
//   min_{b ≥ 0} ‖A·b − y‖² + λ·‖b‖₁
//
// Because b ≥ 0, ‖b‖₁ = 1ᵀb and the problem is the quadratic program
//
//   min_{b ≥ 0} ½·bᵀQb − cᵀb,   Q = AᵀA,   c = Aᵀy − λ/2·1
//
// (the objective above divided by 2, constants dropped). b = 0 is optimal exactly when c ≤ 0, i.e.
// when λ ≥ λ_max = 2·max_j (Aᵀy)_j (the KKT condition at b = 0: ∇ = −2Aᵀy + λ ≥ 0). So λ is given
// as a fraction f of λ_max and c_j = (Aᵀy)_j − f·max_k (Aᵀy)_k: f = 0 is the plain NNLS of the
// thesis, f = 1 gives b = 0.
//
// The solver is Lawson–Hanson's active-set method run on (Q, c) ("FNNLS", Bro & de Jong 1997)
// with an incrementally updated Cholesky factor of the passive block: finite termination, exact up
// to rounding, and cheap when Q is banded (a column of the deconvolution sees only the K layers of
// one footprint, eq. 5.25) because the gradient is updated over the band only.
#include <Eigen/Core>
#include <vector>

#include "sonar3d/core/params.hpp"

namespace sonar3d {

// A sparse design matrix stored by columns (CSC); row indices increase within a column.
struct SparseColumns {
  int rows = 0;
  int cols = 0;
  std::vector<int> start;  // cols + 1 offsets into row/value
  std::vector<int> row;
  std::vector<float> value;

  int nonzeros() const { return static_cast<int>(row.size()); }
  // out[j] = Σ_i A_ij · y[i] for every column j (out has cols entries).
  void transpose_times(const double* y, double* out) const;
  // out[i] += Σ_j A_ij · b[j] for every row i (out has rows entries).
  void times_add(const double* b, double* out) const;
  // Dense copy (tests, small problems).
  Eigen::MatrixXd to_dense() const;
  static SparseColumns from_dense(const Eigen::MatrixXd& A);
};

// A symmetric matrix whose entries vanish when |j − k| > bandwidth, stored as its upper band:
// upper(j, d) = Q(j, j + d) for 0 ≤ d ≤ bandwidth. A dense matrix is the case bandwidth = n − 1.
class BandMatrix {
 public:
  BandMatrix() = default;
  BandMatrix(int n, int bandwidth);
  int size() const { return n_; }
  int bandwidth() const { return bw_; }
  double operator()(int j, int k) const {
    if (j > k) std::swap(j, k);
    const int d = k - j;
    return d > bw_ ? 0.0 : band_[static_cast<std::size_t>(j) * (bw_ + 1) + d];
  }
  double& upper(int j, int d) { return band_[static_cast<std::size_t>(j) * (bw_ + 1) + d]; }
  double upper(int j, int d) const { return band_[static_cast<std::size_t>(j) * (bw_ + 1) + d]; }

  // Q = AᵀA. The bandwidth is the largest |j − k| of two columns sharing a row.
  static BandMatrix gram(const SparseColumns& A);

 private:
  int n_ = 0;
  int bw_ = 0;
  std::vector<double> band_;
};

struct NnlsOptions {
  // KKT tolerance relative to max_j |c_j|: the solve stops when no zero variable has a gradient
  // component w_j = (c − Qb)_j above tolerance·max|c|.
  double tolerance = 1e-10;
  // Outer (entering-variable) iterations; 0 = 3·n + 30 (Lawson–Hanson use 3·n).
  int max_iterations = 0;
  // A variable whose column is numerically dependent on the passive ones (Cholesky pivot below
  // dependency_tolerance·Q_jj) is not admitted.
  double dependency_tolerance = 1e-12;
  void validate() const;
};

// The one declaration of NnlsOptions' fields (core/params.hpp).
template <class V>
void describe(NnlsOptions& c, V& v) {
  using params::param;
  v.field(c.tolerance, param("tolerance", "", "KKT tolerance relative to max |c_j|")
                           .range_open_low(0, 1)
                           .range_open_high(0, 1)
                           .equation("eq. 5.28"));
  v.field(c.max_iterations,
          param("max_iterations", "", "outer iterations at most (0 = 3 n + 30)").non_negative());
  v.field(c.dependency_tolerance,
          param("dependency_tolerance", "",
                "a variable whose Cholesky pivot is below this fraction of Q_jj is not admitted")
              .range_open_low(0, 1)
              .range_open_high(0, 1));
}

struct NnlsStats {
  int iterations = 0;     // outer iterations (variables entered)
  int removals = 0;       // variables that left the passive set
  int nonzeros = 0;       // final passive set size
  bool converged = true;  // false when max_iterations was reached
  double kkt = 0.0;       // final max violation: max(max_{b_j=0} w_j, max_{b_j>0} |w_j|), absolute
};

// Reusable workspace: one per thread. Not thread-safe itself.
class NnlsSolver {
 public:
  // Minimises ½bᵀQb − cᵀb over b ≥ 0. On entry `b` (size n) must be feasible (b ≥ 0): zeros for a
  // cold start, or a previous solution as a warm start; on exit it holds the solution.
  NnlsStats solve(const BandMatrix& Q, const double* c, double* b, const NnlsOptions& options = {});

 private:
  bool append(const BandMatrix& Q, int j, double dep_tol);  // extends the Cholesky factor
  void refactor(const BandMatrix& Q, double dep_tol);       // rebuilds it for passive_
  void solve_passive(const double* c);                      // z = Q_FF⁻¹ c_F

  std::vector<int> passive_;  // passive set, insertion order = factor order
  std::vector<char> in_passive_;
  std::vector<char> blocked_;
  std::vector<double> L_;  // lower-triangular factor, row-major, capacity cap_ × cap_
  int cap_ = 0;
  std::vector<double> z_, tmp_, w_, b_old_;
  std::vector<int> keep_, touched_, blocked_list_, order_;
};

// λ_max = 2·max_j (Aᵀy)_j (0 when that is ≤ 0): the smallest λ for which b = 0 is optimal.
double lambda_max(const SparseColumns& A, const double* y);

// Convenience for one problem: min ‖Ab − y‖² + λ‖b‖₁, b ≥ 0, λ = lambda_fraction·λ_max.
// `b` is resized to A.cols and overwritten.
NnlsStats nnls_l1(const SparseColumns& A, const double* y, double lambda_fraction,
                  std::vector<double>& b, const NnlsOptions& options = {});
// Dense version (tests, small problems).
NnlsStats nnls_l1(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, double lambda_fraction,
                  Eigen::VectorXd& b, const NnlsOptions& options = {});

// Objective ‖Ab − y‖² + λ·1ᵀb (for tests and reports).
double nnls_objective(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, double lambda,
                      const Eigen::VectorXd& b);

}  // namespace sonar3d
