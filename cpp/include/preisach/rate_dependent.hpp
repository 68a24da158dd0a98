// Rate-dependent Preisach model: K Everett tables blended by a filtered input rate.
//
//     y(t) = sum_k b_k(v(t)) Gamma_k(psi(t)),
//
// where psi is the ordinary Preisach boundary (memory.hpp; it depends on the input history
// only, so all K tables share ONE boundary), Gamma_k the read-out of table k (simulator.hpp:
// y_min_k + 2 sum of piece contributions) and v the filtered input rate (V/s):
//
//     r(t) = |u(t) - u(t-1)| / dt                       (rate of the clamped input)
//     v(t) = v(t-1) + (1 - exp(-dt / tau)) (r(t) - v(t-1))
//
// a causal first-order low-pass of |du/dt| with time constant tau (s), exact for a rate held
// over each sample interval; tau = 0 gives v = r.  The basis functions b_k are the hat
// functions of linear interpolation on the knots v_0 < ... < v_{K-1} (V/s), either in ln v
// (RateScale::log) or in v (RateScale::linear): between v_j and v_{j+1}, b_j = 1 - x and
// b_{j+1} = x with x = ln(v / v_j) / ln(v_{j+1} / v_j), resp. (v - v_j) / (v_{j+1} - v_j);
// below v_0 only b_0 = 1, above v_{K-1} only b_{K-1} = 1 (constant extrapolation).  They are a
// partition of unity, so for a constant v the model is the classical one with the blended
// table E = sum_k b_k(v) E_k, y_min = sum_k b_k(v) y_min_k (the read-out is linear in the table
// at a fixed boundary); with K = 1 it is the classical model (b_0 = 1, bit for bit).
//
// RateSimulator runs the boundary exactly as Simulator does (same stack, same fast path and
// the same cell formula), keeping the prefix sums and the live contribution per table: a
// sample costs one grid position, K cell evaluations (their coefficients are stored
// interleaved, one contiguous block of 4 K per cell), the filter and at most one logarithm.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "batch.hpp"
#include "control.hpp"
#include "everett.hpp"
#include "memory.hpp"
#include "regressor.hpp"
#include "simulator.hpp"

namespace preisach {

// The coordinate in which the basis interpolates between knots.
enum class RateScale { log, linear };

inline RateScale parse_rate_scale(const std::string& s) {
    if (s == "log") return RateScale::log;
    if (s == "linear") return RateScale::linear;
    throw std::invalid_argument("scale: expected 'log' or 'linear', got '" + s + "'");
}

inline const char* rate_scale_name(RateScale s) noexcept { return s == RateScale::log ? "log" : "linear"; }

// Hat functions in ln(rate) or in rate on strictly increasing positive knots (V/s).
class RateBasis {
public:
    RateBasis() = default;
    explicit RateBasis(std::vector<double> knots, RateScale scale = RateScale::log)
        : knots_(std::move(knots)), scale_(scale) {
        if (knots_.empty()) throw std::invalid_argument("knots: need at least one rate knot");
        for (std::size_t k = 0; k < knots_.size(); ++k) {
            if (!std::isfinite(knots_[k]) || !(knots_[k] > 0.0))
                throw std::invalid_argument("knots[" + std::to_string(k) + "] = " + std::to_string(knots_[k]) +
                                            " V/s: rate knots must be positive and finite");
            if (k > 0 && !(knots_[k] > knots_[k - 1]))
                throw std::invalid_argument("knots must be strictly increasing; knots[" + std::to_string(k) +
                                            "] <= knots[" + std::to_string(k - 1) + "]");
        }
        // x = (c(v) - c_j) / (c_{j+1} - c_j) with c = ln v or c = v
        coord_.resize(knots_.size());
        for (std::size_t k = 0; k < knots_.size(); ++k)
            coord_[k] = scale_ == RateScale::log ? std::log(knots_[k]) : knots_[k];
        inv_dc_.resize(knots_.size());
        for (std::size_t k = 0; k + 1 < knots_.size(); ++k) inv_dc_[k] = 1.0 / (coord_[k + 1] - coord_[k]);
    }

