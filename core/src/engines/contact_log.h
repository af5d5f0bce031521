// The contact intervals of a record (Record::contacts), kept as an engine reports its stop switches:
// the exact and CVODE engines at located switching instants, the fixed-step engine at samples.
#pragma once

#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/dynamics.h"

namespace strokelab {

class ContactLog {
 public:
  // `initial`: the stops already pushing at t = 0, whose contacts start there.
  ContactLog(std::vector<ContactInterval>* out, ContactMode initial) : out_(out), mode_(initial) {
    if (initial.lower) out_->push_back({0.0, 0.0, false, false});
    if (initial.upper) out_->push_back({0.0, 0.0, true, false});
  }
  // The stops pushing from `time_s` on: a stop that starts opens a contact, one that stops closes it.
  void Update(double time_s, ContactMode mode) {
    Edge(time_s, mode_.lower, mode.lower, false);
    Edge(time_s, mode_.upper, mode.upper, true);
    mode_ = mode;
  }
  // The record ends at `end_s`: contacts still on end there, marked not closed.
  void Finish(double end_s) {
    for (ContactInterval& c : *out_)
      if (!c.closed) c.end_s = end_s;
  }

 private:
  void Edge(double time_s, bool was, bool is, bool upper) {
    if (!was && is) out_->push_back({time_s, time_s, upper, false});
    if (was && !is) {
      for (auto it = out_->rbegin(); it != out_->rend(); ++it) {
        if (it->upper == upper && !it->closed) {
          it->end_s = time_s;
          it->closed = true;
          break;
        }
      }
    }
  }
  std::vector<ContactInterval>* out_;
  ContactMode mode_;
};

}  // namespace strokelab
