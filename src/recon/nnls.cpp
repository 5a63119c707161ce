#include "sonar3d/recon/nnls.hpp"

#include <algorithm>
#include <cmath>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

// ---------------------------------------------------------------------------------------------
// SparseColumns

void SparseColumns::transpose_times(const double* y, double* out) const {
  for (int j = 0; j < cols; ++j) {
    double s = 0.0;
    for (int k = start[j]; k < start[j + 1]; ++k) s += value[k] * y[row[k]];
    out[j] = s;
  }
}

void SparseColumns::times_add(const double* b, double* out) const {
  for (int j = 0; j < cols; ++j) {
    const double bj = b[j];
    if (bj == 0.0) continue;
    for (int k = start[j]; k < start[j + 1]; ++k) out[row[k]] += value[k] * bj;
  }
}

Eigen::MatrixXd SparseColumns::to_dense() const {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int k = start[j]; k < start[j + 1]; ++k) A(row[k], j) = value[k];
  }
  return A;
}

SparseColumns SparseColumns::from_dense(const Eigen::MatrixXd& A) {
  SparseColumns S;
  S.rows = static_cast<int>(A.rows());
  S.cols = static_cast<int>(A.cols());
  S.start.assign(S.cols + 1, 0);
  for (int j = 0; j < S.cols; ++j) {
    for (int i = 0; i < S.rows; ++i) {
      if (A(i, j) != 0.0) {
        S.row.push_back(i);
        S.value.push_back(static_cast<float>(A(i, j)));
      }
    }
    S.start[j + 1] = static_cast<int>(S.row.size());
  }
  return S;
}

// ---------------------------------------------------------------------------------------------
// BandMatrix

BandMatrix::BandMatrix(int n, int bandwidth)
    : n_(n),
      bw_(std::max(0, std::min(bandwidth, n - 1))),
      band_(static_cast<std::size_t>(std::max(n, 0)) * (bw_ + 1), 0.0) {}

BandMatrix BandMatrix::gram(const SparseColumns& A) {
  // Row-wise view (CSR) of A, so that Q = Σ_rows a_rowᵀ a_row costs Σ nnz(row)².
  std::vector<int> count(A.rows + 1, 0);
  for (int k = 0; k < A.nonzeros(); ++k) ++count[A.row[k] + 1];
  for (int i = 0; i < A.rows; ++i) count[i + 1] += count[i];
  std::vector<int> col(A.nonzeros());
  std::vector<double> val(A.nonzeros());
  std::vector<int> fill(count.begin(), count.end() - 1);
  for (int j = 0; j < A.cols; ++j) {
    for (int k = A.start[j]; k < A.start[j + 1]; ++k) {
      const int p = fill[A.row[k]]++;
      col[p] = j;  // columns are visited in increasing order: rows stay sorted
      val[p] = A.value[k];
    }
  }
  int bw = 0;
  for (int i = 0; i < A.rows; ++i) {
    if (count[i + 1] > count[i]) bw = std::max(bw, col[count[i + 1] - 1] - col[count[i]]);
  }
  BandMatrix Q(A.cols, bw);
  for (int i = 0; i < A.rows; ++i) {
    for (int p = count[i]; p < count[i + 1]; ++p) {
      const int j = col[p];
      const double vj = val[p];
      for (int q = p; q < count[i + 1]; ++q) Q.upper(j, col[q] - j) += vj * val[q];
    }
  }
  return Q;
}

// ---------------------------------------------------------------------------------------------
// NnlsSolver

void NnlsOptions::validate() const {
  require(std::isfinite(tolerance) && tolerance > 0 && tolerance < 1,
          "parameter 'nnls.tolerance' must lie in (0, 1)");
  require(max_iterations >= 0, "parameter 'nnls.max_iterations' must be >= 0 (0 = automatic)");
  require(
      std::isfinite(dependency_tolerance) && dependency_tolerance > 0 && dependency_tolerance < 1,
      "parameter 'nnls.dependency_tolerance' must lie in (0, 1)");
}

