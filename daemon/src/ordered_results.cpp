#include "lidartag/daemon/ordered_results.hpp"

namespace lidartag::daemon {

OrderedResults::OrderedResults(size_t detectors, size_t publish_queue)
    : slots_(detectors + publish_queue), order_(detectors + publish_queue) {
  for (auto& s : slots_) free_slots_.push_back(&s);
  for (size_t i = 0; i < detectors; ++i) free_detectors_.push_back(static_cast<int>(i));
}

void OrderedResults::complete(Slot* slot) {
  bool wake = false;
  {
    std::lock_guard lock(mutex_);
    slot->done = true;
    slot->scan = nullptr;
    free_detectors_.push_back(slot->detector);
    slot->detector = -1;
    wake = count_ > 0 && order_[head_] == slot;
  }
  if (wake) ready_.notify_one();
}

OrderedResults::Slot* OrderedResults::next_ready(std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  const bool ready =
      ready_.wait_for(lock, wait, [this] { return count_ > 0 && order_[head_]->done; });
  if (!ready) return nullptr;
  Slot* slot = order_[head_];
  head_ = (head_ + 1) % order_.size();
  --count_;
  return slot;
}

void OrderedResults::recycle(Slot* slot) {
  std::lock_guard lock(mutex_);
  free_slots_.push_back(slot);
}

bool OrderedResults::has_free_slot() const {
  std::lock_guard lock(mutex_);
  return !free_slots_.empty() && !free_detectors_.empty();
}

size_t OrderedResults::in_use() const {
  std::lock_guard lock(mutex_);
  return slots_.size() - free_slots_.size();
}

int64_t OrderedResults::oldest_in_detection_ns() const {
  std::lock_guard lock(mutex_);
  for (size_t i = 0; i < count_; ++i) {
    const Slot* s = order_[(head_ + i) % order_.size()];
    if (!s->done) return s->result.taken_ns;
  }
  return 0;
}

}  // namespace lidartag::daemon
