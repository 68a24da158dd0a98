// Many independent simulations on all cores (each row of the input is one run).
#pragma once

#include <algorithm>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

#include "simulator.hpp"

namespace preisach {

// Run row r of U (m x n, row-major) from states[r] (or states[0] for every row when one
// state is given); outputs go to Y (m x n).  Returns the final states.  threads == 0 means
// std::thread::hardware_concurrency().  The first error (lowest row) is rethrown.
inline std::vector<State> run_batch(const EverettTable& table, const std::vector<State>& states, const double* U,
                                    double* Y, std::size_t m, std::size_t n, InputPolicy policy,
                                    unsigned threads = 0) {
    if (states.size() != 1 && states.size() != m)
        throw std::invalid_argument("states: need one state or one per input row (" + std::to_string(m) +
                                    "), got " + std::to_string(states.size()));
    if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
    threads = unsigned(std::min<std::size_t>(threads, std::max<std::size_t>(m, 1)));
    std::vector<State> finals(m);
    std::vector<std::exception_ptr> errors(m);
    auto work = [&](std::size_t first, std::size_t stride) {
        for (std::size_t r = first; r < m; r += stride) {
            try {
                Simulator sim(table, states.size() == 1 ? states[0] : states[r]);
                sim.run(U + r * n, Y + r * n, n, policy);
                finals[r] = sim.state();
            } catch (...) {
                errors[r] = std::current_exception();
            }
        }
    };
    if (threads <= 1) {
        work(0, 1);
    } else {
        std::vector<std::thread> pool;
        for (unsigned t = 0; t < threads; ++t) pool.emplace_back(work, t, threads);
        for (auto& th : pool) th.join();
    }
    for (std::size_t r = 0; r < m; ++r)
        if (errors[r]) {
            try {
                std::rethrow_exception(errors[r]);
            } catch (const std::invalid_argument& e) {
                throw std::invalid_argument("row " + std::to_string(r) + ": " + e.what());
            }
        }
    return finals;
}

}  // namespace preisach