bool NnlsSolver::append(const BandMatrix& Q, int j, double dep_tol) {
  const int s = static_cast<int>(passive_.size());
  if (s + 1 > cap_) {
    const int new_cap = std::max({16, 2 * cap_, s + 1});
    std::vector<double> L(static_cast<std::size_t>(new_cap) * new_cap, 0.0);
    for (int r = 0; r < s; ++r) {
      std::copy(L_.begin() + static_cast<std::size_t>(r) * cap_,
                L_.begin() + static_cast<std::size_t>(r) * cap_ + r + 1,
                L.begin() + static_cast<std::size_t>(r) * new_cap);
    }
    L_.swap(L);
    cap_ = new_cap;
  }
  const double qjj = Q(j, j);
  if (!(qjj > 0.0)) return false;
  double* l = &L_[static_cast<std::size_t>(s) * cap_];
  // Forward substitution L·l = Q_{F,j}.
  double norm2 = 0.0;
  for (int t = 0; t < s; ++t) {
    const double* Lt = &L_[static_cast<std::size_t>(t) * cap_];
    double v = Q(passive_[t], j);
    for (int u = 0; u < t; ++u) v -= Lt[u] * l[u];
    v /= Lt[t];
    l[t] = v;
    norm2 += v * v;
  }
  const double d2 = qjj - norm2;
  // A column (numerically) in the span of the passive ones would make Q_FF singular.
  if (!(d2 > dep_tol * qjj)) return false;
  l[s] = std::sqrt(d2);
  return true;
}

void NnlsSolver::refactor(const BandMatrix& Q, double dep_tol) {
  order_.swap(passive_);
  passive_.clear();
  for (int j : order_) {
    if (append(Q, j, dep_tol)) {
      passive_.push_back(j);
    } else {
      in_passive_[j] = 0;  // cannot happen in exact arithmetic (a subset of independent columns)
    }
  }
}

void NnlsSolver::solve_passive(const double* c) {
  const int s = static_cast<int>(passive_.size());
  z_.resize(s);
  tmp_.resize(s);
  for (int t = 0; t < s; ++t) {
    const double* Lt = &L_[static_cast<std::size_t>(t) * cap_];
    double v = c[passive_[t]];
    for (int u = 0; u < t; ++u) v -= Lt[u] * tmp_[u];
    tmp_[t] = v / Lt[t];
  }
  for (int t = s - 1; t >= 0; --t) {
    double v = tmp_[t];
    for (int u = t + 1; u < s; ++u) v -= L_[static_cast<std::size_t>(u) * cap_ + t] * z_[u];
    z_[t] = v / L_[static_cast<std::size_t>(t) * cap_ + t];
  }
}

namespace {

// w = c − Q·b over the whole vector.
void full_gradient(const BandMatrix& Q, const double* c, const double* b, std::vector<double>& w) {
  const int n = Q.size();
  const int bw = Q.bandwidth();
  for (int j = 0; j < n; ++j) w[j] = c[j];
  for (int j = 0; j < n; ++j) {
    const double bj = b[j];
    if (bj == 0.0) continue;
    w[j] -= Q.upper(j, 0) * bj;
    for (int d = 1; d <= bw && j + d < n; ++d) w[j + d] -= Q.upper(j, d) * bj;
    for (int d = 1; d <= bw && j - d >= 0; ++d) w[j - d] -= Q.upper(j - d, d) * bj;
  }
}

// w −= Q·e_j·delta, over the band of column j.
inline void gradient_update(const BandMatrix& Q, int j, double delta, std::vector<double>& w) {
  const int n = Q.size();
  const int bw = Q.bandwidth();
  w[j] -= Q.upper(j, 0) * delta;
  for (int d = 1; d <= bw && j + d < n; ++d) w[j + d] -= Q.upper(j, d) * delta;
  for (int d = 1; d <= bw && j - d >= 0; ++d) w[j - d] -= Q.upper(j - d, d) * delta;
}

}  // namespace

