// Streaming CSV recordings in the format of preisach.recording (read by Recording.load).
//
// The file is the project's one recording format: leading "# key: value" metadata lines, a
// header row naming the columns (t, u, y first), one row per sample with every float in its
// shortest round-trip decimal form (std::to_chars, like Python's repr), and trailing
// "# key: value" lines ending with "# end_status: ...".  Metadata values are formatted
// exactly as preisach.recording formats them, so they read back unchanged.
//
// Rows are pushed into a preallocated ring buffer by the sample loop and written by a writer
// thread in chunks.  Why a writer thread rather than flushing chunks from the loop: formatting
// a chunk of rows and above all write()/fsync() can block for milliseconds at unpredictable
// times (page cache writeback, a slow disk), which would make a 1 kHz loop miss deadlines;
// with a writer thread the loop's worst case is a lock-free copy into the ring, and the ring
// (65536 rows by default, a minute at 1 kHz) absorbs disk stalls.  Every chunk is flushed to
// the operating system (and fsync'ed, unless disabled) before the next one, so a crash of
// the process loses at most the rows of the last flush interval (50 ms); a normal end, an
// abort, an exception or a stop request drain the ring completely before the trailer.
#pragma once

#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <variant>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include "ring_buffer.hpp"

namespace preisach::daq {

// Failure to create or write a recording file; carries errno (Python: the matching OSError).
class RecordingIOError : public std::runtime_error {
public:
    RecordingIOError(const std::string& msg, int err, std::string path)
        : std::runtime_error(msg), err_(err), path_(std::move(path)) {}
    int error_code() const noexcept { return err_; }
    const std::string& path() const noexcept { return path_; }

private:
    int err_;
    std::string path_;
};

using MetaValue = std::variant<std::string, long long, double>;
using MetaItem = std::pair<std::string, MetaValue>;

// Metadata keys and column names: letters, digits, '_', '.', '-', starting with a letter or '_'.
inline bool valid_name(const std::string& s) {
    if (s.empty()) return false;
    const auto c0 = static_cast<unsigned char>(s[0]);
    if (!(std::isalpha(c0) || c0 == '_')) return false;
    for (char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        if (!(std::isalnum(c) || c == '_' || c == '.' || c == '-')) return false;
        if (c >= 0x80) return false;
    }
    return true;
}

namespace detail {

// Does s read back as a number in preisach.recording (its _INT_RE / _FLOAT_RE)?
inline bool looks_numeric(const std::string& s) {
    std::size_t i = 0;
    const std::size_t n = s.size();
    if (i < n && (s[i] == '+' || s[i] == '-')) ++i;
    std::string rest;
    for (std::size_t k = i; k < n; ++k) rest += char(std::tolower(static_cast<unsigned char>(s[k])));
    if (rest == "nan" || rest == "inf" || rest == "infinity") return true;
    std::size_t digits = 0, j = 0;
    while (j < rest.size() && std::isdigit(static_cast<unsigned char>(rest[j]))) ++j, ++digits;
    if (j < rest.size() && rest[j] == '.') {
        ++j;
        while (j < rest.size() && std::isdigit(static_cast<unsigned char>(rest[j]))) ++j, ++digits;
    }
    if (digits == 0) return false;
    if (j < rest.size() && rest[j] == 'e') {
        ++j;
        if (j < rest.size() && (rest[j] == '+' || rest[j] == '-')) ++j;
        std::size_t ed = 0;
        while (j < rest.size() && std::isdigit(static_cast<unsigned char>(rest[j]))) ++j, ++ed;
        if (ed == 0) return false;
    }
    return j == rest.size();
}

inline std::string json_quote(const std::string& s) {
    std::string out = "\"";
    for (char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        if (ch == '"') out += "\\\"";
        else if (ch == '\\') out += "\\\\";
        else if (c < 0x20 || c == 0x7f) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", unsigned(c));
            out += buf;
        } else out += ch;  // UTF-8 bytes pass through; json.loads accepts them
    }
    return out + "\"";
}

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }

}  // namespace detail

// Shortest decimal text that reads back to the same double (like Python's repr).
inline std::size_t format_double(char* buf, std::size_t size, double v) {
    const auto r = std::to_chars(buf, buf + size, v);
    return std::size_t(r.ptr - buf);
}

// A metadata value as preisach.recording._format_meta_value writes it.
inline std::string format_meta_value(const MetaValue& v) {
    if (const auto* i = std::get_if<long long>(&v)) return std::to_string(*i);
    if (const auto* d = std::get_if<double>(&v)) {
        if (std::isnan(*d)) return "nan";
        if (std::isinf(*d)) return *d > 0 ? "inf" : "-inf";
        char buf[40];
        std::string s(buf, format_double(buf, sizeof buf, *d));
        if (s.find_first_of(".e") == std::string::npos) s += ".0";  // else it would read back as an int
        return s;
    }
    const std::string& s = std::get<std::string>(v);
    bool plain = s.empty() || (!detail::is_space(s.front()) && !detail::is_space(s.back()));
    plain = plain && (s.empty() || s.front() != '"') && !detail::looks_numeric(s);
    for (char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        if (c < 0x20 || c >= 0x7f) plain = false;  // control or non-ASCII: quote to be safe
    }
    return plain ? s : detail::json_quote(s);
}

inline std::string meta_lines(const std::vector<MetaItem>& items) {
    std::string out;
    for (const auto& [k, v] : items) {
        if (!valid_name(k))
            throw std::invalid_argument("metadata key '" + k +
                                        "' is not a valid name (letters, digits, '_', '.', '-', starting with a "
                                        "letter or '_')");
        std::string line = "# " + k + ": " + format_meta_value(v);
        while (!line.empty() && line.back() == ' ') line.pop_back();
        out += line + "\n";
    }
    return out;
}