    std::size_t size() const noexcept { return knots_.size(); }
    const std::vector<double>& knots() const noexcept { return knots_; }
    RateScale scale() const noexcept { return scale_; }

    // The two weights that can be non-zero: b_j = 1 - x and b_{j+1} = x (x = 0 outside the
    // knots, with j = 0 or K - 1); v is a rate (V/s), v <= 0 counts as below the first knot.
    void segment(double v, std::size_t& j, double& x) const noexcept {
        const std::size_t K = knots_.size();
        x = 0.0;
        if (!(v > knots_[0])) {
            j = 0;
            return;
        }
        if (v >= knots_[K - 1]) {
            j = K - 1;
            return;
        }
        j = 0;
        while (v >= knots_[j + 1]) ++j;
        x = ((scale_ == RateScale::log ? std::log(v) : v) - coord_[j]) * inv_dc_[j];
    }

    // Weights b_k(v) into w[0..K).
    void weights(double v, double* w) const noexcept {
        std::size_t j = 0;
        double x = 0.0;
        segment(v, j, x);
        for (std::size_t k = 0; k < knots_.size(); ++k) w[k] = 0.0;
        w[j] = 1.0 - x;
        if (x != 0.0) w[j + 1] = x;
    }

private:
    std::vector<double> knots_;
    RateScale scale_ = RateScale::log;
    std::vector<double> coord_;
    std::vector<double> inv_dc_;
};

// Coefficient of the first-order rate filter for one sample interval dt (s).
inline double rate_filter_gain(double dt, double tau) {
    if (!(dt > 0.0) || !std::isfinite(dt))
        throw std::invalid_argument("sample_time: must be positive and finite (s), got " + std::to_string(dt));
    return tau > 0.0 ? -std::expm1(-dt / tau) : 1.0;
}

// K Everett tables on one grid, their rate knots and the filter time constant.
class RateDependentModel {
public:
    RateDependentModel(std::vector<EverettTable> tables, std::vector<double> knots, double tau,
                       RateScale scale = RateScale::log)
        : tables_(std::move(tables)), basis_(std::move(knots), scale), tau_(tau) {
        const std::size_t K = tables_.size();
        if (K == 0) throw std::invalid_argument("tables: need at least one Everett table");
        if (basis_.size() != K)
            throw std::invalid_argument("knots: need one rate knot per table (" + std::to_string(K) + "), got " +
                                        std::to_string(basis_.size()));
        if (!std::isfinite(tau) || tau < 0.0)
            throw std::invalid_argument("tau: the rate filter time constant must be >= 0 and finite (s), got " +
                                        std::to_string(tau));
        const auto& lv = tables_[0].levels();
        for (std::size_t k = 0; k < K; ++k)
            if (tables_[k].cubic())
                throw std::invalid_argument("tables[" + std::to_string(k) +
                                            "]: the rate-dependent model interpolates its tables bilinearly; "
                                            "give bilinear tables (EverettTable.with_interpolation)");
        for (std::size_t k = 1; k < K; ++k)
            if (tables_[k].levels() != lv)
                throw std::invalid_argument("tables[" + std::to_string(k) +
                                            "]: every table must be on the same grid of levels as tables[0]");
        const std::size_t n = lv.size(), m = n - 1;
        coef_.assign(m * m * K * 4, 0.0);
        y_min_.resize(K);
        for (std::size_t k = 0; k < K; ++k) {
            const EverettTable& t = tables_[k];
            y_min_[k] = t.y_min();
            for (std::size_t i = 0; i < m; ++i)
                for (std::size_t j = 0; j < m; ++j) {
                    // the same coefficients (same arithmetic) as EverettTable's own
                    const double e00 = t.node(i, j), e01 = t.node(i, j + 1);
                    const double e10 = t.node(i + 1, j), e11 = t.node(i + 1, j + 1);
                    double* c = &coef_[((i * m + j) * K + k) * 4];
                    c[0] = e00;
                    c[1] = e10 - e00;
                    c[2] = e01 - e00;
                    c[3] = e11 - e10 - e01 + e00;
                }
        }
    }