NnlsStats NnlsSolver::solve(const BandMatrix& Q, const double* c, double* b,
                            const NnlsOptions& options) {
  const int n = Q.size();
  NnlsStats stats;
  if (n == 0) return stats;
  double cmax = 0.0;
  bool any_positive_b = false;
  for (int j = 0; j < n; ++j) {
    cmax = std::max(cmax, std::abs(c[j]));
    if (!(b[j] > 0.0)) b[j] = 0.0;  // clamp an infeasible or NaN warm start
    any_positive_b = any_positive_b || b[j] > 0.0;
  }
  if (cmax == 0.0) {
    // ½bᵀQb ≥ 0 with c = 0: b = 0 is optimal.
    std::fill(b, b + n, 0.0);
    return stats;
  }
  if (!any_positive_b) {
    bool any_positive_c = false;
    for (int j = 0; j < n && !any_positive_c; ++j) any_positive_c = c[j] > 0.0;
    // c ≤ 0 and Q ⪰ 0: every feasible b has objective ≥ 0 = f(0) (the λ ≥ λ_max case).
    if (!any_positive_c) return stats;
  }
  const double tol = options.tolerance * cmax;
  const double dep = options.dependency_tolerance;
  const int max_iter = options.max_iterations > 0 ? options.max_iterations : 3 * n + 30;

  in_passive_.assign(n, 0);
  blocked_.assign(n, 0);
  w_.resize(n);
  b_old_.resize(n);
  passive_.clear();
  std::vector<int>& blocked_list = blocked_list_;
  std::vector<int>& touched = touched_;
  blocked_list.clear();

  // Lawson–Hanson inner loop: from a feasible b with b_F > 0, move toward the unconstrained
  // passive solution z, dropping the variables that hit zero, until z > 0. `entering` is the
  // variable just added (−1 for a warm start); returns false when it had to be rejected.
  auto inner = [&](int entering) -> bool {
    bool first = true;
    while (true) {
      solve_passive(c);
      const int s = static_cast<int>(passive_.size());
      bool feasible = true;
      for (int t = 0; t < s; ++t) {
        if (!(z_[t] > 0.0)) {
          feasible = false;
          break;
        }
      }
      if (feasible) {
        for (int t = 0; t < s; ++t) b[passive_[t]] = z_[t];
        return true;
      }
      if (first && entering >= 0 && !(z_[s - 1] > 0.0)) {
        // In exact arithmetic w_j > 0 implies z_j > 0 (Lawson & Hanson, Lemma 23.17); rounding
        // broke it: reject the variable rather than cycle. It is the last factor row.
        passive_.pop_back();
        in_passive_[entering] = 0;
        return false;
      }
      first = false;
      double alpha = 1.0;
      int arg = -1;
      for (int t = 0; t < s; ++t) {
        if (z_[t] > 0.0) continue;
        const double bt = b[passive_[t]];
        const double a = bt / (bt - z_[t]);
        if (a < alpha || arg < 0) {
          alpha = a;
          arg = t;
        }
      }
      std::vector<int>& keep = keep_;
      keep.clear();
      for (int t = 0; t < s; ++t) {
        const int j = passive_[t];
        double v = b[j] + alpha * (z_[t] - b[j]);
        if (t == arg || !(v > 0.0)) {
          b[j] = 0.0;
          in_passive_[j] = 0;
          ++stats.removals;
        } else {
          b[j] = v;
          keep.push_back(j);
        }
      }
      passive_.swap(keep);
      refactor(Q, dep);
      if (passive_.empty()) return true;
    }
  };

  // Warm start: passive set = support of b, restored to a passive-optimal point.
  for (int j = 0; j < n; ++j) {
    if (b[j] > 0.0) {
      passive_.push_back(j);
      in_passive_[j] = 1;
    }
  }
  if (!passive_.empty()) {
    refactor(Q, dep);
    for (int j = 0; j < n; ++j) {
      if (b[j] > 0.0 && !in_passive_[j]) b[j] = 0.0;  // dependent columns dropped
    }
    inner(-1);
  }
  full_gradient(Q, c, b, w_);

  for (int round = 0; round < 3; ++round) {
    while (true) {
      int jmax = -1;
      double wmax = tol;
      for (int j = 0; j < n; ++j) {
        if (!in_passive_[j] && !blocked_[j] && w_[j] > wmax) {
          wmax = w_[j];
          jmax = j;
        }
      }
      if (jmax < 0) break;
      if (stats.iterations >= max_iter) {
        stats.converged = false;
        break;
      }
      ++stats.iterations;
      if (!append(Q, jmax, dep)) {
        blocked_[jmax] = 1;
        blocked_list.push_back(jmax);
        continue;
      }
      passive_.push_back(jmax);
      in_passive_[jmax] = 1;
      touched.assign(passive_.begin(), passive_.end());
      for (int j : touched) b_old_[j] = b[j];
      if (!inner(jmax)) {
        blocked_[jmax] = 1;
        blocked_list.push_back(jmax);
        continue;
      }
      for (int j : touched) {
        const double delta = b[j] - b_old_[j];
        if (delta != 0.0) gradient_update(Q, j, delta, w_);
      }
      for (int j : blocked_list) blocked_[j] = 0;  // b moved: give them another chance
      blocked_list.clear();
    }
    // Recompute the gradient from scratch: incremental updates drift by rounding.
    full_gradient(Q, c, b, w_);
    bool violated = false;
    for (int j = 0; j < n && !violated; ++j) {
      violated = !in_passive_[j] && !blocked_[j] && w_[j] > tol;
    }
    if (!violated || !stats.converged) break;
  }

  double kkt = 0.0;
  for (int j = 0; j < n; ++j) {
    kkt = std::max(kkt, in_passive_[j] ? std::abs(w_[j]) : std::max(0.0, w_[j]));
  }
  stats.kkt = kkt;
  stats.nonzeros = static_cast<int>(passive_.size());
  return stats;
}

