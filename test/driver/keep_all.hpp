// A ScanBatcher sink for tests: keeps every finished rotation, each in a scan of its own (sized by
// the batcher on first use). Shared by the capture tests and the simulator's.
#pragma once

#include <deque>
#include <memory>
#include <vector>

#include "lidartag/driver/scan.hpp"

namespace lidartag::velodyne::testing {

class KeepAll {
 public:
  KeepAll() { fresh(); }
  Scan& current() { return *pool_.back(); }
  void keep(bool finished) {
    if (!finished) return;
    scans.push_back(pool_.back().get());
    fresh();
  }
  std::vector<Scan*> scans;

 private:
  void fresh() { pool_.push_back(std::make_unique<Scan>()); }
  std::deque<std::unique_ptr<Scan>> pool_;
};

}  // namespace lidartag::velodyne::testing
