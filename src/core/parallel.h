// Work spread over threads (the set-up passes: macrocells, inactive blocks,
// pixel bounds; the differentiable renderer's and the fitters' passes): the
// calling thread works too, the others are the process's kept workers
// (run_parallel), and every helper returns when all the work is done,
// rethrowing the first exception a thread's share threw.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <thread>

#include "core/thread_pool.h"

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
    const int nt =
        static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(resolve_threads(threads), n)));
    run_parallel(nt, [&](int) {
        for (std::int64_t i = next++; i < n; i = next++) f(i);
    });
}

/// f(begin, end) over [0, n) in one contiguous chunk per thread, on up to
/// `threads` threads (0: all).
template <class F>
void parallel_chunks(std::int64_t n, int threads, F&& f) {
    const int nt =
        static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(resolve_threads(threads), n)));
    run_parallel(nt, [&](int t) { f(n * t / nt, n * (t + 1) / nt); });
}

/// f(begin, end, thread) over [0, count) in exactly `threads` contiguous
/// blocks (at least 1; thread 0 on the caller's), for passes that keep
/// per-thread buffers; the first exception a block throws (by thread index)
/// is rethrown once all have finished.
template <class F>
void parallel_blocks(std::size_t count, int threads, F&& f) {
    const auto nt = static_cast<std::size_t>(std::max(1, threads));
    run_parallel(static_cast<int>(nt), [&](int t) {
        const auto k = static_cast<std::size_t>(t);
        f(count * k / nt, count * (k + 1) / nt, t);
    });
}

}  // namespace fathom
