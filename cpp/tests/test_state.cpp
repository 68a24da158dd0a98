// State: saturations, neutral states, validation, reduced memory sequence, equality and
// apply_inputs.
#include <limits>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_state {

using namespace ptest;
using preisach::apply_inputs;

namespace {
const double NaN = std::numeric_limits<double>::quiet_NaN();

void check_pieces(const State& s, const std::vector<Piece>& expected) {
    REQUIRE(s.pieces().size() == expected.size());
    for (std::size_t k = 0; k < expected.size(); ++k) {
        INFO("piece " << k);
        CHECK(s.pieces()[k].b0 == doctest::Approx(expected[k].b0).epsilon(1e-15).scale(1.0));
        CHECK(s.pieces()[k].v == doctest::Approx(expected[k].v).epsilon(1e-15).scale(1.0));
        CHECK(s.pieces()[k].antidiag == expected[k].antidiag);
    }
}
}  // namespace

TEST_CASE("state: saturations") {
    const State neg = State::negative_saturation(-1.0, 2.0);
    CHECK(neg.u_min() == -1.0);
    CHECK(neg.u_max() == 2.0);
    CHECK(neg.input() == -1.0);
    CHECK(neg.pieces().empty());
    CHECK(neg.extrema() == std::vector<double>{-1.0});

    const State pos = State::positive_saturation(-1.0, 2.0);
    CHECK(pos.input() == 2.0);
    check_pieces(pos, {Piece{-1.0, 2.0, false}});
    CHECK(pos.extrema() == std::vector<double>{2.0});
    CHECK(pos.piece_end(0) == 2.0);
    CHECK_NOTHROW(pos.validate());
    CHECK(neg != pos);
}

TEST_CASE("state: neutral states") {
    SUBCASE("l > 0 (above the middle of a symmetric range): constant piece then antidiagonal") {
        const State s = State::neutral(-1.0, 1.0, 0.25);
        CHECK(s.input() == 0.25);
        // knee = 2 l - u_max = -0.5: phi = 1 on [-1, -0.5), phi = 0.5 - beta on [-0.5, 0.25].
        check_pieces(s, {Piece{-1.0, 1.0, false}, Piece{-0.5, 0.5, true}});
        CHECK(s.piece_end(1) == 0.25);
        CHECK(s.pieces()[1].phi(0.25) == 0.25);  // meets the diagonal at (l, l)
        CHECK(s.pieces()[1].phi_start() == 1.0);  // continuous at the knee
    }
    SUBCASE("l < 0: a single antidiagonal piece from u_min") {
        const State s = State::neutral(-1.0, 1.0, -0.3);
        check_pieces(s, {Piece{-1.0, -0.6, true}});
        CHECK(s.pieces()[0].phi_start() == doctest::Approx(0.4));
        CHECK(s.pieces()[0].phi(-0.3) == doctest::Approx(-0.3));
    }
    SUBCASE("l = 0: the anhysteretic line alpha + beta = 0 from the corner (u_max, u_min)") {
        const State s = State::neutral(-1.0, 1.0, 0.0);
        check_pieces(s, {Piece{-1.0, 0.0, true}});
        CHECK(s.pieces()[0].phi_start() == 1.0);
    }
    SUBCASE("ends of the range are the saturations") {
        CHECK(State::neutral(-1.0, 1.0, -1.0) == State::negative_saturation(-1.0, 1.0));
        CHECK(State::neutral(-1.0, 1.0, 1.0) == State::positive_saturation(-1.0, 1.0));
    }
    SUBCASE("asymmetric range: the knee is at 2 l - u_max") {
        const State hi = State::neutral(-1.0, 2.0, 1.2);
        check_pieces(hi, {Piece{-1.0, 2.0, false}, Piece{0.4, 2.4, true}});
        const State lo = State::neutral(-1.0, 2.0, 0.3);
        check_pieces(lo, {Piece{-1.0, 0.6, true}});
        const State mid = State::neutral(-1.0, 2.0, 0.5);
        check_pieces(mid, {Piece{-1.0, 1.0, true}});
    }
    SUBCASE("validation") {
        CHECK_THROWS_WITH_AS(State::neutral(-1.0, 1.0, 1.5), doctest::Contains("outside the input range"),
                             std::invalid_argument);
        CHECK_THROWS_AS(State::neutral(-1.0, 1.0, -1.01), std::invalid_argument);
        CHECK_THROWS_AS(State::neutral(-1.0, 1.0, NaN), std::invalid_argument);
        CHECK_THROWS_AS(State::neutral(1.0, -1.0, 0.0), std::invalid_argument);
    }
    SUBCASE("no finite reduced memory sequence") {
        CHECK_THROWS_WITH_AS(State::neutral(-1.0, 1.0, 0.0).extrema(), doctest::Contains("neutral"),
                             std::invalid_argument);
    }
}

