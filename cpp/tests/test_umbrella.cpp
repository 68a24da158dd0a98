// The umbrella header alone is enough for a C++ user: build a model from an Everett callable,
// simulate it, and check the wiping-out property on the way.
#include <cmath>
#include <vector>

#include <doctest/doctest.h>

#include <preisach/preisach.hpp>

TEST_CASE("umbrella header: a self-contained C++ program") {
    const std::size_t n = 41;
    Eigen::VectorXd levels(n);
    for (std::size_t i = 0; i < n; ++i) levels[Eigen::Index(i)] = -100.0 + 200.0 * double(i) / double(n - 1);
    preisach::RowMatrixXd e = preisach::RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    for (Eigen::Index i = 0; i < Eigen::Index(n); ++i)
        for (Eigen::Index j = 0; j <= i; ++j) e(i, j) = 1e-4 * std::pow(levels[i] - levels[j], 2);  // E(alpha, beta)
    const preisach::EverettTable table(levels, e, -2.0);
    preisach::Simulator sim(table, preisach::State::negative_saturation(-100.0, 100.0));
    const double y_top = sim.step(60.0);
    sim.step(-20.0);
    sim.step(40.0);  // a minor loop inside (60, -20) ...
    sim.step(-20.0);
    CHECK(sim.step(60.0) == doctest::Approx(y_top).epsilon(1e-12));  // ... wiped out at 60 V
}