    std::size_t size() const noexcept { return tables_.size(); }
    const EverettTable& table(std::size_t k) const { return tables_.at(k); }
    const std::vector<EverettTable>& tables() const noexcept { return tables_; }
    const RateBasis& basis() const noexcept { return basis_; }
    const std::vector<double>& knots() const noexcept { return basis_.knots(); }
    RateScale scale() const noexcept { return basis_.scale(); }
    double tau() const noexcept { return tau_; }
    double u_min() const noexcept { return tables_[0].u_min(); }
    double u_max() const noexcept { return tables_[0].u_max(); }
    const std::vector<double>& y_mins() const noexcept { return y_min_; }
    const EverettTable& grid() const noexcept { return tables_[0]; }

    // E_k at (alpha, beta) from located positions, for every k, into out[0..K).
    void values(GridPos a, GridPos b, double* out) const noexcept {
        const std::size_t K = tables_.size();
        const double* c = &coef_[((a.i * (tables_[0].size() - 1)) + b.i) * K * 4];
        for (std::size_t k = 0; k < K; ++k, c += 4) out[k] = c[0] + c[1] * a.f + (c[2] + c[3] * a.f) * b.f;
    }

    // The classical table of a constant rate v (V/s): sum_k b_k(v) E_k and y_min likewise.
    EverettTable blended(double v) const {
        const std::size_t K = tables_.size(), n = tables_[0].size();
        std::vector<double> w(K);
        basis_.weights(v, w.data());
        RowMatrixXd e = RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
        double ym = 0.0;
        for (std::size_t k = 0; k < K; ++k) {
            if (w[k] == 0.0) continue;
            ym += w[k] * y_min_[k];
            for (std::size_t i = 0; i < n; ++i)
                for (std::size_t j = 0; j < i; ++j) e(Eigen::Index(i), Eigen::Index(j)) += w[k] * tables_[k].node(i, j);
        }
        const auto& lv = tables_[0].levels();
        return EverettTable(Eigen::Map<const Eigen::VectorXd>(lv.data(), Eigen::Index(n)), e, ym);
    }

private:
    std::vector<EverettTable> tables_;
    RateBasis basis_;
    double tau_ = 0.0;
    std::vector<double> coef_;  // per cell, per table: c0..c3 of EverettTable::value
    std::vector<double> y_min_;
};

// The filtered rate (V/s) of an input sampled every dt seconds, from the previous input u0 and
// rate v0, over inputs already inside the range (see the header comment).
inline void filter_rate(const double* u, double* v, std::size_t n, double u0, double v0, double dt, double tau) {
    const double a = rate_filter_gain(dt, tau);
    const double inv_dt = 1.0 / dt;
    double prev = u0, r = v0;
    for (std::size_t t = 0; t < n; ++t) {
        r += a * (std::abs(u[t] - prev) * inv_dt - r);
        prev = u[t];
        v[t] = r;
    }
}

class RateSimulator {
public:
    // `rate`: the filter's state v (V/s) before the first sample; `sample_time`: dt (s).
    RateSimulator(const RateDependentModel& model, const State& state, double rate, double sample_time)
        : m_(&model), K_(model.size()), dt_(sample_time) {
        gain_ = rate_filter_gain(sample_time, model.tau());
        inv_dt_ = 1.0 / sample_time;
        live_.assign(K_, 0.0);
        eb0_.assign(K_, 0.0);
        s_last_.assign(K_, 0.0);
        vals_.assign(K_, 0.0);
        gamma_.assign(K_, 0.0);
        reset(state, rate);
    }