TEST_CASE("state: validation errors") {
    SUBCASE("bad ranges") {
        CHECK_THROWS_WITH_AS(State(1.0, 1.0, 1.0, {}), doctest::Contains("input range"), std::invalid_argument);
        CHECK_THROWS_AS(State(2.0, 1.0, 1.5, {}), std::invalid_argument);
        CHECK_THROWS_AS(State(NaN, 1.0, 0.0, {}), std::invalid_argument);
        CHECK_THROWS_AS(State(0.0, std::numeric_limits<double>::infinity(), 0.0, {}), std::invalid_argument);
        CHECK_THROWS_AS(State::negative_saturation(1.0, 0.0), std::invalid_argument);
        CHECK_THROWS_AS(State::positive_saturation(0.0, 0.0), std::invalid_argument);
    }
    SUBCASE("input outside the range") {
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 1.5, {Piece{-1.0, 1.0, false}}), doctest::Contains("outside"),
                             std::invalid_argument);
        CHECK_THROWS_AS(State(-1.0, 1.0, NaN, {}), std::invalid_argument);
    }
    SUBCASE("first piece must start at u_min") {
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 0.5, {Piece{-0.5, 0.8, false}}), doctest::Contains("u_min"),
                             std::invalid_argument);
    }
    SUBCASE("empty or unordered pieces") {
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, 0.8, false}, Piece{-1.0, 0.5, false}}),
                             doctest::Contains("piece 0 is empty"), std::invalid_argument);
        CHECK_THROWS_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, 0.8, false}, Piece{0.2, 0.5, false}}),
                        std::invalid_argument);  // piece 1 ends (at u = 0) before it starts
    }
    SUBCASE("crossing the diagonal") {
        // Constant piece M = 0.2 reaching beta = 0.5 > M.
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 0.5, {Piece{-1.0, 0.2, false}}), doctest::Contains("crosses the diagonal"),
                             std::invalid_argument);
        // Antidiagonal piece c = 0 reaching beta = 0.3: phi(0.3) = -0.3 < 0.3.
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 0.3, {Piece{-1.0, 0.0, true}}), doctest::Contains("crosses the diagonal"),
                             std::invalid_argument);
    }
    SUBCASE("increasing boundary") {
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, 0.5, false}, Piece{-0.5, 0.8, false}}),
                             doctest::Contains("non-increasing"), std::invalid_argument);
        // An antidiagonal piece starting above the constant piece before it.
        CHECK_THROWS_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, 0.5, false}, Piece{-0.5, 0.5, true}}),
                        std::invalid_argument);
        // Beyond u_max.
        CHECK_THROWS_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, 1.5, false}}), std::invalid_argument);
        CHECK_THROWS_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, 0.5, true}}), std::invalid_argument);  // phi(-1) = 1.5
    }
    SUBCASE("non-finite piece") {
        CHECK_THROWS_WITH_AS(State(-1.0, 1.0, 0.0, {Piece{-1.0, NaN, false}}), doctest::Contains("not finite"),
                             std::invalid_argument);
    }
    SUBCASE("valid staircases and mixtures pass") {
        CHECK_NOTHROW(State(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}}));
        CHECK_NOTHROW(State(-1.0, 1.0, 0.2, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.4, true}}));
        CHECK_NOTHROW(State(-1.0, 1.0, 0.3, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}}));  // rising to 0.3
    }
}

