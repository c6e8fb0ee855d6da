// SPDX-License-Identifier: MIT
#include "util/thread_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <set>
#include <stdexcept>
#include <thread>

#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(ThreadPool, RunsEveryItemOnce) {
  for (int threads : {1, 2, 4}) {
    ThreadPool pool(threads);
    std::vector<std::atomic<int>> hits(1000);
    pool.ParallelFor(hits.size(), [&](size_t i, int slot) {
      ASSERT_GE(slot, 0);
      ASSERT_LT(slot, threads);
      hits[i].fetch_add(1);
    });
    for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
  }
}

TEST(ThreadPool, SlotsAreExclusiveWithinOneLoop) {
  ThreadPool pool(4);
  std::vector<std::atomic<int>> busy(4);
  std::atomic<bool> clash{false};
  pool.ParallelFor(400, [&](size_t, int slot) {
    if (busy[slot].fetch_add(1) != 0) clash = true;
    std::this_thread::yield();
    busy[slot].fetch_sub(1);
  });
  EXPECT_FALSE(clash.load());
}

TEST(ThreadPool, UsesTheWorkers) {
  ThreadPool pool(2);
  std::mutex m;
  std::set<std::thread::id> ids;
  pool.ParallelFor(64, [&](size_t, int) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    std::lock_guard<std::mutex> lock(m);
    ids.insert(std::this_thread::get_id());
  });
  EXPECT_EQ(ids.size(), 2u);
}

TEST(ThreadPool, NestedLoopsFinishWithoutExtraThreads) {
  // An outer loop over "photos" whose items run inner loops over "rows": the
  // threads in use never exceed the pool's size, and nothing deadlocks.
  ThreadPool pool(3);
  std::atomic<int> running{0}, peak{0};
  std::atomic<long> total{0};
  pool.ParallelFor(12, [&](size_t outer, int) {
    pool.ParallelFor(50, [&](size_t inner, int) {
      const int now = running.fetch_add(1) + 1;
      int p = peak.load();
      while (now > p && !peak.compare_exchange_weak(p, now)) {
      }
      total.fetch_add(static_cast<long>(outer * 100 + inner));
      std::this_thread::yield();
      running.fetch_sub(1);
    });
  });
  long expect = 0;
  for (int o = 0; o < 12; ++o)
    for (int i = 0; i < 50; ++i) expect += o * 100 + i;
  EXPECT_EQ(total.load(), expect);
  EXPECT_LE(peak.load(), 3);
}

TEST(ThreadPool, RethrowsTheFirstErrorAfterEveryItem) {
  ThreadPool pool(2);
  std::atomic<int> ran{0};
  EXPECT_THROW(pool.ParallelFor(100,
                                [&](size_t i, int) {
                                  ran.fetch_add(1);
                                  if (i == 10) throw std::runtime_error("item 10");
                                }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 100);
  // The pool is still usable.
  std::atomic<int> again{0};
  pool.ParallelFor(10, [&](size_t, int) { again.fetch_add(1); });
  EXPECT_EQ(again.load(), 10);
}

TEST(ThreadPool, ManyShortLoopsFromTwoCallers) {
  ThreadPool pool(2);
  std::atomic<long> sum{0};
  auto caller = [&] {
    for (int k = 0; k < 200; ++k) pool.ParallelFor(7, [&](size_t i, int) { sum.fetch_add(static_cast<long>(i)); });
  };
  std::thread a(caller), b(caller);
  a.join();
  b.join();
  EXPECT_EQ(sum.load(), 2L * 200 * 21);
}

TEST(ThreadPool, RejectsABadSize) {
  EXPECT_THROW(ThreadPool(0), InvalidArgument);
  EXPECT_THROW(ThreadPool(1000), InvalidArgument);
}

TEST(ThreadPool, FreeFunctionWithoutAPool) {
  std::vector<int> v(5, 0);
  ParallelFor(nullptr, v.size(), [&](size_t i, int slot) {
    EXPECT_EQ(slot, 0);
    v[i] = static_cast<int>(i);
  });
  EXPECT_EQ(std::accumulate(v.begin(), v.end(), 0), 10);
}

}  // namespace
}  // namespace horizonreg
