// run_parallel (src/core/thread_pool.h) and the helpers on it
// (src/core/parallel.h): every share runs once, on the caller's thread
// for t = 0, exceptions reach the caller, and regions asked for while the
// kept workers are taken (nested, from other threads, in a forked child)
// still run.
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include "core/parallel.h"
#include "core/thread_pool.h"

namespace {

using fathom::run_parallel;

/// Runs a region of n threads and checks every t ran exactly once, t = 0
/// on the calling thread and the others not.
void expect_region(int n) {
    std::vector<std::atomic<int>> ran(static_cast<std::size_t>(n));
    std::vector<std::thread::id> on(static_cast<std::size_t>(n));
    run_parallel(n, [&](int t) {
        ran[static_cast<std::size_t>(t)]++;
        on[static_cast<std::size_t>(t)] = std::this_thread::get_id();
    });
    for (int t = 0; t < n; ++t)
        EXPECT_EQ(ran[static_cast<std::size_t>(t)].load(), 1) << "n " << n << " t " << t;
    EXPECT_EQ(on[0], std::this_thread::get_id()) << "n " << n;
    for (int t = 1; t < n; ++t) EXPECT_NE(on[static_cast<std::size_t>(t)], std::this_thread::get_id()) << t;
}

TEST(Parallel, EveryShareRunsOnceWithTheCallerAsThreadZero) {
    // the kept workers grow from 1 to 7 and serve regions of fewer again
    for (int round = 0; round < 200; ++round)
        for (int n : {1, 2, 3, 8, 2}) expect_region(n);
}

TEST(Parallel, RegionsOfDifferentSizesDoNotRunStaleShares) {
    // a region of 2 after one of 8: the workers 2..7 must not run its job
    std::atomic<int> calls{0};
    for (int round = 0; round < 500; ++round) {
        calls = 0;
        run_parallel(8, [&](int) { calls++; });
        EXPECT_EQ(calls.load(), 8);
        calls = 0;
        run_parallel(2, [&](int) { calls++; });
        EXPECT_EQ(calls.load(), 2);
    }
}

TEST(Parallel, TheLowestThrowingShareReachesTheCaller) {
    for (int round = 0; round < 50; ++round) {
        std::atomic<int> ran{0};
        try {
            run_parallel(4, [&](int t) {
                ran++;
                if (t >= 2) throw std::runtime_error("share " + std::to_string(t));
            });
            ADD_FAILURE() << "no exception";
        } catch (const std::runtime_error& e) {
            EXPECT_STREQ(e.what(), "share 2");
        }
        EXPECT_EQ(ran.load(), 4);  // the others still ran to the end
        try {
            run_parallel(3, [](int t) {
                if (t == 0) throw std::logic_error("caller");
            });
            ADD_FAILURE() << "no exception";
        } catch (const std::logic_error& e) {
            EXPECT_STREQ(e.what(), "caller");
        }
    }
    expect_region(4);  // the workers serve on
}

TEST(Parallel, NestedRegionsRunOnThreadsOfTheirOwn) {
    std::atomic<int> inner{0};
    run_parallel(2, [&](int) { run_parallel(3, [&](int) { inner++; }); });
    EXPECT_EQ(inner.load(), 6);
    std::atomic<std::int64_t> sum{0};
    fathom::parallel_chunks(100, 2, [&](std::int64_t a, std::int64_t b) {
        fathom::parallel_items(b - a, 2, [&](std::int64_t i) { sum += a + i; });
    });
    EXPECT_EQ(sum.load(), 4950);
}

TEST(Parallel, ConcurrentCallersEachGetTheirRegion) {
    std::atomic<int> wrong{0};
    auto caller = [&] {
        for (int round = 0; round < 300; ++round) {
            std::atomic<int> mask{0};
            run_parallel(3, [&](int t) { mask |= 1 << t; });
            if (mask.load() != 7) wrong++;
        }
    };
    std::thread a(caller), b(caller);
    caller();
    a.join();
    b.join();
    EXPECT_EQ(wrong.load(), 0);
}

TEST(Parallel, HelpersCoverTheirRanges) {
    for (int threads : {1, 2, 5}) {
        std::vector<int> hit(1001, 0);
        fathom::parallel_items(1001, threads, [&](std::int64_t i) { hit[static_cast<std::size_t>(i)]++; });
        fathom::parallel_chunks(1001, threads, [&](std::int64_t a, std::int64_t b) {
            for (auto i = a; i < b; ++i) hit[static_cast<std::size_t>(i)]++;
        });
        std::mutex m;
        std::set<int> ids;
        fathom::parallel_blocks(1001, threads, [&](std::size_t a, std::size_t b, int t) {
            for (auto i = a; i < b; ++i) hit[i]++;
            std::lock_guard lock(m);
            ids.insert(t);
        });
        for (int h : hit) ASSERT_EQ(h, 3) << threads;
        EXPECT_EQ(static_cast<int>(ids.size()), threads);
    }
    EXPECT_THROW(fathom::parallel_items(10, 2,
                                        [](std::int64_t i) {
                                            if (i == 7) throw std::runtime_error("item");
                                        }),
                 std::runtime_error);
}

TEST(Parallel, AForkedChildRunsRegionsWithoutTheParentsWorkers) {
    expect_region(2);  // the parent's workers exist
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        std::atomic<int> calls{0};
        for (int round = 0; round < 20; ++round) run_parallel(2, [&](int) { calls++; });
        _exit(calls.load() == 40 ? 0 : 3);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
    expect_region(3);
}

}  // namespace
