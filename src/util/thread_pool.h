// SPDX-License-Identifier: MIT
// One pool of threads shared by every stage (horizon sweep, hypothesis
// scoring, refinement, photos of a batch), so that nested parallelism never
// starts more threads than asked for.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace horizonreg {

// A fixed set of worker threads. ParallelFor(n, fn) runs fn(i, slot) for
// every i in [0, n) on the workers and on the calling thread, and returns
// when all are done. Items are handed out one at a time from a shared
// counter, and the caller takes items too: a ParallelFor called from inside
// another (a photo's registration inside a batch over photos) never waits
// for an idle thread, so nested parallelism neither deadlocks nor
// oversubscribes (with every worker busy the caller runs all its items). A
// caller whose items are all handed out helps with the other loops in the
// pool (its items' nested loops among them) until its own are done.
// `slot` is in [0, size()) and unique among the threads running items of one
// ParallelFor at a time: an index for per-thread scratch space. Which thread
// runs which item is not fixed; callers that need the same result for any
// thread count keep results per item. Exceptions thrown by fn are rethrown in
// the caller (the first one; the remaining items still run).
// Thread-safe; the pool must outlive its ParallelFor calls.
class ThreadPool {
 public:
  // num_threads >= 1 threads in all, the caller's included (num_threads - 1
  // workers are started). Throws InvalidArgument outside [1, 256].
  explicit ThreadPool(int num_threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return size_; }

  template <typename Fn>
  void ParallelFor(size_t n, Fn&& fn) {
    if (n == 0) return;
    if (size_ == 1 || n == 1) {
      for (size_t i = 0; i < n; ++i) fn(i, 0);
      return;
    }
    auto job = std::make_shared<Job>();
    job->n = n;
    job->slots = std::min<size_t>(n, static_cast<size_t>(size_));
    job->body = [&fn](size_t i, int slot) { fn(i, slot); };
    Run(job);
  }

 private:
  struct Job {
    size_t n = 0, slots = 0;
    std::function<void(size_t, int)> body;
    std::atomic<size_t> next{0};       // next item to hand out
    std::atomic<size_t> finished{0};   // items done
    std::atomic<size_t> next_slot{0};  // slots handed to the threads that joined
    std::exception_ptr error;          // guarded by the pool's mutex
  };
  void Run(const std::shared_ptr<Job>& job);
  // Takes items of `job` until none is left. `slot` is this thread's slot
  // for the job.
  void Work(Job& job, int slot);
  // A job with items left and a free slot (the newest first: the innermost
  // of nested loops), with the slot taken; nullptr when there is none. Call
  // with mutex_ held.
  std::shared_ptr<Job> TakeSlot(int& slot);
  void WorkerLoop();

  int size_;
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::shared_ptr<Job>> jobs_;  // jobs with items left to hand out
  bool stop_ = false;
};

// ParallelFor on `pool` when given, else on the calling thread alone.
template <typename Fn>
void ParallelFor(ThreadPool* pool, size_t n, Fn&& fn) {
  if (pool) {
    pool->ParallelFor(n, std::forward<Fn>(fn));
  } else {
    for (size_t i = 0; i < n; ++i) fn(i, 0);
  }
}

}  // namespace horizonreg
