// Shared fixtures of the C++ unit tests: an analytic Everett function, grids, tables built
// from it, random inputs and an independent brute-force relay model.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include <preisach/preisach.hpp>

namespace ptest {

using preisach::EverettTable;
using preisach::Piece;
using preisach::RowMatrixXd;
using preisach::Simulator;
using preisach::State;

// Input range of the analytic model (deliberately not symmetric about 0).
constexpr double U_MIN = -1.0;
constexpr double U_MAX = 2.0;
constexpr double Y_MIN = -3.5;

// Analytic Everett function, d = alpha - beta, s = alpha + beta:
//   E = d^2 exp(0.3 s) + 0.1 d^3,
// whose Preisach density mu = -d2E/(dalpha dbeta) = exp(0.3 s) (2 - 0.09 d^2) + 0.6 d is
// smooth and positive on the range (d <= 3).  E(u, u) = 0.
inline double E_exact(double a, double b) {
    if (a <= b) return 0.0;
    const double d = a - b, s = a + b;
    return d * d * std::exp(0.3 * s) + 0.1 * d * d * d;
}

inline Eigen::VectorXd uniform_levels(std::size_t n, double lo = U_MIN, double hi = U_MAX) {
    Eigen::VectorXd l(Eigen::Index(n), 1);
    for (std::size_t k = 0; k < n; ++k) l[Eigen::Index(k)] = lo + (hi - lo) * double(k) / double(n - 1);
    l[Eigen::Index(n - 1)] = hi;
    return l;
}

// Strictly increasing, visibly non-uniform grid on [lo, hi] (x + 0.08 sin(2 pi x) is monotone).
inline Eigen::VectorXd nonuniform_levels(std::size_t n, double lo = U_MIN, double hi = U_MAX) {
    const double pi = 3.14159265358979323846;
    Eigen::VectorXd l(Eigen::Index(n), 1);
    for (std::size_t k = 0; k < n; ++k) {
        const double x = double(k) / double(n - 1);
        l[Eigen::Index(k)] = lo + (hi - lo) * (x + 0.08 * std::sin(2.0 * pi * x));
    }
    l[0] = lo;
    l[Eigen::Index(n - 1)] = hi;
    return l;
}

// Table of E_exact at the nodes; entries on/above the diagonal are garbage on purpose
// (the constructor must ignore them).
inline EverettTable analytic_table(const Eigen::VectorXd& levels, double y_min = Y_MIN) {
    const Eigen::Index n = levels.size();
    RowMatrixXd v = RowMatrixXd::Constant(n, n, 1234.5);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < i; ++j) v(i, j) = E_exact(levels[i], levels[j]);
    return EverettTable(levels, v, y_min);
}

inline double uniform(std::mt19937& g, double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(g);
}

// Reflected random walk inside [U_MIN, U_MAX].
inline std::vector<double> random_walk(std::mt19937& g, std::size_t n, double start, double sigma) {
    std::normal_distribution<double> nd(0.0, sigma);
    std::vector<double> u(n);
    double x = start;
    for (std::size_t k = 0; k < n; ++k) {
        x += nd(g);
        if (x > U_MAX) x = 2.0 * U_MAX - x;
        if (x < U_MIN) x = 2.0 * U_MIN - x;
        x = std::min(std::max(x, U_MIN), U_MAX);
        u[k] = x;
    }
    return u;
}

inline std::vector<double> random_inputs(std::mt19937& g, std::size_t n, double lo = U_MIN, double hi = U_MAX) {
    std::vector<double> u(n);
    for (auto& x : u) x = uniform(g, lo, hi);
    return u;
}

// A random antidiagonal segment alpha = c - beta, beta in [b0, b1] (b0 <= b1), that stays
// inside the range and on or below the diagonal (alpha in [beta, U_MAX]).
struct Antidiagonal {
    double c, b0, b1;
};
inline Antidiagonal random_antidiagonal(std::mt19937& g) {
    const double c = uniform(g, 2.0 * U_MIN + 0.2, 2.0 * U_MAX - 0.2);
    const double lo = std::max(U_MIN, c - U_MAX), hi = 0.5 * c;
    double b0 = uniform(g, lo, hi), b1 = uniform(g, lo, hi);
    if (b0 > b1) std::swap(b0, b1);
    return {c, b0, b1};
}

// A random starting state: negative or positive saturation or a neutral state.
inline State random_start(std::mt19937& g) {
    const int kind = std::uniform_int_distribution<int>(0, 2)(g);
    if (kind == 0) return State::negative_saturation(U_MIN, U_MAX);
    if (kind == 1) return State::positive_saturation(U_MIN, U_MAX);
    return State::neutral(U_MIN, U_MAX, uniform(g, U_MIN, U_MAX));
}

inline std::vector<double> simulate(const EverettTable& t, const State& s, const std::vector<double>& u) {
    Simulator sim(t, s);
    std::vector<double> y(u.size());
    for (std::size_t k = 0; k < u.size(); ++k) y[k] = sim.step(u[k]);
    return y;
}

inline double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
    double m = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) m = std::max(m, std::abs(a[k] - b[k]));
    return m;
}

// phi(beta) of a state from its documented piece semantics, -inf where beta >= input.
inline double boundary_phi(const State& s, double beta) {
    const auto& p = s.pieces();
    if (!(beta < s.input())) return -HUGE_VAL;
    for (std::size_t k = p.size(); k-- > 0;)
        if (beta >= p[k].b0) return p[k].phi(beta);
    return -HUGE_VAL;  // no pieces: nothing is switched on
}

// Independent brute-force classical Preisach model: one relay per cell of an N x N grid on
// [U_MIN, U_MAX], at the cell centre (at the centroid for the half-cells on the diagonal),
// with the cell's mass from mixed differences of E_exact.  y = y_min + sum w (gamma + 1).
class RelayGrid {
public:
    RelayGrid(std::size_t n, const State& start, double y_min = Y_MIN) : y_min_(y_min) {
        const double h = (U_MAX - U_MIN) / double(n);
        const auto lv = [&](std::size_t k) { return k == n ? U_MAX : U_MIN + h * double(k); };
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = 0; j <= i; ++j) {
                if (i == j) {
                    alpha_.push_back(lv(i) + 2.0 * h / 3.0);
                    beta_.push_back(lv(i) + h / 3.0);
                    w_.push_back(E_exact(lv(i + 1), lv(i)));
                } else {
                    alpha_.push_back(lv(i) + 0.5 * h);
                    beta_.push_back(lv(j) + 0.5 * h);
                    w_.push_back(E_exact(lv(i + 1), lv(j)) - E_exact(lv(i), lv(j)) - E_exact(lv(i + 1), lv(j + 1)) +
                                 E_exact(lv(i), lv(j + 1)));
                }
            }
        on_.assign(w_.size(), 0);
        for (std::size_t r = 0; r < w_.size(); ++r) on_[r] = alpha_[r] <= boundary_phi(start, beta_[r]) ? 1 : 0;
    }

    double step(double u) {
        for (std::size_t r = 0; r < w_.size(); ++r) {
            if (u >= alpha_[r]) on_[r] = 1;
            else if (u <= beta_[r]) on_[r] = 0;
        }
        return output();
    }

    double output() const {
        double y = y_min_;
        for (std::size_t r = 0; r < w_.size(); ++r)
            if (on_[r]) y += 2.0 * w_[r];
        return y;
    }

private:
    std::vector<double> alpha_, beta_, w_;
    std::vector<unsigned char> on_;
    double y_min_;
};

}  // namespace ptest
