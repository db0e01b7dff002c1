// Work spread over threads (the set-up passes: macrocells, inactive blocks,
// pixel bounds; the differentiable renderer's and the fitters' passes): the
// calling thread works too, and every helper returns when all the work is
// done.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <thread>
#include <vector>

namespace fathom {

/// The thread count a setting asks for: itself when positive, else every
/// hardware thread.
inline int resolve_threads(int threads) {
    return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

/// f(i) for i in [0, n), items handed out one at a time by an atomic
/// counter (uneven items balance), on up to `threads` threads (0: all).
template <class F>
void parallel_items(std::int64_t n, int threads, F&& f) {
    std::atomic<std::int64_t> next{0};
    auto worker = [&] {
        for (std::int64_t i = next++; i < n; i = next++) f(i);
    };
    const int nt =
        static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(resolve_threads(threads), n)));
    std::vector<std::thread> pool;
    for (int t = 1; t < nt; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
}

/// f(begin, end) over [0, n) in one contiguous chunk per thread, on up to
/// `threads` threads (0: all).
template <class F>
void parallel_chunks(std::int64_t n, int threads, F&& f) {
    const int nt =
        static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(resolve_threads(threads), n)));
    std::vector<std::thread> pool;
    for (int t = 1; t < nt; ++t) pool.emplace_back([&, t] { f(n * t / nt, n * (t + 1) / nt); });
    f(0, n / nt);
    for (auto& t : pool) t.join();
}

/// f(begin, end, thread) over [0, count) in exactly `threads` contiguous
/// blocks (at least 1; thread 0 on the caller's), for passes that keep
/// per-thread buffers; the first exception a block throws (by thread index)
/// is rethrown once all have finished.
template <class F>
void parallel_blocks(std::size_t count, int threads, F&& f) {
    const auto nt = static_cast<std::size_t>(std::max(1, threads));
    std::vector<std::exception_ptr> failure(nt);
    auto work = [&](std::size_t t) {
        try {
            f(count * t / nt, count * (t + 1) / nt, static_cast<int>(t));
        } catch (...) {
            failure[t] = std::current_exception();
        }
    };
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < nt; ++t) pool.emplace_back(work, t);
    work(0);
    for (auto& th : pool) th.join();
    for (const auto& e : failure)
        if (e) std::rethrow_exception(e);
}

}  // namespace fathom
