// Many independent simulations on all cores (each row of the input is one run).
#pragma once

#include <algorithm>
#include <cstddef>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "simulator.hpp"

namespace preisach {

// Throws unless there is one state (for every row) or one per row of m.
inline void check_row_states(std::size_t n_states, std::size_t m) {
    if (n_states != 1 && n_states != m)
        throw std::invalid_argument("states: need one state or one per input row (" + std::to_string(m) +
                                    "), got " + std::to_string(n_states));
}

// Calls work(r) for every row r < m on `threads` worker threads (0: every core; rows are
// dealt round-robin).  A row's exception is kept; afterwards the first one (lowest row) is
// rethrown, an invalid_argument with "row r: " in front of its message.  Every batched run of
// the package (classical and rate-dependent, open and closed loop) goes through here.
template <class Work>
void for_each_row(std::size_t m, unsigned threads, Work&& work) {
    if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
    threads = unsigned(std::min<std::size_t>(threads, std::max<std::size_t>(m, 1)));
    std::vector<std::exception_ptr> errors(m);
    auto rows = [&](std::size_t first, std::size_t stride) {
        for (std::size_t r = first; r < m; r += stride) {
            try {
                work(r);
            } catch (...) {
                errors[r] = std::current_exception();
            }
        }
    };
    if (threads <= 1) {
        rows(0, 1);
    } else {
        std::vector<std::thread> pool;
        for (unsigned t = 0; t < threads; ++t) pool.emplace_back(rows, t, threads);
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
}

// Run row r of U (m x n, row-major) from states[r] (or states[0] for every row when one
// state is given); outputs go to Y (m x n).  Returns the final states.  threads == 0 means
// std::thread::hardware_concurrency().  The first error (lowest row) is rethrown.
inline std::vector<State> run_batch(const EverettTable& table, const std::vector<State>& states, const double* U,
                                    double* Y, std::size_t m, std::size_t n, InputPolicy policy,
                                    unsigned threads = 0) {
    check_row_states(states.size(), m);
    std::vector<State> finals(m);
    for_each_row(m, threads, [&](std::size_t r) {
        Simulator sim(table, states.size() == 1 ? states[0] : states[r]);
        sim.run(U + r * n, Y + r * n, n, policy);
        finals[r] = sim.state();
    });
    return finals;
}

}  // namespace preisach