    void reset(const State& state, double rate) {
        state.validate();
        if (!std::isfinite(rate) || rate < 0.0)
            throw std::invalid_argument("rate: the filtered input rate must be >= 0 and finite (V/s), got " +
                                        std::to_string(rate));
        const EverettTable& g = m_->grid();
        const double span = g.u_max() - g.u_min();
        if (std::abs(state.u_min() - g.u_min()) > 1e-9 * span || std::abs(state.u_max() - g.u_max()) > 1e-9 * span)
            throw std::invalid_argument("state: its input range [" + std::to_string(state.u_min()) + ", " +
                                        std::to_string(state.u_max()) + "] differs from the model's [" +
                                        std::to_string(g.u_min()) + ", " + std::to_string(g.u_max()) + "]");
        u_min_ = state.u_min();
        u_max_ = state.u_max();
        cur_ = state.input();
        v_ = rate;
        const auto& p = state.pieces();
        const std::size_t k = p.size();
        pieces_.clear();
        pieces_.reserve(std::max<std::size_t>(k, 64));
        S_.clear();
        S_.reserve(std::max<std::size_t>(k, 64) * K_);
        E0_.clear();
        E0_.reserve(std::max<std::size_t>(k, 64) * K_);
        for (std::size_t q = 0; q < K_; ++q) {
            const EverettTable& t = m_->table(q);
            double acc = 0.0;
            live_[q] = 0.0;
            for (std::size_t i = 0; i < k; ++i) {
                const double eb0 = p[i].antidiag ? 0.0 : t(p[i].v, p[i].b0);
                const double end = state.piece_end(i);
                const double c = p[i].antidiag ? t.antidiagonal_integral(p[i].v, p[i].b0, end) : eb0 - t(p[i].v, end);
                if (q == 0) {
                    pieces_.push_back(p[i]);
                    S_.resize(S_.size() + K_, 0.0);
                    E0_.resize(E0_.size() + K_, 0.0);
                }
                S_[i * K_ + q] = acc;
                E0_[i * K_ + q] = eb0;
                if (i + 1 < k) acc += c; else live_[q] = c;
            }
        }
        rising_ = k > 0 && !p.back().antidiag && p.back().v == cur_;
        cur_pos_ = g.position(cur_);
        if (k > 0 && !p.back().antidiag) fix_ = g.position(rising_ ? p.back().b0 : p.back().v);
        set_limits();
        update_output();
    }

    // Advance by one input sample (volts, inside the range); returns the output.
    double step(double u) {
        v_ += gain_ * (std::abs(u - cur_) * inv_dt_ - v_);
        if (u == cur_) {
            update_output();
            return y_;
        }
        const bool up = u > cur_;
        if (u > lo_ && u < hi_) {  // the fast path of Simulator::step, per table
            const EverettTable& g = m_->grid();
            const GridPos pu = g.position(u);
            double* live = live_.data();
            if (up == rising_) {
                const GridPos a{up ? pu.i : fix_.i, up ? pu.f : fix_.f};
                const GridPos b{up ? fix_.i : pu.i, up ? fix_.f : pu.f};
                m_->values(a, b, vals_.data());
                if (up) {
                    for (std::size_t q = 0; q < K_; ++q) live[q] = vals_[q];
                    pieces_.back().v = u;
                } else {
                    for (std::size_t q = 0; q < K_; ++q) live[q] = eb0_[q] - vals_[q];
                }
            } else if (up) {  // reversal at a minimum: push a rising piece from cur_
                for (std::size_t q = 0; q < K_; ++q) s_last_[q] += live[q];
                pieces_.push_back(Piece{cur_, u, false});
                S_.insert(S_.end(), s_last_.begin(), s_last_.end());
                E0_.resize(E0_.size() + K_, 0.0);
                lo_ = cur_;
                fix_ = cur_pos_;
                m_->values(pu, fix_, live);
                rising_ = true;
            } else {  // reversal at a maximum: the rising piece becomes a falling one
                double* e0 = &E0_[(pieces_.size() - 1) * K_];
                for (std::size_t q = 0; q < K_; ++q) e0[q] = eb0_[q] = live[q];
                hi_ = cur_;
                fix_ = cur_pos_;
                m_->values(fix_, pu, vals_.data());
                for (std::size_t q = 0; q < K_; ++q) live[q] = eb0_[q] - vals_[q];
                rising_ = false;
            }
            cur_ = u;
            cur_pos_ = pu;
            update_output();
            return y_;
        }
        if (up) rise(u); else fall(u);
        update_output();
        return y_;
    }

    double step_checked(double u, InputPolicy policy, std::size_t index) {
        if (!(u >= u_min_ && u <= u_max_)) {
            if (!std::isfinite(u))
                throw std::invalid_argument("input u[" + std::to_string(index) + "] is not finite");
            if (policy == InputPolicy::raise)
                throw std::invalid_argument("input u[" + std::to_string(index) + "] = " + std::to_string(u) +
                                            " V is outside the model range [" + std::to_string(u_min_) + ", " +
                                            std::to_string(u_max_) + "] V");
            u = std::min(std::max(u, u_min_), u_max_);
        }
        return step(u);
    }

