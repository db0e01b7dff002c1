#include "core/thread_pool.h"

#include <unistd.h>

#include <atomic>
#include <exception>
#include <thread>
#include <vector>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace fathom {
namespace {

/// A moment's wait in a spin loop.
inline void relax() {
#if defined(__x86_64__) || defined(__i386__)
    _mm_pause();
#else
    std::this_thread::yield();
#endif
}

/// Spins before a worker (or the caller, waiting on them) sleeps: about
/// 50 µs, longer than the gap between a frame's regions, so that the next
/// one finds the workers awake (waking a sleeping one costs tens of µs on
/// a virtual machine).
constexpr int kSpins = 4000;

/// Regions of at most this many threads use the kept workers (the count
/// travels in the low byte of the region's word).
constexpr int kMostThreads = 255;

/// Rethrows the first of a region's shares' exceptions (the lowest share), if any.
void rethrow_first(const std::vector<std::exception_ptr>& failure) {
    for (const auto& e : failure)
        if (e) std::rethrow_exception(e);
}

void run_on_new_threads(int n, const std::function<void(int)>& f) {
    std::vector<std::exception_ptr> failure(static_cast<std::size_t>(n));
    auto work = [&](int t) {
        try {
            f(t);
        } catch (...) {
            failure[static_cast<std::size_t>(t)] = std::current_exception();
        }
    };
    std::vector<std::thread> pool;
    pool.reserve(static_cast<std::size_t>(n - 1));
    for (int t = 1; t < n; ++t) pool.emplace_back(work, t);
    work(0);
    for (auto& th : pool) th.join();
    rethrow_first(failure);
}

class Workers {
public:
    /// The region on n threads, or false (nothing run) where the workers
    /// are taken.
    bool run(int n, const std::function<void(int)>& f) {
        bool expected = false;
        if (!busy_.compare_exchange_strong(expected, true, std::memory_order_acquire)) return false;
        struct Release {
            std::atomic<bool>& busy;
            ~Release() { busy.store(false, std::memory_order_release); }
        } release{busy_};
        while (static_cast<int>(threads_.size()) < n - 1) {
            const int index = static_cast<int>(threads_.size()) + 1;
            const unsigned seen = region_.load(std::memory_order_relaxed);
            threads_.emplace_back([this, index, seen] { serve(index, seen); });
        }
        job_ = &f;
        failure_.assign(static_cast<std::size_t>(n), nullptr);
        left_.store(n - 1, std::memory_order_relaxed);
        // the region's number (high 24 bits, wrapping) and thread count (low
        // byte) in one word, so that a worker reads both at once: a worker
        // sees each new word (every region wakes them all), and only one
        // asleep through 2²⁴ regions could take a later word for its last
        const unsigned next = ((region_.load(std::memory_order_relaxed) >> 8) + 1) << 8;
        region_.store(next | static_cast<unsigned>(n), std::memory_order_release);
        region_.notify_all();
        try {
            f(0);
        } catch (...) {
            failure_[0] = std::current_exception();
        }
        for (int i = 0;; ++i) {
            const int left = left_.load(std::memory_order_acquire);
            if (left == 0) break;
            if (i < kSpins)
                relax();
            else
                left_.wait(left, std::memory_order_acquire);
        }
        job_ = nullptr;
        rethrow_first(failure_);
        return true;
    }

    /// The process the workers belong to (a forked child has none of them).
    [[nodiscard]] pid_t owner() const { return owner_; }

private:
    void serve(int index, unsigned seen) {
        for (;;) {
            unsigned now = 0;
            for (int i = 0;; ++i) {
                now = region_.load(std::memory_order_acquire);
                if (now != seen) break;
                if (i < kSpins)
                    relax();
                else
                    region_.wait(seen, std::memory_order_acquire);
            }
            seen = now;
            // the count of this region; its job stays set until every one of
            // its threads has finished, this one included
            if (index >= static_cast<int>(now & 0xFFu)) continue;
            try {
                (*job_)(index);
            } catch (...) {
                failure_[static_cast<std::size_t>(index)] = std::current_exception();
            }
            if (left_.fetch_sub(1, std::memory_order_acq_rel) == 1) left_.notify_one();
        }
    }

    std::atomic<bool> busy_{false};
    std::atomic<unsigned> region_{0};
    std::atomic<int> left_{0};
    const std::function<void(int)>* job_ = nullptr;
    std::vector<std::exception_ptr> failure_;
    std::vector<std::thread> threads_;  // never joined: they serve until the process ends
    pid_t owner_ = getpid();
};

/// The process's workers, made on first use and never destroyed (threads
/// parked at exit must not meet a destroyed pool).
Workers& workers() {
    static Workers* const w = new Workers;
    return *w;
}

}  // namespace

void run_parallel(int n, const std::function<void(int)>& f) {
    if (n <= 1) {
        f(0);
        return;
    }
    if (n <= kMostThreads) {
        Workers& w = workers();
        if (w.owner() == getpid() && w.run(n, f)) return;
    }
    run_on_new_threads(n, f);
}

}  // namespace fathom
