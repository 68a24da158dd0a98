// The state of a Preisach model: the boundary psi between P+ and P-.
//
// In the (alpha, beta) half-plane the relays that are +1 are exactly those with
// alpha <= phi(beta), where phi is a non-increasing function on [u_min, u] and u is the
// current input (the boundary meets the diagonal at (u, u)).  phi is stored as a short
// list of pieces, lowest beta first:
//   * a constant piece, phi(beta) = M on [b0, b1): the input rose to M and later fell
//     to b1 (a corner of the staircase of the reduced memory sequence);
//   * an antidiagonal piece, phi(beta) = c - beta on [b0, b1]: a horizontal segment
//     s = c/2 of the boundary in the (r, s) plane, as in the anhysteretic state (c = 0)
//     and the neutral state psi_n^l of Eq 2.17 (c = 2 l).  It is held exactly.
// A rising input u sets phi = max(phi, u) on [u_min, u]; a falling input u cuts phi at u.
// Both only touch the end of the list, so the list is a stack (wiping-out pops it).
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace preisach {

struct Piece {
    double b0;        // start of the piece (beta, volts)
    double v;         // constant piece: M = phi; antidiagonal piece: c = alpha + beta
    bool antidiag;    // false: constant piece, true: antidiagonal piece

    double phi(double beta) const noexcept { return antidiag ? v - beta : v; }
    double phi_start() const noexcept { return phi(b0); }
    bool operator==(const Piece& o) const noexcept { return b0 == o.b0 && v == o.v && antidiag == o.antidiag; }
    bool operator!=(const Piece& o) const noexcept { return !(*this == o); }
};

class State {
public:
    State() = default;
    State(double u_min, double u_max, double u, std::vector<Piece> pieces)
        : u_min_(u_min), u_max_(u_max), u_(u), pieces_(std::move(pieces)) {
        validate();
    }

    static State negative_saturation(double u_min, double u_max) { return State(u_min, u_max, u_min, {}); }
    static State positive_saturation(double u_min, double u_max) {
        return State(u_min, u_max, u_max, {Piece{u_min, u_max, false}});
    }
    // Neutral state psi_n^l (Eq 2.17), generalised to any range: the boundary is the
    // horizontal line s = l near r = 0 and follows the edge of the restricted plane after.
    static State neutral(double u_min, double u_max, double l) {
        check_range(u_min, u_max);
        if (!(l >= u_min && l <= u_max))
            throw std::invalid_argument("neutral state: l = " + std::to_string(l) + " is outside the input range [" +
                                        std::to_string(u_min) + ", " + std::to_string(u_max) + "]");
        const double c = 2.0 * l;
        std::vector<Piece> p;
        const double knee = c - u_max;  // where alpha + beta = c meets alpha = u_max
        if (knee > u_min) {
            p.push_back(Piece{u_min, u_max, false});
            if (l > knee) p.push_back(Piece{knee, c, true});
        } else if (l > u_min) {
            p.push_back(Piece{u_min, c, true});
        }
        return State(u_min, u_max, l, std::move(p));
    }

    double u_min() const noexcept { return u_min_; }
    double u_max() const noexcept { return u_max_; }
    double input() const noexcept { return u_; }
    const std::vector<Piece>& pieces() const noexcept { return pieces_; }
    std::vector<Piece>& mutable_pieces() noexcept { return pieces_; }
    void set_input(double u) noexcept { u_ = u; }

    // End of piece k (start of the next one, or the current input).
    double piece_end(std::size_t k) const noexcept { return k + 1 < pieces_.size() ? pieces_[k + 1].b0 : u_; }

    bool operator==(const State& o) const noexcept {
        return u_min_ == o.u_min_ && u_max_ == o.u_max_ && u_ == o.u_ && pieces_ == o.pieces_;
    }
    bool operator!=(const State& o) const noexcept { return !(*this == o); }

    // Reduced memory sequence (alternating dominant extrema after the start at u_min) when
    // the boundary is a staircase; throws if it holds an antidiagonal piece.
    std::vector<double> extrema() const {
        std::vector<double> e;
        for (std::size_t k = 0; k < pieces_.size(); ++k) {
            if (pieces_[k].antidiag)
                throw std::invalid_argument("state holds a horizontal (neutral) boundary segment; it has no finite "
                                            "reduced memory sequence");
            if (k > 0) e.push_back(pieces_[k].b0);
            e.push_back(pieces_[k].v);
        }
        if (e.empty() || e.back() != u_) e.push_back(u_);
        return e;
    }

    void validate() const {
        check_range(u_min_, u_max_);
        if (!(u_ >= u_min_ && u_ <= u_max_))
            throw std::invalid_argument("state: input " + std::to_string(u_) + " is outside [" +
                                        std::to_string(u_min_) + ", " + std::to_string(u_max_) + "]");
        double prev_phi_end = u_max_;
        const double tol = 1e-12 * (u_max_ - u_min_);
        for (std::size_t k = 0; k < pieces_.size(); ++k) {
            const Piece& p = pieces_[k];
            // the message is built only on error: validate runs on every state entering the core
            if (!std::isfinite(p.b0) || !std::isfinite(p.v)) invalid_piece(k, " is not finite");
            if (k == 0 && p.b0 != u_min_) invalid_piece(k, " must start at u_min");
            const double end = piece_end(k);
            if (!(end > p.b0))
                invalid_piece(k, " is empty or out of order (starts at " + std::to_string(p.b0) + ", ends at " +
                                     std::to_string(end) + ")");
            if (p.phi_start() > u_max_ + tol) invalid_piece(k, " lies beyond u_max");
            if (p.phi_start() > prev_phi_end + tol)
                invalid_piece(k, ": the boundary must be non-increasing (Lipschitz in (r, s))");
            if (p.phi(end) < end - tol) invalid_piece(k, " crosses the diagonal alpha = beta");
            prev_phi_end = p.phi(end);
        }
    }

private:
    [[noreturn]] static void invalid_piece(std::size_t k, const std::string& what) {
        throw std::invalid_argument("state: piece " + std::to_string(k) + what);
    }

    static void check_range(double u_min, double u_max) {
        if (!std::isfinite(u_min) || !std::isfinite(u_max) || !(u_max > u_min))
            throw std::invalid_argument("input range: need finite u_min < u_max, got [" + std::to_string(u_min) +
                                        ", " + std::to_string(u_max) + "]");
    }

    double u_min_ = -1.0, u_max_ = 1.0, u_ = -1.0;
    std::vector<Piece> pieces_;
};

}  // namespace preisach