// ---------------------------------------------------------------------------------------------
// Convenience wrappers

double lambda_max(const SparseColumns& A, const double* y) {
  std::vector<double> g(A.cols);
  A.transpose_times(y, g.data());
  double m = 0.0;
  for (double v : g) m = std::max(m, v);
  return 2.0 * m;
}

NnlsStats nnls_l1(const SparseColumns& A, const double* y, double lambda_fraction,
                  std::vector<double>& b, const NnlsOptions& options) {
  options.validate();
  require(std::isfinite(lambda_fraction) && lambda_fraction >= 0 && lambda_fraction <= 1,
          "nnls: lambda fraction must lie in [0, 1]");
  std::vector<double> c(A.cols);
  A.transpose_times(y, c.data());
  double m = 0.0;
  for (double v : c) m = std::max(m, v);
  // c = Aᵀy − λ/2 with λ = f·λ_max = f·2·max(Aᵀy).
  const double half_lambda = lambda_fraction * m;
  for (double& v : c) v -= half_lambda;
  b.assign(A.cols, 0.0);
  NnlsSolver solver;
  return solver.solve(BandMatrix::gram(A), c.data(), b.data(), options);
}

NnlsStats nnls_l1(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, double lambda_fraction,
                  Eigen::VectorXd& b, const NnlsOptions& options) {
  options.validate();
  require(A.rows() == y.size(), "nnls: A and y disagree in size");
  require(std::isfinite(lambda_fraction) && lambda_fraction >= 0 && lambda_fraction <= 1,
          "nnls: lambda fraction must lie in [0, 1]");
  const int n = static_cast<int>(A.cols());
  // Dense Gram in double precision (bandwidth n − 1).
  const Eigen::MatrixXd G = A.transpose() * A;
  BandMatrix Q(n, n - 1);
  for (int j = 0; j < n; ++j) {
    for (int d = 0; j + d < n; ++d) Q.upper(j, d) = G(j, j + d);
  }
  Eigen::VectorXd c = A.transpose() * y;
  const double half_lambda = lambda_fraction * std::max(0.0, n > 0 ? c.maxCoeff() : 0.0);
  c.array() -= half_lambda;
  b = Eigen::VectorXd::Zero(n);
  NnlsSolver solver;
  return solver.solve(Q, c.data(), b.data(), options);
}

double nnls_objective(const Eigen::MatrixXd& A, const Eigen::VectorXd& y, double lambda,
                      const Eigen::VectorXd& b) {
  return (A * b - y).squaredNorm() + lambda * b.sum();
}

}  // namespace sonar3d