TEST_CASE("state: extrema of a staircase") {
    const State s(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.5, false}, Piece{-0.2, 0.3, false}});
    CHECK(s.extrema() == std::vector<double>{0.8, -0.4, 0.5, -0.2, 0.3, 0.1});
    // Rising: the last maximum is the input itself and is not repeated.
    const State r(-1.0, 1.0, 0.3, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}});
    CHECK(r.extrema() == std::vector<double>{0.8, -0.4, 0.3});
    // The same from inputs (wiping out the dominated ones).
    const State a = apply_inputs(State::negative_saturation(-1.0, 1.0), {0.6, -0.5, 0.8, -0.4, 0.5, -0.2, 0.25,
                                                                          0.0, 0.3, 0.1});
    CHECK(a.extrema() == std::vector<double>{0.8, -0.4, 0.5, -0.2, 0.3, 0.1});
    CHECK(a == s);
    // Falling from positive saturation: u_max, then the minimum.
    CHECK(apply_inputs(State::positive_saturation(-1.0, 1.0), {-0.5}).extrema() == std::vector<double>{1.0, -0.5});
}

TEST_CASE("state: equality") {
    const State a(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}});
    const State b(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}});
    CHECK(a == b);
    CHECK_FALSE(a != b);
    CHECK(a != State(-1.0, 1.0, 0.0, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}}));
    CHECK(a != State(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.35, false}}));
    CHECK(a != State(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.5, 0.3, false}}));
    CHECK(a != State(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, true}}));
    CHECK(a != State(-1.0, 1.5, 0.1, {Piece{-1.0, 0.8, false}, Piece{-0.4, 0.3, false}}));
    CHECK(a != State(-1.0, 1.0, 0.1, {Piece{-1.0, 0.8, false}}));
    CHECK(Piece{0.0, 1.0, false} != Piece{0.0, 1.0, true});
}

TEST_CASE("state: apply_inputs builds the documented boundary") {
    const State n = State::negative_saturation(-1.0, 1.0);
    // Rise, fall, rise: two constant pieces.
    check_pieces(apply_inputs(n, {0.7, -0.2, 0.4}), {Piece{-1.0, 0.7, false}, Piece{-0.2, 0.4, false}});
    // A higher maximum wipes out the previous pair.
    check_pieces(apply_inputs(n, {0.7, -0.2, 0.4, 0.0, 0.9}), {Piece{-1.0, 0.9, false}});
    // A lower minimum cuts back to the first piece.
    const State f = apply_inputs(n, {0.7, -0.2, 0.4, -0.5});
    check_pieces(f, {Piece{-1.0, 0.7, false}});
    CHECK(f.input() == -0.5);
    // Rising out of a neutral state cuts the antidiagonal at c - u.
    const State z = apply_inputs(State::neutral(-1.0, 1.0, 0.0), {0.3});
    check_pieces(z, {Piece{-1.0, 0.0, true}, Piece{-0.3, 0.3, false}});
    // Falling inside it just moves the end.
    const State d = apply_inputs(State::neutral(-1.0, 1.0, 0.0), {-0.4});
    check_pieces(d, {Piece{-1.0, 0.0, true}});
    CHECK(d.input() == -0.4);
    // Inputs are checked.
    CHECK_THROWS_WITH_AS(apply_inputs(n, {0.1, 1.5}), doctest::Contains("u[1]"), std::invalid_argument);
}

}  // namespace unity_test_state