    // y[i] for every input; the filtered rate after each sample goes to v (if not null).
    void run(const double* u, double* y, std::size_t n, InputPolicy policy, double* v = nullptr) {
        for (std::size_t i = 0; i < n; ++i) {
            y[i] = step_checked(u[i], policy, i);
            if (v) v[i] = v_;
        }
    }

    double output() const noexcept { return y_; }
    double input() const noexcept { return cur_; }
    double rate() const noexcept { return v_; }
    double sample_time() const noexcept { return dt_; }
    const RateDependentModel& model() const noexcept { return *m_; }
    std::size_t depth() const noexcept { return pieces_.size(); }
    // b_k(v) and Gamma_k(psi) of the current sample (K values each).
    std::vector<double> weights() const {
        std::vector<double> w(K_, 0.0);
        w[wj_] = 1.0 - wx_;
        if (wx_ != 0.0) w[wj_ + 1] = wx_;
        return w;
    }
    std::vector<double> readouts() const {
        std::vector<double> g(K_);
        const double* ym = m_->y_mins().data();
        for (std::size_t q = 0; q < K_; ++q) g[q] = ym[q] + 2.0 * (s_last_[q] + live_[q]);
        return g;
    }

    State state() const { return State(u_min_, u_max_, cur_, pieces_); }

    // One-sided dy/du at the current state and rate: sum_k b_k(v) times the slopes of table k
    // (the rate held fixed; Appendix A per table).
    Slopes slopes() const {
        double up = 0.0, down = 0.0;
        const std::vector<double> w = weights();
        for (std::size_t q = 0; q < K_; ++q) {
            if (w[q] == 0.0) continue;
            const EverettTable& t = m_->table(q);
            if (cur_ < u_max_) {
                double bstar = cur_;
                std::size_t k = pieces_.size();
                while (k > 0 && pieces_[k - 1].phi_start() <= cur_) bstar = pieces_[--k].b0;
                up += w[q] * 2.0 * t.d_alpha(cur_, bstar);
            }
            if (cur_ > u_min_) {
                std::size_t k = pieces_.size();
                while (k > 0 && pieces_[k - 1].b0 >= cur_) --k;
                if (k > 0) down += w[q] * -2.0 * t.d_beta(pieces_[k - 1].phi(cur_), cur_);
            }
        }
        return {up, down};
    }

private:
    // y = (1 - x) Gamma_j + x Gamma_{j+1}: only the two tables whose weights can be non-zero.
    void update_output() noexcept {
        m_->basis().segment(v_, wj_, wx_);
        const double* ym = m_->y_mins().data();
        const std::size_t j = wj_;
        const double g0 = ym[j] + 2.0 * (s_last_[j] + live_[j]);
        if (wx_ == 0.0) {
            y_ = g0;
        } else {
            const double g1 = ym[j + 1] + 2.0 * (s_last_[j + 1] + live_[j + 1]);
            y_ = (1.0 - wx_) * g0 + wx_ * g1;
        }
    }

    void set_limits() noexcept {
        const std::size_t k = pieces_.size();
        for (std::size_t q = 0; q < K_; ++q) s_last_[q] = k ? S_[(k - 1) * K_ + q] : 0.0;
        const double inf = std::numeric_limits<double>::infinity();
        if (k == 0 || pieces_[k - 1].antidiag) {
            lo_ = inf;
            hi_ = -inf;
            return;
        }
        const Piece& last = pieces_[k - 1];
        lo_ = last.b0;
        if (rising_) {
            hi_ = k >= 2 ? pieces_[k - 2].phi(last.b0) : inf;
        } else {
            hi_ = last.v;
            for (std::size_t q = 0; q < K_; ++q) eb0_[q] = E0_[(k - 1) * K_ + q];
        }
    }

    void pop() {
        pieces_.pop_back();
        S_.resize(S_.size() - K_);
        E0_.resize(E0_.size() - K_);
    }

