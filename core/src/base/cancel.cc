// CancelScope and the polls of its flag (cancel.h).
#include "strokelab/base/cancel.h"

#include "strokelab/base/errors.h"

namespace strokelab {
namespace {
thread_local const std::atomic<bool>* t_cancel_flag = nullptr;
}  // namespace

CancelScope::CancelScope(const std::atomic<bool>* flag) : previous_(t_cancel_flag) { t_cancel_flag = flag; }
CancelScope::~CancelScope() { t_cancel_flag = previous_; }

const std::atomic<bool>* CurrentCancelFlag() { return t_cancel_flag; }

bool CancelRequested() { return t_cancel_flag != nullptr && t_cancel_flag->load(std::memory_order_relaxed); }

void ThrowIfCancelled() {
  if (CancelRequested()) throw Cancelled();
}

}  // namespace strokelab
