// Work spread over threads for the set-up passes (macrocells, inactive
// blocks, pixel bounds): the calling thread works too, and every helper
// returns when all the work is done.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
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

}  // namespace fathom