    // Simulator::rise, per table.
    void rise(double u) {
        const EverettTable& g = m_->grid();
        std::size_t k = pieces_.size();
        double bstar = cur_;
        bool popped = false;
        std::vector<double>& s_top = vals_;  // S of the last popped piece
        while (k > 0 && pieces_[k - 1].phi_start() <= u) {
            bstar = pieces_[k - 1].b0;
            for (std::size_t q = 0; q < K_; ++q) s_top[q] = S_[(k - 1) * K_ + q];
            pop();
            --k;
            popped = true;
        }
        if (k > 0) {
            const Piece last = pieces_[k - 1];
            const double* S_last = &S_[(k - 1) * K_];
            const bool cut = last.antidiag && last.v - bstar < u;
            const double b_cut = last.v - u;
            for (std::size_t q = 0; q < K_; ++q) {
                double c = popped ? s_top[q] - S_last[q] : live_[q];
                if (cut) c -= m_->table(q).antidiagonal_integral(last.v, b_cut, bstar);
                s_top[q] = S_last[q] + c;  // S of the new piece
            }
            if (cut) bstar = b_cut;
        } else {
            bstar = u_min_;
            for (std::size_t q = 0; q < K_; ++q) s_top[q] = 0.0;
        }
        pieces_.push_back(Piece{bstar, u, false});
        S_.insert(S_.end(), s_top.begin(), s_top.end());
        E0_.resize(E0_.size() + K_, 0.0);
        fix_ = bstar == cur_ ? cur_pos_ : g.position(bstar);
        cur_pos_ = g.position(u);
        m_->values(cur_pos_, fix_, live_.data());
        rising_ = true;
        cur_ = u;
        set_limits();
    }

    // Simulator::fall, per table.
    void fall(double u) {
        const EverettTable& g = m_->grid();
        std::size_t k = pieces_.size();
        bool same_piece = false;
        if (rising_) {
            for (std::size_t q = 0; q < K_; ++q) E0_[(k - 1) * K_ + q] = live_[q];
            fix_ = cur_pos_;
            rising_ = false;
            same_piece = true;
        }
        double old_end = cur_;
        std::vector<double>& c_old = vals_;
        for (std::size_t q = 0; q < K_; ++q) c_old[q] = live_[q];
        bool popped = false;
        while (k > 0 && pieces_[k - 1].b0 >= u) {
            old_end = pieces_[k - 1].b0;
            for (std::size_t q = 0; q < K_; ++q) c_old[q] = S_[(k - 1) * K_ + q];
            pop();
            --k;
            popped = true;
        }
        cur_ = u;
        cur_pos_ = g.position(u);
        if (k == 0) {
            for (std::size_t q = 0; q < K_; ++q) live_[q] = 0.0;
            set_limits();
            return;
        }
        const Piece last = pieces_[k - 1];
        if (last.antidiag) {
            for (std::size_t q = 0; q < K_; ++q) {
                double c = c_old[q];
                if (popped) c -= S_[(k - 1) * K_ + q];
                live_[q] = c - m_->table(q).antidiagonal_integral(last.v, u, old_end);
            }
        } else {
            if (popped || !same_piece) fix_ = g.position(last.v);
            m_->values(fix_, cur_pos_, gamma_.data());  // scratch
            for (std::size_t q = 0; q < K_; ++q) live_[q] = E0_[(k - 1) * K_ + q] - gamma_[q];
        }
        set_limits();
    }