// Streams rows to a CSV recording from a writer thread (see the file comment).
class StreamingCsv {
public:
    StreamingCsv(const std::string& path, const std::vector<std::string>& columns,
                 const std::vector<MetaItem>& metadata, bool overwrite = false, bool fsync = true,
                 std::size_t capacity_rows = 65536, double flush_interval = 0.05)
        : path_(path), ring_(capacity_rows, columns.size()), fsync_(fsync),
          interval_(std::chrono::microseconds(std::int64_t(flush_interval * 1e6))) {
        check_columns(columns);
        std::string head = meta_lines(metadata);
        for (std::size_t i = 0; i < columns.size(); ++i) head += (i ? "," : "") + columns[i];
        head += "\n";
        fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | (overwrite ? O_TRUNC : O_EXCL), 0644);
        if (fd_ < 0) {
            const int e = errno;
            throw RecordingIOError("cannot create recording '" + path + "': " + std::strerror(e), e, path);
        }
        if (!write_all(head) || !sync()) {
            const std::string msg = error_;
            ::close(fd_);
            fd_ = -1;
            throw RecordingIOError(msg, err_, path);
        }
        thread_ = std::thread([this] { loop(); });
    }
    StreamingCsv(const StreamingCsv&) = delete;
    StreamingCsv& operator=(const StreamingCsv&) = delete;
    ~StreamingCsv() {
        try {
            finish({});
        } catch (...) {
        }
    }

    // Producer side: false when the ring is full (the caller waits and retries).
    bool try_push(const double* row) noexcept { return ring_.try_push(row); }
    // True once a write failed; the message is error().
    bool failed() const noexcept { return failed_.load(); }
    std::string error() const {
        std::lock_guard<std::mutex> lock(mutex_);
        return error_;
    }
    std::size_t rows_written() const noexcept { return rows_.load(); }
    std::size_t buffered() const noexcept { return ring_.size(); }
    const std::string& path() const noexcept { return path_; }

    // Drain every pushed row, append the trailing metadata, sync and close.  Idempotent.
    // Throws RecordingIOError if any write failed (the rows before the failure stay valid).
    void finish(const std::vector<MetaItem>& trailer) {
        if (fd_ < 0) return;
        stop_.store(true);
        if (thread_.joinable()) thread_.join();
        drain();
        if (!failed_) {
            write_all(meta_lines(trailer));
            sync();
        }
        ::close(fd_);
        fd_ = -1;
        if (failed_) throw RecordingIOError(error(), err_, path_);
    }

private:
    static void check_columns(const std::vector<std::string>& c) {
        for (std::size_t i = 0; i < c.size(); ++i) {
            if (!valid_name(c[i]) || c[i].rfind("__", 0) == 0)
                throw std::invalid_argument("column name '" + c[i] + "' is not valid");
            for (std::size_t j = 0; j < i; ++j)
                if (c[i] == c[j]) throw std::invalid_argument("duplicate column name '" + c[i] + "'");
        }
        for (const char* req : {"t", "u", "y"}) {
            bool found = false;
            for (const auto& s : c) found = found || s == req;
            if (!found) throw std::invalid_argument(std::string("columns must include '") + req + "'");
        }
    }

    void loop() {
        while (!stop_.load()) {
            if (drain() == 0) std::this_thread::sleep_for(interval_);
        }
    }

    // Write every row currently in the ring; returns the number of rows written.
    std::size_t drain() {
        if (failed_) return 0;
        const std::size_t w = ring_.width();
        const std::size_t chunk = 4096;
        rows_buf_.resize(chunk * w);
        std::size_t total = 0;
        for (;;) {
            const std::size_t n = ring_.pop(rows_buf_.data(), chunk);
            if (n == 0) break;
            text_.clear();
            char buf[40];
            for (std::size_t r = 0; r < n; ++r) {
                for (std::size_t c = 0; c < w; ++c) {
                    if (c) text_ += ',';
                    text_.append(buf, format_double(buf, sizeof buf, rows_buf_[r * w + c]));
                }
                text_ += '\n';
            }
            if (!write_all(text_)) return total;
            rows_.fetch_add(n);
            total += n;
            if (n < chunk) break;
        }
        if (total && !sync()) return total;
        return total;
    }

    bool write_all(const std::string& s) {
        std::size_t off = 0;
        while (off < s.size()) {
            const ssize_t r = ::write(fd_, s.data() + off, s.size() - off);
            if (r < 0) {
                if (errno == EINTR) continue;
                fail("writing", errno);
                return false;
            }
            off += std::size_t(r);
        }
        return true;
    }
    bool sync() {
        if (!fsync_) return true;
        if (::fsync(fd_) != 0 && errno != EINVAL && errno != EROFS) {
            fail("syncing", errno);
            return false;
        }
        return true;
    }
    void fail(const char* what, int e) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!failed_) {
            err_ = e;
            error_ = std::string("error ") + what + " recording '" + path_ + "': " + std::strerror(e);
            failed_.store(true);
        }
    }

    std::string path_;
    RowRing ring_;
    bool fsync_;
    std::chrono::microseconds interval_;
    int fd_ = -1;
    std::thread thread_;
    std::atomic<bool> stop_{false};
    std::atomic<bool> failed_{false};
    std::atomic<std::size_t> rows_{0};
    mutable std::mutex mutex_;
    std::string error_;
    int err_ = 0;
    std::vector<double> rows_buf_;
    std::string text_;
};

}  // namespace preisach::daq
