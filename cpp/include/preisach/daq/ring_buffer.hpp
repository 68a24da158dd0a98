// Single-producer single-consumer ring buffer of fixed-width rows of doubles.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace preisach::daq {

// Preallocated once; push and pop never allocate, lock or make a system call, so the
// sample loop can push from a real-time thread while a writer thread pops.  The two
// counters only grow (row index = counter mod capacity); the producer owns head_, the
// consumer owns tail_, and acquire/release ordering publishes the row contents.
class RowRing {
public:
    RowRing(std::size_t capacity_rows, std::size_t width) : cap_(capacity_rows), width_(width) {
        if (capacity_rows < 2) throw std::invalid_argument("ring buffer: capacity must be >= 2 rows");
        if (width == 0) throw std::invalid_argument("ring buffer: row width must be >= 1");
        data_.assign(cap_ * width_, 0.0);
    }
    std::size_t capacity() const noexcept { return cap_; }
    std::size_t width() const noexcept { return width_; }
    std::size_t size() const noexcept { return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire); }

    // Producer: copy one row in; false (nothing written) when the ring is full.
    bool try_push(const double* row) noexcept {
        const std::size_t h = head_.load(std::memory_order_relaxed);
        if (h - tail_.load(std::memory_order_acquire) >= cap_) return false;
        std::copy(row, row + width_, data_.begin() + std::ptrdiff_t((h % cap_) * width_));
        head_.store(h + 1, std::memory_order_release);
        return true;
    }

    // Consumer: copy up to max_rows rows into out (row-major); returns the number copied.
    std::size_t pop(double* out, std::size_t max_rows) noexcept {
        const std::size_t t = tail_.load(std::memory_order_relaxed);
        const std::size_t n = std::min(max_rows, head_.load(std::memory_order_acquire) - t);
        for (std::size_t i = 0; i < n; ++i) {
            const auto src = data_.begin() + std::ptrdiff_t(((t + i) % cap_) * width_);
            std::copy(src, src + std::ptrdiff_t(width_), out + i * width_);
        }
        tail_.store(t + n, std::memory_order_release);
        return n;
    }

private:
    std::size_t cap_, width_;
    std::vector<double> data_;
    alignas(64) std::atomic<std::size_t> head_{0};
    alignas(64) std::atomic<std::size_t> tail_{0};
};

}  // namespace preisach::daq