    const RateDependentModel* m_;
    std::size_t K_;
    double dt_, gain_, inv_dt_;
    std::vector<Piece> pieces_;  // the shared boundary, lowest beta first
    std::vector<double> S_;      // per piece, per table: sum of the contributions below it
    std::vector<double> E0_;     // per piece, per table: E(M, b0) once the piece stopped rising
    std::vector<double> live_, eb0_, s_last_;  // per table, as in Simulator
    std::vector<double> vals_, gamma_;         // scratch
    std::size_t wj_ = 0;                       // weights: b_wj = 1 - wx, b_{wj+1} = wx
    double wx_ = 0.0;
    double u_min_ = 0.0, u_max_ = 0.0;
    GridPos cur_pos_{0, 0.0}, fix_{0, 0.0};
    double lo_ = 0.0, hi_ = 0.0;
    double cur_ = 0.0, y_ = 0.0, v_ = 0.0;
    bool rising_ = false;
};

// Many independent runs on all cores: row r of U (m x n) from states[r] and rates[r] (or
// the single ones for every row).  Y receives m x n outputs; V (if not null) the filtered
// rates.  Returns the final states and rates.  threads == 0: every core.
struct RateBatchResult {
    std::vector<State> states;
    std::vector<double> rates;
};

inline void check_rate_rows(const std::vector<State>& states, const std::vector<double>& rates, std::size_t m) {
    check_row_states(states.size(), m);
    if (rates.size() != states.size())
        throw std::invalid_argument("rates: need one rate per state (" + std::to_string(states.size()) + "), got " +
                                    std::to_string(rates.size()));
}

inline RateBatchResult run_rate_batch(const RateDependentModel& model, const std::vector<State>& states,
                                      const std::vector<double>& rates, double sample_time, const double* U,
                                      double* Y, double* V, std::size_t m, std::size_t n, InputPolicy policy,
                                      unsigned threads = 0) {
    check_rate_rows(states, rates, m);
    rate_filter_gain(sample_time, model.tau());
    RateBatchResult out{std::vector<State>(m), std::vector<double>(m, 0.0)};
    for_each_row(m, threads, [&](std::size_t r) {
        const std::size_t s = states.size() == 1 ? 0 : r;
        RateSimulator sim(model, states[s], rates[s], sample_time);
        sim.run(U + r * n, Y + r * n, n, policy, V ? V + r * n : nullptr);
        out.states[r] = sim.state();
        out.rates[r] = sim.rate();
    });
    return out;
}

// The PI loop of control.hpp (run_pi_loop) around a rate-dependent model.
inline void run_rate_closed_loop(RateSimulator& sim, const double* u_open, double* u, double* y, double* uc,
                                 std::size_t n, const ClosedLoopConfig& cfg, InputPolicy policy) {
    if (std::abs(cfg.sample_time - sim.sample_time()) > 1e-9 * sim.sample_time())
        throw std::invalid_argument("closed loop: sample_time " + std::to_string(cfg.sample_time) +
                                    " s differs from the simulator's " + std::to_string(sim.sample_time()) + " s");
    run_pi_loop([&](double v, std::size_t k) { return sim.step_checked(v, policy, k); }, sim.model().u_min(),
                sim.model().u_max(), u_open, u, y, uc, n, cfg, policy);
}

// Row r of U_open (m x n) from states[r] / rates[r] (or the single ones) on `threads` threads.
inline RateBatchResult run_rate_closed_loop_batch(const RateDependentModel& model, const std::vector<State>& states,
                                                  const std::vector<double>& rates, const double* U_open, double* U,
                                                  double* Y, double* UC, std::size_t m, std::size_t n,
                                                  const ClosedLoopConfig& cfg, InputPolicy policy,
                                                  unsigned threads = 0) {
    check_rate_rows(states, rates, m);
    cfg.validate();
    RateBatchResult out{std::vector<State>(m), std::vector<double>(m, 0.0)};
    for_each_row(m, threads, [&](std::size_t r) {
        const std::size_t s = states.size() == 1 ? 0 : r;
        RateSimulator sim(model, states[s], rates[s], cfg.sample_time);
        const std::size_t off = r * n;
        run_rate_closed_loop(sim, U_open + off, U + off, Y + off, UC + off, n, cfg, policy);
        out.states[r] = sim.state();
        out.rates[r] = sim.rate();
    });
    return out;
}

// ---- least squares across rates -----------------------------------------------------------
// For a fixed input history the output is linear in the K tables:
//     y_t = sum_k b_k(v_t) r_t . theta_k,
// r_t the EverettRegressor row (Everett nodes then y_min, regressor.hpp) and v_t the filtered
// rate; the stacked parameter vector is (theta_0, ..., theta_{K-1}), table k's block at k p.
// accumulate_rate_normal_equations_into() sums the Gram matrix, right-hand side and y^2 of
// these rows per fold, as accumulate_normal_equations_into() does for one table.
struct RateRegression {
    std::vector<double> knots;  // V/s
    double tau = 0.0;           // s
    double sample_time = 1e-3;  // s
    double rate0 = 0.0;         // filtered rate before the first sample (V/s)
    RateScale scale = RateScale::log;
};

inline void accumulate_rate_normal_equations_into(const VectorRef& levels, const State& state, const double* u,
                                                  const double* y, const std::int32_t* fold, std::size_t n,
                                                  int n_folds, InputPolicy policy, const RateRegression& rr,
                                                  NormalEquationsOut out, State* final_state = nullptr,
                                                  double* final_rate = nullptr) {
    if (n_folds < 1) throw std::invalid_argument("n_folds: must be >= 1, got " + std::to_string(n_folds));
    if (!std::isfinite(rr.tau) || rr.tau < 0.0)
        throw std::invalid_argument("tau: must be >= 0 and finite (s), got " + std::to_string(rr.tau));
    if (!std::isfinite(rr.rate0) || rr.rate0 < 0.0)
        throw std::invalid_argument("rate: must be >= 0 and finite (V/s), got " + std::to_string(rr.rate0));
    const RateBasis basis(rr.knots, rr.scale);
    const double gain = rate_filter_gain(rr.sample_time, rr.tau), inv_dt = 1.0 / rr.sample_time;
    EverettRegressor reg(levels, state);
    const std::size_t p1 = reg.n_params(), K = basis.size(), p = p1 * K, F = std::size_t(n_folds);
    std::fill(out.gram, out.gram + F * p * p, 0.0);
    std::fill(out.rhs, out.rhs + F * p, 0.0);
    std::fill(out.yy, out.yy + F, 0.0);
    std::fill(out.ysum, out.ysum + F, 0.0);
    std::fill(out.count, out.count + F, std::int64_t(0));
    std::vector<double> w(K), vals;
    std::vector<std::size_t> idx;
    double v = rr.rate0, prev = state.input();
    const double lo = reg.u_min(), hi = reg.u_max();
    for (std::size_t t = 0; t < n; ++t) {
        if (fold[t] >= n_folds)
            throw std::invalid_argument("fold[" + std::to_string(t) + "] = " + std::to_string(fold[t]) +
                                        " is not below n_folds = " + std::to_string(n_folds));
        reg.step(u[t], policy, t);  // validates and clamps u[t] per the policy
        const double uc = std::min(std::max(u[t], lo), hi);
        v += gain * (std::abs(uc - prev) * inv_dt - v);
        prev = uc;
        if (fold[t] < 0) continue;
        const double yt = y[t];
        if (!std::isfinite(yt)) throw std::invalid_argument("output y[" + std::to_string(t) + "] is not finite");
        basis.weights(v, w.data());
        const auto& ix = reg.row_index();
        const auto& vx = reg.row_value();
        idx.clear();
        vals.clear();
        for (std::size_t k = 0; k < K; ++k) {
            if (w[k] == 0.0) continue;
            for (std::size_t a = 0; a < ix.size(); ++a) {
                idx.push_back(k * p1 + ix[a]);
                vals.push_back(w[k] * vx[a]);
            }
        }
        const std::size_t f = std::size_t(fold[t]);
        double* G = out.gram + f * p * p;
        double* b = out.rhs + f * p;
        const std::size_t m = idx.size();
        for (std::size_t a = 0; a < m; ++a) {  // idx ascending: blocks in k order, ix ascending
            const double va = vals[a];
            double* row = G + idx[a] * p;
            for (std::size_t c = a; c < m; ++c) row[idx[c]] += va * vals[c];
            b[idx[a]] += va * yt;
        }
        out.yy[f] += yt * yt;
        out.ysum[f] += yt;
        ++out.count[f];
    }
    for (std::size_t f = 0; f < F; ++f) {
        double* G = out.gram + f * p * p;
        for (std::size_t a = 0; a < p; ++a)
            for (std::size_t c = 0; c < a; ++c) G[a * p + c] = G[c * p + a];
    }
    if (final_state) *final_state = reg.state();
    if (final_rate) *final_rate = v;
}

}  // namespace preisach
