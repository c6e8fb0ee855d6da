// SPDX-License-Identifier: MIT
#include "util/thread_pool.h"

#include "util/errors.h"

namespace horizonreg {

ThreadPool::ThreadPool(int num_threads) : size_(num_threads) {
  if (num_threads < 1 || num_threads > 256) ThrowField("ThreadPool::num_threads", num_threads, "1 <= n <= 256");
  for (int i = 1; i < num_threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::Work(Job& job, int slot) {
  for (size_t i = job.next.fetch_add(1); i < job.n; i = job.next.fetch_add(1)) {
    try {
      job.body(i, slot);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!job.error) job.error = std::current_exception();
    }
    if (job.finished.fetch_add(1) + 1 == job.n) {
      // Under the mutex, so that a caller between its check and its wait
      // cannot miss the notification.
      std::lock_guard<std::mutex> lock(mutex_);
      wake_.notify_all();
    }
  }
}

std::shared_ptr<ThreadPool::Job> ThreadPool::TakeSlot(int& slot) {
  for (auto it = jobs_.rbegin(); it != jobs_.rend(); ++it) {
    Job& j = **it;
    if (j.next.load() >= j.n || j.next_slot.load() >= j.slots) continue;
    slot = static_cast<int>(j.next_slot.fetch_add(1));
    return *it;
  }
  return nullptr;
}

void ThreadPool::Run(const std::shared_ptr<Job>& job) {
  int slot = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs_.push_back(job);
    slot = static_cast<int>(job->next_slot.fetch_add(1));
  }
  wake_.notify_all();
  Work(*job, slot);
  std::unique_lock<std::mutex> lock(mutex_);
  while (job->finished.load() != job->n) {
    int other_slot = 0;
    if (std::shared_ptr<Job> other = TakeSlot(other_slot)) {
      lock.unlock();
      Work(*other, other_slot);
      lock.lock();
      continue;
    }
    wake_.wait(lock);
  }
  for (auto it = jobs_.begin(); it != jobs_.end(); ++it)
    if (it->get() == job.get()) {
      jobs_.erase(it);
      break;
    }
  const std::exception_ptr error = job->error;
  lock.unlock();
  if (error) std::rethrow_exception(error);
}

void ThreadPool::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    if (stop_) return;
    int slot = 0;
    if (std::shared_ptr<Job> job = TakeSlot(slot)) {
      lock.unlock();
      Work(*job, slot);
      lock.lock();
      continue;
    }
    wake_.wait(lock);
  }
}

}  // namespace horizonreg
